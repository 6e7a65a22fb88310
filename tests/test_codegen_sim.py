"""`umlbot sim --engine cpp`: the generated program drives the car to the goal in the simulator."""

from __future__ import annotations

import queue
import tempfile
import time
from pathlib import Path

import pytest
from codegen_support import TEST_MODELS, built_programs
from conftest import BrokerProcess

from umlbot.sim import SimOptions, find_track, run_sim
from umlbot.sim.track import bundled_tracks

pytestmark = [pytest.mark.network, pytest.mark.timeout(600)]


def test_the_generated_program_reaches_the_goal_of_the_corridor(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
) -> None:
    program = built_programs()["robot_car"]
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))  # where the runner keeps the program's trace
    result = run_sim(SimOptions(model=TEST_MODELS["robot_car"], track=find_track("corridor"), speed=2.0,
                                port=0, timeout_s=60.0, engine="cpp", program=program))
    assert result.reason == "goal", result.as_dict()
    assert result.goal_reached and result.collisions == 0 and result.failure is None
    assert result.actions > 20  # the program's feature calls, read from its trace
    assert result.action_p50_ms is not None and result.action_p50_ms > 0
    assert list(tmp_path.iterdir()) == [], "the program's trace, kept by nobody, is removed"


@pytest.mark.slow  # ~90 s on 2 loaded cores
def test_the_generated_program_reaches_the_goal_of_every_bundled_track() -> None:
    """On the event-driven sim clock (`--sim-clock`): at --speed 100 on a loaded machine too."""
    program = built_programs()["robot_car"]
    tracks = bundled_tracks()
    assert len(tracks) >= 19
    missed: dict[str, object] = {}
    for name, track in tracks.items():
        result = run_sim(SimOptions(model=TEST_MODELS["robot_car"], track=track, speed=100.0, port=0,
                                    timeout_s=200.0, engine="cpp", program=program))
        if not result.ok or result.reason != "goal":
            missed[name] = result.as_dict()
    assert not missed, missed


@pytest.mark.parametrize("track", ["corridor", "chicane", "t_junction"])
def test_the_generated_program_drives_as_the_interpreter_does(track: str) -> None:
    """Both engines on the same sim clock: the car reaches the goal at the same sim time, with
    the same number of feature calls."""
    program = built_programs()["robot_car"]
    results = {engine: run_sim(SimOptions(model=TEST_MODELS["robot_car"], track=find_track(track),
                                          speed=100.0, port=0, timeout_s=200.0, engine=engine,
                                          program=program if engine == "cpp" else None))
               for engine in ("python", "cpp")}
    assert all(r.ok for r in results.values()), {e: r.as_dict() for e, r in results.items()}
    assert results["cpp"].sim_s == pytest.approx(results["python"].sim_s, abs=0.05)
    assert results["cpp"].distance_m == pytest.approx(results["python"].distance_m, abs=0.01)
    assert results["cpp"].final_pose == pytest.approx(results["python"].final_pose, abs=0.01)
    assert results["cpp"].actions == results["python"].actions  # the same feature calls, all counted


def test_an_unknown_engine_is_refused() -> None:
    from umlbot.base.errors import SimError

    with pytest.raises(SimError, match="--engine must be python or cpp"):
        run_sim(SimOptions(model=TEST_MODELS["robot_car"], track=find_track("corridor"), port=0,
                           engine="java"))


def test_the_clock_bridge_moves_sim_time_only_while_the_program_has_nothing_to_do(
    mosquitto_broker: BrokerProcess,
) -> None:
    """`ClockBridge` against a stand-in for the program's `--sim-clock` messages (docs/codegen.md)."""
    from umlbot.services.bus import BrokerSettings, BusConnection
    from umlbot.sim.clock import SimClock
    from umlbot.sim.program import ClockBridge

    clock = SimClock(speed=1000.0)
    bridge = ClockBridge(clock, mosquitto_broker.url, "r").start()
    wakes: queue.Queue[dict[str, float]] = queue.Queue()
    program = BusConnection(BrokerSettings.from_url(mosquitto_broker.url), "fake-program", robot="r")
    program.subscribe(bridge.outbox, lambda message: wakes.put(message.json()), qos=0)
    program.start(5.0)

    def say(*messages: dict[str, float]) -> None:
        for message in messages:
            program.publish(bridge.inbox, message, qos=0)

    try:
        say({"busy": 1, "woken": 0}, {"sleep": 1, "s": 0.5}, {"sleep": 2, "s": 0.2}, {"busy": 0, "woken": 0})
        first = wakes.get(timeout=5)
        assert first["wake"] == 2 and first["now"] == pytest.approx(0.2)
        # woken, not yet handled by the program: time stands still (0.3 s of wall time is 300 s here)
        time.sleep(0.3)
        assert clock.now() == pytest.approx(0.2) and wakes.empty()
        say({"busy": 0, "woken": 1})
        second = wakes.get(timeout=5)
        assert second["wake"] == 1 and second["now"] == pytest.approx(0.5)
        # a busy program holds time too; a cancelled sleep is no deadline any more
        say({"busy": 1, "woken": 2}, {"sleep": 3, "s": 0.1}, {"cancel": 3}, {"sleep": 4, "s": 1.0})
        time.sleep(0.3)
        assert clock.now() == pytest.approx(0.5) and wakes.empty()
        say({"busy": 0, "woken": 2})
        third = wakes.get(timeout=5)
        assert third["wake"] == 4 and third["now"] == pytest.approx(1.5)
    finally:
        program.close()
        bridge.stop()
