"""`umlbot generate cpp MODEL -o DIR`: the model's swimlanes as a C++17 CMake project.

The built program is a drop-in for `umlbot run COMPILED` (same options, topics, trace, status and
exit codes). Without the toolchain the sources are still written, and the command says what the
build needs (docs/codegen.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import click

from umlbot.commands.checked import checked_model


@click.command(name="generate")
@click.argument("language", type=click.Choice(["cpp"]))
@click.argument("model", type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", type=click.Path(file_okay=False, path_type=Path), required=True,
              help="Folder of the generated project (made as needed).")
@click.option("--deployment", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Deployment file to use instead of the model's own.")
@click.option("--build", is_flag=True, help="Also build it (CMake + Ninja) into DIR/out.")
@click.option("--jobs", "-j", type=click.IntRange(min=1), default=None, help="Parallel build jobs.")
def command(language: str, model: Path, output: Path, deployment: Path | None, build: bool,
            jobs: int | None) -> None:
    """Generate MODEL (a model folder or file, or a compiled model file) as a C++ project in DIR."""
    from umlbot.codegen import APT_LINE, build_cpp, generate_cpp, missing_toolchain, program_name
    from umlbot.compiler.compiled import CompiledModel, load_compiled

    compiled: CompiledModel
    if model.is_file() and model.suffix == ".json":
        compiled = load_compiled(model)
    else:
        compiled = checked_model(model, deployment)
    written = generate_cpp(compiled, output, source=model.name)
    click.echo(f"wrote {output} ({len(written)} file(s) changed; program {program_name(compiled)})", err=True)
    missing = missing_toolchain()
    if missing:
        click.echo(f"to build it, install {', '.join(missing)}: {APT_LINE}", err=True)
        if build:
            sys.exit(1)
        return
    if not build:
        click.echo(f"build: cmake -S {output} -B {output}/out -G Ninja && cmake --build {output}/out",
                   err=True)
        return
    program = build_cpp(output, jobs=jobs)
    click.echo(f"built {program}", err=True)
