"""The studio's hub: collects the robot's events from any thread and sends them to every page.

Events (`MonitorEvent` dicts, the objects `umlbot monitor --json` prints) arrive on the bus's
dispatcher thread; `push` only appends them to a list under a lock (and wakes the event loop when
nothing is scheduled yet). The event loop flushes at once when its `Pacer` allows it, else when it
does: at most `FLUSHES_PER_S` (100) flushes in any second, of which `FLUSH_BURST` (4) may follow
each other closely — so a lone event reaches the page within a millisecond or two, so do the next
few trace messages of a robot's burst, and a busy robot makes at most 100 flushes a second, one
every `Pacer.interval_s` (10.3 ms) when it keeps talking. A flush keeps what a page opened later
needs (the snapshot: the latest availability, retained state, broker and orchestrator status, the trace
history, the last calls, and with a simulated world its latest state and the pings of its last
second) and sends one `events` frame to each connected page. The history is bounded
(`keep_trace`): a page that opens after more than that many trace events sees the newest ones;
so are the last calls, and the availability and retained state of at most `MAX_ROWS` components
(names come from the wire; the one updated longest ago goes first).

What one page can hold is bounded too. A value larger than `MAX_VALUE_CHARS` of JSON (a retained
state, a payload, a call's arguments or result, a datastore's value) is replaced when it arrives by
a text saying so (`cut_value`). Each page has its own queue, counted in characters of JSON
(`Page.queued`); the snapshot a page opens with is not copied into it but serialized in frames of
about `SNAPSHOT_FRAME_CHARS` as the page takes them. A page whose queue would exceed
`MAX_PAGE_CHARS` (it stopped reading, or reads slower than the robot talks) is dropped: its queue
goes, and the server closes its socket with `CLOSE_TOO_SLOW` and the reason; the page reconnects
and starts again from a fresh hello and snapshot. A page that closes keeps nothing.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from umlbot.base.bounded import MAX_ROWS, RecentDict
from umlbot.base.logs import get_logger
from umlbot.base.pacing import Pacer

if TYPE_CHECKING:
    from aiohttp import web

log = get_logger(__name__)

#: flushes to the pages in any second at most (events are coalesced in between): one per
#: `FLUSH_S` on average.
FLUSHES_PER_S = 100
FLUSH_S = 1.0 / FLUSHES_PER_S
#: flushes that may follow each other closely within that bound (a robot's burst of messages).
FLUSH_BURST = 4
#: trace events kept for pages that open later.
DEFAULT_KEEP_TRACE = 100_000
#: feature calls kept for pages that open later.
KEEP_CALLS = 200
#: events in one frame at most (a large burst is split into several frames).
MAX_FRAME_EVENTS = 20_000
#: characters of JSON in one frame of the snapshot, about (the snapshot goes out in such frames).
SNAPSHOT_FRAME_CHARS = 256 * 1024
#: characters of JSON one page may have waiting to be sent; a page further behind is dropped.
MAX_PAGE_CHARS = 8 * 1024 * 1024
#: the largest value an event carries to a page, in characters of JSON (a retained state, ...).
MAX_VALUE_CHARS = 64 * 1024
#: the keys of an event that hold values from the robot (what `cut_value` bounds).
VALUE_KEYS = ("payload", "value", "args")
#: WebSocket close code of a page dropped for falling behind (an application code, 4000-4999).
CLOSE_TOO_SLOW = 4000
#: sim seconds of sonar pings a page opening later gets (the page draws the last second's).
KEEP_PINGS_S = 1.0
#: sonar pings kept for pages that open later, at most (the page draws at most 400).
KEEP_PINGS = 400

Send = Callable[[str], Any]


def dumps(data: Any) -> str:
    """Compact JSON; values that are not JSON (NaN from the wire) become null or text."""
    try:
        return json.dumps(data, separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    except ValueError:
        return json.dumps(_finite(data), separators=(",", ":"), ensure_ascii=False, default=str)


def json_response(data: Any, status: int = 200) -> web.Response:
    """`data` as the studio answers a request: `dumps`'d, never cached by the browser."""
    from aiohttp import web

    return web.Response(text=dumps(data), status=status, content_type="application/json",
                        headers={"Cache-Control": "no-store"})


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if value == value and value not in (float("inf"), float("-inf")) else None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_finite(item) for item in value]
    return value


