"""`umlbot check` and `umlbot compile` from the command line: output, exit codes, files."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from click.testing import CliRunner
from compiler_support import HEADER, MAIN

from umlbot.cli import cli
from umlbot.compiler.compiled import load_compiled

ROBOT_CAR = Path(__file__).resolve().parent.parent / "models" / "robot_car"
BROKEN = HEADER.replace("Motor: {impl: l298n}", "Motor: {impl: l293d}") + MAIN.replace(
    "Motor.enabled(true)", "Motor.angle(90)")


def test_check_ok() -> None:
    result = CliRunner().invoke(cli, ["check", str(ROBOT_CAR)])
    assert result.exit_code == 0, result.output
    assert result.stdout == ""
    assert result.stderr == f"{ROBOT_CAR}: ok: 5 components, 8 swimlanes, 152 nodes, 0 warning(s)\n"


def test_check_prints_every_problem_and_fails(tmp_path: Path) -> None:
    model = tmp_path / "broken.yaml"
    model.write_text(BROKEN, encoding="utf-8")
    result = CliRunner().invoke(cli, ["check", str(model)])
    assert result.exit_code == 1
    assert result.stdout.splitlines() == [
        f"{model}:13:19: error: unknown implementation id 'l293d' for component 'Motor'"]
    assert result.stderr == f"{model}: 1 error(s), 0 warning(s)\n"


def test_an_undeployable_component_is_still_checked_by_its_kind(tmp_path: Path) -> None:
    model = tmp_path / "m.yaml"
    model.write_text(BROKEN.replace("Motor.angle(90)", "Motor.angle(400)"), encoding="utf-8")
    lines = CliRunner().invoke(cli, ["check", str(model)]).stdout.splitlines()
    assert lines == [
        f"{model}:13:19: error: unknown implementation id 'l293d' for component 'Motor'",
        f"{model}:20:50: error: argument 1 (degrees) of Motor.angle must be 0..360, got 400"]


def test_warnings_as_errors(tmp_path: Path) -> None:
    model = tmp_path / "m.yaml"
    model.write_text(HEADER + MAIN.replace(
        "      - {id: end, kind: end}\n",
        "      - {id: d, kind: decision, branches: [{if: Application.exit, then: end}]}\n"
        "      - {id: end, kind: end}\n"), encoding="utf-8")
    relaxed = CliRunner().invoke(cli, ["check", str(model)])
    strict = CliRunner().invoke(cli, ["check", "-W", str(model)])
    assert relaxed.exit_code == 0 and strict.exit_code == 1
    assert "warning: decision 'd' has no else output" in relaxed.stdout


def test_compile_writes_a_loadable_file(tmp_path: Path) -> None:
    out = tmp_path / "sub" / "car.json"
    result = CliRunner().invoke(cli, ["compile", str(ROBOT_CAR), "-o", str(out)])
    assert result.exit_code == 0, result.output
    model = load_compiled(out)
    assert model.name == "car" and "RaspberryPI" in model.lanes
    assert result.stderr.startswith(f"wrote {out} (sha256:")
    assert [p.name for p in out.parent.iterdir()] == ["car.json"]  # no temporary file left


def test_compile_to_stdout_and_with_the_plain_deployment() -> None:
    result = CliRunner().invoke(cli, ["compile", str(ROBOT_CAR), "-o", "-", "--deployment",
                                      str(ROBOT_CAR / "deployment.txt")])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["components"]["Sensor"]["impl"] == "servo"
    assert data["components"]["Sensor"]["settings"] == {}


def test_compile_refuses_a_broken_model(tmp_path: Path) -> None:
    model = tmp_path / "broken.yaml"
    model.write_text(BROKEN, encoding="utf-8")
    out = tmp_path / "out.json"
    result = CliRunner().invoke(cli, ["compile", str(model), "-o", str(out)])
    assert result.exit_code == 1
    assert "error: unknown implementation id 'l293d'" in result.stderr
    assert result.stderr.strip().endswith("nothing written")
    assert not out.exists()


def test_the_installed_command_exits_1_on_errors(tmp_path: Path) -> None:
    model = tmp_path / "broken.yaml"
    model.write_text(BROKEN, encoding="utf-8")
    umlbot = Path(sys.executable).parent / "umlbot"
    done = subprocess.run([str(umlbot), "check", str(model)], capture_output=True, text=True,
                          timeout=60, check=False)
    assert done.returncode == 1
    assert done.stdout.startswith(f"{model}:13:19: error: unknown implementation id 'l293d'")
