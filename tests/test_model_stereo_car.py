"""models/stereo_car (the reference car with a stereo camera) in the simulator: it reaches the goal
without a collision on a bundled track and on a held-out corridor at an angle, with the camera's
readings in use (its trace shows them). The full table, both cars on every track and seed:
`python bench/stereo_car.py` (docs/performance.md)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from umlbot.sim import SimOptions, run_sim

REPO = Path(__file__).resolve().parent.parent
MODEL = REPO / "models" / "stereo_car"


@pytest.mark.parametrize("track", [REPO / "models" / "tracks" / "right_bend.yaml",
                                   REPO / "bench" / "tracks" / "unseen" / "h_diag_right60.yaml"])
def test_stereo_car_reaches_the_goal_seeing_with_the_camera(track: Path, tmp_path: Path) -> None:
    trace = tmp_path / "trace.jsonl"
    result = run_sim(SimOptions(model=MODEL, track=track, port=0, seed=1, sonar_noise_cm=1.0,
                                sonar_drop=0.05, timeout_s=120, trace_file=trace))
    assert result.ok, (result.reason, result.failure)
    assert result.collisions == 0
    seen = [json.loads(line) for line in trace.read_text().splitlines()]
    camera = [e["value"] for e in seen if e.get("lane") == "Ahead" and e.get("node") == "centre"
              and "value" in e]
    assert camera and any(v > 0 for v in camera), "the camera measured the way ahead"
