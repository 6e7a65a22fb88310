"""A section of the wrong shape is its one error: its names are unknown, not absent.

`components: 5` used to give one real error and 37 follow-ons ("unknown component", "deployment
names unknown component") plus a false "never called" warning; an emptied activity file gave a
warning and one "unknown swimlane" per call. Each case edits a copy of the reference car and
reads `umlbot check`'s own output; a real problem elsewhere is still reported beside the damage.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner, Result
from compiler_support import position

from umlbot.base.catalog import component_kinds
from umlbot.cli import cli

ROOT = Path(__file__).resolve().parent.parent
ROBOT_CAR = ROOT / "models" / "robot_car"


def _car(tmp_path: Path) -> Path:
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    return model


def _edit(path: Path, old: str, new: str) -> tuple[int, int]:
    """Replace the first `old` in `path` by `new`; the position of the replacement."""
    text = path.read_text(encoding="utf-8")
    assert old in text, old
    where = position(text, old)
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return where


def _check(model: Path) -> Result:
    return CliRunner().invoke(cli, ["check", str(model)])


# (file, old text, new text, the one error's column offset from the edit, its message)
SHAPES: dict[str, tuple[str, str, str, int, str]] = {
    "components a number": (
        "model.yaml", "components:\n  RaspberryPI:\n    kind: system\n",
        "components: 5\nformer:\n  RaspberryPI:\n    kind: system\n", 12,
        "'components' is a mapping: ComponentName: {kind: ..., ports: {...}}"),
    "components a list": (
        "model.yaml", "components:\n  RaspberryPI:\n    kind: system\n",
        "components: [RaspberryPI]\nformer:\n  RaspberryPI:\n    kind: system\n", 12,
        "'components' is a mapping: ComponentName: {kind: ..., ports: {...}}"),
    "lanes a mapping": (
        "activities/motion.yaml", "lanes:\n", "lanes: {a: 1}\nformer:\n", 7,
        "'lanes' is a list of swimlanes, each {lane: Name, nodes: [...]}"),
    "a swimlane's name a list": (
        "activities/motion.yaml", "lane: MoveForward", "lane: [MoveForward]", 6,
        "a swimlane needs 'lane: Name' (a plain name)"),
    "a whole activity file a number": (
        "activities/measure.yaml", "lane:", "7\nformer:", 0,
        "a swimlane is a mapping {lane: Name, nodes: [...]}"),
}


@pytest.mark.parametrize("case", sorted(SHAPES))
def test_a_section_of_the_wrong_shape_is_its_one_error(tmp_path: Path, case: str) -> None:
    name, old, new, column, message = SHAPES[case]
    model = _car(tmp_path)
    path = model / name
    line, col = _edit(path, old, new)
    if case == "a whole activity file a number":
        path.write_text("7\n", encoding="utf-8")
        line, col = 1, 1
    result = _check(model)
    # the unknown keys the edit leaves ('former') are not what is tested: they are real errors
    lines = [x for x in result.stdout.splitlines() if "unknown key 'former'" not in x]
    assert lines == [f"{path}:{line}:{col + column}: error: {message}"]
    assert result.exit_code == 1
    assert "warning" not in result.stderr.replace("0 warning(s)", "")


def test_with_components_unknown_a_real_error_elsewhere_is_still_reported(tmp_path: Path) -> None:
    model = _car(tmp_path)
    _edit(model / "model.yaml", "components:\n  RaspberryPI:", "components: 5\nformer:\n  RaspberryPI:")
    main = model / "activities" / "main.yaml"
    line, column = _edit(main, "call: Stop}", "call: Stpo}")  # no swimlane was lost: a typo
    lines = _check(model).stdout.splitlines()
    assert f"{main}:{line}:{column + 6}: error: unknown swimlane or builtin 'Stpo'" in lines
    assert not [x for x in lines if "unknown component" in x or "never called" in x]


def test_one_bad_component_entry_leaves_the_others_known(tmp_path: Path) -> None:
    # LeftActuator's entry cannot be read: references to it are not reported again (its entry's
    # error says what is wrong); references to the other components are checked as ever
    model = _car(tmp_path)
    line, column = _edit(model / "model.yaml", "LeftActuator:\n    kind: actuator",
                         "LeftActuator:\n    kind: [actuator]")
    motion = model / "activities" / "motion.yaml"
    typo_line, typo_column = _edit(motion, "RightActuator.direction(true)", "RightActuator.direktion(true)")
    result = _check(model)
    assert result.stdout.splitlines() == [
        f"{motion}:{typo_line}:{typo_column + 14}: error: unknown feature 'direktion' of actuator "
        "component 'RightActuator' (known: enabled, direction, dutycycle)",
        f"{model / 'model.yaml'}:{line + 1}:11: error: a component's kind is one of "
        f"{', '.join(component_kinds())}",
    ]
    assert column == 3


@pytest.mark.parametrize("edit, message", [
    (("kind: sensor", "kind: sensr"), f"unknown component kind 'sensr' (known: "
                                      f"{', '.join(component_kinds())})"),
    (("ports: {range: value}", "ports: [range]"), "'ports' is a mapping: port_name: feature"),
])
def test_a_damaged_component_is_reported_once(tmp_path: Path, edit: tuple[str, str], message: str) -> None:
    # DistanceRead: its kind or ports unknown, the link to its port `range` and the calls of its
    # feature `value` are not follow-on errors
    model = _car(tmp_path)
    line, column = _edit(model / "model.yaml", *edit)
    offset = 6 if edit[0].startswith("kind") else 7
    assert _check(model).stdout.splitlines() == [
        f"{model / 'model.yaml'}:{line}:{column + offset}: error: {message}"]


def test_a_plain_deployment_line_without_implementation_is_one_error(tmp_path: Path) -> None:
    model = _car(tmp_path)
    (model / "deployment.yaml").unlink()  # the plain deployment.txt is read
    plain = model / "deployment.txt"
    line, _ = _edit(plain, "LeftActuator=CModelL298NActuator", "LeftActuator=")
    assert _check(model).stdout.splitlines() == [
        f"{plain}:{line}:1: error: expected '<component>=<implementation id>'"]
    # a line that names no component: none is reported as undeployed
    _edit(plain, "LeftActuator=", "=CModelL298NActuator")
    assert _check(model).stdout.splitlines() == [
        f"{plain}:{line}:1: error: expected '<component>=<implementation id>'"]
    # a component that is simply not there still is
    _edit(plain, "=CModelL298NActuator", "")
    assert _check(model).stdout.splitlines() == [
        f"{model / 'model.yaml'}:9:3: error: component 'LeftActuator' has no implementation in the "
        "deployment"]


def test_a_node_of_the_wrong_shape_leaves_its_swimlane_unknown_not_wrong(tmp_path: Path) -> None:
    model = _car(tmp_path)
    main = model / "activities" / "main.yaml"
    # the start node and a datastore the lane reads later: no "no start node", no "unknown
    # datastore 'speed_percent'"
    start_line, _ = _edit(main, "  - {id: start, kind: start}", "  - [start]")
    store_line, _ = _edit(main, "  - {id: set_speed, kind: datastore, name: speed_percent, value: 70}",
                          "  - [set_speed, 70]")
    assert _check(model).stdout.splitlines() == [
        f"{main}:{start_line}:5: error: an activity node is a mapping {{id: ..., kind: ..., ...}}",
        f"{main}:{store_line}:5: error: an activity node is a mapping {{id: ..., kind: ..., ...}}",
    ]


# --- an empty activity file -------------------------------------------------------------------------


def test_an_emptied_activity_file_is_one_error_naming_the_swimlanes_missing(tmp_path: Path) -> None:
    model = _car(tmp_path)
    motion = model / "activities" / "motion.yaml"
    motion.write_bytes(b"")
    main = model / "activities" / "main.yaml"
    text = main.read_text(encoding="utf-8")
    calls = {name: position(text, f"call: {name}") for name in
             ("Stop", "MoveForward", "MoveBackward", "TurnRight", "TurnLeft")}
    listed = ", ".join(f"{name} (first at {main}:{line}:{column + 6})"
                       for name, (line, column) in sorted(calls.items(), key=lambda kv: kv[1]))
    result = _check(model)
    assert result.stdout.splitlines() == [
        f"{motion}:1:1: error: empty activity file, and the model names 5 swimlanes defined nowhere: "
        f"{listed}"]
    assert (result.exit_code, result.stderr) == (1, f"{model}: 1 error(s), 0 warning(s)\n")


def test_two_emptied_files_share_the_list(tmp_path: Path) -> None:
    model = _car(tmp_path)
    (model / "activities" / "motion.yaml").write_bytes(b"")
    (model / "activities" / "measure.yaml").write_text("# nothing yet\n", encoding="utf-8")
    lines = _check(model).stdout.splitlines()
    assert len(lines) == 2, lines
    first, second = sorted(lines, key=lambda x: "listed at" in x)
    assert first.startswith(f"{model / 'activities' / 'measure.yaml'}:1:1: error: empty activity file, "
                            "and the model names 7 swimlanes defined nowhere: ")
    assert "Measure (first at" in first and "Stop (first at" in first
    assert second == (f"{model / 'activities' / 'motion.yaml'}:1:1: error: empty activity file (the "
                      f"swimlanes defined nowhere are listed at {model / 'activities' / 'measure.yaml'}"
                      ":1:1)")


def test_an_empty_activity_file_that_nothing_misses_is_a_warning(tmp_path: Path) -> None:
    model = _car(tmp_path)
    extra = model / "activities" / "later.yaml"
    extra.write_bytes(b"")
    result = _check(model)
    assert result.stdout.splitlines() == [f"{extra}:1:1: warning: empty activity file"]
    assert result.exit_code == 0


def test_more_than_ten_swimlanes_missing_are_cut_short(tmp_path: Path) -> None:
    model = _car(tmp_path)
    blank = model / "activities" / "blank.yaml"
    blank.write_bytes(b"")
    calls = "".join(f"  - {{id: c{i}, kind: action, call: Ghost{i}}}\n" for i in range(12))
    (model / "activities" / "ghosts.yaml").write_text(
        f"lane: Ghosts\nnodes:\n  - {{id: start, kind: start}}\n{calls}  - {{id: end, kind: end}}\n",
        encoding="utf-8")
    ghosts = model / "activities" / "ghosts.yaml"
    listed = ", ".join(f"Ghost{i} (first at {ghosts}:{i + 4}:34)" for i in range(10))
    assert _check(model).stdout.splitlines() == [
        f"{blank}:1:1: error: empty activity file, and the model names 12 swimlanes defined nowhere: "
        f"{listed} and 2 more"]
