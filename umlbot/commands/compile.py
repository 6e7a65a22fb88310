"""`umlbot compile MODEL -o FILE`: check a model and write its compiled model file."""

from __future__ import annotations

from pathlib import Path

import click

from umlbot.commands.checked import checked_model


@click.command(name="compile")
@click.argument("model", type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Compiled file to write ('-' for stdout). Default: <model name>.compiled.json.")
@click.option("--deployment", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Deployment file to use instead of the model's own.")
def command(model: Path, output: Path | None, deployment: Path | None) -> None:
    """Compile MODEL (a model folder or file) into a compiled model file for `umlbot run`."""
    from umlbot.compiler.compiled import dump_compiled, write_compiled

    compiled = checked_model(model, deployment)
    if output is not None and str(output) == "-":
        click.echo(dump_compiled(compiled).decode("utf-8"), nl=False)
        return
    target = output or Path(f"{compiled.name}.compiled.json")
    write_compiled(compiled, target)
    click.echo(f"wrote {target} ({compiled.source_hash})", err=True)