def cut_value(event: dict[str, Any], limit: int = MAX_VALUE_CHARS) -> dict[str, Any]:
    """`event` with each value (`VALUE_KEYS`) over `limit` characters of JSON replaced by a text
    that says it was cut and how large it was (the same event when none is). A short text or a
    number is not measured: the common event costs a few type checks."""
    cut: dict[str, Any] | None = None
    for key in VALUE_KEYS:
        value = event.get(key)
        if value is None or isinstance(value, bool | int | float):
            continue
        if isinstance(value, str) and len(value) * 6 + 2 <= limit:  # even if every char is escaped
            continue
        size = len(dumps(value))
        if size > limit:
            cut = cut if cut is not None else dict(event)
            cut[key] = f"(cut by the studio: {size:,} characters of JSON, more than the {limit:,} it shows)"
    return cut if cut is not None else event


class Page:
    """One connected page: its frame sequence, its snapshot still to send and its queue (counted
    in characters), drained by its own task (`pump`); dropped when the queue would pass `limit`."""

    def __init__(self, send: Send, limit: int = MAX_PAGE_CHARS) -> None:
        self.seq = 0
        self.limit = limit
        #: characters of JSON waiting in the queue.
        self.queued = 0
        #: why the page was dropped (None: it was not).
        self.dropped: str | None = None
        self.closed = False
        self._queue: collections.deque[tuple[str, int, bool]] = collections.deque()  # text, size, events?
        self._first: str | None = None  # the hello
        self._snapshot: list[dict[str, Any]] | None = None  # None: sent (or none to send)
        self._snapshot_at = 0
        self._wake = asyncio.Event()
        #: set when the page is closed or dropped (its socket's handler waits for it).
        self.gone = asyncio.Event()
        self._send = send

    def put(self, text: str, events: bool = False) -> bool:
        """Queue one frame (`events`: the JSON array of an `events` frame, numbered when it is
        sent); False when the page is closed or is dropped now for falling behind. A frame
        larger than the limit is taken when nothing else waits (a page is not dropped for one
        large model)."""
        if self.closed:
            return False
        size = len(text)
        if self.queued and self.queued + size > self.limit:
            self.drop(f"the page fell behind: more than {self.limit:,} characters of frames waiting")
            return False
        self._queue.append((text, size, events))
        self.queued += size
        self._wake.set()
        return True

    def greet(self, hello: str) -> None:
        """The first frame of all (the socket's hello), before the snapshot."""
        self._first = hello
        self._wake.set()

    def start(self, snapshot: list[dict[str, Any]]) -> None:
        """The events a page opening now gets after the hello and before anything queued: at least
        one `events` frame (with no events when there are none), numbered from 1."""
        self._snapshot, self._snapshot_at = snapshot, 0
        self._wake.set()

    def drop(self, reason: str) -> None:
        """Give up on this page: forget what waits for it (the server closes its socket)."""
        if not self.closed:
            self.dropped = reason
        self.close()

    def close(self) -> None:
        """Nothing more for this page; what waits is forgotten and the pump ends."""
        self.closed = True
        self._queue.clear()
        self._first = self._snapshot = None
        self.queued = 0
        self._wake.set()
        self.gone.set()

    def _next(self) -> str | None:
        """The next frame to send: the hello, the snapshot's frames, then the queue's."""
        if self._first is not None:
            text, self._first = self._first, None
            return text
        snapshot = self._snapshot
        if snapshot is not None:
            parts: list[str] = []
            size = 0
            while self._snapshot_at < len(snapshot) and size < SNAPSHOT_FRAME_CHARS \
                    and len(parts) < MAX_FRAME_EVENTS:
                part = dumps(snapshot[self._snapshot_at])
                self._snapshot_at += 1
                parts.append(part)
                size += len(part) + 1
            if self._snapshot_at >= len(snapshot):
                self._snapshot = None
            return self._events("[" + ",".join(parts) + "]")
        if self._queue:
            text, size, events = self._queue.popleft()
            self.queued -= size
            return self._events(text) if events else text
        return None

    def _events(self, array: str) -> str:
        self.seq += 1
        return f'{{"type":"events","seq":{self.seq},"events":{array}}}'

    async def pump(self) -> None:
        """Send the frames in order until the page is closed (or the socket fails). A send is
        shielded: cancelling the pump must not cancel the socket's drain, which aiohttp shares
        with the close frame that follows (a cancelled drain would fail that close at once)."""
        while not self.closed:
            text = self._next()
            if text is None:
                self._wake.clear()
                await self._wake.wait()
                continue
            await asyncio.shield(self._send(text))


