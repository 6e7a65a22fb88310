"""One failing model per check: the exact message, line and column of each problem."""

from __future__ import annotations

from pathlib import Path

import pytest
from compiler_support import HEADER, MAIN, at, check_text, errors_of, position

from umlbot.base.catalog import component_kinds
from umlbot.compiler.api import check_model
from umlbot.compiler.compiled import dump_compiled


def lane(*nodes: str, name: str = "Pi") -> str:
    body = "".join(f"      - {node}\n" for node in nodes)
    return f"  - lane: {name}\n    nodes:\n{body}"


def main_with(*middle: str) -> str:
    return lane("{id: start, kind: start}", *middle, "{id: end, kind: end}")


# (case id, model text, expected message, text to find the position by, which occurrence)
CASES: list[tuple[str, str, str, str, int]] = [
    ("unknown component",
     HEADER + main_with("{id: a, kind: action, call: Motr.enabled(true)}"),
     "unknown component 'Motr'", "Motr.", 0),
    ("unknown feature",
     HEADER + main_with("{id: a, kind: action, call: Motor.speed(3)}"),
     "unknown feature 'speed' of actuator component 'Motor' (known: enabled, direction, dutycycle)",
     "speed", 0),
    ("wrong argument count",
     HEADER + main_with("{id: a, kind: action, call: Motor.enabled()}"),
     "Motor.enabled takes 1 argument(s) (on: bool), got 0", "Motor.enabled()", 0),
    ("wrong argument type",
     HEADER + main_with("{id: a, kind: action, call: Motor.dutycycle(true)}"),
     "argument 1 (percent) of Motor.dutycycle must be int, got bool", "true)", 0),
    ("argument out of range",
     HEADER + main_with("{id: a, kind: action, call: Motor.dutycycle(150)}"),
     "argument 1 (percent) of Motor.dutycycle must be 0..100 by implementation 'l298n', got 150",
     "150", 0),
    ("argument out of the implementation's range",
     HEADER + main_with("{id: a, kind: action, call: Servo.angle(270)}"),
     "argument 1 (degrees) of Servo.angle must be 0..180 by implementation 'servo', got 270", "270", 0),
    ("negative constant out of range",
     HEADER + main_with("{id: a, kind: action, call: Servo.angle(-5)}"),
     "argument 1 (degrees) of Servo.angle must be 0..180 by implementation 'servo', got -5", "-5", 0),
    ("constant expression out of range",
     HEADER + main_with("{id: a, kind: action, call: Servo.angle(90 * 3)}"),
     "argument 1 (degrees) of Servo.angle must be 0..180 by implementation 'servo', got 270", "90 * 3", 0),
    ("negative constant sleep",
     HEADER + main_with("{id: a, kind: action, call: msleep(100 - 250)}"),
     "msleep needs a duration of 0 or more, got -150", "100 - 250", 0),
    ("implementation does not offer the feature",
     HEADER + main_with("{id: a, kind: action, call: Motor.angle(90)}"),
     "implementation 'l298n' of 'Motor' does not offer feature 'angle' (it offers: enabled, direction, "
     "dutycycle)", "angle", 0),
    ("duplicate start",
     HEADER + main_with("{id: again, kind: start, next: end}"),
     "duplicate start node 'again': swimlane 'Pi' already starts at 'start'", "again", 0),
    ("missing start",
     HEADER + lane("{id: a, kind: action, call: Motor.enabled(true)}", "{id: end, kind: end}"),
     "swimlane 'Pi' has no start node", "Pi\n    nodes", 0),
    ("missing end",
     HEADER + lane("{id: start, kind: start}", "{id: a, kind: action, call: Motor.enabled(true), "
                   "next: a}"),
     "swimlane 'Pi' has no end node", "Pi\n    nodes", 0),
    ("node with no path from the start",
     HEADER + lane("{id: start, kind: start, next: end}", "{id: lost, kind: action, call: "
                   "Motor.enabled(true)}", "{id: end, kind: end}"),
     "node 'lost' has no path from the start of swimlane 'Pi'", "lost", 0),
    ("edge to an unknown node",
     HEADER + main_with("{id: d, kind: decision, branches: [{if: 'true', then: nowhere}, {else: end}]}"),
     "flow from 'd' goes to unknown node 'nowhere'", "nowhere", 0),
    ("decision output without guard",
     HEADER + main_with("{id: d, kind: decision, branches: [{then: end}, {else: end}]}"),
     "decision output without guard: write {if: <guard>, then: <node>} or {else: <node>}",
     "{then: end}", 0),
    ("empty guard: its one error (the node it leads to is still reached)",
     HEADER + main_with("{id: d, kind: decision, branches: [{if: '', then: on}, {else: end}]}",
                        "{id: on, kind: action, call: Motor.enabled(true), next: end}"),
     "decision output without guard: write {if: <guard>, then: <node>} or {else: <node>}",
     "{if: ''", 0),
    ("a guard that is not an expression: its one error",
     HEADER + main_with("{id: d, kind: decision, branches: [{if: [1], then: on}, {else: end}]}",
                        "{id: on, kind: action, call: Motor.enabled(true), next: end}"),
     "a guard is an expression", "[1]", 0),
    ("fork without matching join",
     HEADER + main_with("{id: f, kind: fork, targets: [a, b]}",
                        "{id: a, kind: action, call: Motor.enabled(true), next: end}",
                        "{id: b, kind: action, call: Motor.enabled(false), next: end}"),
     "fork 'f' has no matching join: its flows never reach a join", "f,", 0),
    ("join that can never fire (two flows of one branch)",
     HEADER + main_with(
         "{id: f, kind: fork, targets: [a, d]}",
         "{id: a, kind: action, call: Motor.enabled(true), next: j}",
         "{id: d, kind: decision, branches: [{if: 'true', then: x}, {else: y}]}",
         "{id: x, kind: action, call: msleep(1), next: j}",
         "{id: y, kind: action, call: msleep(2), next: j}",
         "{id: j, kind: join}"),
     "join 'j' can never fire: the flows from 'x' and 'y' come from the same branch of fork 'f' "
     "(from 'd'), so only one of them arrives", "j, kind: join", 0),
    ("join that can never fire (no fork)",
     HEADER + main_with(
         "{id: d, kind: decision, branches: [{if: 'true', then: x}, {else: y}]}",
         "{id: x, kind: action, call: msleep(1), next: j}",
         "{id: y, kind: action, call: msleep(2), next: j}",
         "{id: j, kind: join}"),
     "join 'j' can never fire: its incoming flows (x, y) do not come from one fork", "j, kind: join", 0),
    ("unknown datastore",
     HEADER + main_with("{id: a, kind: action, call: msleep(delay)}"),
     "unknown datastore 'delay' in swimlane 'Pi'", "delay", 0),
    ("unknown datastore of another lane",
     HEADER + main_with("{id: x, kind: datastore, name: x, value: 1}",
                        "{id: a, kind: action, call: msleep(Pi.y)}"),
     "unknown datastore 'y' in swimlane 'Pi'", "y)", 0),
    ("feature read without parentheses",
     HEADER + main_with("{id: x, kind: datastore, name: x, value: Sonar.value}"),
     "unknown datastore 'value' in swimlane 'Sonar'; to call the feature, write Sonar.value()",
     "value}", 0),
    ("call to an unknown lane",
     HEADER + main_with("{id: a, kind: action, call: TurnAround}"),
     "unknown swimlane or builtin 'TurnAround'", "TurnAround", 0),
    ("call to an unknown lane with parentheses",
     HEADER + main_with("{id: a, kind: action, call: TurnAround()}"),
     "unknown swimlane or builtin 'TurnAround'", "TurnAround", 0),
    ("call of a component's lane",
     HEADER + main_with("{id: a, kind: action, call: Pi()}"),
     "'Pi' is the swimlane of component 'Pi'; only virtual swimlanes can be called", "Pi()", 0),
    ("virtual lane called with arguments",
     HEADER + main_with("{id: a, kind: action, call: Helper(1)}")
     + lane("{id: start, kind: start}", "{id: end, kind: end}", name="Helper"),
     "swimlane 'Helper' takes no arguments, got 1", "1)", 0),
    ("a value that is not there",
     HEADER + main_with("{id: x, kind: datastore, name: x, value: Motor.enabled(true)}"),
     "'Motor.enabled(true)' gives no value", "Motor.enabled(true)", 0),
    ("guard that is not a bool",
     HEADER + main_with("{id: d, kind: decision, branches: [{if: 1 + 2, then: end}, {else: end}]}"),
     "a guard must be a bool, got int", "1 + 2", 0),
    ("operator on wrong types",
     HEADER + main_with("{id: x, kind: datastore, name: x, value: true + 1}"),
     "'+' needs numbers, got bool and int", "+ 1", 0),
    ("expression syntax error",
     HEADER + main_with("{id: x, kind: datastore, name: x, value: '(1 + 2'}"),
     "expected ')', found end of expression", "'}", 0),
    ("expression syntax error in double quotes",
     HEADER + main_with('{id: x, kind: datastore, name: x, value: "1 = 2"}'),
     "unexpected character '=' (write '==')", "= 2", 0),
    ("action that is not a call",
     HEADER + main_with("{id: a, kind: action, call: 1 + 2}"),
     "an action is a call: Component.feature(args), a virtual swimlane, or a builtin such as msleep(ms)",
     "1 + 2", 0),
    ("duplicate node id",
     HEADER + main_with("{id: start, kind: action, call: msleep(1)}"),
     "duplicate node id 'start' in swimlane 'Pi'", "start, kind: action", 0),
    ("unknown key in a node",
     HEADER + main_with("{id: a, kind: action, call: msleep(1), nxt: end}"),
     "unknown key 'nxt' in action node (expected: id, kind, call, next)", "nxt", 0),
    ("unknown node kind",
     HEADER + main_with("{id: a, kind: activity}"),
     "node 'a': 'kind' must be one of start, end, action, datastore, decision, fork, join, send, accept",
     "activity", 0),
    ("node without outgoing flow",
     HEADER + lane("{id: start, kind: start}",
                   "{id: d, kind: decision, branches: [{if: 'true', then: last}, {else: end}]}",
                   "{id: end, kind: end}", "{id: last, kind: action, call: msleep(1)}"),
     "action node 'last' has no outgoing flow: give it 'next' or put a node after it", "last", 1),
    ("duplicate swimlane",
     HEADER + MAIN + MAIN,
     "duplicate swimlane 'Pi' (first defined at {file}:17)", "Pi\n    nodes", 1),
    ("unknown component kind",
     HEADER.replace("Pi: {kind: system}", "Pi: {kind: computer}") + MAIN,
     f"unknown component kind 'computer' (known: {', '.join(component_kinds())})", "computer", 0),
    ("port naming an unknown feature",
     HEADER.replace("ports: {drive: enabled}", "ports: {drive: speed}") + MAIN,
     "port 'drive' names unknown feature 'speed' of actuator component 'Motor' (known: enabled, "
     "direction, dutycycle, angle)", "speed", 0),
    ("port naming a feature the implementation lacks",
     HEADER.replace("ports: {drive: enabled}", "ports: {drive: angle}") + MAIN,
     "implementation 'l298n' of 'Motor' does not offer feature 'angle' (port 'drive')", "angle", 0),
    ("link to an unknown port",
     HEADER + MAIN + "links:\n  - {id: wire, from: Motor.drive, to: Sonar.echo}\n",
     "link 'wire' names unknown port 'echo' of component 'Sonar'", "Sonar.echo", 0),
    ("deployment naming an unknown component",
     HEADER.replace("    Sonar: {impl: hcsr04}\n", "    Sonar: {impl: hcsr04}\n    Wheel: {impl: l298n}\n")
     + MAIN,
     "deployment names unknown component 'Wheel'", "Wheel", 0),
    ("deployment naming an unknown implementation",
     HEADER.replace("Motor: {impl: l298n}", "Motor: {impl: l293d}") + MAIN,
     "unknown implementation id 'l293d' for component 'Motor'", "l293d", 0),
    ("deployment missing a component",
     HEADER.replace("    Sonar: {impl: hcsr04}\n", "") + MAIN,
     "component 'Sonar' has no implementation in the deployment", "Sonar", 0),
    ("implementation of another kind",
     HEADER.replace("Sonar: {impl: hcsr04}", "Sonar: {impl: l298n}") + MAIN,
     "component 'Sonar' is a sensor but implementation 'l298n' is an actuator", "l298n}", 1),
    ("settings the hardware drivers refuse",
     HEADER.replace("driver: mock", "driver: auto")
     .replace("Servo: {impl: servo}", "Servo: {impl: servo, settings: {gpio: 40}}") + MAIN,
     "settings of 'Servo' (servo) refused by the hardware drivers: gpio: Input should be less than or "
     "equal to 27", "gpio: 40", 0),
    ("a robot id that is not one topic level",
     HEADER.replace("  driver: mock", "  robot: my/car\n  driver: mock") + MAIN,
     "robot id 'my/car' cannot be used in an MQTT topic (letters, digits, '_', '-', '.'; no '/', '+', "
     "'#' or spaces)", "robot: my/car", 0),
    ("empty settings for the hardware",
     HEADER.replace("driver: mock", "driver: auto")
     .replace("Servo: {impl: servo}", "Servo: {impl: servo, settings: {}}")
     .replace("Motor: {impl: l298n}", "Motor: {impl: l298n, settings: {in1: 5, in2: 6}}")
     .replace("Sonar: {impl: hcsr04}", "Sonar: {impl: hcsr04, settings: {trigger: 8, echo: 7}}") + MAIN,
     "settings of 'Servo' (servo) refused by the hardware drivers: gpio: Field required", "settings: {}", 0),
    ("settings a named driver refuses",
     HEADER.replace("Sonar: {impl: hcsr04}", "Sonar: {impl: hcsr04, driver: pigpio, "
                    "settings: {trigger: 8, echo: 8}}") + MAIN,
     "settings of 'Sonar' (hcsr04) refused by driver 'pigpio': Value error, trigger and echo must be "
     "different pins, got 8", "settings: {trigger", 0),
    ("an unknown driver",
     HEADER.replace("Motor: {impl: l298n}", "Motor: {impl: l298n, driver: pigpoi}") + MAIN,
     "unknown driver 'pigpoi' for 'Motor' (motor service; known: auto, lgpio, mock, pigpio, sim)",
     "driver: pigpoi", 0),
    ("an unknown default driver",
     HEADER.replace("driver: mock", "driver: simm") + MAIN,
     "unknown driver 'simm' (known: auto, lgpio, mock, pigpio, sim)", "driver: simm", 0),
    ("a default driver one service lacks",
     HEADER.replace("driver: mock", "driver: sim") + MAIN,
     "the gpio service of 'Pi' has no driver 'sim' (known: auto, lgpio, mock, pigpio); give it a driver "
     "of its own", "driver: sim", 0),
    ("two components on one pin",
     HEADER.replace("driver: mock", "driver: auto")
     .replace("Motor: {impl: l298n}", "Motor: {impl: l298n, settings: {in1: 5, in2: 6}}")
     .replace("Sonar: {impl: hcsr04}", "Sonar: {impl: hcsr04, settings: {trigger: 8, echo: 6}}") + MAIN,
     "GPIO 6 ('echo' of 'Sonar') is already wired to 'Motor' ('in2'): each pin belongs to one component",
     "echo", 0),
    ("a gpio pin list entry on another component's pin",
     HEADER.replace("Pi: {impl: raspberrypi}", "Pi: {impl: raspberrypi, settings: {pins: [4, 6]}}")
     .replace("Motor: {impl: l298n}", "Motor: {impl: l298n, settings: {in1: 5, in2: 6}}") + MAIN,
     "GPIO 6 ('in2' of 'Motor') is already wired to 'Pi' ('pins'): each pin belongs to one component",
     "in2: 6", 0),
    ("a misspelt hardware setting under the mock driver (the robot would refuse it)",
     HEADER.replace("Motor: {impl: l298n}", "Motor: {impl: l298n, settings: {in_1: 5, in2: 6}}") + MAIN,
     "settings of 'Motor' (l298n) refused by driver 'mock': in_1: Extra inputs are not permitted",
     "in_1", 0),
    ("a hardware setting out of range under the sim driver",
     HEADER.replace("Sonar: {impl: hcsr04}", "Sonar: {impl: hcsr04, driver: sim, settings: {trigger: 30}}")
     + MAIN,
     "settings of 'Sonar' (hcsr04) refused by driver 'sim': trigger: Input should be less than or equal "
     "to 27",
     "trigger: 30", 0),
    ("reserved name",
     HEADER + MAIN + lane("{id: start, kind: start}", "{id: end, kind: end}", name="Application"),
     "'Application' is a reserved name; choose another swimlane name", "Application", 0),
    ("builtin misspelt",
     HEADER + main_with("{id: d, kind: decision, branches: [{if: Application.quit, then: end}, "
                        "{else: end}]}"),
     "unknown builtin 'Application.quit' (known: Application.exit)", "quit", 0),
    ("sleep without argument",
     HEADER + main_with("{id: a, kind: action, call: msleep}"),
     "msleep needs an argument: msleep(ms)", "msleep", 0),
]


