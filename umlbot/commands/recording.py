"""What `umlbot sim`, `umlbot run` and `umlbot record` share about recordings (docs/recording.md)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click


def sim_recording(model: Path, record_file: Path | None, foxglove: bool, foxglove_port: int,
                  announce: Callable[[str], None]) -> Any:
    """The `SimRecording` of `umlbot sim --record/--foxglove` (an error naming the extra when the
    record extra is not installed, before the run starts)."""
    from umlbot.base import rosmsg
    from umlbot.record import SimRecording

    # MissingExtra now, not once the robot runs
    rosmsg.require("rosbags.typesys", "record", "Recordings (--record, --foxglove)")
    rosmsg.typestore("record")
    if record_file is not None:
        from umlbot.record import check_writable

        check_writable(record_file)
    extra_sinks = None
    if foxglove:
        from umlbot.record import check_port, live_sinks

        check_port(foxglove_port)
        extra_sinks = live_sinks(foxglove_port, announce)
    return SimRecording(record_file, model=model.name, extra_sinks=extra_sinks)


def report(path: Path | None, stats: Any, as_json: bool) -> None:
    """Say on stderr when a recording did not get everything (disk full, writer behind)."""
    if stats is None:
        return
    if stats.failed:
        click.echo(f"warning: the recording stopped early: {stats.failed}; {path} holds the run up to "
                   "then", err=True)
    if stats.dropped:
        click.echo(f"warning: the recording dropped {stats.dropped} items (its writer fell behind)", err=True)