class Hub:
    """Fan-out of the robot's events to the pages, with a snapshot for late joiners."""

    def __init__(self, keep_trace: int = DEFAULT_KEEP_TRACE) -> None:
        self._lock = threading.Lock()
        self._incoming: list[dict[str, Any]] = []
        self._world: dict[str, Any] | None = None
        self._world_pings: list[dict[str, Any]] = []
        #: the robot id the pages follow from the next flush on (`follow_robot`).
        self._new_robot: str | None = None
        self.pages: set[Page] = set()
        # the snapshot
        self.availability: RecentDict[str, dict[str, Any]] = RecentDict(MAX_ROWS)
        self.retained: RecentDict[str, dict[str, Any]] = RecentDict(MAX_ROWS)
        self.orchestrator: dict[str, Any] | None = None
        #: the connection to the broker (the latest `broker` event of the broker source).
        self.broker: dict[str, Any] | None = None
        #: the connection to the broker of a studio *Run* (its latest `broker` event).
        self.run_broker: dict[str, Any] | None = None
        self.trace: collections.deque[dict[str, Any]] = collections.deque(maxlen=keep_trace)
        self.calls: collections.deque[dict[str, Any]] = collections.deque(maxlen=KEEP_CALLS)
        #: the simulated world's latest state and its recent pings (under `_lock`).
        self.world: dict[str, Any] | None = None
        self.world_pings: collections.deque[dict[str, Any]] = collections.deque(maxlen=KEEP_PINGS)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._scheduled = False
        #: when the next flush may go (at most `FLUSHES_PER_S` a second, `FLUSH_BURST` back to back).
        self.pacer = Pacer(FLUSHES_PER_S, FLUSH_BURST)
        #: pages dropped for falling behind, since the start, and the most characters of JSON
        #: one page ever had waiting.
        self.dropped_pages = 0
        self.peak_queued = 0

    # --- any thread ------------------------------------------------------------------------------

    def push(self, event: dict[str, Any]) -> None:
        """Queue one event for the pages (thread-safe, never blocks); a value too large for a
        page is cut here (`cut_value`), so the snapshot never keeps it either."""
        event = cut_value(event)
        with self._lock:
            self._incoming.append(event)
            wake = not self._scheduled and self._loop is not None
            self._scheduled = True
        if wake:
            self._wake()

    def push_world(self, frame: dict[str, Any]) -> None:
        """The simulated world's latest state; its `pings` accumulate until the next flush."""
        with self._lock:
            self._world_pings.extend(frame.get("pings", []))
            self._world = frame
            wake = not self._scheduled and self._loop is not None
            self._scheduled = True
        if wake:
            self._wake()

    def follow_robot(self, robot: str) -> None:
        """The events come from robot `robot` from now on: the next flush forgets the snapshot of
        the robot followed so far and tells the pages first (a `robot` frame). Thread-safe; call it
        after the old robot's source stopped pushing."""
        with self._lock:
            self._incoming = []
            self._new_robot = robot
            wake = not self._scheduled and self._loop is not None
            self._scheduled = True
        if wake:
            self._wake()

    def reset_world(self) -> None:
        """A new simulated run starts: forget the previous run's world (thread-safe)."""
        with self._lock:
            self._world, self._world_pings = None, []
            self.world = None
            self.world_pings.clear()

    def _wake(self) -> None:
        loop = self._loop
        if loop is not None:
            with contextlib.suppress(RuntimeError):  # the loop has closed: nobody to send to
                loop.call_soon_threadsafe(self._due)

    # --- the event loop ----------------------------------------------------------------------------

    def snapshot(self) -> list[dict[str, Any]]:
        """What a page opening now needs, in the order it should apply it."""
        events: list[dict[str, Any]] = list(self.availability.values())
        events += self.retained.values()
        if self.broker is not None:
            events.append(self.broker)
        if self.run_broker is not None:
            events.append(self.run_broker)
        if self.orchestrator is not None:
            events.append(self.orchestrator)
        events += self.trace
        events += self.calls
        return events

    def world_snapshot(self) -> dict[str, Any] | None:
        """The `world` frame a page opening now needs: the latest state, the recent pings."""
        with self._lock:
            if self.world is None:
                return None
            return {**self.world, "type": "world", "pings": list(self.world_pings)}

    def attach(self, page: Page) -> None:
        """Register a page; it gets the snapshot now and every flush after."""
        with self._lock:
            pending = self._scheduled
        if pending:  # what came in since the last flush (the run's last world) is in the snapshot
            self._safe_flush()
        page.start(self.snapshot())
        world = self.world_snapshot()
        if world is not None:
            page.put(dumps(world))
        self.pages.add(page)

    def detach(self, page: Page) -> None:
        """The page closed: it keeps nothing."""
        self.pages.discard(page)
        page.close()

    def queued(self) -> int:
        """Characters of JSON waiting for all pages together."""
        return sum(page.queued for page in self.pages)

    def _send(self, text: str, events: bool = False) -> None:
        """Queue one frame for every page; a page that falls too far behind is dropped."""
        for page in list(self.pages):
            if page.put(text, events):
                self.peak_queued = max(self.peak_queued, page.queued)
            elif page.dropped is not None:
                self.pages.discard(page)
                self.dropped_pages += 1
                log.warning("studio page dropped", reason=page.dropped, pages=len(self.pages))

    def flush(self) -> None:
        """Move queued events into the snapshot and send them to every page as one frame."""
        self.pacer.sent(time.monotonic())
        with self._lock:
            self._scheduled = False
            events, self._incoming = self._incoming, []
            robot, self._new_robot = self._new_robot, None
            world, self._world = self._world, None
            pings, self._world_pings = self._world_pings, []
            if world is not None:
                self._remember_world(world, pings)
        if robot is not None:
            self.availability.clear()
            self.retained.clear()
            self.orchestrator = None
            self.trace.clear()
            self.calls.clear()
            self.broadcast({"type": "robot", "robot": robot})
        for event in events:
            self._remember(event)
        if self.pages:
            for first in range(0, len(events), MAX_FRAME_EVENTS):  # one text for every page
                self._send(dumps(events[first:first + MAX_FRAME_EVENTS]), events=True)
            if world is not None:
                self._send(dumps({**world, "type": "world", "pings": pings}))

    def broadcast(self, frame: dict[str, Any]) -> None:
        """Send one frame to every page now (on the event loop; e.g. a file changed on disk)."""
        self._send(dumps(frame))

    def _remember_world(self, world: dict[str, Any], pings: list[dict[str, Any]]) -> None:
        """Keep the latest world state and the pings of its last `KEEP_PINGS_S` (under `_lock`)."""
        self.world = {key: value for key, value in world.items() if key != "pings"}
        self.world_pings.extend(pings)
        now = world.get("t")
        if isinstance(now, int | float):
            while self.world_pings and abs(now - float(self.world_pings[0].get("t", now))) > KEEP_PINGS_S:
                self.world_pings.popleft()

    def _remember(self, event: dict[str, Any]) -> None:
        kind = event.get("type")
        if kind == "trace":
            self.trace.append(event)
        elif kind == "call":
            self.calls.append(event)
        elif kind == "availability":
            self.availability[f"{event.get('robot')}/{event.get('component')}"] = event
        elif kind == "state":
            self.retained[f"{event.get('robot')}/{event.get('component')}"] = event
        elif kind == "orchestrator":
            self.orchestrator = event
        elif kind == "broker" and event.get("source") == "run":
            self.run_broker = event
        elif kind == "broker":
            self.broker = event

    def _due(self) -> None:
        wait = self.pacer.wait(time.monotonic())
        loop = self._loop
        if wait > 0 and loop is not None:
            loop.call_later(wait, self._safe_flush)
        else:
            self._safe_flush()

    def _safe_flush(self) -> None:
        try:
            self.flush()
        except Exception as exc:  # a bad event must not stop the page updates
            log.warning("studio flush failed", error=str(exc))

    async def run(self) -> None:
        """Deliver events to the pages until cancelled (events pushed meanwhile wake it)."""
        self._loop = asyncio.get_running_loop()
        try:
            self._safe_flush()  # whatever arrived before the loop ran
            await asyncio.Event().wait()
        finally:
            self._loop = None
