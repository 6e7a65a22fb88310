"""The execution trace: one `TraceEvent` per executed node, published in batches off the hot path.

The engine hands each executed node to `TraceRecorder.record` as a plain tuple. The recorder
numbers the events (`seq` 1, 2, 3 … in recording order), turns each into its JSON text at once (a
few microseconds, no I/O: the encoding cost is spread evenly instead of falling on the loop as one
block of a batch's worth while a reply waits behind it), and ships them in batches from the event
loop, at most 50 messages in any second (`window_s` 20 ms: one per window on average) of which up
to `burst` (4) may follow each other closely (`umlbot.base.pacing.Pacer`): an event recorded when
the pacer allows a message leaves at the loop's next turn, together with every event recorded in
the same turn (so a lone node is seen at once, and so are the next few clusters of a burst — the
nodes a lane runs after each reply); otherwise it waits until a message is allowed again (at most
`Pacer.interval_s`, 21.3 ms, after the last one). Everything pending then (at most `batch` events)
leaves as ONE message on `…/orchestrator/trace` (QoS 0), a JSON array of `TraceEvent` objects in
recording order. A full batch pending leaves at the loop's next turn, and `close` ships the rest. The same
events go to the `--trace FILE` copy (JSON lines, one event a line) and to an optional listener.
When shipping falls behind by more than `max_pending` events, the oldest are dropped and counted
(`dropped`); their `seq` numbers are missing, so a consumer sees the gap.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import time
from collections.abc import Callable
from json.encoder import encode_basestring as _string
from pathlib import Path
from typing import IO, Any

from umlbot.base.logs import get_logger
from umlbot.base.pacing import Pacer
from umlbot.services.bus import json_default
from umlbot.services.orchestrator.engine import TraceRecord

log = get_logger(__name__)

#: events kept while the publisher is behind; older ones are dropped (and counted) beyond this.
DEFAULT_MAX_PENDING = 20_000
#: events in one trace message at most; this many pending are shipped without waiting.
DEFAULT_BATCH = 500
#: one message per window on average: at most 1 / window_s (50) messages in any second.
DEFAULT_WINDOW_S = 0.020
#: messages that may leave back to back within that bound (the clusters of a lane's burst).
DEFAULT_BURST = 4

Publish = Callable[[bytes], None]
Listener = Callable[[dict[str, Any]], None]

# strict JSON for every consumer (a browser's JSON.parse rejects NaN): such values go as their repr
_ENCODER = json.JSONEncoder(separators=(",", ":"), ensure_ascii=False, allow_nan=False,
                            default=json_default)


def event_dict(record: TraceRecord, seq: int | None = None) -> dict[str, Any]:
    """The `TraceEvent` JSON object of one engine trace record (`seq`: its number in the run)."""
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
    if seq is not None:
        event["seq"] = seq
    return event


def encode_record(record: TraceRecord, seq: int) -> str:
    """The JSON text of `event_dict(record, seq)`, made without the dict (a third cheaper).

    Strict JSON: a value that is not (NaN, an object) goes as its repr.
    """
    lane, node, kind, label, start, end, value, error, warning = record
    text = (f'{{"lane":{_string(lane)},"node":{_string(node)},"kind":{_string(kind)},'
            f'"start":{float(start)!r},"end":{float(end)!r},'
            f'"duration_ms":{round((end - start) * 1000.0, 3)!r}')
    if value is not None:
        try:
            text += f',"value":{_ENCODER.encode(value)}'
        except (TypeError, ValueError) as exc:
            log.debug("trace value not JSON", node=node, error=str(exc))
            text += f',"value":{_string(repr(value))}'
    if error is not None:
        text += f',"error":{_string(error)},"level":"error","detail":{_string(label)}'
    elif warning is not None:
        text += f',"level":"warning","detail":{_string(f"{label}: {warning}")}'
    else:
        text += f',"level":"info","detail":{_string(label)}'
    return f'{text},"seq":{seq}}}'


class TraceRecorder:
    """Collects trace records from the engine and ships them in batches on the event loop.

    Shipping runs as a loop callback, so it fills the time the lanes spend waiting for replies
    (no extra thread competing for the interpreter while a reply is being handled); a lane that
    never waits gives the loop a turn every `engine.YIELD_EVERY` nodes, and each turn ships at most
    one batch. Must be made and used on the event loop's thread.
    """

    def __init__(
        self,
        publish: Publish | None,
        trace_file: str | Path | None = None,
        listener: Listener | None = None,
        max_pending: int = DEFAULT_MAX_PENDING,
        batch: int = DEFAULT_BATCH,
        window_s: float = DEFAULT_WINDOW_S,
        burst: int = DEFAULT_BURST,
    ) -> None:
        if batch < 1 or max_pending < 1 or window_s < 0 or burst < 1:
            raise ValueError("batch, max_pending and burst must be >= 1 and window_s >= 0")
        self._loop = asyncio.get_running_loop()
        self._publish = publish
        self._listener = listener
        self._file: IO[str] | None = None
        if trace_file is not None:
            # a missing folder is made, as for every file umlbot writes (compile -o, sim --plot);
            # line-buffered so that a crash loses at most the line being written
            Path(trace_file).parent.mkdir(parents=True, exist_ok=True)
            self._file = Path(trace_file).open("w", encoding="utf-8", buffering=1)  # noqa: SIM115
        # each pending event as its JSON text (made when recorded: a few microseconds each, never
        # a batch's worth at once while a reply waits) and its record (for the listener); the
        # pending events are always the last len(_pending) recorded: seq needs no storage
        self._pending: collections.deque[tuple[str, TraceRecord]] = collections.deque()
        self._max_pending = max_pending
        self._batch = batch
        #: when a message may leave (at most 1 / window_s a second, `burst` back to back).
        self.pacer = Pacer.every(window_s, burst)
        self._handle: asyncio.Handle | None = None  # the scheduled _drain
        self._soon = False  # _handle runs at the loop's next turn
        self._closed = False
        #: events recorded so far (the `seq` of the last one).
        self.recorded = 0
        self.dropped = 0
        self.shipped = 0
        #: trace messages published.
        self.messages = 0

    def record(self, record: TraceRecord) -> None:
        """Queue one executed node (called by the engine on the event loop; never blocks)."""
        self.recorded += 1
        pending = self._pending
        if len(pending) >= self._max_pending:
            pending.popleft()
            self.dropped += 1
        pending.append((encode_record(record, self.recorded), record))
        if self._handle is None:
            if not self._closed:
                wait = self.pacer.wait(time.monotonic())
                if wait > 0:
                    self._handle = self._loop.call_later(wait, self._drain)
                else:  # a message may leave: with whatever this turn of the loop records
                    self._soon = True
                    self._handle = self._loop.call_soon(self._drain)
        elif not self._soon and len(pending) >= self._batch:
            self._handle.cancel()
            self._soon = True
            self._handle = self._loop.call_soon(self._drain)

    def _drain(self) -> None:
        self._handle = None
        self._soon = False
        self._ship(self._batch)
        pending = self._pending
        if pending and not self._closed:
            if len(pending) >= self._batch:
                self._soon = True
                self._handle = self._loop.call_soon(self._drain)
            else:
                self._handle = self._loop.call_later(self.pacer.wait(time.monotonic()), self._drain)

    def close(self, timeout: float = 2.0) -> None:
        """Ship what is queued (for at most `timeout` s), then close the file; idempotent."""
        if not self._closed:
            self._closed = True
            if self._handle is not None:
                self._handle.cancel()
                self._handle = None
            deadline = time.monotonic() + timeout
            pending = self._pending
            while pending and time.monotonic() < deadline:
                self._ship(self._batch)
            self.dropped += len(pending)
            pending.clear()
            if self.dropped:
                log.warning("trace events dropped: the publisher fell behind", dropped=self.dropped)
        if self._file is not None:
            with contextlib.suppress(OSError):
                self._file.close()
            self._file = None

    def _ship(self, limit: int) -> None:
        """Publish the oldest `limit` pending events as one message (file and listener too)."""
        pending = self._pending
        count = min(limit, len(pending))
        if not count:
            return
        self.pacer.sent(time.monotonic())
        first = self.recorded - len(pending) + 1  # the seq of the oldest pending event
        popleft = pending.popleft
        shipped = [popleft() for _ in range(count)]
        texts = [text for text, _ in shipped]
        array = "[" + ",".join(texts) + "]"
        if self._publish is not None:
            try:
                self._publish(array.encode("utf-8"))
                self.messages += 1
            except Exception as exc:  # tracing must never take the orchestrator down
                log.warning("trace events not published", events=count, error=str(exc))
        try:
            if self._file is not None:
                self._file.write("\n".join(texts) + "\n")
            if self._listener is not None:
                for seq, (_, record) in enumerate(shipped, first):
                    self._listener(event_dict(record, seq))
        except Exception as exc:
            log.warning("trace events not written", events=count, error=str(exc))
        self.shipped += count