@pytest.mark.parametrize(("text", "message", "needle", "nth"),
                         [case[1:] for case in CASES], ids=[case[0] for case in CASES])
def test_each_check_reports_message_line_and_column(tmp_path: Path, text: str, message: str,
                                                    needle: str, nth: int) -> None:
    result = check_text(tmp_path, text)
    file = str(tmp_path / "model.yaml")
    errors = errors_of(result)
    assert result.model is None
    assert [e.message for e in errors] == [message.replace("{file}", file)], [str(e) for e in errors]
    assert at(errors[0]) == position(text, needle, nth)
    assert errors[0].location.file == file
    assert str(errors[0]).startswith(f"{file}:{errors[0].location.line}:{errors[0].location.column}: "
                                     "error: ")


def test_invalid_yaml_points_at_the_problem(tmp_path: Path) -> None:
    text = HEADER + "  - lane: Pi\n    nodes: [\n"
    errors = errors_of(check_text(tmp_path, text))
    assert len(errors) == 1
    assert errors[0].message.startswith("invalid YAML: ")  # the parser's own words follow
    assert at(errors[0]) == (text.count("\n") + 1, 1)


def test_exact_position_of_an_unknown_feature(tmp_path: Path) -> None:
    """The same check as above, with the position written out: line 20, column 43."""
    text = HEADER + main_with("{id: a, kind: action, call: Motor.speed(3)}")
    errors = errors_of(check_text(tmp_path, text))
    assert at(errors[0]) == (20, 43)


