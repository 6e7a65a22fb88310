"""Where the studio's data comes from: the model (compiled by the studio itself), the broker, a
recorded trace, or the simulated world of `umlbot sim --studio`.

Every source produces the same `MonitorEvent`s `umlbot monitor` uses (one code path for live and
replay, one decoder of the robot's topics: `services.monitor`).
"""

from __future__ import annotations

import math
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

from umlbot.logs import get_logger
from umlbot.studio.hub import Hub
from umlbot.studio.server import StudioData

if TYPE_CHECKING:
    from compiler.api import CheckResult
    from services.bus.settings import BrokerSettings
    from services.monitor import MonitorEvent
    from services.monitor.live import LiveMonitor
    from umlbot.sim.world import World

log = get_logger(__name__)

#: seconds between two samples of the simulated world.
WORLD_EVERY_S = 0.05


def event_dict(event: MonitorEvent) -> dict[str, Any]:
    """A monitor event as the page gets it (the `umlbot monitor --json` object)."""
    return event.model_dump(mode="json", exclude_none=True)


def studio_data(path: Path, robot: str | None, mode: str = "live",
                result: CheckResult | None = None) -> StudioData:
    """The page's data for the model at `path` (compiled here unless `result` is its check already);
    the robot id is `robot`, else the model's name."""
    from compiler.api import check_model
    from umlbot.studio.model_view import diagnostic_view, model_view

    if result is None:
        result = check_model(path)
    compiled = result.model
    robot_id = robot or (compiled.name if compiled is not None else "car")
    return StudioData(mode=mode, robot=robot_id, source=str(path),
                      model=model_view(compiled) if compiled is not None else None,
                      diagnostics=[diagnostic_view(d) for d in result.diagnostics])


def replay_events(trace_file: Path, robot: str) -> list[dict[str, Any]]:
    """Every event of a recorded trace (`umlbot run --trace FILE`) as the page gets it."""
    from services.monitor import MonitorState
    from services.monitor.replay import read_trace

    state = MonitorState()
    return [event_dict(state.observe_trace(trace, robot)) for trace in read_trace(trace_file)]


class BrokerSource:
    """Follows one robot on the broker (read-only) and pushes its events into the hub.

    Connects in the background and keeps reconnecting, so the page shows the model even while the
    broker is not there yet.
    """

    def __init__(self, settings: BrokerSettings, robot: str, hub: Hub) -> None:
        from services.monitor.live import LiveMonitor

        self.hub = hub
        self.monitor: LiveMonitor = LiveMonitor(settings, robot, self._on_event)

    def _on_event(self, event: MonitorEvent) -> None:
        self.hub.push(event_dict(event))

    def start(self) -> None:
        self.monitor.start(timeout=None)

    def tick(self) -> None:
        """Report calls that stayed unanswered."""
        self.monitor.tick()

    def close(self) -> None:
        self.monitor.close()


class RobotFollower:
    """A `BrokerSource` whose robot can change: `follow` switches to another robot id (the model
    was created or renamed and the robot id is the model's name)."""

    def __init__(self, settings: BrokerSettings, robot: str, hub: Hub) -> None:
        self.settings = settings
        self.robot = robot
        self.hub = hub
        self.source = BrokerSource(settings, robot, hub)
        self._lock = threading.Lock()
        self._started = False

    def start(self) -> None:
        with self._lock:
            self._started = True
            self.source.start()

    def tick(self) -> None:
        self.source.tick()

    def follow(self, robot: str) -> None:
        """Stop following the robot so far and follow `robot` (ConfigError: not a robot id)."""
        from services.monitor.live import topic_filter

        topic_filter(robot)  # a bad id is refused before the old robot is dropped
        with self._lock:
            if robot == self.robot:
                return
            self.source.close()
            self.robot = robot
            self.hub.follow_robot(robot)
            self.source = BrokerSource(self.settings, robot, self.hub)
            if self._started:
                self.source.start()
        log.info("studio follows another robot", robot=robot)

    def close(self) -> None:
        with self._lock:
            self._started = False
            self.source.close()


def track_view(world: World) -> dict[str, Any]:
    """The track and the car's size for the page's sim panel."""
    track = world.track
    return {
        "name": track.name,
        "walls": [[list(point) for point in line] for line in track.walls],
        "start": track.start.model_dump(),
        "goal": track.goal.model_dump(),
        "car": {"length_m": world.car.length_m, "width_m": world.car.width_m,
                "sonar_forward_m": world.car.sonar_forward_m},
    }


class WorldSource:
    """Samples the simulated world every `WORLD_EVERY_S` (wall time) and pushes `world` frames."""

    def __init__(self, world: World, hub: Hub) -> None:
        self.world = world
        self.hub = hub
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="studio-world", daemon=True)
        self._sent_pings = 0

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(2.0)
        self.sample()  # the final pose and pings

    def _run(self) -> None:
        while not self._stop.wait(WORLD_EVERY_S):
            try:
                self.sample()
            except Exception as exc:  # the picture must never stop the run
                log.warning("studio world sample failed", error=str(exc))

    def sample(self) -> None:
        snap = self.world.snapshot()
        pings = self.world.pings
        new, self._sent_pings = pings[self._sent_pings:], len(pings)
        self.hub.push_world({
            "t": round(snap.time_s, 3),
            "car": {"x": round(snap.pose.x, 4), "y": round(snap.pose.y, 4),
                    "heading_deg": round(math.degrees(snap.pose.heading), 2)},
            "servo_deg": round(snap.servo_deg, 1),
            "collisions": snap.collisions,
            "goal": snap.goal_reached,
            "pings": [_ping(p) for p in new],
        })


def _ping(ping: Any) -> dict[str, Any]:
    """A sonar ping as a line from the sensor to where it echoed (max range when no echo)."""
    reach_m = (ping.distance_cm if ping.distance_cm is not None else 400) / 100.0
    x0, y0 = ping.origin.x, ping.origin.y
    return {"t": round(ping.time_s, 3), "x0": round(x0, 4), "y0": round(y0, 4),
            "x1": round(x0 + reach_m * math.cos(ping.angle), 4),
            "y1": round(y0 + reach_m * math.sin(ping.angle), 4), "cm": ping.distance_cm}
