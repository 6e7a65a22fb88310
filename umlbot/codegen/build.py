"""Building a generated project: what the toolchain needs, and one CMake + Ninja build."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
from pathlib import Path

from umlbot.base.errors import UmlbotError
from umlbot.compiler.compiled import CompiledModel

#: (Debian package, what it provides that the build looks for)
TOOLCHAIN: tuple[tuple[str, str], ...] = (
    ("g++", "program g++"),
    ("cmake", "program cmake"),
    ("ninja-build", "program ninja"),
    ("libmosquitto-dev", "/usr/include/mosquitto.h"),
    ("nlohmann-json3-dev", "/usr/include/nlohmann/json.hpp"),
)

APT_LINE = "sudo apt-get install -y " + " ".join(package for package, _ in TOOLCHAIN)


class BuildError(UmlbotError):
    """The generated project did not build (the compiler's last lines say why)."""


def missing_toolchain() -> list[str]:
    """The Debian packages of the toolchain that are not installed (by what each provides)."""
    missing = []
    for package, provides in TOOLCHAIN:
        if provides.startswith("program "):
            found = shutil.which(provides.removeprefix("program ")) is not None
        else:
            found = Path(provides).exists()
        if not found:
            missing.append(package)
    return missing


def build_cpp(project: str | Path, build_dir: str | Path | None = None, jobs: int | None = None,
              build_type: str = "Release", timeout_s: float = 900.0) -> Path:
    """Configure and build `project` with CMake and Ninja; returns the built program's path.

    Raises `BuildError` with the tail of the compiler's output when a step fails, and when the
    toolchain is missing (naming the packages)."""
    missing = missing_toolchain()
    if missing:
        raise BuildError(f"cannot build: missing {', '.join(missing)} (install with: {APT_LINE})")
    source = Path(project)
    out = Path(build_dir) if build_dir is not None else source / "out"
    steps = [
        ["cmake", "-S", str(source), "-B", str(out), "-G", "Ninja", f"-DCMAKE_BUILD_TYPE={build_type}"],
        ["cmake", "--build", str(out)] + (["-j", str(jobs)] if jobs else []),
    ]
    for step in steps:
        done = subprocess.run(step, capture_output=True, text=True, timeout=timeout_s,
                              env={**os.environ, "LC_ALL": "C"}, check=False)
        if done.returncode != 0:
            tail = "\n".join((done.stdout + done.stderr).strip().splitlines()[-30:])
            raise BuildError(f"{' '.join(step[:2])} failed in {source}:\n{tail}")
    programs = sorted(path for path in out.glob("*-orchestrator") if path.is_file())
    if not programs:
        raise BuildError(f"the build of {source} made no *-orchestrator program in {out}")
    return programs[0]


def cached_program(model: CompiledModel, cache_dir: str | Path | None = None,
                   jobs: int | None = None) -> Path:
    """The model's generated program, built once per set of sources in `cache_dir` (default
    `$XDG_CACHE_HOME/umlbot/codegen`, else `~/.cache/umlbot/codegen`); `umlbot sim --engine cpp`
    uses it. Raises `BuildError` when the toolchain is missing or the build fails."""
    from umlbot.codegen.cpp import generate_cpp, program_name, project_files

    files = project_files(model)
    digest = hashlib.sha256()
    for relative, data in files.items():
        digest.update(relative.encode("utf-8") + b"\0" + hashlib.sha256(data).digest())
    base = Path(cache_dir) if cache_dir is not None else (
        Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "umlbot" / "codegen")
    root = base / f"{program_name(model)}-{digest.hexdigest()[:16]}"
    program = root / "out" / program_name(model)
    if (root / "built").exists() and program.exists():
        return program
    generate_cpp(model, root)
    built = build_cpp(root, jobs=jobs)
    (root / "built").write_text("ok\n", encoding="utf-8")
    return built
