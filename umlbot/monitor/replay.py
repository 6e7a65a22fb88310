"""Reading a recorded trace for replay: JSON lines, each one `TraceEvent` object (what
`umlbot run --trace FILE` writes) or a JSON array of them (a copy of the trace topic's messages),
or an MCAP recording (`--record FILE.mcap`, told by its first bytes: `umlbot.monitor.mcap_trace`)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from pydantic import ValidationError
from pydantic_core import from_json

from umlbot.base.errors import ConfigError, ModelError
from umlbot.base.files import decode_utf8
from umlbot.base.logs import get_logger
from umlbot.monitor.mcap_trace import is_mcap, read_mcap_trace
from umlbot.monitor.state import MonitorEvent, MonitorState, first_problem, trace_items
from umlbot.services.bus import TraceEvent

log = get_logger(__name__)


def read_trace(path: str | Path, notes: list[str] | None = None) -> Iterator[TraceEvent]:
    """The events of a trace file (JSON lines or MCAP) in order; a bad line raises ConfigError naming
    file and line (an MCAP file: the byte where it breaks).

    A last line after the first that is cut off (no newline at its end and not a whole event: the
    run was killed, or it is still writing) ends the trace instead: the events before it are read, and a note
    saying so is appended to `notes` (logged as a warning when `notes` is None).
    """
    file = Path(path)
    if is_mcap(file):
        yield from read_mcap_trace(file)
        return
    try:
        handle = file.open("rb")  # bytes: a line that is not UTF-8 is named with its bad byte
    except OSError as exc:
        raise ConfigError(f"cannot read trace file {file}: {exc.strerror or exc}") from exc
    with handle:
        for lineno, line in enumerate(handle, start=1):
            if not line.strip():
                continue
            # only a file's last line can lack its newline; a file that is one such line (a binary
            # file, say) is no trace cut off but no trace: its own error
            cut = not line.endswith(b"\n") and lineno > 1
            try:
                text = decode_utf8(line, str(file))
            except ModelError as exc:  # its line and column in the file, not in the line
                if cut:
                    _cut_off(file, lineno, notes)
                    return
                raise ConfigError(f"{file}:{lineno}:{exc.column}: cannot read trace file: "
                                  f"{exc.message}") from None
            try:
                events = [TraceEvent.model_validate(item) for item in trace_items(from_json(text))]
            except (ValueError, ValidationError) as exc:
                if cut:
                    _cut_off(file, lineno, notes)
                    return
                raise ConfigError(f"{file}:{lineno}: not a trace event: {first_problem(exc)}") from exc
            yield from events


def _cut_off(file: Path, lineno: int, notes: list[str] | None) -> None:
    note = (f"{file.name}:{lineno}: the last line is cut off (the run was killed or is still "
            f"writing the trace): replayed the lines before it")
    if notes is None:
        log.warning("trace file ends in a partial line", file=str(file), line=lineno)
    else:
        notes.append(note)


def replay(
    path: str | Path,
    state: MonitorState,
    robot: str,
    emit: Callable[[MonitorEvent], None],
    speed: float = 1.0,
    sleep: Callable[[float], None] = time.sleep,
) -> int:
    """Feed a trace file into `state`, calling `emit` per event; returns how many were played.

    `speed` 1.0 keeps the recorded pace (gaps between node ends), 2.0 twice as fast, 0 no waiting.
    """
    played = 0
    previous_end: float | None = None
    for trace in read_trace(path):
        if not math.isfinite(trace.end):  # nothing to pace by
            pass
        elif previous_end is None:
            previous_end = trace.end
        elif trace.end > previous_end:
            if speed > 0:
                sleep((trace.end - previous_end) / speed)
            previous_end = trace.end
        emit(state.observe_trace(trace, robot))
        played += 1
    return played
