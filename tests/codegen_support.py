"""Helpers for the code generation tests: build generated programs once, run them like `umlbot run`.

`build_programs(models)` generates each model (`umlbot.codegen.generate_cpp`) into a cache folder
named by the hash of every generated file, and builds them all in ONE CMake project (the runtime
compiled once as a static library with a precompiled header, one executable per model: the same
sources the generated projects hold). A later session with the same sources finds the programs
built. `CppRun` runs one program as a child process against a `Rig`'s broker and mock services.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from umlbot.codegen import build_cpp, generate_cpp, project_files
from umlbot.codegen.cpp import program_name
from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import CompiledModel

CACHE = Path(tempfile.gettempdir()) / "umlbot-codegen-tests"
MODELS = Path(__file__).parent / "models"

#: every model a codegen test runs as a generated program (built together, once)
TEST_MODELS: dict[str, Path] = {
    "fork": MODELS / "fork.yaml",
    "sensor_decision": MODELS / "sensor_decision.yaml",
    "reentrant": MODELS / "reentrant.yaml",
    "no_match": MODELS / "no_match.yaml",
    "values": MODELS / "codegen_values.yaml",
    "signals": MODELS / "signals.yaml",
    "held_signals": MODELS / "held_signals.yaml",
    "exit_loop": MODELS / "exit_loop.yaml",
    "drive_and_read": MODELS / "drive_and_read.yaml",
    "fault_loop": MODELS / "fault_loop.yaml",
    "stubborn": MODELS / "stubborn.yaml",
    "robot_car": Path(__file__).parent.parent / "models" / "robot_car",
}

_HARNESS = """cmake_minimum_required(VERSION 3.16)
project(umlbot_codegen_tests LANGUAGES CXX)
set(CMAKE_CXX_STANDARD 17)
set(CMAKE_CXX_STANDARD_REQUIRED ON)
find_package(Threads REQUIRED)
find_package(nlohmann_json 3.2 REQUIRED)
find_path(MOSQUITTO_INCLUDE_DIR mosquitto.h REQUIRED)
find_library(MOSQUITTO_LIBRARY mosquitto REQUIRED)
add_library(umlbot_runtime STATIC runtime/umlbot_runtime.cpp)
target_include_directories(umlbot_runtime PUBLIC runtime ${MOSQUITTO_INCLUDE_DIR})
target_link_libraries(umlbot_runtime PUBLIC nlohmann_json::nlohmann_json ${MOSQUITTO_LIBRARY}
                      Threads::Threads)
