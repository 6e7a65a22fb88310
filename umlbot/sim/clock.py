"""The simulator's clock: sim time at `speed` x wall time, with exact sleeps and a timeless bus.

A plain `Clock` at speed 10 turns every millisecond the bus takes into ten sim milliseconds: the
two `enabled(true)` calls that start the car's sides one round trip apart would let one side run
alone for ~40 sim ms, and an `msleep(350)` that the event loop wakes 2 ms late would turn the car
20 sim ms too long. How far the simulated car goes would then depend on how busy the machine is.
`SimClock` keeps the `Clock` interface and adds four rules:

* while a feature call is in flight (`call_started()` .. `call_finished()`), sim time stands still:
  the bus is taken as instantaneous (on the robot a call takes 1-5 ms, small next to its moves);
* what takes time on the robot is charged explicitly by the world (`charge()`): an HC-SR04 ping
  costs its echo time and the 60 ms the sensor needs between pings;
* sim time never passes the earliest pending sleep's deadline until that sleeper has woken up,
  so `msleep(t)` lasts exactly `t` sim seconds however late the event loop wakes it;
* when a sleep ends, sim time holds at its deadline until the sleeper's next feature call goes
  out (at most `HOLD_WALL_S` of wall time), so the motors stop exactly `t` after they started
  even when the event loop is slow to run the sleeper again.

Between those, sim time runs at `speed` x wall time. The world follows `now()`, so the car moves for
exactly as long as the model sleeps, whatever the load of the machine.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import threading
import time

from umlbot.clock import Clock

#: Wall seconds sim time may hold at a finished sleep's deadline, waiting for the next call.
HOLD_WALL_S = 0.005

Entry = tuple[float, int]  # (sim deadline, id)


class SimClock(Clock):
    """A `Clock` for the simulator (see the module docstring); thread-safe."""

    def __init__(self, speed: float = 1.0) -> None:
        super().__init__(speed)
        self._lock = threading.Lock()
        self._wall_mark = time.monotonic()
        self._sim_mark = 0.0
        self._in_flight = 0
        self._deadlines: list[Entry] = []  # heap of pending sleeps
        self._holds: dict[int, tuple[float, float]] = {}  # id -> (sim deadline, wall expiry)
        self._ids = itertools.count()

    # --- the time line (callers hold the lock) ---------------------------------------------------

    def _limit(self) -> float:
        limits = [d for d, _ in self._holds.values()]
        if self._deadlines:
            limits.append(self._deadlines[0][0])
        return min(limits) if limits else float("inf")

    def _step_to(self, wall: float) -> None:
        rate = 0.0 if self._in_flight else self.speed
        sim = min(self._sim_mark + (wall - self._wall_mark) * rate, self._limit())
        self._sim_mark = max(self._sim_mark, sim)
        self._wall_mark = wall

    def _advance(self) -> float:
        """Bring the marks up to the wall clock and return sim time."""
        wall = time.monotonic()
        while self._holds:
            ident, (_, expiry) = min(self._holds.items(), key=lambda item: item[1][1])
            if expiry > wall:
                break
            self._step_to(expiry)
            del self._holds[ident]
        self._step_to(wall)
        return self._sim_mark

    # --- the Clock interface and the simulator's hooks -------------------------------------------

    def now(self) -> float:
        with self._lock:
            return self._advance()

    def call_started(self) -> None:
        """A feature call went out: sim time stands still until it is answered."""
        with self._lock:
            self._advance()
            self._holds.clear()
            self._in_flight += 1

    def call_finished(self) -> None:
        """A feature call was answered (or failed)."""
        with self._lock:
            self._advance()
            self._in_flight = max(0, self._in_flight - 1)

    def charge(self, sim_seconds: float) -> None:
        """Something took `sim_seconds` of robot time (a sonar ping): move sim time on by that."""
        with self._lock:
            self._advance()
            self._sim_mark += max(0.0, sim_seconds)

    def _register(self, sim_seconds: float) -> Entry:
        with self._lock:
            entry = (self._advance() + max(0.0, sim_seconds), next(self._ids))
            heapq.heappush(self._deadlines, entry)
            return entry

    def _remaining_wall(self, entry: Entry) -> float:
        """Wall seconds still to wait for `entry` (0 when its deadline has come)."""
        with self._lock:
            left = entry[0] - self._advance()
            if left <= 0:
                return 0.0
            # while calls are in flight time stands still: look again soon
            return 0.001 if self._in_flight else left / self.speed

    def _release(self, entry: Entry, completed: bool) -> None:
        with self._lock:
            self._advance()
            if entry in self._deadlines:
                self._deadlines.remove(entry)
                heapq.heapify(self._deadlines)
            if completed:
                self._holds[entry[1]] = (entry[0], time.monotonic() + HOLD_WALL_S)

    async def asleep(self, sim_seconds: float) -> None:
        entry = self._register(sim_seconds)
        completed = False
        try:
            while True:
                wait = self._remaining_wall(entry)
                if wait <= 0:
                    completed = True
                    return
                await asyncio.sleep(wait)
        finally:
            self._release(entry, completed)

    def sleep(self, sim_seconds: float, stop: threading.Event | None = None) -> bool:
        entry = self._register(sim_seconds)
        completed = False
        try:
            while (wait := self._remaining_wall(entry)) > 0:
                if stop is not None:
                    if stop.wait(wait):
                        return True
                else:
                    time.sleep(wait)
            completed = True
            return False
        finally:
            self._release(entry, completed)
