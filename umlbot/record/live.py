"""`umlbot sim --foxglove`: the recording's messages served live to Foxglove, with a 3D scene.

`FoxgloveLive` is a recorder sink: a foxglove-sdk WebSocket server (127.0.0.1 by default; the
SDK speaks the subprotocol `foxglove.sdk.v1`) with one channel per recorded topic, carrying the
same CDR bytes and `ros2msg` schemas as the MCAP file, and in the sim a `foxglove.SceneUpdate`
channel `/umlbot/<robot>/sim/scene`: the track's walls, the goal, the car and its sonar beam.
"""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from umlbot.base import rosmsg
from umlbot.base.errors import ConfigError
from umlbot.base.logs import get_logger
from umlbot.record.messages import ros_name

if TYPE_CHECKING:
    from umlbot.sim import World

log = get_logger(__name__)

DEFAULT_HOST = "127.0.0.1"
#: how often the track is sent again (a client that connects later sees it too), wall seconds
TRACK_EVERY_S = 1.0
CAR_HEIGHT_M = 0.08


class FoxgloveLive:
    """A recorder sink serving every message live over Foxglove's WebSocket protocol."""

    def __init__(self, robot: str, port: int = 8765, host: str = DEFAULT_HOST,
                 car: tuple[float, float] = (0.26, 0.16)) -> None:
        self.fox = rosmsg.require("foxglove", "record", "The live Foxglove server")
        self.store = rosmsg.typestore("record")
        self.context = self.fox.Context()
        try:
            self.server = self.fox.start_server(name=f"umlbot {robot}", host=host, port=port,
                                                context=self.context)
        except RuntimeError as exc:  # the SDK's FoxgloveError
            raise ConfigError(f"cannot start the Foxglove server on {host}:{port}: {exc} "
                              "(--foxglove-port 0 picks a free port)") from None
        self.port: int = self.server.port
        self.url = f"ws://{host}:{self.port}"
        self.scene_topic = f"/umlbot/{ros_name(robot)}/sim/scene"
        self.log_topic = f"/umlbot/{ros_name(robot)}/log"
        self._log: Any = None
        self._channels: dict[str, Any] = {}
        self._scene: Any = None
        self._car = car
        self._walls: Any = None
        self._goal: Any = None
        self._walls_sent = -math.inf
        self._beam: tuple[float, float, float, float] | None = None  # x0, y0, angle, metres
        self.closed = False

    # -- the Sink protocol ----------------------------------------------------------------------

    def write_cdr(self, topic: str, msgtype: str, data: bytes | memoryview, stamp_ns: int) -> None:
        channel = self._channels.get(topic)
        if channel is None:
            msgdef, _ = self.store.generate_msgdef(msgtype, ros_version=2)
            schema = self.fox.Schema(name=msgtype, encoding="ros2msg", data=msgdef.encode("utf-8"))
            channel = self.fox.Channel(topic, schema=schema, message_encoding="cdr", context=self.context)
            self._channels[topic] = channel
        channel.log(bytes(data), log_time=stamp_ns)

    def tick(self) -> None:
        """Nothing to flush: the server sends as it goes."""

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self.server.stop()

    def on_trace(self, event: Any) -> None:
        """A trace event (a `umlbot_msgs/msg/TraceEvent`) also as a `foxglove.Log` line, for the
        Log panel: `<lane>/<node> <detail> (<duration> ms)`."""
        m = self.fox.messages
        if self._log is None:
            self._log = self.fox.channels.LogChannel(self.log_topic, context=self.context)
        level = {"warning": m.LogLevel.Warning, "error": m.LogLevel.Error}.get(event.level, m.LogLevel.Info)
        text = f"{event.node} {event.detail} ({event.duration_ms:g} ms)"
        if event.error:
            text += f": {event.error}"
        elif event.value_json:
            text += f" -> {event.value_json}"
        self._log.log(m.Log(timestamp=_timestamp(m, event.end), level=level, message=text, name=event.lane),
                      log_time=_ns(event.end))

    # -- the scene (sim samples, called by the recorder) ----------------------------------------

    def sample(self, item: tuple[Any, ...]) -> None:
        kind = item[0]
        if kind == "track":
            _, _, walls, goal = item
            self._track(walls, goal)
        elif kind == "sonar" and len(item) >= 6:
            _, _, cm, x0, y0, angle = item[:6]
            self._beam = (x0, y0, angle, (cm if cm is not None else 400) / 100.0)
        elif kind == "pose":
            _, at, x, y, heading = item
            self._update(at, x, y, heading)

    def _track(self, walls: list[list[tuple[float, float]]], goal: tuple[float, float, float, float]) -> None:
        m = self.fox.messages
        points = []
        for line in walls:
            for (x0, y0), (x1, y1) in itertools.pairwise(line):
                points += [m.Point3(x=x0, y=y0, z=0.0), m.Point3(x=x1, y=y1, z=0.0)]
        self._walls = m.LinePrimitive(type=m.LinePrimitiveLineType.LineList, thickness=0.02,
                                      points=points, color=m.Color(r=0.2, g=0.2, b=0.25, a=1.0))
        gx, gy, sx, sy = goal
        self._goal = m.CubePrimitive(pose=_pose(m, gx, gy, 0.0, 0.005), size=m.Vector3(x=sx, y=sy, z=0.01),
                                     color=m.Color(r=0.1, g=0.7, b=0.2, a=0.5))

    def _update(self, at: float, x: float, y: float, heading: float) -> None:
        m = self.fox.messages
        if self._scene is None:
            self._scene = self.fox.channels.SceneUpdateChannel(self.scene_topic, context=self.context)
        stamp = _timestamp(m, at)
        length, width = self._car
        entities = [m.SceneEntity(
            timestamp=stamp, frame_id="world", id="car",
            cubes=[m.CubePrimitive(pose=_pose(m, x, y, heading, CAR_HEIGHT_M / 2),
                                   size=m.Vector3(x=length, y=width, z=CAR_HEIGHT_M),
                                   color=m.Color(r=0.9, g=0.4, b=0.1, a=1.0))],
            lines=[self._beam_line(m)] if self._beam is not None else [],
        )]
        now = time.monotonic()
        if self._walls is not None and now - self._walls_sent >= TRACK_EVERY_S:
            self._walls_sent = now
            entities.append(m.SceneEntity(timestamp=stamp, frame_id="world", id="track",
                                          lines=[self._walls], cubes=[self._goal]))
        self._scene.log(m.SceneUpdate(entities=entities), log_time=_ns(at))

    def _beam_line(self, m: Any) -> Any:
        assert self._beam is not None
        x0, y0, angle, reach = self._beam
        end = m.Point3(x=x0 + reach * math.cos(angle), y=y0 + reach * math.sin(angle), z=CAR_HEIGHT_M)
        return m.LinePrimitive(type=m.LinePrimitiveLineType.LineStrip, thickness=0.01,
                               points=[m.Point3(x=x0, y=y0, z=CAR_HEIGHT_M), end],
                               color=m.Color(r=0.1, g=0.5, b=1.0, a=0.8))