def test_decision_without_else_is_a_warning(tmp_path: Path) -> None:
    text = HEADER + main_with("{id: d, kind: decision, branches: [{if: Application.exit, then: end}]}")
    result = check_text(tmp_path, text)
    assert result.ok
    assert [(w.message, at(w)) for w in result.warnings] == [
        ("decision 'd' has no else output: when no guard holds, this flow stops",
         position(text, "d, kind: decision"))]


def test_virtual_lane_never_called_is_a_warning(tmp_path: Path) -> None:
    text = HEADER + MAIN + lane("{id: start, kind: start}", "{id: end, kind: end}", name="Spare")
    result = check_text(tmp_path, text)
    assert result.ok
    assert [(w.message, at(w)) for w in result.warnings] == [
        ("virtual swimlane 'Spare' is never called", position(text, "Spare"))]


def test_recursion_between_virtual_lanes(tmp_path: Path) -> None:
    text = (HEADER + main_with("{id: a, kind: action, call: Ping}")
            + lane("{id: start, kind: start}", "{id: p, kind: action, call: Pong}", "{id: end, kind: end}",
                   name="Ping")
            + lane("{id: start, kind: start}", "{id: p, kind: action, call: Ping()}",
                   "{id: end, kind: end}", name="Pong"))
    errors = errors_of(check_text(tmp_path, text))
    assert [e.message for e in errors] == ["recursion between virtual swimlanes: Ping -> Pong -> Ping"]
    assert at(errors[0]) == position(text, "Ping()")


