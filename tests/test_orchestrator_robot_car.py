"""The reference robot car model (models/robot_car, unchanged) against mock drivers.

A scripted distance sequence drives it through every choice of its main loop: a step forward when
the way ahead is clear (the two glances at the front corners read while it drives) and a small
steer away from a near front corner; when the way ahead is blocked, a turn toward the side with
more room, the same way again while still blocked, and a back-off when too near to turn or when
there is no room on either side, looking again after each back-off until a side opens (or, far
out, turning round).
"""

from __future__ import annotations

import pytest
from conftest import BrokerProcess
from orchestrator_support import ROBOT_CAR, rig, wait_for

from compiler.api import compile_model
from umlbot.clock import Clock

pytestmark = pytest.mark.network

F, B, L, R = (True, True), (False, False), (False, True), (True, False)  # (left, right) forward?
#: (readings, the `choose` branch, then the moves as (left, right) directions) per loop; the
#: readings are ahead, then the glance (front-left, front-right) or the look (left, right).
SCRIPT: list[tuple[list[int], str, list[tuple[bool, bool]]]] = [
    ([100, 80, 80], "straight", [F]),
    ([100, 30, 80], "straight", [F, R]),  # front-left near: steer right
    ([100, 80, 30], "straight", [F, L]),  # front-right near: steer left
    ([100, 15, 80], "straight", [F, B, R]),  # front-left very near: back off, then steer right
    ([100, 80, 15], "straight", [F, B, L]),  # front-right very near: back off, then steer left
    ([40, 15, 80], "straight", [F]),  # a wall ahead, seen by a glance too: no steering
    ([100, 30, 30], "straight", [F]),  # near on both sides: no steering
    ([10, 30, 80], "look", [R]),  # blocked: more room on the right
    ([40], "turn_right", [R]),  # not clearly free yet: keep turning right, no look
    ([10], "turn_right", [R]),
    ([100, 80, 80], "straight", [F]),
    ([10, 80, 30], "look", [L]),  # blocked: more room on the left
    ([100, 80, 80], "straight", [F]),
    ([5], "back_off", [B]),  # too near to turn in place
    ([10, 20, 20], "look", [B]),  # no room on either side: back off ...
    ([60, 20, 20], "look", [B]),  # ... and look again, not forward, until a side opens
    ([60, 20, 80], "look", [R]),
    ([100, 80, 80], "straight", [F]),
    ([10, 20, 20], "look", [B]),
    ([95], "choose_left", [L]),  # backed out far with no side open: turn round (the last reading repeats)
]


def test_robot_car_drives_by_the_scripted_distances(broker: BrokerProcess) -> None:
    model = compile_model(ROBOT_CAR)
    distances = [d for readings, _, _ in SCRIPT for d in readings]
    expected = [move for _, _, moves in SCRIPT for move in moves]
    with rig(broker.url, model, settings={"DistanceRead": {"mock_distances": distances}}) as r:
        left, right = r.driver("LeftActuator"), r.driver("RightActuator")
        running = r.start(clock=Clock(20.0))
        assert wait_for(lambda: len(left.commands_named("set_direction")) >= len(expected) + 1, 20.0), \
            running.orchestrator.failure
        running.orchestrator.request_exit("test over")
        assert running.wait(10.0) == 0, running.orchestrator.failure
        left_directions = [args[0] for args in left.commands_named("set_direction")]
        right_directions = [args[0] for args in right.commands_named("set_direction")]
        assert list(zip(left_directions, right_directions, strict=False))[:len(expected)] == expected
        # every move: directions set, both sides enabled, then the halt disables both
        for driver in (left, right):
            moves = [(name, args) for name, args in driver.commands
                     if name in ("set_direction", "set_enabled")]
            assert moves[:2] == [("set_enabled", (False,)), ("set_enabled", (False,))]  # ours, the model's
            for i in range(len(expected)):
                chunk = moves[2 + 3 * i: 5 + 3 * i]
                assert [name for name, _ in chunk] == ["set_direction", "set_enabled", "set_enabled"]
                assert [args for _, args in chunk[1:]] == [(True,), (False,)]
            assert driver.commands_named("set_duty_cycle")[0] == (70,)
            assert not driver.running
        chosen = [e["value"] for e in r.trace(kind="decision") if e["node"] == "choose"]
        assert chosen[:len(SCRIPT)] == [branch for _, branch, _ in SCRIPT]
        # the sonar looks ahead, glances at both front corners on each step, looks to both sides
        # when blocked, and is back ahead before the next ping
        angles = [args[0] for args in r.driver("Sensor").commands_named("set_angle")]
        assert angles[:22] == [90] + [135, 45, 90] * 7
        assert angles[22:25] == [180, 0, 90]
