"""Safety on the robot, end to end: what keeps a motor running and what stops it.

- The orchestrator's lease: a model that sets the motors once and then only reads the sonar
  (msleep(100) between the reads) drives on well past the motors' watchdog_s while its
  orchestrator runs (`umlbot run` against mock services, and `umlbot sim`), and a frozen
  orchestrator (SIGSTOP) stops them within watchdog_s.
- The deadman outside the motor service: a frozen (SIGSTOP) or killed (SIGKILL) motor service in
  `umlbot sim --processes` stops the car within watchdog_s of sim time, because the world stops a
  motor whose driver stops renewing it, as the robot's hardware path does.
"""

from __future__ import annotations

import json
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import BrokerProcess, RawClient
from orchestrator_support import MODELS, rig, wait_for
from test_orchestrator_cli import compiled_file, umlbot_run

from umlbot.compiler.api import compile_model
from umlbot.services.bus import Heartbeat
from umlbot.services.motor.service import MotorService
from umlbot.services.orchestrator.orchestrator import HEARTBEAT_MAX_S, heartbeat_period_s
from umlbot.sim import CarSpec, Progress, SimOptions, World, run_sim

pytestmark = pytest.mark.network

MODEL = MODELS / "drive_and_read.yaml"
WATCHDOG_S = 2.0  # the model's motors
#: the motor service's safety round plus the orchestrator's heartbeat period: how late after
#: watchdog_s a stop may come
ROUND_S = 0.05 + HEARTBEAT_MAX_S
#: 60 % duty: the simulated car's speed
SPEED_MPS = CarSpec().top_speed_mps * 0.6
#: a straight corridor 40 m long: nothing ends the drive but the time
CORRIDOR = """
name: long_straight
start: {x: 0.0, y: 0.0, heading_deg: 90}
goal: {x_min: -0.3, x_max: 0.3, y_min: 39.0, y_max: 39.5}
walls:
  - [[-0.6, -1.0], [0.6, -1.0], [0.6, 40.0], [-0.6, 40.0], [-0.6, -1.0]]
"""


def test_a_model_that_sets_the_motors_once_drives_on_until_its_orchestrator_freezes(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient], tmp_path: Path,
) -> None:
    raw = raw_client(mosquitto_broker)
    raw.subscribe("umlbot/test/orchestrator/heartbeat", qos=0)
    compiled = compiled_file(tmp_path, MODEL.name)
    log = tmp_path / "run.log"
    with rig(mosquitto_broker.url, MODEL) as r:
        proc = umlbot_run(str(compiled), "--broker", mosquitto_broker.url, "--robot", "test", "--no-trace",
                          log=log)
        try:
            left, right = r.driver("LeftActuator"), r.driver("RightActuator")
            assert wait_for(lambda: left.running and right.running, 15.0), log.read_text()
            beat = Heartbeat.model_validate_json(raw.get(topic="umlbot/test/orchestrator/heartbeat").payload)
            assert beat.period_s == HEARTBEAT_MAX_S and beat.reply_to.startswith("umlbot/test/_reply/")
            time.sleep(WATCHDOG_S * 1.5)  # only sonar reads since: the watchdog alone would stop them
            assert left.running and right.running, "a correct model drives on while its orchestrator runs"
            assert left.stops == right.stops == 1, "no safety stop since the start-up stop"
            frozen = time.monotonic()
            os.kill(proc.pid, signal.SIGSTOP)  # hung: no heartbeat, no call, no last will
            assert wait_for(lambda: not left.running and not right.running, WATCHDOG_S + 2.0)
            stopped = time.monotonic() - frozen
            assert stopped <= WATCHDOG_S + ROUND_S, stopped
            left_service = r.hosts["motor"].services["LeftActuator"]
            assert isinstance(left_service, MotorService)
            assert left_service.stop_reason == "orchestrator unresponsive"
        finally:
            proc.kill()
            proc.wait(5)


def test_the_heartbeat_is_a_quarter_of_the_shortest_watchdog() -> None:
    model = compile_model(MODEL)
    assert heartbeat_period_s(model) == HEARTBEAT_MAX_S
    faster = model.model_copy(update={"components": {
        name: comp.model_copy(update={"settings": {**comp.settings, "watchdog_s": 0.4}})
        for name, comp in model.components.items()}})
    assert heartbeat_period_s(faster) == pytest.approx(0.1)


@pytest.mark.timeout(120)
def test_in_the_simulator_a_model_that_sets_the_motors_once_drives_on(tmp_path: Path) -> None:
    track = tmp_path / "straight.yaml"
    track.write_text(CORRIDOR, encoding="utf-8")
    result = run_sim(SimOptions(model=MODEL, track=track, speed=10.0, port=0, timeout_s=8.0,
                                check_goal=False))
    assert result.reason == "timeout", result
    # stopped by the watchdog after 2 s it would have gone 0.6 m; it drove the whole 8 s
    assert result.distance_m > SPEED_MPS * 7.0, result
    assert result.safety_stops == {} and result.deadman_stops == [] and result.stood_still is None


@pytest.mark.timeout(150)
@pytest.mark.parametrize("signum", [signal.SIGSTOP, signal.SIGKILL], ids=["SIGSTOP", "SIGKILL"])
def test_a_frozen_or_killed_motor_service_stops_the_simulated_car_within_watchdog_s(
    tmp_path: Path, signum: int,
) -> None:
    track = tmp_path / "straight.yaml"
    track.write_text(CORRIDOR, encoding="utf-8")
    worlds: list[World] = []
    hit: list[tuple[float, float]] = []  # (sim time, distance) when the signal went

    def observe(world: World, url: str, robot: str) -> Callable[[], None]:
        worlds.append(world)
        return lambda: None

    def signal_motor_service(progress: Progress) -> None:
        if not hit and progress.snapshot.distance_m > 0.3:
            os.kill(progress.service_pids["motor"], signum)
            world = worlds[0]
            hit.append((world.time_s(), world.snapshot().distance_m))

    options = SimOptions(model=MODEL, track=track, speed=10.0, port=0, processes=True,
                         timeout_s=12.0, progress_interval_s=0.02, check_goal=False)
    result = run_sim(options, signal_motor_service, observe=observe)
    assert hit, f"the car never moved: {result}"
    (at, distance), world = hit[0], worlds[0]
    # the car goes no farther than watchdog_s at its speed after the signal (it would drive the
    # whole run: the sonar service and the orchestrator go on)
    assert result.distance_m - distance <= SPEED_MPS * WATCHDOG_S + 0.1, (result, hit)
    if signum == signal.SIGSTOP:
        assert result.reason == "timeout", result  # the model reads on; only the motors stopped
        assert sorted(side for _, side in world.deadman_stops) == ["left", "right"], world.deadman_stops
        stops = world.deadman_stops
        assert all(at < when <= at + WATCHDOG_S + 0.01 for when, _ in stops), (at, stops)
        assert "deadman stopped it" in (result.stood_still or ""), result
        assert json.loads(json.dumps(result.as_dict()))["deadman_stops"], "in the summary too"
    else:
        assert result.reason in ("service failed", "orchestrator failed"), result  # it ends the run
