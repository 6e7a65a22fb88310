"""The reference robot car model (models/robot_car, unchanged) against mock drivers.

A scripted distance sequence (centre, left, right per measurement) drives it through every
choice of its main loop: forward when the way ahead is clear, a left turn when only the left is
clear, a right turn when only the right is, backward when boxed in.
"""

from __future__ import annotations

import pytest
from conftest import BrokerProcess
from orchestrator_support import ROBOT_CAR, rig, wait_for

from compiler.api import compile_model
from umlbot.clock import Clock

pytestmark = pytest.mark.network

#: (centre, left, right) per measurement; the last reading repeats (boxed in for good).
SCRIPT = [(100, 5, 5), (10, 80, 5), (10, 10, 80), (10, 10, 10)]
#: the (left, right) directions each measurement leads to: forward, left, right, backward.
EXPECTED = [(True, True), (False, True), (True, False), (False, False)]


def test_robot_car_drives_by_the_scripted_distances(broker: BrokerProcess) -> None:
    model = compile_model(ROBOT_CAR)
    distances = [d for triple in SCRIPT for d in triple]
    with rig(broker.url, model, settings={"DistanceRead": {"mock_distances": distances}}) as r:
        left, right = r.driver("LeftActuator"), r.driver("RightActuator")
        running = r.start(clock=Clock(20.0))
        assert wait_for(lambda: len(left.commands_named("set_direction")) >= len(EXPECTED) + 1, 20.0), \
            running.orchestrator.failure
        running.orchestrator.request_exit("test over")
        assert running.wait(10.0) == 0, running.orchestrator.failure
        left_directions = [args[0] for args in left.commands_named("set_direction")]
        right_directions = [args[0] for args in right.commands_named("set_direction")]
        assert list(zip(left_directions, right_directions, strict=False))[:4] == EXPECTED
        # every move: directions set, both sides enabled, then the halt disables both
        for driver in (left, right):
            moves = [(name, args) for name, args in driver.commands
                     if name in ("set_direction", "set_enabled")]
            assert moves[:2] == [("set_enabled", (False,)), ("set_enabled", (False,))]  # ours, the model's
            for i in range(4):
                chunk = moves[2 + 3 * i: 5 + 3 * i]
                assert [name for name, _ in chunk] == ["set_direction", "set_enabled", "set_enabled"]
                assert [args for _, args in chunk[1:]] == [(True,), (False,)]
            assert driver.commands_named("set_duty_cycle")[0] == (70,)
            assert not driver.running
        angles = [args[0] for args in r.driver("Sensor").commands_named("set_angle")]
        assert angles[:4] == [90, 180, 0, 90]
        chosen = [e["value"] for e in r.trace(kind="decision") if e["node"] == "choose"]
        assert chosen[:4] == ["forward", "turn_left", "turn_right", "backward"]
