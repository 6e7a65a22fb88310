"""The reference robot car model (models/robot_car, unchanged) against mock drivers.

A scripted distance sequence drives it through every choice of its main loop: a step forward when
the way ahead is clear (the two glances at the front corners read while it drives) and a small
steer away from a near front corner; an opening beside the way (a glance that jumps to more than
twice the room), turned into once that glance meets a wall again and a look finds it open; when the
way ahead is blocked, a turn toward the side with more room, the same way again while still
blocked, and a back-off when too near to turn or when there is no room on either side, looking
again after each back-off until a side opens (or, far out, turning round).
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
    ([100, 55, 30], "straight", [F, L]),  # front-right near: steer left
    ([100, 15, 50], "straight", [F, B, R]),  # front-left very near: back off, then steer right
    ([100, 30, 30], "straight", [F]),  # near on both sides: no steering
    ([100, 45, 15], "straight", [F, B, L]),  # front-right very near: back off, then steer left
    ([40, 40, 15], "straight", [F]),  # a wall ahead, seen by a glance too: no steering
    ([10, 30, 80], "forget_sides", [R]),  # blocked: look; more room on the right
    ([40], "turn_right", [R]),  # not clearly free yet: keep turning right, no look
    ([10], "turn_right", [R]),
    ([100, 80, 80], "straight", [F]),
    ([10, 80, 30], "forget_sides", [L]),  # blocked: more room on the left
    ([100, 80, 80], "straight", [F]),
    ([100, 40, 80], "straight", [F]),  # a wall 40 cm off the front-left ...
    ([100, 90, 80], "straight", [F]),  # ... then more than twice that: an opening on the left
    # the glance meets a wall as near as before again: look to the side (120 on the left: open),
    # one more step, a quarter turn into the opening, and a glance at the front corners
    ([100, 45, 80, 120, 80, 80, 80], "straight", [F, F, L]),
    ([5], "back_off", [B]),  # too near to turn in place
    ([10, 20, 20], "forget_sides", [B]),  # no room on either side: back off ...
    ([60, 20, 20], "forget_sides", [B]),  # ... and look again, not forward, until a side opens
    ([60, 20, 80], "forget_sides", [R]),
    ([100, 80, 80], "straight", [F]),
    ([10, 20, 20], "forget_sides", [B]),
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
        # the opening is marked by the jump, and turned into after one more step
        decided = {node: [e["value"] for e in r.trace(kind="decision") if e["node"] == node]
                   for node in ("opening", "into_opening")}
        assert "aside_left" in decided["opening"] and decided["into_opening"][:1] == ["abreast_left"]
        # the sonar looks ahead, glances at both front corners on each step, looks to both sides
        # when blocked, and is back ahead before the next ping
        angles = [args[0] for args in r.driver("Sensor").commands_named("set_angle")]
        assert angles[:22] == [90] + [135, 45, 90] * 7
        assert angles[22:25] == [180, 0, 90]
