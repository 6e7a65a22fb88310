"""`umlbot compile MODEL -o FILE`: check a model and write its compiled model file."""

from __future__ import annotations

import errno
import os
import sys
import tempfile
from pathlib import Path

import click

from umlbot.errors import ConfigError


@click.command(name="compile")
@click.argument("model", type=click.Path(exists=True, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Compiled file to write ('-' for stdout). Default: <model name>.compiled.json.")
@click.option("--deployment", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Deployment file to use instead of the model's own.")
def command(model: Path, output: Path | None, deployment: Path | None) -> None:
    """Compile MODEL (a model folder or file) into a compiled model file for `umlbot run`."""
    from compiler.api import check_model
    from compiler.compiled import dump_compiled

    result = check_model(model, deployment)
    for diagnostic in result.diagnostics:
        click.echo(str(diagnostic), err=True)
    if result.model is None:
        click.echo(f"{model}: {len(result.errors)} error(s); nothing written", err=True)
        sys.exit(1)
    data = dump_compiled(result.model)
    if output is not None and str(output) == "-":
        click.echo(data.decode("utf-8"), nl=False)
        return
    target = output or Path(f"{result.model.name}.compiled.json")
    try:
        _write_atomically(target, data)
    except OSError as exc:
        raise ConfigError(f"cannot write {target}: {exc.strerror or exc}") from exc
    click.echo(f"wrote {target} ({result.model.source_hash})", err=True)


def _write_atomically(path: Path, data: bytes) -> None:
    """Write through a temporary file and rename, so a reader never sees half a file."""
    for folder in (path.parent, *path.parent.parents):
        if folder.exists() and not folder.is_dir():
            raise NotADirectoryError(errno.ENOTDIR, f"{folder} is not a folder")
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.fchmod(fd, 0o666 & ~umask)  # mkstemp makes 0600; a compiled model is an ordinary file
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