def test_a_virtual_lane_calling_itself(tmp_path: Path) -> None:
    text = (HEADER + main_with("{id: a, kind: action, call: Loop}")
            + lane("{id: start, kind: start}", "{id: again, kind: action, call: Loop}",
                   "{id: end, kind: end}", name="Loop"))
    errors = errors_of(check_text(tmp_path, text))
    assert [e.message for e in errors] == ["virtual swimlane 'Loop' calls itself (recursion is not allowed)"]
    assert at(errors[0]) == position(text, "Loop}", 1)


def test_every_problem_in_one_run(tmp_path: Path) -> None:
    text = HEADER.replace("Motor: {impl: l298n}", "Motor: {impl: l293d}") + main_with(
        "{id: a, kind: action, call: Motr.enabled(true)}",
        "{id: b, kind: action, call: Servo.angle(999)}",
        "{id: c, kind: action, call: msleep(delay), next: nowhere}",
    )
    result = check_text(tmp_path, text)
    messages = [e.message for e in errors_of(result)]
    assert messages == [
        "unknown implementation id 'l293d' for component 'Motor'",
        "unknown component 'Motr'",
        "argument 1 (degrees) of Servo.angle must be 0..180 by implementation 'servo', got 999",
        "unknown datastore 'delay' in swimlane 'Pi'",
        "flow from 'c' goes to unknown node 'nowhere'",
        "node 'end' has no path from the start of swimlane 'Pi'",
    ]
    lines = [e.location.line for e in errors_of(result)]
    assert lines == sorted(lines)


