"""Reading a recorded trace (`umlbot run --trace FILE`: JSON lines of `TraceEvent`) for replay."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from pydantic import ValidationError

from services.bus.envelopes import TraceEvent
from services.monitor.state import MonitorEvent, MonitorState
from umlbot.errors import ConfigError


def read_trace(path: str | Path) -> Iterator[TraceEvent]:
    """The events of a trace file in order; a bad line raises ConfigError naming file and line."""
    file = Path(path)
    try:
        handle = file.open("rb")  # bytes: a line that is not UTF-8 fails in json.loads, named
    except OSError as exc:
        raise ConfigError(f"cannot read trace file {file}: {exc.strerror or exc}") from exc
    with handle:
        for lineno, line in enumerate(handle, start=1):
            if not line.strip():
                continue
            try:
                yield TraceEvent.model_validate(json.loads(line))
            except (ValueError, ValidationError) as exc:
                raise ConfigError(f"{file}:{lineno}: not a trace event: {_first_problem(exc)}") from exc


def _first_problem(exc: ValueError | ValidationError) -> str:
    if not isinstance(exc, ValidationError):
        return str(exc)
    first = exc.errors()[0]
    where = ".".join(str(p) for p in first["loc"])
    return f"{where}: {first['msg']}" if where else str(first["msg"])


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
        if speed > 0 and previous_end is not None and trace.end > previous_end:
            sleep((trace.end - previous_end) / speed)
        previous_end = trace.end if previous_end is None else max(previous_end, trace.end)
        emit(state.observe_trace(trace, robot))
        played += 1
    return played
