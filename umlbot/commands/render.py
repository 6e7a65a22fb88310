"""`umlbot render MODEL`: the component and activity diagrams as Mermaid, PlantUML, DOT and SVG."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from umlbot.commands.checked import checked_model

#: exit status when every other format was written but the SVG could not be drawn (no `dot`).
SVG_NOT_DRAWN = 3


@click.command(name="render")
@click.argument("model", type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder to write the diagrams into. Default: <model name>-diagrams.")
@click.option("--format", "fmt", type=click.Choice(["mermaid", "plantuml", "dot", "svg", "all"]),
              default="all", show_default=True, help="Which notation to write.")
@click.option("--deployment", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Deployment file to use instead of the model's own.")
def command(model: Path, out_dir: Path | None, fmt: str,
            deployment: Path | None) -> None:
    """Draw MODEL's diagrams (SVG needs Graphviz's `dot`: without it the other formats are
    written and the command exits 3)."""
    from umlbot.compiler.render import FORMATS, Format, SvgNotDrawn, render_model

    compiled = checked_model(model, deployment, nothing="nothing drawn")
    formats: tuple[Format, ...] = FORMATS if fmt == "all" else (fmt,)  # type: ignore[assignment]
    target = out_dir or Path(f"{compiled.name}-diagrams")
    try:
        written = render_model(compiled, target, formats)
    except SvgNotDrawn as exc:
        for path in exc.written:
            click.echo(str(path))
        click.echo(f"error: {exc}", err=True)
        sys.exit(SVG_NOT_DRAWN)
    for path in written:
        click.echo(str(path))