def _pose(m: Any, x: float, y: float, heading: float, z: float) -> Any:
    return m.Pose(position=m.Vector3(x=x, y=y, z=z),
                  orientation=m.Quaternion(x=0.0, y=0.0, z=math.sin(heading / 2), w=math.cos(heading / 2)))


def _ns(seconds: float) -> int:
    return max(0, int(seconds * 1e9))


def _timestamp(m: Any, seconds: float) -> Any:
    ns = _ns(seconds)
    return m.Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)


def check_port(port: int, host: str = DEFAULT_HOST) -> None:
    """ConfigError now when the Foxglove server's port is taken (before the run starts)."""
    import socket

    if port == 0:
        return
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((host, port))
        except OSError as exc:
            raise ConfigError(f"cannot start the Foxglove server on {host}:{port}: {exc.strerror or exc} "
                              "(--foxglove-port 0 picks a free port)") from None


def live_sinks(port: int, announce: Callable[[str], None]) -> Callable[[World, str], list[Any]]:
    """The `extra_sinks` factory of `SimRecording` for `--foxglove`: a server per run, announced."""

    def make(world: World, robot: str) -> list[Any]:
        live = FoxgloveLive(robot, port, car=(world.car.length_m, world.car.width_m))
        announce(f"{live.url}  (in Foxglove: Open connection, Foxglove WebSocket, this URL)")
        return [live]

    return make
