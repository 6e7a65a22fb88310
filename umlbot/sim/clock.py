"""The simulator's clock: discrete sim time that moves from event to event, paced by `speed`.

A clock that runs at `speed` x wall time makes a run depend on the machine: at speed 20 every
millisecond the event loop spends between two feature calls is 20 sim ms of the car driving on,
and two branches of a fork that sleep and ping in parallel interleave differently on every run.
`SimClock` therefore does not flow with the wall clock at all. Sim time is a number that moves only
to the next *event*: the earliest deadline of a pending sleep (`asleep`, `sleep`) or of robot time
being spent (`charge`, an HC-SR04 ping). It moves there only when nothing else can happen first:

* no feature call is in flight (`call_started()` .. `call_finished()`), unless the call is itself
  waiting for sim time (a ping being charged): the bus takes no sim time;
* the orchestrator's event loop has nothing ready to run (every lane is blocked on a sleep, a
  call, a join or an accept): computing takes no sim time;
* the wall clock has reached `deadline / speed` since the clock started: `speed` only paces the
  run (a machine too slow for it runs later, not differently).

So a run is a function of the model, the track and the seed: the same at every `--speed`, on an
idle or a loaded machine. The events are advanced by a ticker task on the orchestrator's event
loop (the loop of the first `asleep` or `call_started`); a clock without one (a world used alone,
a thread that sleeps) moves itself on when the wall clock reaches the deadline.

A hold (`hold(key, until_s, grace_wall_s)`: the world's motor leases) keeps sim time short of
`until_s` until it is renewed, dropped (`unhold`) or `grace_wall_s` wall seconds have passed:
sim time waits for a motor driver's renewal as it waits for a call in flight, so a live driver
renews in time at any speed, and a frozen one lets its lease end at the exact sim time.

`halt()` stops time where it is (the run ended: goal, collision, fault); waits that are pending
then stay pending until `release()` lets them all return at once (the run shuts down).
`limit_s` ends time at that sim time: the clock halts there (the run's time-out).
"""

from __future__ import annotations

import asyncio
import contextlib
import heapq
import itertools
import math
import threading
import time
from collections.abc import Iterable

from umlbot.base.clock import Clock

#: Wall seconds the ticker sleeps at most before it looks again (a missed wake-up costs no more).
POLL_WALL_S = 0.05
#: Event-loop turns the ticker waits at most for the loop to have nothing ready.
SETTLE_TURNS = 200

Entry = tuple[float, int]  # (sim deadline, id)


