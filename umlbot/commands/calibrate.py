"""`umlbot calibrate stereo FOLDER -o FILE`: a stereo calibration from chessboard image pairs."""

from __future__ import annotations

from pathlib import Path

import click


@click.group(name="calibrate")
def command() -> None:
    """Calibrate a sensor (stereo: a camera pair, from chessboard images)."""


@command.command(name="stereo")
@click.argument("folder", type=click.Path(path_type=Path))
@click.option("-o", "--output", type=click.Path(path_type=Path), required=True,
              help="the calibration file to write (JSON)")
@click.option("--inner", default="9x6", show_default=True,
              help="inner corners of the chessboard, columns x rows")
@click.option("--square-mm", type=float, default=25.0, show_default=True,
              help="the side of one printed square, millimetres")
def stereo(folder: Path, output: Path, inner: str, square_mm: float) -> None:
    """Calibrate a stereo camera from FOLDER's left*.png / right*.png chessboard pairs."""
    from umlbot.services.stereo import calibrate_pairs, read_pairs, save_calibration

    try:
        columns, rows = (int(n) for n in inner.lower().split("x"))
    except ValueError:
        raise click.BadParameter(f"must be COLUMNSxROWS such as 9x6, got {inner!r}",
                                 param_hint="--inner") from None
    if not square_mm > 0:
        raise click.BadParameter("must be > 0", param_hint="--square-mm")
    result = calibrate_pairs(read_pairs(folder), (columns, rows), square_mm / 1000.0)
    for reason in result.skipped:
        click.echo(f"skipped {reason}", err=True)
    save_calibration(result.calibration, output)
    cal = result.calibration
    click.echo(f"{output}: {len(result.used)} pairs, reprojection error {cal.rms_px} px, "
               f"focal length {cal.focal_px:.1f} px, baseline {cal.baseline_m * 1000:.1f} mm")
