"""A model with one file that cannot be read: every defect of the other files in one run.

Before, a `model.yaml` or an activity file that could not be read (a YAML syntax error, a byte that
is not UTF-8) was the only problem reported: the defects of every other file showed only once it
was fixed, one round trip each. Now every defect that does not depend on the unreadable file is
reported with it; what could be a follow-on of it (a call of a swimlane it may define, a feature
of a component it may declare, what its deployment would say) is left out, and its error says how
many checks were left out, once.

Each case plants a defect in every file of a copy of the reference car, makes one file
unreadable, and reads `umlbot check`'s own output and the studio's problems for the same folder.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from compiler_support import position

from umlbot.cli import cli
from umlbot.studio.workspace import Workspace

ROBOT_CAR = Path(__file__).resolve().parent.parent / "models" / "robot_car"

MAIN, MEASURE, MOTION = "activities/main.yaml", "activities/measure.yaml", "activities/motion.yaml"

#: one defect in each file (file -> (old, new) edits), none of which depends on another file.
DEFECTS: dict[str, list[tuple[str, str]]] = {
    "model.yaml": [("ports: {pointing: angle}", "ports: {pointing: angel}")],
    MAIN: [("call: Sensor.angle(90)}", "call: Sensor.angle(900)}"),
           ("msleep(forward_ms)}", "msleep(forward_mss)}"),
           ("{id: finish, kind: action, call: Stop}",
            "{id: finish, kind: action, call: Stop, next: nowhere}")],
    MEASURE: [("msleep(RaspberryPI.glance_ms)}", "msleep(RaspberryPI.glance_msx)}")],
    MOTION: [("RightActuator.direction(true)", "RightActuator.direktion(true)")],
    "deployment.yaml": [("settings: {gpio: 18}", "settings: {gpio: 99}"),
                        ("  DistanceRead:\n",
                         "  Ghost: {impl: servo, settings: {gpio: 17}}\n  DistanceRead:\n")],
}

COMPONENTS = ("RaspberryPI", "LeftActuator", "RightActuator", "Sensor", "DistanceRead")
VIRTUAL = {MEASURE: ("Measure", "Glance"),
           MOTION: ("MoveForward", "MoveBackward", "TurnLeft", "TurnRight", "Stop")}


def _car(tmp_path: Path, plain: bool = False) -> Path:
    """A copy of the car with the defects planted (with `plain`, the seed's deployment.txt is its
    deployment: deployment.yaml is removed)."""
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    for name, edits in DEFECTS.items():
        path = model / name
        text = path.read_text(encoding="utf-8")
        for old, new in edits:
            assert old in text, old
            text = text.replace(old, new, 1)
        path.write_text(text, encoding="utf-8")
    if plain:
        (model / "deployment.yaml").unlink()
    return model


def _at(model: Path, name: str, needle: str, offset: int = 0) -> str:
    line, column = position((model / name).read_text(encoding="utf-8"), needle)
    return f"{model / name}:{line}:{column + offset}"


def _expected(model: Path, unread: str) -> list[str]:
    """The lines of every planted defect that `unread` (the file that cannot be read) leaves
    findable, sorted as `umlbot check` prints them."""
    deployment_read = unread not in ("deployment.yaml", "deployment.txt")
    range_by = " by implementation 'servo'" if deployment_read else ""  # else the kind's 0..360
    angle = f"0..180{range_by}" if deployment_read else "0..360"
    known_more = "" if deployment_read else ", angle"
    lines: dict[str, list[str]] = {
        "model.yaml": [
            f"{_at(model, 'model.yaml', 'angel')}: error: port 'pointing' names unknown feature 'angel' of "
            "actuator component 'Sensor' (known: enabled, direction, dutycycle, angle)"],
        MAIN: [
            # a feature's argument range needs the component diagram (Sensor's kind)
            *([f"{_at(model, MAIN, '900)')}: error: argument 1 (degrees) of Sensor.angle must be "
               f"{angle}, got 900"] if unread != "model.yaml" else []),
            f"{_at(model, MAIN, 'forward_mss')}: error: unknown datastore 'forward_mss' in swimlane "
            "'RaspberryPI'",
            f"{_at(model, MAIN, 'nowhere')}: error: flow from 'finish' goes to unknown node 'nowhere'",
            f"{_at(model, MAIN, 'id: end, kind: end', 4)}: error: node 'end' has no path from the start "
            "of swimlane 'RaspberryPI'"],
        # RaspberryPI's datastores are in main.yaml
        MEASURE: [f"{_at(model, MEASURE, 'glance_msx')}: error: unknown datastore 'glance_msx' in "
                  "swimlane 'RaspberryPI'"] if unread != MAIN else [],
        # RightActuator's features need the component diagram (and its implementation's are
        # fewer than its kind's)
        MOTION: [f"{_at(model, MOTION, 'direktion')}: error: unknown feature 'direktion' of actuator "
                 f"component 'RightActuator' (known: enabled, direction, dutycycle{known_more})"]
        if unread != "model.yaml" else [],
        "deployment.yaml": [
            f"{_at(model, 'deployment.yaml', 'gpio: 99')}: error: settings of 'Sensor' (servo) refused "
            "by the hardware drivers: gpio: Input should be less than or equal to 27",
            # whether Ghost is a component is model.yaml's to say
            *([f"{_at(model, 'deployment.yaml', 'Ghost')}: error: deployment names unknown component "
               "'Ghost'"] if unread != "model.yaml" else [])]
        if (model / "deployment.yaml").exists() and unread != "deployment.yaml" else [],
    }
    return [line for name in sorted(lines) if name != unread for line in lines[name]]


def _code(model: Path, *names: str) -> str:
    """The text of model files without their comments."""
    return "\n".join(line.split("#", 1)[0] for name in names
                     for line in (model / name).read_text(encoding="utf-8").splitlines())


def _left_out(model: Path, unread: str) -> int:
    """How many checks depend on `unread`, counted from the texts of the other files: each use of
    a name it may define, and each check of what it would hold (docs/model-format.md)."""
    activities = (MAIN, MEASURE, MOTION)
    feature_calls = re.compile(rf"\b(?:{'|'.join(COMPONENTS)})\.\w+\(")
    if unread in VIRTUAL:  # the calls of its swimlanes and the reads of their datastores
        return len(re.findall(rf"\b(?:{'|'.join(VIRTUAL[unread])})\b", _code(model, MAIN)))
    if unread == MAIN:
        # the reads of RaspberryPI's datastores, and "never called" for each virtual swimlane
        # (main.yaml calls them all)
        reads = re.findall(r"\bRaspberryPI\.", _code(model, MEASURE, MOTION))
        return len(reads) + sum(len(lanes) for lanes in VIRTUAL.values())
    if unread == "model.yaml":
        # each feature call (is it a component, has it that feature), each call of a swimlane
        # (is it a virtual one), "never called" for RaspberryPI's swimlane (which may be virtual),
        # and each deployment entry (is it a component, of its implementation's kind)
        calls = feature_calls.findall(_code(model, *activities))
        lanes = [name for names in VIRTUAL.values() for name in names]
        lane_calls = re.findall(rf"call: (?:{'|'.join(lanes)})\b", _code(model, *activities))
        entries = re.findall(r"^  \w+:", _code(model, "deployment.yaml"), re.MULTILINE)
        return len(calls) + len(lane_calls) + 1 + len(entries)
    # a deployment: each component's implementation (has it one, of its kind, offering its
    # ports' features) and each feature call (offered, in the implementation's range)
    return len(COMPONENTS) + len(feature_calls.findall(_code(model, *activities)))


def _note(count: int) -> str:
    if count == 1:
        return " (1 check that depends on this file was left out until it can be read)"
    return f" ({count} checks that depend on this file were left out until it can be read)"


def _make_unreadable(model: Path, name: str, how: str) -> str:
    """Make `name` unreadable; the start of its one line (`file:line:col: error: problem`)."""
    path = model / name
    data = path.read_bytes()
    if how == "not UTF-8":
        assert data.startswith(b"# ")  # every file of the car begins with a comment
        path.write_bytes(b"# \xff" + data[2:])
        return f"{path}:1:3: error: not UTF-8 text: byte 0xff: invalid start byte"
    assert how == "invalid YAML"
    path.write_bytes(data + b"oops: a: b\n")
    lines = data.count(b"\n") + 1
    return f"{path}:{lines}:8: error: invalid YAML: mapping values are not allowed in this context"


def _in_order(lines: list[str]) -> list[str]:
    """`file:line:col: ...` lines in the order `umlbot check` prints them."""
    return sorted(lines, key=lambda line: (line.split(":")[0], *map(int, line.split(":")[1:3])))


CASES = [(name, how) for name in ("model.yaml", MAIN, MEASURE, MOTION, "deployment.yaml")
         for how in ("not UTF-8", "invalid YAML")] + [("deployment.txt", "not UTF-8")]


@pytest.mark.parametrize("unread, how", CASES)
def test_every_defect_of_the_other_files_is_reported_with_the_unreadable_one(
        tmp_path: Path, unread: str, how: str) -> None:
    model = _car(tmp_path, plain=unread == "deployment.txt")
    count, found = _left_out(model, unread), _expected(model, unread)
    problem = _make_unreadable(model, unread, how)
    result = CliRunner().invoke(cli, ["check", str(model)])
    expected = _in_order([problem + _note(count), *found])
    assert result.stdout.splitlines() == expected
    assert (result.exit_code, result.stderr) == (1, f"{model}: {len(expected)} error(s), 0 warning(s)\n")
    # the studio checks the folder's files from memory: the same problems, the same lines
    shown = [d["text"] for d in Workspace(model).check()["diagnostics"]]
    assert shown == expected


def test_the_installed_command_reports_them_all_in_one_run(tmp_path: Path) -> None:
    model = _car(tmp_path)
    count, found = _left_out(model, MEASURE), _expected(model, MEASURE)
    problem = _make_unreadable(model, MEASURE, "invalid YAML")
    umlbot = Path(sys.executable).parent / "umlbot"
    done = subprocess.run([str(umlbot), "check", str(model)], capture_output=True, text=True,
                          timeout=60, check=False)
    assert done.returncode == 1
    assert done.stdout.splitlines() == _in_order([problem + _note(count), *found])
    assert done.stderr.splitlines()[-1] == f"{model}: {len(found) + 1} error(s), 0 warning(s)"


def test_without_an_unreadable_file_every_planted_defect_is_reported(tmp_path: Path) -> None:
    # the defects the cases above expect are what the car with them reports when all is readable
    model = _car(tmp_path)
    lines = CliRunner().invoke(cli, ["check", str(model)]).stdout.splitlines()
    assert lines == _expected(model, "")


def _check(model: Path) -> list[str]:
    result = CliRunner().invoke(cli, ["check", str(model)])
    assert result.exit_code == 1
    return result.stdout.splitlines()


def _edit(path: Path, old: str, new: str) -> str:
    """Replace `old` in `path` by `new`; `file:line:col` of the replacement."""
    text = path.read_text(encoding="utf-8")
    assert old in text, old
    line, column = position(text, old)
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return f"{path}:{line}:{column}"


def test_the_other_names_of_an_expression_are_still_checked(tmp_path: Path) -> None:
    # an expression is checked past a name that may be in the unreadable file: a misspelt
    # datastore beside `Glance.left`, and the arguments of a feature call of a component that
    # model.yaml may declare
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    main = model / MAIN
    guard = _edit(main, "Glance.left < wall_cm and", "Glance.left < wall_cmm and")
    call = _edit(main, "LeftActuator.dutycycle(speed_percent)", "LeftActuator.dutycycle(speed_percnt)")
    (model / MEASURE).write_bytes(b"lanes: [\n")
    line, column = map(int, guard.split(":")[1:3])
    assert f"{main}:{line}:{column + 14}: error: unknown datastore 'wall_cmm' in swimlane 'RaspberryPI'" \
        in _check(model)
    (model / MEASURE).write_bytes((ROBOT_CAR / MEASURE).read_bytes())
    (model / "model.yaml").write_bytes(b"components: [\n")
    line, column = map(int, call.split(":")[1:3])
    assert f"{main}:{line}:{column + 23}: error: unknown datastore 'speed_percnt' in swimlane " \
        "'RaspberryPI'" in _check(model)


def test_each_unreadable_file_says_what_waits_for_it(tmp_path: Path) -> None:
    # a swimlane main.yaml calls may be in either unreadable file: the check waits for both
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    for name in (MEASURE, MOTION):
        (model / name).write_bytes(b"# \xff\n")
    lanes = [name for names in VIRTUAL.values() for name in names]
    count = len(re.findall(rf"\b(?:{'|'.join(lanes)})\b", _code(model, MAIN)))
    assert _check(model) == [f"{model / name}:1:3: error: not UTF-8 text: byte 0xff: invalid start byte"
                             f"{_note(count)}" for name in (MEASURE, MOTION)]


def test_an_empty_activity_file_beside_an_unreadable_one_is_a_warning(tmp_path: Path) -> None:
    # the swimlanes main.yaml calls in vain may be in the unreadable file: the emptied one is not
    # made the error that names them
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    (model / MOTION).write_bytes(b"")
    (model / MEASURE).write_bytes(b"# \xff\n")
    lines = _check(model)
    assert lines[1:] == [f"{model / MOTION}:1:1: warning: empty activity file"]
    assert lines[0].startswith(f"{model / MEASURE}:1:3: error: not UTF-8 text: byte 0xff")


def test_what_model_yaml_would_say_of_the_deployment_is_left_out(tmp_path: Path) -> None:
    # no "the model has no deployment" (model.yaml may have a `deployment` section), and no
    # robot id error for the folder's name when the deployment has no `robot` (model.yaml may
    # give the model a `name`)
    model = tmp_path / "my car"
    shutil.copytree(ROBOT_CAR, model)
    (model / "model.yaml").write_bytes(b"# \xff\n")
    _edit(model / "deployment.yaml", "robot: car", "")
    shown = f"{model / 'model.yaml'}:1:3: error: not UTF-8 text: byte 0xff: invalid start byte"
    lines = _check(model)
    assert len(lines) == 1 and lines[0].startswith(shown)
    deployment = (model / "deployment.yaml").read_bytes()
    for name in ("deployment.yaml", "deployment.txt"):
        (model / name).unlink()
    lines = _check(model)
    assert len(lines) == 1 and lines[0].startswith(shown)
    # with model.yaml read (and without a name), each is an error
    shutil.copyfile(ROBOT_CAR / "model.yaml", model / "model.yaml")
    _edit(model / "model.yaml", "name: car\n", "")
    assert [line.split(": error: ")[1][:27] for line in _check(model)] == ["the model has no deployment"]
    (model / "deployment.yaml").write_bytes(deployment)
    assert [line.split(": error: ")[1][:25] for line in _check(model)] == ["the model's name 'my car'"]
