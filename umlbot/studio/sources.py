"""Where the studio's data comes from: the model (compiled by the studio itself), the broker, a
recorded trace, or the simulated world of `umlbot sim --studio`.

Every source produces the same `MonitorEvent`s `umlbot monitor` uses (one code path for live and
replay, one decoder of the robot's topics: `umlbot.monitor`).
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from umlbot.base.logs import get_logger
from umlbot.studio.data import StudioData
from umlbot.studio.hub import Hub

if TYPE_CHECKING:
    from umlbot.compiler.api import CheckResult
    from umlbot.compiler.compiled import CompiledModel
    from umlbot.monitor import LiveMonitor, MonitorEvent
    from umlbot.services.bus import BrokerSettings
    from umlbot.sim import World

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
    from umlbot.compiler.api import check_model
    from umlbot.studio.model_view import diagnostic_view, model_view

    if result is None:
        result = check_model(path)
    compiled = result.model
    robot_id = robot or (compiled.name if compiled is not None else "car")
    return StudioData(mode=mode, robot=robot_id, source=str(path),
                      model=model_view(compiled) if compiled is not None else None,
                      diagnostics=[diagnostic_view(d) for d in result.diagnostics],
                      call_timeout_s=compiled.call_timeout_s if compiled is not None else None)


def replay_data(trace_file: Path, robot: str, model: CompiledModel | None) -> dict[str, Any]:
    """A recorded trace (`umlbot run --trace FILE`) as the page replays it: `events` (each trace
    event, the feature calls it made, the orchestrator's state as the trace shows it) and `notes`
    (what the user should know: a cut-off last line, nodes the model does not have).

    Raises ConfigError for a bad line and for a file without events.
    """
    from umlbot.base.errors import ConfigError
    from umlbot.compiler.compiled import ActionNode, DatastoreNode
    from umlbot.compiler.expr import Call, Const, FeatureTarget
    from umlbot.monitor import MonitorState, read_trace

    # (lane, node) -> the feature call the node makes: component, feature, its text, constant args
    calls: dict[tuple[str, str], tuple[str, str, str, list[Any] | None]] = {}
    nodes: set[tuple[str, str]] | None = None
    if model is not None:
        nodes = set()
        for lane in model.lanes.values():
            for node in lane.nodes.values():
                nodes.add((lane.name, node.id))
                expr = node.call if isinstance(node, ActionNode) else (
                    node.value if isinstance(node, DatastoreNode) else None)
                if isinstance(expr, Call) and isinstance(expr.target, FeatureTarget):
                    text = node.label
                    if isinstance(node, DatastoreNode) and " = " in text:
                        text = text.split(" = ", 1)[1]  # the call, without the store it sets
                    consts = [a.value for a in expr.args if isinstance(a, Const)]
                    args = consts if len(consts) == len(expr.args) else None
                    calls[(lane.name, node.id)] = (expr.target.component, expr.target.feature, text, args)
    notes: list[str] = []
    state = MonitorState()
    events: list[dict[str, Any]] = []
    unknown, example = 0, ""
    fault: dict[str, Any] | None = None
    for trace in read_trace(trace_file, notes):
        event = event_dict(state.observe_trace(trace, robot))
        events.append(event)
        key = (trace.lane, trace.node)
        if nodes is not None and key not in nodes:
            unknown += 1
            example = example or f"{trace.lane}/{trace.node}"
        made = calls.get(key)
        if made is not None:
            component, feature, text, args = made
            call: dict[str, Any] = {"type": "call", "time": event["time"], "robot": robot,
                                    "component": component, "feature": feature, "detail": text,
                                    "ok": trace.error is None, "latency_ms": trace.duration_ms}
            if args is not None:
                call["args"] = args
            if trace.error is not None:
                call["error"] = trace.error
            elif "value" in event:
                call["value"] = event["value"]
            events.append(call)
        if fault is None and trace.level == "error" and math.isfinite(trace.end):
            fault = event
    if not events:
        raise ConfigError(f"{trace_file}: no trace events")
    times = [e["time"] for e in events if isinstance(e.get("time"), int | float) and math.isfinite(e["time"])]
    if times:  # the trace has no status messages: what it shows of the orchestrator, said so
        events.insert(0, {"type": "orchestrator", "time": min(times), "robot": robot, "state": "running",
                          "detail": "from the trace"})
        if fault is not None:
            reason = fault.get("error") or fault.get("detail")
            events.append({"type": "orchestrator", "time": fault["time"], "robot": robot, "state": "failed",
                           "detail": f"{fault['lane']}/{fault['node']}: {reason}"})
        else:
            events.append({"type": "orchestrator", "time": max(times), "robot": robot, "state": "trace ended",
                           "detail": "no fault recorded"})
    if unknown:
        what = "1 event names a node" if unknown == 1 else f"{unknown} events name nodes"
        notes.append(f"{what} not in the model (e.g. {example}): is it the model the trace was "
                     "recorded with?")
    return {"file": trace_file.name, "events": events, "notes": notes}


class BrokerSource:
    """Follows one robot on the broker (read-only) and pushes its events into the hub.

    Connects in the background and keeps reconnecting, so the page shows the model even while the
    broker is not there yet.
    """

    def __init__(self, settings: BrokerSettings, robot: str, hub: Hub,
                 call_timeout_s: float | None = None, origin: str | None = None) -> None:
        from umlbot.monitor import DEFAULT_CALL_TIMEOUT_S, LiveMonitor, MonitorState
        from umlbot.services.bus import redact_url

        self.hub = hub
        self.url = redact_url(settings.url)
        # until the orchestrator's status says its time-out, the model's (`call_timeout_s`)
        state = MonitorState(fallback_call_timeout_s=call_timeout_s or DEFAULT_CALL_TIMEOUT_S)
        self.monitor: LiveMonitor = LiveMonitor(settings, robot, self._on_event, state=state)
        self._broker_seen: tuple[object, ...] | None = None
        self._ended = False
        #: `broker` events say where they come from when it is not the robot's broker ("run":
        #: the simulator's own broker of a studio *Run*).
        self._origin = {"source": origin} if origin else {}

    def _on_event(self, event: MonitorEvent) -> None:
        self.hub.push(event_dict(event))

    def start(self) -> None:
        self.monitor.start(timeout=None)
        self.hub.push({"type": "broker", "time": time.time(), "url": self.url, "connected": False,
                       "attempts": 0, "problem": None, **self._origin})

    def tick(self) -> None:
        """Report calls that stayed unanswered and a change of the broker connection."""
        if self._ended:
            return
        self.monitor.tick()
        self.report_broker()

    def report_broker(self) -> None:
        """Push a `broker` event when the connection's state changed (connected, or why not)."""
        status = self.monitor.broker_status()
        seen = (status.get("connected"), status.get("problem"), status.get("attempts"))
        if seen != self._broker_seen:
            self._broker_seen = seen
            self.hub.push({"type": "broker", "time": time.time(), "url": self.url, **status, **self._origin})

    def close(self, ended: str | None = None) -> None:
        """Stop following; `ended`: why the broker is gone for good (a simulated run ended), said to
        the page in place of the lost connection (which it is not: nothing is retried)."""
        self._ended = self._ended or ended is not None
        self.monitor.close()
        if ended is not None:
            self.hub.push({"type": "broker", "time": time.time(), "url": self.url, "connected": False,
                           "problem": None, "ended": ended, **self._origin})


class RobotFollower:
    """A `BrokerSource` whose robot can change: `follow` switches to another robot id (the model
    was created or renamed and the robot id is the model's name)."""

    def __init__(self, settings: BrokerSettings, robot: str, hub: Hub,
                 call_timeout_s: float | None = None) -> None:
        self.settings = settings
        self.robot = robot
        self.hub = hub
        self.call_timeout_s = call_timeout_s
        self.source = BrokerSource(settings, robot, hub, call_timeout_s)
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
        from umlbot.monitor import topic_filter

        topic_filter(robot)  # a bad id is refused before the old robot is dropped
        with self._lock:
            if robot == self.robot:
                return
            self.source.close()
            self.robot = robot
            self.hub.follow_robot(robot)
            self.source = BrokerSource(self.settings, robot, self.hub, self.call_timeout_s)
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
        self._sent_pings, new = self.world.pings_since(self._sent_pings)
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
    """A sonar ping as a line from the sensor to the wall point its echo came from (the beam is
    ~15° wide: not always straight ahead); along the beam's centre at max range when no echo."""
    x0, y0 = ping.origin.x, ping.origin.y
    hit = getattr(ping, "hit", None)
    if hit is not None:
        x1, y1 = hit.x, hit.y
    else:
        reach_m = (ping.distance_cm if ping.distance_cm is not None else 400) / 100.0
        x1, y1 = x0 + reach_m * math.cos(ping.angle), y0 + reach_m * math.sin(ping.angle)
    return {"t": round(ping.time_s, 3), "x0": round(x0, 4), "y0": round(y0, 4),
            "x1": round(x1, 4), "y1": round(y1, 4), "cm": ping.distance_cm}
