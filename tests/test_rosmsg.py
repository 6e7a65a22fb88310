"""umlbot's ROS 2 message definitions: shipped, parsed by rosbags, CDR round trip, clear error
without the extra, and the core import does not pull rosbags in."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from umlbot.base import rosmsg
from umlbot.base.errors import MissingExtra


def test_every_definition_is_shipped_and_parses() -> None:
    texts = rosmsg.message_definitions()
    assert set(texts) == set(rosmsg.TYPE_NAMES)
    store = rosmsg.typestore()
    for name in rosmsg.TYPE_NAMES:
        assert name in store.types
        # every message is stamped: the recorder and the ROS 2 bridge rely on it
        assert "builtin_interfaces/Time stamp" in texts[name]


def test_trace_event_cdr_round_trip() -> None:
    store = rosmsg.typestore()
    time_type = store.types["builtin_interfaces/msg/Time"]
    trace_type = store.types["umlbot_msgs/msg/TraceEvent"]
    event = trace_type(
        stamp=time_type(sec=12, nanosec=500_000_000), seq=7, lane="Drive", node="n3", kind="action",
        start=12.25, end=12.5, duration_ms=250.0, value_json=json.dumps({"cm": 41}), level="info",
        error="", detail="LeftActuator.dutycycle(60)",
    )
    raw = store.serialize_cdr(event, "umlbot_msgs/msg/TraceEvent")
    back: Any = store.deserialize_cdr(raw, "umlbot_msgs/msg/TraceEvent")
    assert back.seq == 7 and back.lane == "Drive" and back.stamp.nanosec == 500_000_000
    assert json.loads(back.value_json) == {"cm": 41}


def test_missing_rosbags_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "rosbags", None)
    monkeypatch.setitem(sys.modules, "rosbags.typesys", None)
    rosmsg.typestore.cache_clear()
    try:
        with pytest.raises(MissingExtra, match=r"pip install 'umlbot\[ros2\]'") as caught:
            rosmsg.typestore("ros2")
        assert isinstance(caught.value, ImportError)
    finally:
        rosmsg.typestore.cache_clear()


def test_core_import_does_not_import_rosbags() -> None:
    code = ("import sys, umlbot.base.rosmsg as m; m.message_definitions(); "
            "print(sorted(n for n in sys.modules if n.split('.')[0] in ('rosbags', 'mcap', 'foxglove')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60)
    assert out.stdout.strip() == "[]"


def test_the_core_commands_do_not_import_the_record_extra() -> None:
    code = ("import sys\n"
            "import umlbot.cli, umlbot.commands.sim, umlbot.commands.run, umlbot.commands.monitor\n"
            "import umlbot.commands.record, umlbot.monitor, umlbot.record, umlbot.studio.sources\n"
            "extra = ('rosbags', 'mcap', 'mcap_ros2', 'foxglove')\n"
            "print(sorted(n for n in sys.modules if n.split('.')[0] in extra))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60)
    assert out.stdout.strip() == "[]"


def test_record_without_the_extra_is_one_clear_line(tmp_path: Path) -> None:
    # rosbags made unimportable in the child: as on an install without umlbot[record]
    code = ("import sys; sys.modules['rosbags'] = None\n"
            "from umlbot.cli import main; main()")
    model = Path(__file__).resolve().parents[1] / "models" / "robot_car"
    done = subprocess.run([sys.executable, "-c", code, "sim", str(model), "--port", "0",
                           "--record", str(tmp_path / "run.mcap")],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode != 0
    assert "Traceback" not in done.stderr
    assert "pip install 'umlbot[record]'" in done.stderr
    assert not (tmp_path / "run.mcap").exists()
