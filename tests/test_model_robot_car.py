"""The reference robot car model: it compiles cleanly and says what the issue asks for."""

from __future__ import annotations

from pathlib import Path

from umlbot.compiler.api import check_model, compile_model
from umlbot.compiler.compiled import ActionNode, CompiledModel, DatastoreNode, DecisionNode, ForkNode, Lane
from umlbot.compiler.expr import Call, Const, FeatureTarget, LaneTarget, Ref
from umlbot.services.sonar import HCSR04Settings

ROBOT_CAR = Path(__file__).resolve().parent.parent / "models" / "robot_car"


def actions(lane: Lane) -> list[Call]:
    return [n.call for n in lane.nodes.values() if isinstance(n, ActionNode)]


def feature_calls(lane: Lane) -> list[tuple[str, str, object]]:
    calls: list[tuple[str, str, object]] = []
    for call in actions(lane):
        if isinstance(call.target, FeatureTarget):
            arg = call.args[0].value if call.args and isinstance(call.args[0], Const) else None
            calls.append((call.target.component, call.target.feature, arg))
    return calls


def test_checks_clean_with_either_deployment() -> None:
    for deployment in (None, ROBOT_CAR / "deployment.txt", ROBOT_CAR / "deployment.yaml"):
        result = check_model(ROBOT_CAR, deployment)
        assert result.ok, [str(d) for d in result.diagnostics]
        assert result.diagnostics == []


def test_components_and_both_deployments() -> None:
    rich = compile_model(ROBOT_CAR)
    plain = compile_model(ROBOT_CAR, ROBOT_CAR / "deployment.txt")
    expected = {"RaspberryPI": ("system", "raspberrypi", "gpio"),
                "LeftActuator": ("actuator", "l298n", "motor"),
                "RightActuator": ("actuator", "l298n", "motor"),
                "Sensor": ("actuator", "servo", "servo"),
                "DistanceRead": ("sensor", "hcsr04", "sonar")}
    for model in (rich, plain):
        assert {name: (c.kind, c.impl, c.service) for name, c in model.components.items()} == expected
    settings = {name: c.settings for name, c in rich.components.items()}
    assert settings["LeftActuator"]["in1"] == 22 and settings["LeftActuator"]["in2"] == 23
    assert settings["RightActuator"]["in1"] == 24 and settings["RightActuator"]["in2"] == 25
    assert settings["Sensor"] == {"gpio": 18}
    assert settings["DistanceRead"] == {"trigger": 8, "echo": 7, "samples": 3}
    assert rich.name == "car"
    assert [(link.source_component, link.target_component) for link in rich.links] == [
        ("Sensor", "DistanceRead")]


def test_motion_lanes_set_direction_then_enable() -> None:
    model = compile_model(ROBOT_CAR)
    expected = {"MoveForward": (True, True), "MoveBackward": (False, False),
                "TurnLeft": (False, True), "TurnRight": (True, False)}
    for name, (left, right) in expected.items():
        lane = model.lanes[name]
        assert lane.virtual
        assert feature_calls(lane) == [
            ("LeftActuator", "direction", left), ("RightActuator", "direction", right),
            ("LeftActuator", "enabled", True), ("RightActuator", "enabled", True)]
    stop = model.lanes["Stop"]
    assert any(isinstance(n, ForkNode) for n in stop.nodes.values())
    assert sorted(feature_calls(stop)) == [("LeftActuator", "enabled", False),
                                           ("RightActuator", "enabled", False)]


def _sequence(lane: Lane) -> list[tuple[str, object]]:
    """A straight lane's steps: servo angles, waits and the datastores it reads into."""
    order: list[tuple[str, object]] = []
    node = lane.nodes[lane.start]
    while node.kind != "end":
        if isinstance(node, DatastoreNode):
            order.append(("read", node.name))
        elif isinstance(node, ActionNode) and isinstance(node.call.target, FeatureTarget):
            order.append(("servo", node.call.args[0].value))  # type: ignore[union-attr]
        elif isinstance(node, ActionNode):
            order.append(("wait", node.call.target.name))  # type: ignore[union-attr]
        node = lane.nodes[node.next]  # type: ignore[union-attr]
    return order


