"""One clock for the whole robot, with a speed factor the simulator can set.

Model sleeps (`usleep`, `msleep`) and the simulated world both use sim time: at speed 10, one sim
second passes in 0.1 wall seconds. On the real robot the speed is 1.
"""

from __future__ import annotations

import asyncio
import threading
import time


class Clock:
    """Sim time derived from the monotonic wall clock times a fixed speed factor."""

    def __init__(self, speed: float = 1.0) -> None:
        if not speed > 0:
            raise ValueError(f"clock speed must be > 0, got {speed!r}")
        self.speed = speed
        self._wall_start = time.monotonic()
        self._epoch_start = time.time()

    def now(self) -> float:
        """Sim seconds since the clock was made."""
        return (time.monotonic() - self._wall_start) * self.speed

    def epoch(self) -> float:
        """Unix time as the robot lives it: the wall time when the clock was made plus the sim
        seconds since. At speed 1 it runs with the wall clock; at speed 10 a `msleep(1500)` lasts
        1.5 s of it, as a trace's timestamps and durations show it."""
        return self._epoch_start + self.now()

    def wall_seconds(self, sim_seconds: float) -> float:
        """How long `sim_seconds` of sim time take on the wall clock."""
        return max(0.0, sim_seconds) / self.speed

    def call_started(self) -> None:
        """A feature call left: a simulated clock (`umlbot.sim.clock.SimClock`) stands still until
        it comes back; this one runs on."""

    def call_finished(self) -> None:
        """The call `call_started` announced came back (or failed)."""

    def sleep(self, sim_seconds: float, stop: threading.Event | None = None) -> bool:
        """Sleep for sim time; returns True early when `stop` is set."""
        wall = self.wall_seconds(sim_seconds)
        if stop is None:
            time.sleep(wall)
            return False
        return stop.wait(wall)

    async def asleep(self, sim_seconds: float) -> None:
        """Asyncio sleep for sim time."""
        await asyncio.sleep(self.wall_seconds(sim_seconds))
