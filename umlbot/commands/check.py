"""`umlbot check MODEL`: validate a model and print every problem as `file:line:col: message`."""

from __future__ import annotations

import sys
from pathlib import Path

import click


@click.command(name="check")
@click.argument("model", type=click.Path(exists=True, path_type=Path))
@click.option("--deployment", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Deployment file to use instead of the model's own.")
@click.option("--warnings-as-errors", "-W", is_flag=True, help="Fail on warnings too.")
def command(model: Path, deployment: Path | None, warnings_as_errors: bool) -> None:
    """Validate MODEL (a model folder or file): print every problem, exit 1 on any error."""
    from umlbot.compiler.api import check_model

    result = check_model(model, deployment)
    for diagnostic in result.diagnostics:
        click.echo(str(diagnostic))
    errors, warnings = len(result.errors), len(result.warnings)
    if result.ok and result.model is not None:
        nodes = sum(len(lane.nodes) for lane in result.model.lanes.values())
        summary = (f"{model}: ok: {len(result.model.components)} components, "
                   f"{len(result.model.lanes)} swimlanes, {nodes} nodes, {warnings} warning(s)")
    else:
        summary = f"{model}: {errors} error(s), {warnings} warning(s)"
    click.echo(summary, err=True)
    if errors or (warnings_as_errors and warnings):
        sys.exit(1)
