"""bench/record.py, run small: a recorder subscribed from outside keeps every trace event of a
steady stream (counted in the file it wrote), and the writer thread keeps up with a burst."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.network

REPO = Path(__file__).resolve().parent.parent


@pytest.mark.timeout(120)
def test_no_trace_event_is_lost_at_a_steady_rate() -> None:
    done = subprocess.run([sys.executable, str(REPO / "bench" / "record.py"), "--parts", "throughput",
                           "--rate", "1000", "--seconds", "1.5", "--writer-events", "3000"],
                          capture_output=True, text=True, timeout=110, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])["throughput"]
    assert result["sent"] == 1500
    assert result["in_file"] == result["sent"] and result["lost"] == 0 and result["dropped"] == 0
    assert result["writer_dropped"] == 0 and result["writer_events_per_s"] > 0
