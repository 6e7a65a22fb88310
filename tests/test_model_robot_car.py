"""The reference robot car model: it compiles cleanly and says what the issue asks for."""

from __future__ import annotations

from pathlib import Path

from compiler.api import check_model, compile_model
from compiler.compiled import ActionNode, CompiledModel, DatastoreNode, DecisionNode, ForkNode, Lane
from compiler.expr import Call, Const, FeatureTarget, LaneTarget

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
    assert settings["DistanceRead"] == {"trigger": 8, "echo": 7}
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


def test_measure_reads_centre_left_right_and_recentres() -> None:
    lane = compile_model(ROBOT_CAR).lanes["Measure"]
    assert lane.virtual and lane.datastores == ["center", "left", "right"]
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
    assert order == [("read", "center"), ("wait", "msleep"), ("servo", 180), ("wait", "msleep"),
                     ("read", "left"), ("wait", "msleep"), ("servo", 0), ("wait", "msleep"),
                     ("read", "right"), ("servo", 90), ("wait", "msleep")]


def _main(model: CompiledModel) -> Lane:
    return model.lanes["RaspberryPI"]


def test_main_lane_tuning_stop_and_loop() -> None:
    model = compile_model(ROBOT_CAR)
    main = _main(model)
    assert not main.virtual and main.component == "RaspberryPI"
    # the tuning numbers are the first nodes after the start
    node = main.nodes[main.nodes[main.start].next]  # type: ignore[union-attr]
    tuning = {}
    while isinstance(node, DatastoreNode):
        assert isinstance(node.value, Const)
        tuning[node.name] = node.value.value
        node = main.nodes[node.next]
    assert set(tuning) >= {"forward_ms", "turn_ms", "backward_ms", "clearance_cm", "echo_fade_ms",
                           "servo_settle_ms"}
    assert tuning["clearance_cm"] == 20
    # then every actuator is stopped
    assert isinstance(node, ActionNode) and node.call.target == LaneTarget(lane="Stop")
    loop = main.nodes["running"]
    assert isinstance(loop, DecisionNode)
    assert [b.label for b in loop.branches] == ["Application.exit", "else"]
    choose = main.nodes["choose"]
    assert isinstance(choose, DecisionNode)
    assert [b.label for b in choose.branches] == [
        "Measure.center > clearance_cm", "Measure.left > clearance_cm", "Measure.right > clearance_cm",
        "else"]
    called = [main.nodes[b.target] for b in choose.branches]
    assert [n.call.target.lane for n in called] == [  # type: ignore[union-attr]
        "MoveForward", "TurnLeft", "TurnRight", "MoveBackward"]