def test_missing_deployment(tmp_path: Path) -> None:
    text = HEADER.split("deployment:")[0] + "lanes:\n" + MAIN
    errors = errors_of(check_text(tmp_path, text))
    assert [e.message for e in errors] == [
        "the model has no deployment (deployment.yaml or deployment.txt beside model.yaml, or a "
        "'deployment' section)"]
    assert at(errors[0]) == (1, 1)


def test_a_component_without_settings_for_the_hardware_is_a_warning(tmp_path: Path) -> None:
    text = HEADER.replace("driver: mock", "driver: auto") + MAIN
    result = check_text(tmp_path, text)
    assert result.ok
    warnings = [(w.message, at(w)) for w in result.warnings]
    assert ("'Servo' has no settings: the hardware drivers need gpio (it runs with the mock and sim "
            "drivers only)", position(text, "Servo: {impl")) in warnings, warnings
    motor = "'Motor' has no settings: the hardware drivers need in1, in2"
    assert any(m.startswith(motor) for m, _ in warnings), warnings
    # the seed's plain format has no settings at all: nothing to say
    root = _folder_model(tmp_path, "Pi=raspberrypi\nMotor=l298n\nServo=servo\nSonar=hcsr04\n")
    assert not [w for w in check_model(root).warnings if "settings" in w.message]


