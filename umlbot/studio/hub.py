"""The studio's hub: collects the robot's events from any thread and sends them to every page.

Events (`MonitorEvent` dicts, the objects `umlbot monitor --json` prints) arrive on the bus's
dispatcher thread; `push` only appends them to a list under a lock (and wakes the event loop when
nothing is scheduled yet). The event loop flushes at once when the last flush is more than
`FLUSH_S` ago, else when it is due (so a lone event reaches the page within a millisecond or two,
and a busy robot makes at most one frame per `FLUSH_S`). A flush keeps what a page opened later
needs (the snapshot: the latest availability, retained state, broker and orchestrator status, the trace
history, the last calls, and with a simulated world its latest state and the pings of its last
second) and sends one `events` frame to each connected page. Nothing is dropped on the way; the
snapshot is bounded: the trace history (`keep_trace`: a page that opens after more than that many
trace events sees the newest ones), the last calls, and the availability and retained state of at
most `MAX_ROWS` components (names come from the wire; the one updated longest ago goes first).
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
import threading
import time
from collections.abc import Callable
from typing import Any

from umlbot.bounded import MAX_ROWS, RecentDict
from umlbot.logs import get_logger

log = get_logger(__name__)

#: seconds between two frames to the pages at most (events are coalesced in between).
FLUSH_S = 0.010
#: trace events kept for pages that open later.
DEFAULT_KEEP_TRACE = 100_000
#: feature calls kept for pages that open later.
KEEP_CALLS = 200
#: events in one frame at most (a large snapshot is split into several frames).
MAX_FRAME_EVENTS = 20_000
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


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if value == value and value not in (float("inf"), float("-inf")) else None
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, list):
        return [_finite(item) for item in value]
    return value


class Page:
    """One connected page: its own frame sequence and an outgoing queue drained by its own task."""

    def __init__(self, send: Send) -> None:
        self.seq = 0
        self.queue: asyncio.Queue[str | None] = asyncio.Queue()
        self._send = send

    def frame(self, events: list[dict[str, Any]]) -> None:
        for first in range(0, max(len(events), 1), MAX_FRAME_EVENTS):
            self.seq += 1
            chunk = events[first:first + MAX_FRAME_EVENTS]
            self.queue.put_nowait(dumps({"type": "events", "seq": self.seq, "events": chunk}))

    async def pump(self) -> None:
        """Send queued frames in order until `None` is queued or the socket fails."""
        while True:
            text = await self.queue.get()
            if text is None:
                return
            await self._send(text)


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
        self._last_flush = 0.0

    # --- any thread ------------------------------------------------------------------------------

    def push(self, event: dict[str, Any]) -> None:
        """Queue one event for the pages (thread-safe, never blocks)."""
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
        page.frame(self.snapshot())
        world = self.world_snapshot()
        if world is not None:
            page.queue.put_nowait(dumps(world))
        self.pages.add(page)

    def detach(self, page: Page) -> None:
        self.pages.discard(page)
        page.queue.put_nowait(None)

    def flush(self) -> None:
        """Move queued events into the snapshot and send them to every page as one frame."""
        self._last_flush = time.monotonic()
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
        if events:
            for page in self.pages:
                page.frame(events)
        if world is not None:
            text = dumps({**world, "type": "world", "pings": pings})
            for page in self.pages:
                page.queue.put_nowait(text)

    def broadcast(self, frame: dict[str, Any]) -> None:
        """Send one frame to every page now (on the event loop; e.g. a file changed on disk)."""
        text = dumps(frame)
        for page in self.pages:
            page.queue.put_nowait(text)

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
        wait = self._last_flush + FLUSH_S - time.monotonic()
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
