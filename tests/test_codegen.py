"""`umlbot generate cpp`: deterministic, readable sources; clear errors; the project builds as a
user builds it; without the toolchain the sources are still written and the command says why."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest
from click.testing import CliRunner
from codegen_support import build_project
from orchestrator_support import ROBOT_CAR

from umlbot.cli import cli
from umlbot.codegen import GenerateError, generate_cpp, project_files, render_cpp
from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import write_compiled


def _tree(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_the_same_model_gives_byte_identical_projects(tmp_path: Path) -> None:
    runner = CliRunner()
    for name in ("one", "two"):
        result = runner.invoke(cli, ["generate", "cpp", str(ROBOT_CAR), "-o", str(tmp_path / name)])
        assert result.exit_code == 0, result.output
    one, two = _tree(tmp_path / "one"), _tree(tmp_path / "two")
    assert sorted(one) == ["CMakeLists.txt", "runtime/umlbot_runtime.cpp", "runtime/umlbot_runtime.hpp",
                           "src/model.cpp"]
    assert one == two
    # from the compiled file: the same sources
    compiled = tmp_path / "car.json"
    write_compiled(compile_model(ROBOT_CAR), compiled)
    result = runner.invoke(cli, ["generate", "cpp", str(compiled), "-o", str(tmp_path / "three")])
    assert result.exit_code == 0, result.output
    three = _tree(tmp_path / "three")
    assert three["CMakeLists.txt"] == one["CMakeLists.txt"]
    assert three["src/model.cpp"].split(b"\n", 1)[1] == one["src/model.cpp"].split(b"\n", 1)[1]


def test_generating_again_rewrites_nothing_that_is_unchanged(tmp_path: Path) -> None:
    model = compile_model(ROBOT_CAR)
    assert len(generate_cpp(model, tmp_path)) == 4
    assert generate_cpp(model, tmp_path) == []


def test_lanes_read_like_the_model_with_node_ids_and_file_lines() -> None:
    text = render_cpp(compile_model(ROBOT_CAR))
    assert "namespace lane_RaspberryPI {" in text and "namespace lane_Measure {" in text
    assert "Datastore speed_percent{\"speed_percent\"};" in text
    # a case per node, commented with its id, label and file:line
    assert "case N_set_speed:  // datastore set_speed: speed_percent = 70 (activities/main.yaml:" in text
    call = 'rt.call(act, "LeftActuator", "dutycycle", Value::array({lane_RaspberryPI::speed_percent.get()}))'
    assert call in text
    assert "act.fork(" in text and "act.arrive(" in text and "act.decide(" in text
    assert "eval" not in text.replace("evaluated", "")


def test_a_model_the_generator_cannot_express_is_an_error_at_its_line(tmp_path: Path) -> None:
    model = tmp_path / "big.yaml"
    model.write_text(
        "name: big\ncomponents:\n  RaspberryPI: {kind: system}\nlanes:\n  - lane: RaspberryPI\n    nodes:\n"
        "      - {id: start, kind: start}\n"
        "      - {id: huge, kind: datastore, name: huge, value: 100000000000000000000000}\n"
        "      - {id: end, kind: end}\n"
        "deployment:\n  driver: mock\n  components:\n    RaspberryPI: {impl: raspberrypi}\n",
        encoding="utf-8")
    with pytest.raises(GenerateError) as caught:
        project_files(compile_model(model))
    assert (caught.value.file, caught.value.line) == ("big.yaml", 8)
    result = CliRunner().invoke(cli, ["generate", "cpp", str(model), "-o", str(tmp_path / "out")])
    assert isinstance(result.exception, GenerateError)  # `umlbot` prints it as one `error:` line, exit 1
    assert "big.yaml:8:1: the integer 100000000000000000000000 does not fit" in str(result.exception)
    assert not (tmp_path / "out").exists()


def test_without_the_toolchain_the_sources_are_written_and_the_needs_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "nothing"))  # no g++, cmake or ninja on it
    argv = ["generate", "cpp", str(ROBOT_CAR), "-o", str(tmp_path / "car"), "--build"]
    result = CliRunner().invoke(cli, argv)
    assert result.exit_code == 1
    assert "to build it, install g++, cmake, ninja-build" in result.output
    assert "apt-get install -y g++ cmake ninja-build libmosquitto-dev nlohmann-json3-dev" in result.output
    assert (tmp_path / "car" / "src" / "model.cpp").exists()


@pytest.mark.timeout(600)
def test_the_generated_project_builds_with_cmake_and_its_program_answers_help() -> None:
    program = build_project(compile_model(ROBOT_CAR))
    assert program.name == "car-orchestrator"
    done = subprocess.run([str(program), "--help"], capture_output=True, text=True, timeout=10, check=False)
    assert done.returncode == 0
    for option in ("--broker", "--robot", "--trace", "--no-trace", "--log-level", "--call-timeout"):
        assert option in done.stdout
    done = subprocess.run([str(program), "--frobnicate"], capture_output=True, text=True, timeout=10,
                          check=False, env={**os.environ, "UMLBOT_BROKER": ""})
    assert done.returncode == 2 and "No such option: --frobnicate" in done.stderr


@pytest.mark.timeout(600)
def test_the_program_needs_only_libmosquitto_and_the_c_library_at_run_time() -> None:
    """libstdc++ and libgcc are linked in (resident memory: docs/codegen.md)."""
    program = build_project(compile_model(ROBOT_CAR))
    done = subprocess.run(["readelf", "-d", str(program)], capture_output=True, text=True, timeout=30,
                          check=True)
    needed = sorted(line.split("[", 1)[1].rstrip("]")
                    for line in done.stdout.splitlines() if "(NEEDED)" in line)
    assert any(name.startswith("libmosquitto.so") for name in needed), needed
    assert not [name for name in needed if name.startswith(("libstdc++", "libgcc_s"))], needed