def test_a_folder_name_that_cannot_be_the_robot_id_asks_for_a_name(tmp_path: Path) -> None:
    root = tmp_path / "my robot"
    root.mkdir()
    (root / "model.yaml").write_text(HEADER.replace("name: t\n", "") + MAIN, encoding="utf-8")
    assert [e.message for e in errors_of(check_model(root))] == [
        "the model's name 'my robot' cannot be used in an MQTT topic (letters, digits, '_', '-', '.'; "
        "no '/', '+', '#' or spaces); it is the robot id: give the model a `name` (or the deployment a "
        "`robot`)"]
    (root / "model.yaml").write_text(HEADER + MAIN, encoding="utf-8")
    assert check_model(root).ok


def test_a_folders_model_yaml_is_the_folder() -> None:
    car = Path(__file__).resolve().parents[1] / "models" / "robot_car"
    by_file, by_folder = check_model(car / "model.yaml").model, check_model(car).model
    assert by_file is not None and by_folder is not None
    assert dump_compiled(by_file) == dump_compiled(by_folder)  # the same lanes, deployment, name


def _folder_model(tmp_path: Path, deployment: str, name: str = "deployment.txt") -> Path:
    root = tmp_path / "m"
    (root / "activities").mkdir(parents=True)
    components = HEADER.split("deployment:")[0]
    (root / "model.yaml").write_text(components, encoding="utf-8")
    (root / "activities" / "main.yaml").write_text(
        "lane: Pi\nnodes:\n  - {id: start, kind: start}\n  - {id: end, kind: end}\n", encoding="utf-8")
    (root / name).write_text(deployment, encoding="utf-8")
    return root