class SimClock(Clock):
    """A `Clock` for the simulator (see the module docstring); thread-safe."""

    def __init__(self, speed: float = 1.0) -> None:
        super().__init__(speed)
        self._cond = threading.Condition()
        self._now = 0.0
        self._wall_origin = time.monotonic()
        self._in_flight = 0
        self._time_waits = 0  # charges waiting for sim time inside a call in flight
        self._deadlines: list[Entry] = []  # heap of pending waits
        self._futures: dict[int, asyncio.Future[None]] = {}
        self._charges: set[int] = set()  # ids of the pending charges
        self._ids = itertools.count()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._ticker: asyncio.Task[None] | None = None
        self._kick: asyncio.Event | None = None
        self._halted = False
        self._released = False
        self._quiet = threading.Event()
        self._holds: dict[str, tuple[float, float]] = {}  # key -> (sim time, wall deadline)
        #: time ends here: the clock halts at this sim time
        self.limit_s = math.inf

    # --- the Clock interface ---------------------------------------------------------------------

    def now(self) -> float:
        with self._cond:
            return self._now

    @property
    def halted(self) -> bool:
        return self._halted

    def halt(self) -> None:
        """Stop sim time where it is; pending waits stay pending (see `release`)."""
        with self._cond:
            self._halted = True
            self._cond.notify_all()
        self._poke()

    def release(self) -> None:
        """Let every pending and future wait return at once (time stays halted): shut-down."""
        with self._cond:
            self._halted = True
            self._released = True
            futures = list(self._futures.values())
            self._futures.clear()
            self._deadlines.clear()
            self._holds.clear()
            self._cond.notify_all()
        loop = self._loop
        if loop is not None and futures:
            with contextlib.suppress(RuntimeError):  # the loop is closed
                loop.call_soon_threadsafe(_resolve, futures)

    def hold(self, key: str, until_s: float, grace_wall_s: float) -> None:
        """Keep sim time short of `until_s` for at most `grace_wall_s` wall seconds from now (a
        later `hold` with the same key replaces this one)."""
        with self._cond:
            self._holds[key] = (until_s, time.monotonic() + grace_wall_s)
        self._poke()

    def unhold(self, key: str) -> None:
        """Drop the hold of `key` (none: nothing to do)."""
        with self._cond:
            dropped = self._holds.pop(key, None)
        if dropped is not None:
            self._poke()

    def _barrier(self) -> tuple[float, float]:
        """(the sim time no deadline may reach, wall seconds until that changes by itself);
        (inf, inf) without holds. Caller holds the lock."""
        now = time.monotonic()
        live = [(until, deadline) for until, deadline in self._holds.values() if deadline > now]
        if not live:
            return math.inf, math.inf
        return min(until for until, _ in live), min(deadline for _, deadline in live) - now

    def wait_quiet(self, timeout: float) -> bool:
        """After `halt()`: wait until the orchestrator has nothing left to do but wait."""
        self._poke()
        return self._quiet.wait(timeout)

    # --- the simulator's hooks -------------------------------------------------------------------

    def call_started(self) -> None:
        """A feature call went out (on the orchestrator's loop): sim time stands still."""
        self._attach()
        with self._cond:
            self._in_flight += 1
            self._quiet.clear()

    def call_finished(self) -> None:
        """A feature call was answered (or failed)."""
        with self._cond:
            self._in_flight = max(0, self._in_flight - 1)
        self._poke()

    def charge(self, sim_seconds: float) -> None:
        """Something took `sim_seconds` of robot time (a sonar ping): wait until it has passed.

        Called by the world in a service's thread while a feature call is in flight; other lanes
        run on meanwhile (a sleep that ends during the ping ends at its own deadline).
        """
        with self._cond:
            if self._halted or sim_seconds <= 0:
                return
            if self._loop is None or self._loop.is_closed():  # no ticker: move on at once
                self._now += sim_seconds
                return
            entry = (self._now + sim_seconds, next(self._ids))
            heapq.heappush(self._deadlines, entry)
            self._charges.add(entry[1])
            self._time_waits += 1
        try:
            self._poke()
            self._wait_thread(entry, None, halt_ends=True)
        finally:
            with self._cond:
                if entry[1] in self._charges:  # not fired (halted, released)
                    self._charges.discard(entry[1])
                    self._time_waits -= 1
                self._remove(entry)

    def sleep(self, sim_seconds: float, stop: threading.Event | None = None) -> bool:
        """Sleep in a thread for sim time; returns True early when `stop` is set."""
        with self._cond:
            entry = (self._now + max(0.0, sim_seconds), next(self._ids))
            heapq.heappush(self._deadlines, entry)
        try:
            self._poke()
            return self._wait_thread(entry, stop)
        finally:
            with self._cond:
                self._remove(entry)

    async def asleep(self, sim_seconds: float) -> None:
        self._attach()
        loop = asyncio.get_running_loop()
        future: asyncio.Future[None] = loop.create_future()
        with self._cond:
            if self._released:
                return
            entry = (self._now + max(0.0, sim_seconds), next(self._ids))
            heapq.heappush(self._deadlines, entry)
            self._futures[entry[1]] = future
            self._quiet.clear()
        self._poke()
        try:
            await future
        finally:
            with self._cond:
                self._futures.pop(entry[1], None)
                self._remove(entry)

    # --- internals -------------------------------------------------------------------------------

    def _remove(self, entry: Entry) -> None:
        if entry in self._deadlines:
            self._deadlines.remove(entry)
            heapq.heapify(self._deadlines)

    def _wait_thread(self, entry: Entry, stop: threading.Event | None, *, halt_ends: bool = False) -> bool:
        """Block this (non-loop) thread until sim time reaches `entry`'s deadline.

        True when `stop` was set first. `halt_ends`: a halted clock ends the wait (a ping on a
        halted world takes no time, so the call is answered and the orchestrator goes quiet).
        """
        with self._cond:
            while self._now < entry[0] and not self._released:
                if stop is not None and stop.is_set():
                    return True
                if self._halted and halt_ends:
                    return False
                ticking = self._loop is not None and not self._loop.is_closed()
                if ticking or self._halted:
                    self._cond.wait(POLL_WALL_S)
                    continue
                # nobody ticks: move on when the wall clock reaches the deadline
                wait = self._wall_origin + entry[0] / self.speed - time.monotonic()
                if wait <= 0 and self._deadlines and self._deadlines[0] == entry:
                    self._fire(entry[0])
                    break
                self._cond.wait(min(max(wait, 0.001), POLL_WALL_S))
            return stop is not None and stop.is_set()

    def _attach(self) -> None:
        """Remember the orchestrator's loop and start the ticker on it (called on the loop)."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        if self._loop is not loop or self._ticker is None or self._ticker.done():
            self._loop = loop
            self._kick = asyncio.Event()
            self._ticker = loop.create_task(self._tick(loop), name="sim-clock")

    def _poke(self) -> None:
        """Make the ticker look again (from any thread)."""
        loop, kick = self._loop, self._kick
        if loop is None or kick is None or loop.is_closed():
            with self._cond:
                self._cond.notify_all()
            return
        try:
            if _running_loop() is loop:
                kick.set()
            else:
                loop.call_soon_threadsafe(kick.set)
        except RuntimeError:  # the loop is closed
            pass

    def _fire(self, deadline: float) -> list[asyncio.Future[None]]:
        """Move sim time to `deadline`; wake the waits that are due. Caller holds the lock."""
        self._now = max(self._now, deadline)
        due: list[asyncio.Future[None]] = []
        while self._deadlines and self._deadlines[0][0] <= self._now:
            _, ident = heapq.heappop(self._deadlines)
            if ident in self._charges:
                # the call is busy again from this moment, not from when its thread wakes up
                self._charges.discard(ident)
                self._time_waits -= 1
            future = self._futures.pop(ident, None)
            if future is not None:
                due.append(future)
        self._cond.notify_all()
        return due

    async def _settled(self, loop: asyncio.AbstractEventLoop) -> bool:
        """Give the loop's ready callbacks their turn; True once nothing but this task is ready."""
        for turn in range(SETTLE_TURNS):
            await asyncio.sleep(0)
            ready = getattr(loop, "_ready", None)
            if ready is None:  # not the standard loop: a few turns are the best we can do
                if turn >= 10:
                    return True
            elif not ready:
                return True
        return False

    async def _tick(self, loop: asyncio.AbstractEventLoop) -> None:
        kick = self._kick
        assert kick is not None
        while not loop.is_closed():
            timeout = POLL_WALL_S
            with self._cond:
                busy = self._in_flight > self._time_waits
                halted = self._halted
                target = self._next_time()
                at_barrier = target is None and bool(self._deadlines)
                barrier_wall_s = self._barrier()[1]
            if halted:
                if not busy and await self._settled(loop):
                    with self._cond:
                        if self._in_flight <= self._time_waits:
                            self._quiet.set()
            elif at_barrier and not busy:
                timeout = min(barrier_wall_s, POLL_WALL_S)  # at a lease's end: wait for its renewal
            elif target is not None and not busy:
                wait = self._wall_origin + min(target, self.limit_s) / self.speed - time.monotonic()
                if wait <= 0:
                    if await self._settled(loop):
                        self._advance(target)
                    continue
                timeout = min(wait, POLL_WALL_S)
            kick.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(kick.wait(), timeout)

    def _next_time(self) -> float | None:
        """Where sim time moves next: the earliest deadline, or a hold's time when that comes
        first (time stops there until the hold is renewed or its grace is over); None when it
        stands at a hold already, or nothing waits. Caller holds the lock."""
        if not self._deadlines:
            return None
        head = self._deadlines[0][0]
        barrier = self._barrier()[0]
        if head < barrier:
            return head
        return barrier if self._now < barrier else None

    def _advance(self, target: float) -> None:
        """Move to `target` when it is still where time goes next and nothing got busy meanwhile."""
        with self._cond:
            if self._halted or self._in_flight > self._time_waits:
                return
            if self._next_time() != target:
                return
            if target > self.limit_s:
                self._now = max(self._now, self.limit_s)
                self._halted = True
                self._cond.notify_all()
                return
            due = self._fire(target)
        _resolve(due)


def _resolve(futures: Iterable[asyncio.Future[None]]) -> None:
    for future in futures:
        if not future.done():
            future.set_result(None)


def _running_loop() -> asyncio.AbstractEventLoop | None:
    try:
        return asyncio.get_running_loop()
    except RuntimeError:
        return None
