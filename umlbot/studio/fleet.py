"""The studio's fleet view: every robot seen on a broker (a fleet hub), for `umlbot studio --fleet`.

`FleetWatch` reads `umlbot/+/#` read-only (a `LiveMonitor` of every robot) and keeps one row per
robot: its orchestrator's state and reason, the node each lane runs, its faults (a failed run, a
node that ended in an error, a component offline) and its components' availability. The page
polls `GET /api/fleet` (the rows and whether the hub is reachable) and follows a robot with
`POST /api/fleet/follow {"robot": id}`: the studio's live view switches to that robot.
"""

from __future__ import annotations

import asyncio
import json
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from aiohttp import web

from umlbot.base.errors import ConfigError

if TYPE_CHECKING:
    from umlbot.monitor import MonitorEvent
    from umlbot.services.bus import BrokerSettings
    from umlbot.studio.server import StudioServer

#: rows kept at most (a hub of a thousand robots still answers in one small frame per second)
MAX_ROBOTS = 2000
#: faults kept per robot (the newest)
MAX_FAULTS = 5


@dataclass
class RobotRow:
    """What the fleet view shows of one robot."""

    robot: str
    seen: float = 0.0
    orchestrator: str = "unknown"
    reason: str | None = None
    #: lane -> the node it runs (the newest trace event of the lane)
    nodes: dict[str, str] = field(default_factory=dict)
    components: dict[str, str] = field(default_factory=dict)
    faults: list[str] = field(default_factory=list)

    def fault(self, text: str) -> None:
        if text not in self.faults:
            self.faults = [*self.faults, text][-MAX_FAULTS:]

    def view(self, now: float) -> dict[str, Any]:
        offline = sorted(name for name, state in self.components.items() if state != "online")
        faults = list(self.faults) + [f"{name} {self.components[name]}" for name in offline]
        return {"robot": self.robot, "orchestrator": self.orchestrator, "reason": self.reason,
                "nodes": dict(sorted(self.nodes.items())),
                "components": dict(sorted(self.components.items())),
                "faults": faults, "age_s": round(max(0.0, now - self.seen), 1)}


class FleetWatch:
    """The robots on one broker, from its traffic (thread-safe: the bus thread writes, the page's
    requests read)."""

    def __init__(self, settings: BrokerSettings, url: str,
                 follow: Callable[[str], None] | None = None) -> None:
        from umlbot.monitor import LiveMonitor, MonitorState

        self.url = url
        self.follow_robot = follow
        self.followed: str | None = None
        self._lock = threading.Lock()
        self._rows: dict[str, RobotRow] = {}
        self.monitor = LiveMonitor(settings, "*", self._on_event, MonitorState())

    def start(self) -> None:
        self.monitor.start(timeout=None)  # keeps trying: the page says the hub is unreachable

    def close(self) -> None:
        self.monitor.close()

    def _on_event(self, event: MonitorEvent) -> None:
        with self._lock:
            row = self._rows.get(event.robot)
            if row is None:
                if len(self._rows) >= MAX_ROBOTS:
                    return
                row = self._rows[event.robot] = RobotRow(event.robot)
            row.seen = time.time()  # a trace event's own time is the robot's (sim) clock
            if event.type == "orchestrator":
                row.orchestrator = event.state or "unknown"
                row.reason = event.detail
                if row.orchestrator == "failed":
                    row.fault(f"run failed: {event.detail or 'no reason given'}")
                elif row.orchestrator in ("starting", "running"):
                    row.faults = []  # a new run: the old run's faults are history
            elif event.type == "availability" and event.component:
                row.components[event.component] = event.state or "unknown"
            elif event.type == "trace" and event.lane:
                row.nodes[event.lane] = event.node or ""
                if event.error:
                    row.fault(f"{event.lane}/{event.node}: {event.error}")

    def snapshot(self, now: float | None = None) -> dict[str, Any]:
        now = time.time() if now is None else now
        with self._lock:
            rows = [row.view(now) for _, row in sorted(self._rows.items())]
        return {"hub": {"url": self.url, **self.monitor.broker_status(now)}, "robots": rows,
                "followed": self.followed}

    def routes(self, app: web.Application, server: StudioServer) -> None:
        """`GET /api/fleet` and `POST /api/fleet/follow` on the studio's app."""

        async def rows(request: web.Request) -> web.StreamResponse:
            server.check_origin(request)
            return web.json_response(self.snapshot(), headers={"Cache-Control": "no-store"})

        async def follow(request: web.Request) -> web.StreamResponse:
            server.check_origin(request)
            try:
                body = json.loads(await request.text())
            except ValueError:
                raise web.HTTPBadRequest(text="the body is not JSON") from None
            robot = body.get("robot") if isinstance(body, dict) else None
            if not isinstance(robot, str) or self.follow_robot is None:
                raise web.HTTPBadRequest(text='give {"robot": "<id>"}')
            try:
                await asyncio.get_running_loop().run_in_executor(None, self.follow_robot, robot)
            except ConfigError as exc:
                raise web.HTTPBadRequest(text=str(exc)) from exc
            self.followed = robot
            return web.json_response({"followed": robot})

        app.router.add_get("/api/fleet", rows)
        app.router.add_post("/api/fleet/follow", follow)
