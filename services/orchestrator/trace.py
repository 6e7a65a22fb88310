"""The execution trace: one `TraceEvent` per executed node, published off the lanes' hot path.

The engine hands each executed node to `TraceRecorder.record` as a plain tuple (an append to a
deque, no I/O, no JSON). A background thread turns the tuples into `TraceEvent` JSON and publishes
them on `…/orchestrator/trace` (QoS 0), writes them to the `--trace FILE` copy (JSON lines, the
same objects) and hands them to an optional listener. When the publisher falls behind by more than
`max_pending` events, the oldest are dropped and counted (`dropped`), so tracing can slow the lanes
only by the cost of the append.
"""

from __future__ import annotations

import collections
import contextlib
import threading
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from services.bus.envelopes import dumps
from services.orchestrator.engine import TraceRecord
from umlbot.logs import get_logger

log = get_logger(__name__)

#: events kept while the publisher is behind; older ones are dropped (and counted) beyond this.
DEFAULT_MAX_PENDING = 20_000

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
    """Collects trace records from the engine and ships them from a background thread."""

    def __init__(
        self,
        publish: Publish | None,
        trace_file: str | Path | None = None,
        listener: Listener | None = None,
        max_pending: int = DEFAULT_MAX_PENDING,
    ) -> None:
        self._publish = publish
        self._listener = listener
        self._file: IO[str] | None = None
        if trace_file is not None:
            # line-buffered so that a crash loses at most the line being written
            self._file = Path(trace_file).open("w", encoding="utf-8", buffering=1)  # noqa: SIM115
        self._pending: collections.deque[TraceRecord] = collections.deque()
        self._max_pending = max_pending
        self._wake = threading.Event()
        self._stopping = False
        self._idle = threading.Event()
        self._idle.set()
        self.dropped = 0
        self.published = 0
        self._thread = threading.Thread(target=self._run, name="umlbot-trace", daemon=True)
        self._thread.start()

    @property
    def enabled(self) -> bool:
        """True when events go anywhere (topic, file or listener)."""
        return self._publish is not None or self._file is not None or self._listener is not None

    def record(self, record: TraceRecord) -> None:
        """Queue one executed node (called by the engine on the event loop; never blocks)."""
        pending = self._pending
        if len(pending) >= self._max_pending:
            pending.popleft()
            self.dropped += 1
        pending.append(record)
        if not self._wake.is_set():
            self._wake.set()

    def flush(self, timeout: float = 2.0) -> bool:
        """Wait until every queued event was shipped; False when `timeout` passed first."""
        self._wake.set()
        deadline = threading.Event()
        waited = 0.0
        while self._pending or not self._idle.is_set():
            if waited >= timeout:
                return False
            deadline.wait(0.01)
            waited += 0.01
        return True

    def close(self, timeout: float = 2.0) -> None:
        """Ship what is queued (bounded by `timeout`), stop the thread, close the file; idempotent."""
        if not self._stopping:
            self.flush(timeout)
            self._stopping = True
            self._wake.set()
            self._thread.join(timeout)
        if self._file is not None:
            with contextlib.suppress(OSError):
                self._file.close()
            self._file = None
        if self.dropped:
            log.warning("trace events dropped: the publisher fell behind", dropped=self.dropped)

    def _run(self) -> None:
        pending = self._pending
        while True:
            self._wake.wait(0.5)
            self._wake.clear()
            if not pending:
                if self._stopping:
                    return
                continue
            self._idle.clear()
            try:
                while pending:
                    try:
                        record = pending.popleft()
                    except IndexError:
                        break
                    self._ship(record)
            finally:
                self._idle.set()

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
                self.published += 1
            if self._file is not None:
                self._file.write(text + "\n")
            if self._listener is not None:
                self._listener(event)
        except Exception as exc:  # tracing must never take the orchestrator down
            log.warning("trace event not shipped", error=str(exc))
