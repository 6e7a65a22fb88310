"""models/ros2_car in `umlbot sim`: its base and range finder are ROS 2 components, and the
simulated world plays the ROS 2 drivers (a Twist subscriber on /cmd_vel, a Range publisher on
/range) over real DDS on loopback. The car reaches the goal on hard tracks with no collision;
the other tracks are in docs/ros2.md."""

from __future__ import annotations

from pathlib import Path

import pytest
from ros2_support import session_domain

from umlbot.sim.runner import SimOptions, run_sim
from umlbot.sim.track import tracks_dir

pytestmark = [pytest.mark.network, pytest.mark.slow]

MODEL = Path(__file__).resolve().parents[1] / "models" / "ros2_car"
TRACKS = [tracks_dir() / f"{name}.yaml" for name in ("chicane", "side_exit")]


@pytest.mark.timeout(120)
@pytest.mark.parametrize("track", TRACKS, ids=[t.stem for t in TRACKS])
def test_ros2_car_reaches_the_goal_through_dds(track: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", str(session_domain()))
    monkeypatch.delenv("CYCLONEDDS_URI", raising=False)  # loopback only
    result = run_sim(SimOptions(model=MODEL, track=track, speed=10.0, port=0, timeout_s=300.0))
    assert result.reason == "goal", result
    assert result.ok and result.collisions == 0
    assert result.safety_stops == {}, "no fail-safe stop: every reading came in time"
    assert result.actions > 10
