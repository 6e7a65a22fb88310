"""The reference robot car model (models/robot_car, unchanged) against mock drivers.

A scripted distance sequence drives it through every choice of its main loop: a step forward when
the way ahead is clear (the glances at the two front corners read while it drives, and the glance
ends with the way ahead where the step ended) and a small steer away from a near front corner; an
opening beside the way (a glance that jumps to more than `jump_ratio` times the room), turned into
once that glance meets a wall again and a look finds it open; when the way ahead is blocked, a turn
toward the side with more room, the same way again until an echo shows the way clear (no echo is
not a clear way); a back-off when too near to turn (a wall ahead, or a side wall), a creep nearer
when no side is open, then backing off and looking again until a side opens (or, far out, turning
round).
"""

from __future__ import annotations

import pytest
from conftest import BrokerProcess
from orchestrator_support import ROBOT_CAR, rig, wait_for

from umlbot.base.clock import Clock
from umlbot.compiler.api import compile_model

pytestmark = pytest.mark.network

F, B, L, R = (True, True), (False, False), (False, True), (True, False)  # (left, right) forward?
#: the first reading: the way ahead at the start
START = 100
#: (the `choose` branch of a loop, the readings until the next loop's, then the moves as (left,
#: right) directions) per loop. A step's glance reads front-left, front-right and then the way ahead
#: for the next loop; a look reads left and right; every move that ends in a halt pings ahead anew.
#: So the last reading of each row is the way ahead the next row chooses by. None: no echo.
SCRIPT: list[tuple[str, list[int | None], list[tuple[bool, bool]]]] = [
    # (no glance here reads more than jump_ratio times the one before: that would mark an opening)
    ("straight", [80, 80, 100], [F]),
    ("straight", [30, 80, 100, 100], [F, R]),  # front-left near: steer right, then ping ahead
    ("straight", [40, 30, 100, 100], [F, L]),  # front-right near: steer left
    ("straight", [45, 15, 100, 100], [F, B, L]),  # front-right very near: back off, then steer left
    ("straight", [30, 20, 100], [F]),  # near on both sides: no steering
    ("straight", [20, 28, 100], [F]),
    ("straight", [15, 40, 100, 100], [F, B, R]),  # front-left very near: back off, then steer right
    ("straight", [20, 15, 10], [F]),  # a wall ahead where the step ended, seen by a glance too: no steering
    ("forget_sides", [30, 80, 40], [R]),  # blocked: look; more room on the right
    ("turn_right", [None], [R]),  # not clearly free yet: keep turning right, no look
    ("turn_right", [100], [R]),  # no echo is no clear way (a wall seen obliquely): keep turning
    ("straight", [80, 80, 10], [F]),
    ("forget_sides", [80, 30, 100], [L]),  # blocked: more room on the left
    ("straight", [80, 80, 100], [F]),
    ("straight", [40, 80, 100], [F]),  # a wall 40 cm off the front-left ...
    ("straight", [90, 80, 100], [F]),  # ... then more than jump_ratio times that: an opening on the left
    # the glance meets a wall as near as before again: look to the side (120 on the left: open),
    # one more step, a quarter turn into the opening, and a glance at the front corners (and ahead)
    ("straight", [45, 80, 100, 120, 80, 80, 80, 100, 5], [F, F, L]),
    ("back_off", [25], [B]),  # too near to turn in place
    ("forget_sides", [20, 20, 10], [F]),  # no room on either side: creep nearer (more than creep_cm ahead)
    ("forget_sides", [20, 20, 60], [B]),  # ... then back off ...
    ("forget_sides", [20, 20, 60], [B]),  # ... and look again, not forward, until a side opens
    ("forget_sides", [12, 80, 60], [B]),  # the right is open, but a side wall too near to turn: back off
    ("forget_sides", [20, 80, 100], [R]),
    ("straight", [80, 80, 10], [F]),
    ("forget_sides", [20, 20, 130], [B]),
    ("choose_left", [95], [L]),  # backed out far with no side open: turn round (the last reading repeats)
]


def test_robot_car_drives_by_the_scripted_distances(broker: BrokerProcess) -> None:
    model = compile_model(ROBOT_CAR)
    distances = [START] + [d for _, readings, _ in SCRIPT for d in readings]
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
        assert chosen[:len(SCRIPT)] == [branch for branch, _, _ in SCRIPT]
        # the opening is marked by the jump, and turned into after one more step
        decided = {node: [e["value"] for e in r.trace(kind="decision") if e["node"] == node]
                   for node in ("opening", "into_opening")}
        assert "aside_left" in decided["opening"] and decided["into_opening"][:1] == ["abreast_left"]
        # the sonar looks ahead, glances at both front corners on each step and is back ahead for
        # the reading the next loop chooses by, looks to both sides when blocked
        angles = [args[0] for args in r.driver("Sensor").commands_named("set_angle")]
        assert angles[:25] == [90] + [135, 45, 90] * 8
        assert angles[25:28] == [180, 0, 90]