def test_plain_deployment_positions(tmp_path: Path) -> None:
    from umlbot.compiler.api import check_model

    text = "# seed format\nPi=CModelSystemRaspberryPI\nMotor=CModelL298NActuator\n  Servo = CModelServo\n" \
           "Sonar=CModelDistanceSensorHCSR\nWheel=l298n\n"
    root = _folder_model(tmp_path, text)
    errors = errors_of(check_model(root))
    file = str(root / "deployment.txt")
    assert [(e.message, e.location.file, at(e)) for e in errors] == [
        ("unknown implementation id 'CModelServo' for component 'Servo'", file, (4, 11)),
        ("deployment names unknown component 'Wheel'", file, (6, 1)),
    ]


def test_rich_deployment_shape_error_position(tmp_path: Path) -> None:
    from umlbot.compiler.api import check_model

    text = "driver: mock\ncomponents:\n  Pi: {impl: raspberrypi, colour: red}\n"
    root = _folder_model(tmp_path, text, "deployment.yaml")
    errors = errors_of(check_model(root))
    assert [(e.message, at(e)) for e in errors] == [
        ("invalid deployment: components.Pi.colour: Extra inputs are not permitted", (3, 27))]


def test_folder_model_errors_name_their_files(tmp_path: Path) -> None:
    from umlbot.compiler.api import check_model

    root = _folder_model(tmp_path, "Pi=raspberrypi\nMotor=l298n\nServo=servo\nSonar=hcsr04\n")
    (root / "activities" / "extra.yaml").write_text(
        "lane: Extra\nnodes:\n  - {id: start, kind: start}\n  - {id: a, kind: action, call: Motor.fly()}\n"
        "  - {id: end, kind: end}\n", encoding="utf-8")
    errors = errors_of(check_model(root))
    assert [(e.location.file, at(e), e.message) for e in errors] == [
        (str(root / "activities" / "extra.yaml"), (4, 39),
         "unknown feature 'fly' of actuator component 'Motor' (known: enabled, direction, dutycycle)")]


def test_missing_model_file(tmp_path: Path) -> None:
    from umlbot.compiler.api import check_model

    result = check_model(tmp_path)
    assert [e.message for e in result.errors] == ["not a model: no model.yaml in this folder"]


def test_compile_model_raises_model_errors_with_every_diagnostic(tmp_path: Path) -> None:
    from umlbot import ModelError
    from umlbot.base.diagnostics import ModelErrors
    from umlbot.compiler.api import compile_model

    path = tmp_path / "model.yaml"
    path.write_text(HEADER + main_with("{id: a, kind: action, call: Motr.enabled(true)}",
                                       "{id: b, kind: action, call: Motor.fly()}"), encoding="utf-8")
    with pytest.raises(ModelErrors) as caught:
        compile_model(path)
    assert isinstance(caught.value, ModelError)
    assert caught.value.message == "unknown component 'Motr' (and 1 more error(s))"
    assert (caught.value.line, caught.value.column) == (20, 37)
    assert len(caught.value.diagnostics) == 2


def test_datastore_types_are_inferred_from_every_write(tmp_path: Path) -> None:
    text = HEADER + main_with(
        "{id: a, kind: datastore, name: a, value: b}",          # reads b before b is written
        "{id: b, kind: datastore, name: b, value: 1}",
        "{id: c0, kind: datastore, name: count, value: 0}",
        "{id: c1, kind: datastore, name: count, value: count + 1.5}",
        "{id: ok, kind: action, call: Motor.dutycycle(a)}",
        "{id: bad, kind: action, call: Motor.dutycycle(count)}",
    )
    errors = errors_of(check_text(tmp_path, text))
    assert [(e.message, at(e)) for e in errors] == [
        ("argument 1 (percent) of Motor.dutycycle must be int, got float", position(text, "count)}"))]


def test_an_accepted_payload_can_be_anything(tmp_path: Path) -> None:
    text = HEADER + main_with(
        "{id: w, kind: accept, signal: speed, store: speed}",
        "{id: set, kind: action, call: Motor.dutycycle(speed)}",
        "{id: d, kind: decision, branches: [{if: speed, then: end}, {else: end}]}",
    )
    assert check_text(tmp_path, text).ok