def test_measure_and_glance_read_both_sides_and_recentre() -> None:
    model = compile_model(ROBOT_CAR)
    for name, left, right in (("Measure", 180, 0), ("Glance", 135, 45)):
        lane = model.lanes[name]
        # the glance, taken while the car steps, ends with the way ahead where the step ended
        ahead = [("read", "ahead")] if name == "Glance" else []
        assert lane.virtual and lane.datastores == sorted(["left", "right"] + [read for _, read in ahead])
        assert _sequence(lane) == [("servo", left), ("wait", "msleep"), ("read", "left"),
                                   ("servo", right), ("wait", "msleep"), ("read", "right"),
                                   ("servo", 90), ("wait", "msleep"), *ahead]


def _main(model: CompiledModel) -> Lane:
    return model.lanes["RaspberryPI"]


def _branches(lane: Lane, node_id: str) -> list[tuple[str, str]]:
    decision = lane.nodes[node_id]
    assert isinstance(decision, DecisionNode)
    return [(b.label, b.target) for b in decision.branches]


def test_main_lane_tuning_stop_and_loop() -> None:
    model = compile_model(ROBOT_CAR)
    main = _main(model)
    assert not main.virtual and main.component == "RaspberryPI"
    # the tuning numbers are the first nodes after the start
    node = main.nodes[main.nodes[main.start].next]  # type: ignore[union-attr]
    tuning: dict[str, float] = {}
    while isinstance(node, DatastoreNode):
        assert isinstance(node.value, Const) and isinstance(node.value.value, int | float)
        tuning[node.name] = node.value.value
        node = main.nodes[node.next]
    assert set(tuning) == {"speed_percent", "forward_ms", "backward_ms", "turn_ms", "nudge_ms",
                           "clearance_cm", "near_cm", "side_cm", "wall_cm", "corner_cm", "back_cm",
                           "open_cm", "glance_ms", "servo_settle_ms", "creep_cm", "creep_ms",
                           "jump_ratio", "past_cm", "quarter_ms", "no_echo_cm", "spin_cm"}
    assert tuning["near_cm"] < tuning["clearance_cm"] < tuning["side_cm"] < tuning["back_cm"]
    # a creep ends nearer than a step would go, but not too near to turn in place
    assert tuning["near_cm"] < tuning["creep_cm"] < tuning["clearance_cm"]
    assert tuning["creep_ms"] < tuning["forward_ms"]
    assert tuning["side_cm"] < tuning["open_cm"]  # much room on a side is more than room to turn
    assert tuning["corner_cm"] < tuning["wall_cm"]
    # a side wall too near to turn in place is nearer than a front corner to back off from
    assert tuning["near_cm"] < tuning["spin_cm"] < tuning["corner_cm"]
    assert tuning["nudge_ms"] < tuning["turn_ms"] < tuning["quarter_ms"]  # 15°, 45°, 90°
    assert tuning["jump_ratio"] > 1 and tuning["past_cm"] < tuning["wall_cm"]
    # what the HC-SR04 service answers when no echo returns (the deployment keeps the default)
    sonar = model.components["DistanceRead"].settings
    assert "max_range_cm" not in sonar and tuning["no_echo_cm"] == HCSR04Settings(**sonar).max_range_cm
    # then every actuator is stopped
    assert isinstance(node, ActionNode) and node.call.target == LaneTarget(lane="Stop")
    # the loop: the way ahead, then the exit check and the choice; a halt pings ahead anew
    assert main.nodes["ping_ahead"].next == "running"  # type: ignore[union-attr]
    assert main.nodes["halt"].next == "ping_ahead"  # type: ignore[union-attr]
    assert _branches(main, "running") == [("Application.exit", "finish"), ("else", "choose")]
    assert _branches(main, "choose") == [
        ("ahead > clearance_cm and turning == 'none'", "straight"),
        # a turn ends on an echo from further than side_cm: no echo may be a wall seen obliquely
        ("ahead > side_cm and ahead < no_echo_cm and turning != 'back'", "straight"),
        ("turning == 'back' and ahead > back_cm", "choose_left"), ("turning == 'left'", "turn_left"),
        ("turning == 'right'", "turn_right"), ("ahead < near_cm", "back_off"),
        ("else", "forget_sides")]
    # room ahead: the step forward and the glance run together
    step = main.nodes["step"]
    assert isinstance(step, ForkNode) and sorted(step.targets) == ["forward", "glance"]
    # after the step the way ahead is the glance's last reading, taken where the step ended: the
    # steering and the next choice go by it (no ping of their own)
    join = main.nodes["stepped"]
    seen = main.nodes[join.next]  # type: ignore[union-attr]
    assert isinstance(seen, DatastoreNode) and seen.name == "ahead"
    assert seen.value == Ref(lane="Glance", name="ahead")
    assert "running" in {target for _, target in _branches(main, "steer")}
    # after the step: a glance that jumps to more than twice the room marks an opening beside the
    # way; when it meets a wall as near as before again, the car looks and turns into it
    assert _branches(main, "opening") == [
        ("aside == 'left' and Glance.left <= wall_before + past_cm", "look_aside"),
        ("aside == 'right' and Glance.right <= wall_before + past_cm", "look_aside"),
        ("aside == 'none' and Glance.left > jump_ratio * was_left and Glance.left < no_echo_cm",
         "aside_left"),
        ("aside == 'none' and Glance.right > jump_ratio * was_right and Glance.right < no_echo_cm",
         "aside_right"),
        ("else", "remember_left")]
    assert _branches(main, "into_opening") == [
        # one more step only when the wall beside is not near: abreast of the opening's middle
        ("aside == 'left' and Measure.left > open_cm and ahead > side_cm and Glance.left >= wall_cm",
         "abreast_left"),
        ("aside == 'right' and Measure.right > open_cm and ahead > side_cm and Glance.right >= wall_cm",
         "abreast_right"),
        ("aside == 'left' and Measure.left > open_cm", "enter_left"),
        ("aside == 'right' and Measure.right > open_cm", "enter_right"),
        ("else", "no_opening_here")]
    # steering away from a wall, never toward a marked opening
    assert _branches(main, "steer") == [
        ("ahead <= side_cm", "running"),
        ("Glance.left < corner_cm and Glance.right >= wall_cm", "retreat_right"),
        ("Glance.right < corner_cm and Glance.left >= wall_cm", "retreat_left"),
        ("Glance.left < wall_cm and Glance.right >= wall_cm and aside != 'right'", "nudge_right"),
        ("Glance.right < wall_cm and Glance.left >= wall_cm and aside != 'left'", "nudge_left"),
        ("else", "running")]
    # turned into an opening: the front corners are glanced at before driving on
    assert _branches(main, "turned_steer") == [
        ("Glance.left < wall_cm and Glance.right >= wall_cm", "nudge_right"),
        ("Glance.right < wall_cm and Glance.left >= wall_cm", "nudge_left"), ("else", "ping_ahead")]
    # no room ahead: much room on both sides, the other way than last time; else the side with
    # more room
    assert _branches(main, "pick_side") == [
        ("Measure.left > open_cm and Measure.right > open_cm and last_turn == 'left'", "choose_right"),
        ("Measure.left > open_cm and Measure.right > open_cm and last_turn == 'right'", "choose_left"),
        ("Measure.left < spin_cm or Measure.right < spin_cm", "backing"),  # too near a side to turn
        ("Measure.left >= Measure.right and Measure.left > side_cm", "choose_left"),
        ("Measure.right > side_cm", "choose_right"),
        ("turning == 'none' and ahead > creep_cm", "creep"), ("else", "backing")]
    lanes = {node_id: main.nodes[node_id].call.target.lane  # type: ignore[union-attr]
             for node_id in ("forward", "glance", "retreat_left", "retreat_right", "nudge_left",
                             "nudge_right", "turn_left", "turn_right", "back_off", "look", "creep",
                             "look_aside", "enter_left", "enter_right", "check_sides")}
    assert lanes == {"forward": "MoveForward", "glance": "Glance", "retreat_left": "MoveBackward",
                     "retreat_right": "MoveBackward", "nudge_left": "TurnLeft",
                     "nudge_right": "TurnRight", "turn_left": "TurnLeft", "turn_right": "TurnRight",
                     "back_off": "MoveBackward", "look": "Measure", "creep": "MoveForward",
                     "look_aside": "Measure", "enter_left": "TurnLeft", "enter_right": "TurnRight",
                     "check_sides": "Glance"}
