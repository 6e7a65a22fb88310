"""The execution trace: one `TraceEvent` per executed node, published off the lanes' hot path.

The engine hands each executed node to `TraceRecorder.record` as a plain tuple (an append to a
deque, no I/O, no JSON). Later turns of the event loop turn the tuples into `TraceEvent` JSON and
publish them on `…/orchestrator/trace` (QoS 0), write them to the `--trace FILE` copy (JSON lines,
the same objects) and hand them to an optional listener. When shipping falls behind by more than
`max_pending` events, the oldest are dropped and counted (`dropped`), so a busy lane is slowed by
at most one batch per `YIELD_EVERY` nodes.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from services.bus.envelopes import dumps
from services.orchestrator.engine import TraceRecord
from umlbot.logs import get_logger

log = get_logger(__name__)

#: events kept while the publisher is behind; older ones are dropped (and counted) beyond this.
DEFAULT_MAX_PENDING = 20_000
#: events shipped per turn of the event loop.
DEFAULT_BATCH = 32
#: how long the first queued event waits for others, so that events leave in bursts.
DEFAULT_DELAY_S = 0.005

Publish = Callable[[bytes], None]
Listener = Callable[[dict[str, Any]], None]


def event_dict(record: TraceRecord) -> dict[str, Any]:
    """The `TraceEvent` JSON object of one engine trace record."""
    lane, node, kind, label, start, end, value, error, warning = record
    event: dict[str, Any] = {
        "lane": lane,
        "node": node,
        "kind": kind,
        "start": start,
        "end": end,
        "duration_ms": round((end - start) * 1000.0, 3),
    }
    if value is not None:
        event["value"] = value
    if error is not None:
        event["error"] = error
        event["level"] = "error"
        event["detail"] = label
    elif warning is not None:
        event["level"] = "warning"
        event["detail"] = f"{label}: {warning}"
    else:
        event["level"] = "info"
        event["detail"] = label
    return event


class TraceRecorder:
    """Collects trace records from the engine and ships them in small batches on the event loop.

    Shipping runs as a loop callback, so it fills the time the lanes spend waiting for replies
    (no extra thread competing for the interpreter while a reply is being handled); a lane that
    never waits gives the loop a turn every `engine.YIELD_EVERY` nodes, and each turn ships at most
    `batch` events. Must be made and used on the event loop's thread.
    """

    def __init__(
        self,
        publish: Publish | None,
        trace_file: str | Path | None = None,
        listener: Listener | None = None,
        max_pending: int = DEFAULT_MAX_PENDING,
        batch: int = DEFAULT_BATCH,
        delay_s: float = DEFAULT_DELAY_S,
    ) -> None:
        self._loop = asyncio.get_running_loop()
        self._publish = publish
        self._listener = listener
        self._file: IO[str] | None = None
        if trace_file is not None:
            # line-buffered so that a crash loses at most the line being written
            self._file = Path(trace_file).open("w", encoding="utf-8", buffering=1)  # noqa: SIM115
        self._pending: collections.deque[TraceRecord] = collections.deque()
        self._max_pending = max_pending
        self._batch = batch
        self._delay_s = delay_s
        self._scheduled = False
        self._closed = False
        self.dropped = 0
        self.shipped = 0

    def record(self, record: TraceRecord) -> None:
        """Queue one executed node (called by the engine on the event loop; never blocks)."""
        pending = self._pending
        if len(pending) >= self._max_pending:
            pending.popleft()
            self.dropped += 1
        pending.append(record)
        if not self._scheduled and not self._closed:
            self._scheduled = True
            self._loop.call_later(self._delay_s, self._drain)

    def _drain(self) -> None:
        self._scheduled = False
        pending = self._pending
        ship = self._ship
        for _ in range(min(self._batch, len(pending))):
            ship(pending.popleft())
        if pending and not self._closed:
            self._scheduled = True
            self._loop.call_soon(self._drain)

    def close(self, timeout: float = 2.0) -> None:
        """Ship what is queued (for at most `timeout` s), then close the file; idempotent."""
        if not self._closed:
            self._closed = True
            deadline = time.monotonic() + timeout
            pending = self._pending
            while pending and time.monotonic() < deadline:
                self._ship(pending.popleft())
            self.dropped += len(pending)
            pending.clear()
            if self.dropped:
                log.warning("trace events dropped: the publisher fell behind", dropped=self.dropped)
        if self._file is not None:
            with contextlib.suppress(OSError):
                self._file.close()
            self._file = None

    def _ship(self, record: TraceRecord) -> None:
        try:
            event = event_dict(record)
            text = dumps(event)
        except (TypeError, ValueError) as exc:  # a value that is not JSON: keep its text
            lane, node, kind, label, start, end, value, error, warning = record
            event = event_dict((lane, node, kind, label, start, end, repr(value), error, warning))
            text = dumps(event)
            log.debug("trace value not JSON", error=str(exc))
        try:
            if self._publish is not None:
                self._publish(text.encode("utf-8"))
            if self._file is not None:
                self._file.write(text + "\n")
            if self._listener is not None:
                self._listener(event)
            self.shipped += 1
        except Exception as exc:  # tracing must never take the orchestrator down
            log.warning("trace event not shipped", error=str(exc))