target_precompile_headers(umlbot_runtime PRIVATE runtime/umlbot_runtime.hpp)
"""


def compiled(model: str | Path) -> CompiledModel:
    return compile_model(Path(model))


def build_programs(models: dict[str, CompiledModel], jobs: int = 2) -> dict[str, Path]:
    """Name → built program for every model, built once per set of sources (cached)."""
    digest = hashlib.sha256(_HARNESS.encode("utf-8") + b"-O0")  # how they are built counts too
    projects = {name: project_files(model) for name, model in sorted(models.items())}
    for name, files in projects.items():
        digest.update(name.encode())
        for relative, data in files.items():
            digest.update(relative.encode() + b"\0" + hashlib.sha256(data).digest())
    root = CACHE / digest.hexdigest()[:20]
    programs = {name: root / "out" / f"{name}-orchestrator" for name in projects}
    if (root / "built").exists() and all(p.exists() for p in programs.values()):
        return programs
    if root.exists():
        shutil.rmtree(root)
    lines = [_HARNESS]
    for name, model in sorted(models.items()):
        generate_cpp(model, root / name)
        lines.append(f"add_executable({name}-orchestrator {name}/src/model.cpp)\n"
                     f"target_link_libraries({name}-orchestrator PRIVATE umlbot_runtime)\n"
                     f"target_precompile_headers({name}-orchestrator REUSE_FROM umlbot_runtime)\n")
    first = next(iter(sorted(models)))
    shutil.copytree(root / first / "runtime", root / "runtime")
    (root / "CMakeLists.txt").write_text("".join(lines), encoding="utf-8")
    # -O0: these programs test semantics, not speed, and build in half the time
    configure = ["cmake", "-S", str(root), "-B", str(root / "out"), "-G", "Ninja", "-DCMAKE_BUILD_TYPE=",
                 "-DCMAKE_CXX_FLAGS=-O0"]
    for step in (configure, ["cmake", "--build", str(root / "out"), "-j", str(jobs)]):
        done = subprocess.run(step, capture_output=True, text=True, timeout=900, check=False)
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(step)} failed:\n{(done.stdout + done.stderr)[-4000:]}")
    (root / "built").write_text("ok\n", encoding="utf-8")
    return programs


@functools.cache
def built_programs() -> dict[str, Path]:
    """Every `TEST_MODELS` program, built once per session (and cached between sessions)."""
    return build_programs({name: compile_model(path) for name, path in TEST_MODELS.items()})


def build_project(model: CompiledModel) -> Path:
    """The model's own generated project, built as a user builds it (cached by its sources)."""
    digest = hashlib.sha256()
    for relative, data in project_files(model).items():
        digest.update(relative.encode() + b"\0" + data)
    root = CACHE / f"project-{digest.hexdigest()[:20]}"
    program = root / "out" / program_name(model)
    if (root / "built").exists() and program.exists():
        return program
    generate_cpp(model, root)
    built = build_cpp(root, jobs=2)
    (root / "built").write_text("ok\n", encoding="utf-8")
    return built


@dataclass
class CppRun:
    """A generated program running as a child process (the `umlbot run` options)."""

    program: Path
    broker_url: str
    workdir: Path
    robot: str = "test"
    options: list[str] = field(default_factory=list)
    proc: subprocess.Popen[str] | None = None

    @property
    def trace_file(self) -> Path:
        return self.workdir / "cpp-trace.jsonl"

    def start(self) -> CppRun:
        argv = [str(self.program), "--broker", self.broker_url, "--robot", self.robot, "--trace",
                str(self.trace_file), "--startup-timeout", "5", *self.options]
        self.proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     env={**os.environ, "UMLBOT_BROKER": ""})
        return self

    def wait(self, timeout: float = 15.0) -> tuple[int, str]:
        """(exit code, stderr); kills it and raises AssertionError after `timeout`."""
        assert self.proc is not None
        try:
            _, err = self.proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            _, err = self.proc.communicate()
            raise AssertionError(
                f"{self.program.name} did not finish within {timeout} s:\n{err[-3000:]}") from None
        return self.proc.returncode, err

    def terminate(self) -> None:
        assert self.proc is not None
        self.proc.send_signal(signal.SIGTERM)

    def events(self) -> list[dict[str, Any]]:
        if not self.trace_file.exists():
            return []
        return [json.loads(line) for line in self.trace_file.read_text(encoding="utf-8").splitlines() if line]

    def nodes(self) -> list[str]:
        return [e["node"] for e in self.events()]


def wait_for(predicate: Any, timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


def outcomes(events: Iterable[dict[str, Any]]) -> dict[tuple[str, str], list[tuple[Any, ...]]]:
    """(lane, node) → what each execution of it gave, in order: (kind, value, error, level)."""
    found: dict[tuple[str, str], list[tuple[Any, ...]]] = {}
    for e in events:
        found.setdefault((e["lane"], e["node"]), []).append(
            (e["kind"], e.get("value"), e.get("error"), e["level"]))
    return found


def lane_sequences(events: Iterable[dict[str, Any]]) -> dict[str, list[tuple[Any, ...]]]:
    """lane → its events in order: (node, kind, value, error, level)."""
    found: dict[str, list[tuple[Any, ...]]] = {}
    for e in events:
        found.setdefault(e["lane"], []).append(
            (e["node"], e["kind"], e.get("value"), e.get("error"), e["level"]))
    return found
