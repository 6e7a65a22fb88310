"""`umlbot compile MODEL -o FILE`: check a model and write its compiled model file."""

from __future__ import annotations

import sys
from pathlib import Path

import click


@click.command(name="compile")
@click.argument("model", type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Compiled file to write ('-' for stdout). Default: <model name>.compiled.json.")
@click.option("--deployment", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Deployment file to use instead of the model's own.")
def command(model: Path, output: Path | None, deployment: Path | None) -> None:
    """Compile MODEL (a model folder or file) into a compiled model file for `umlbot run`."""
    from umlbot.compiler.api import check_model
    from umlbot.compiler.compiled import dump_compiled, write_compiled

    result = check_model(model, deployment)
    for diagnostic in result.diagnostics:
        click.echo(str(diagnostic), err=True)
    if result.model is None:
        click.echo(f"{model}: {len(result.errors)} error(s); nothing written", err=True)
        sys.exit(1)
    if output is not None and str(output) == "-":
        click.echo(dump_compiled(result.model).decode("utf-8"), nl=False)
        return
    target = output or Path(f"{result.model.name}.compiled.json")
    write_compiled(result.model, target)
    click.echo(f"wrote {target} ({result.model.source_hash})", err=True)

