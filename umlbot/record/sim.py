"""Recording a simulated run: the world sampled into the recorder, sim time as the clock.

`SimRecording.observe` is `run_sim`'s `observe` hook (like the studio's follower): when the sim's
broker runs it subscribes the recorder to the robot's topics, writes the track once and samples
the world every `SAMPLE_EVERY_S` wall seconds (the car's pose and motors, every sonar ping since
the last sample) until the run ends. Everything is stamped with the sim clock's time.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from umlbot.base.logs import get_logger
from umlbot.record.recorder import Recorder, Sink, open_file_recorder

if TYPE_CHECKING:
    from umlbot.sim import World

log = get_logger(__name__)

#: wall seconds between two samples of the world (pose, motors, new pings)
SAMPLE_EVERY_S = 0.05


def sim_now(world: World) -> Callable[[], float]:
    """The run's clock as the orchestrator stamps its trace in the sim (`Clock.epoch`): the wall
    time the sim clock started plus the sim seconds since; wall time before it started."""

    def now() -> float:
        clock = world.clock
        return clock.epoch() if clock is not None else time.time()

    return now


def _epoch_offset(world: World) -> float | None:
    """What to add to the world's sim seconds to get `sim_now`'s time (None before the clock)."""
    clock = world.clock
    return None if clock is None else clock.epoch() - clock.now()


class WorldSampler:
    """Puts the world's state into a recorder from its own thread until `close()`."""

    def __init__(self, world: World, recorder: Recorder, every_s: float = SAMPLE_EVERY_S) -> None:
        self.world = world
        self.recorder = recorder
        self.every_s = every_s
        self._pings = 0
        self._last_time = -math.inf
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="umlbot-record-world", daemon=True)

    def start(self) -> None:
        track = self.world.track
        walls = [[(float(x), float(y)) for x, y in line] for line in track.walls]
        goal = track.goal
        box = ((goal.x_min + goal.x_max) / 2, (goal.y_min + goal.y_max) / 2,
               goal.x_max - goal.x_min, goal.y_max - goal.y_min)
        self.recorder.offer("track", time.time(), walls, box)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self.every_s):
            try:
                self.sample()
            except Exception as exc:  # the recording must never stop the run
                log.warning("recording: world sample failed", error=str(exc))

    def sample(self) -> None:
        offset = _epoch_offset(self.world)
        if offset is None:  # the run's clock has not started: the car stands at its start
            return
        snap = self.world.try_snapshot(self.every_s)
        if snap is None:
            return
        pings = self.world.pings
        new, self._pings = pings[self._pings:], len(pings)
        offer = self.recorder.offer
        for ping in new:
            offer("sonar", offset + ping.time_s, ping.distance_cm, ping.origin.x, ping.origin.y, ping.angle)
        if snap.time_s > self._last_time:  # the car moves only when sim time does
            self._last_time = snap.time_s
            at = offset + snap.time_s
            offer("pose", at, snap.pose.x, snap.pose.y, snap.pose.heading)
            left, right = self.world.motor("left"), self.world.motor("right")
            duty = tuple(m.duty_percent * (1 if m.forward else -1) if m.enabled else 0.0
                         for m in (left, right))
            offer("motors", at, duty, (snap.left_speed_mps, snap.right_speed_mps))

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        self.sample()  # the final pose and pings


class SimRecording:
    """`umlbot sim --record FILE` (and `--foxglove`): `observe` is `run_sim`'s hook, `on_trace`
    its trace listener; `close()` ends the recording and returns its stats."""

    def __init__(self, path: Path | None, model: str | None = None,
                 extra_sinks: Callable[[World, str], list[Sink]] | None = None) -> None:
        self.path = path
        self.model = model
        self.extra_sinks = extra_sinks
        self.recorder: Recorder | None = None
        self._sampler: WorldSampler | None = None

    def observe(self, world: World, broker_url: str, robot: str) -> Callable[[], None]:
        from umlbot.services.bus import BrokerSettings

        now = sim_now(world)
        sinks = self.extra_sinks(world, robot) if self.extra_sinks is not None else []
        if self.path is not None:
            self.recorder = open_file_recorder(self.path, robot, "sim", now, self.model, sinks)
        else:
            self.recorder = Recorder(robot, sinks, now, clock="sim")
        self.recorder.listen(BrokerSettings.from_url(broker_url), trace=False)
        self._sampler = WorldSampler(world, self.recorder)
        self._sampler.start()
        return self.finish

    def on_trace(self, event: dict[str, Any]) -> None:
        if self.recorder is not None:
            self.recorder.on_trace(event)

    def finish(self) -> None:
        """The run ended (its broker still runs): the last sample, off the bus; the recorder stays
        open for the trace's last events."""
        if self._sampler is not None:
            self._sampler.close()
            self._sampler = None
        if self.recorder is not None:
            self.recorder.stop_listening()

    def close(self) -> Any:
        """End the recording (idempotent); its `RecordStats`, or None when it never started."""
        self.finish()
        return self.recorder.close() if self.recorder is not None else None
