"""The simulator's clock: sim time at `speed` x wall time, with exact sleeps and unscaled bus latency.

A plain `Clock` at speed 10 turns every millisecond the bus takes into ten sim milliseconds, so a
2 ms request would move the simulated car as long as a 20 ms one, and an `msleep(350)` that wakes
up 1 ms late would turn the car 10 ms too long. The robot does not see that. `SimClock` keeps the
`Clock` interface and adds two rules:

* while a feature call is in flight (`call_started()` .. `call_finished()`), sim time runs at the
  wall-clock rate (x1): the call costs the sim what it would cost on the robot, not `speed` times;
* sim time never passes the earliest pending sleep's deadline until that sleeper has woken up,
  so `msleep(t)` lasts exactly `t` sim seconds however late the event loop wakes it.

Between those, sim time runs at `speed` x wall time. The world follows `now()`, so the car moves for
exactly as long as the model sleeps.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import threading
import time

from umlbot.clock import Clock


class SimClock(Clock):
    """A `Clock` for the simulator (see the module docstring); thread-safe."""

    def __init__(self, speed: float = 1.0) -> None:
        super().__init__(speed)
        self._lock = threading.Lock()
        self._wall_mark = time.monotonic()
        self._sim_mark = 0.0
        self._in_flight = 0
        self._deadlines: list[tuple[float, int]] = []
        self._ids = itertools.count()

    def _advance(self) -> float:
        """Bring the marks up to now (caller holds the lock) and return sim time."""
        wall = time.monotonic()
        rate = 1.0 if self._in_flight else self.speed
        sim = self._sim_mark + (wall - self._wall_mark) * rate
        if self._deadlines:
            sim = min(sim, self._deadlines[0][0])
        self._sim_mark = max(self._sim_mark, sim)
        self._wall_mark = wall
        return self._sim_mark

    def now(self) -> float:
        with self._lock:
            return self._advance()

    def call_started(self) -> None:
        """A feature call went out: sim time runs at x1 until it is answered."""
        with self._lock:
            self._advance()
            self._in_flight += 1

    def call_finished(self) -> None:
        """A feature call was answered (or failed)."""
        with self._lock:
            self._advance()
            self._in_flight = max(0, self._in_flight - 1)

    def _register(self, sim_seconds: float) -> tuple[float, int]:
        with self._lock:
            entry = (self._advance() + max(0.0, sim_seconds), next(self._ids))
            heapq.heappush(self._deadlines, entry)
            return entry

    def _remaining_wall(self, entry: tuple[float, int]) -> float:
        """Wall seconds still to wait for `entry` (0 when its deadline has come)."""
        with self._lock:
            sim = self._advance()
            left = entry[0] - sim
            if left <= 0:
                return 0.0
            return left / (1.0 if self._in_flight else self.speed)

    def _release(self, entry: tuple[float, int]) -> None:
        with self._lock:
            self._advance()
            if entry in self._deadlines:
                self._deadlines.remove(entry)
                heapq.heapify(self._deadlines)

    async def asleep(self, sim_seconds: float) -> None:
        entry = self._register(sim_seconds)
        try:
            while True:
                wait = self._remaining_wall(entry)
                if wait <= 0:
                    return
                await asyncio.sleep(wait)
        finally:
            self._release(entry)

    def sleep(self, sim_seconds: float, stop: threading.Event | None = None) -> bool:
        entry = self._register(sim_seconds)
        try:
            while (wait := self._remaining_wall(entry)) > 0:
                if stop is not None:
                    if stop.wait(wait):
                        return True
                else:
                    time.sleep(wait)
            return False
        finally:
            self._release(entry)
