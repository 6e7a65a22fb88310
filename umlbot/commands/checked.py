"""The model a command works on, checked: its diagnostics on stderr, exit 1 when it has errors.

Shared by the commands that turn a model into something (`compile`, `generate`, `render`); `check`
prints its own summary instead.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

if TYPE_CHECKING:
    from umlbot.compiler.compiled import CompiledModel


def checked_model(model: Path, deployment: Path | None, nothing: str = "nothing written") -> CompiledModel:
    """Check MODEL (a folder or file) and print every diagnostic; exit 1 with `nothing` said when it
    has errors."""
    from umlbot.compiler.api import check_model  # the compiler only when a command runs

    result = check_model(model, deployment)
    for diagnostic in result.diagnostics:
        click.echo(str(diagnostic), err=True)
    if result.model is None:
        click.echo(f"{model}: {len(result.errors)} error(s); {nothing}", err=True)
        sys.exit(1)
    return result.model
