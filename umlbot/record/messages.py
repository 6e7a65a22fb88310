"""What a recording holds: umlbot's traffic and the simulated world as ROS 2 messages.

`Topics` names the recording's topics (ROS 2 names under `/umlbot/<robot>/`); the `*_message`
functions turn one payload of SPEC §3 (or one sample of the sim) into a message of the typestore
(`umlbot.base.rosmsg.typestore()`): umlbot's own `umlbot_msgs` types, and the standard ones where
one fits (`geometry_msgs/msg/PoseStamped`, `sensor_msgs/msg/Range`, `sensor_msgs/msg/JointState`,
`visualization_msgs/msg/MarkerArray`). Wire values are untrusted: a field of the wrong type is
recorded as empty, never raised on.
"""

from __future__ import annotations

import itertools
import json
import math
import re
from dataclasses import dataclass
from typing import Any, Final

from umlbot.services.bus import dumps

TRACE: Final = "umlbot_msgs/msg/TraceEvent"
CALL: Final = "umlbot_msgs/msg/FeatureCall"
STATUS: Final = "umlbot_msgs/msg/ComponentStatus"
STATE: Final = "umlbot_msgs/msg/ComponentState"
ORCHESTRATOR: Final = "umlbot_msgs/msg/OrchestratorStatus"
SIGNAL: Final = "umlbot_msgs/msg/Signal"
POSE: Final = "geometry_msgs/msg/PoseStamped"
RANGE: Final = "sensor_msgs/msg/Range"
JOINTS: Final = "sensor_msgs/msg/JointState"
MARKERS: Final = "visualization_msgs/msg/MarkerArray"

#: the frame the sim's track, pose and markers are given in (x, y in metres, z up).
WORLD_FRAME: Final = "world"
SONAR_FRAME: Final = "sonar"
SONAR_FIELD_OF_VIEW_RAD: Final = math.radians(15.0)
SONAR_MIN_M: Final = 0.02
SONAR_MAX_M: Final = 4.0

_NOT_ROS = re.compile(r"[^A-Za-z0-9_]")


def ros_name(name: str) -> str:
    """`name` as one level of a ROS 2 topic name (letters, digits, '_'; not starting with a digit)."""
    cleaned = _NOT_ROS.sub("_", name) or "_"
    return f"_{cleaned}" if cleaned[0].isdigit() else cleaned


@dataclass(frozen=True)
class Topics:
    """The recording's topic names for one robot."""

    robot: str

    @property
    def base(self) -> str:
        return f"/umlbot/{ros_name(self.robot)}"

    @property
    def trace(self) -> str:
        return f"{self.base}/orchestrator/trace"

    @property
    def orchestrator(self) -> str:
        return f"{self.base}/orchestrator/status"

    @property
    def calls(self) -> str:
        return f"{self.base}/calls"

    @property
    def signals(self) -> str:
        return f"{self.base}/signals"

    def status(self, component: str) -> str:
        return f"{self.base}/{ros_name(component)}/status"

    def state(self, component: str) -> str:
        return f"{self.base}/{ros_name(component)}/state"

    @property
    def pose(self) -> str:
        return f"{self.base}/sim/pose"

    @property
    def sonar(self) -> str:
        return f"{self.base}/sim/sonar"

    @property
    def motors(self) -> str:
        return f"{self.base}/sim/motors"

    @property
    def track(self) -> str:
        return f"{self.base}/sim/track"


def to_ns(seconds: float) -> int:
    """Seconds (unix or sim) as integer nanoseconds, clamped to the range a stamp can hold."""
    if not math.isfinite(seconds) or seconds <= 0:
        return 0
    return min(round(seconds * 1e9), 2**63 - 1)


def json_text(value: Any) -> str:
    """A wire value as JSON text; "" for None (no value)."""
    if value is None:
        return ""
    try:
        return dumps(value)
    except (TypeError, ValueError):
        return json.dumps(repr(value))


def _text(value: Any) -> str:
    if value is None:
        return ""
    return value if isinstance(value, str) else json_text(value)


def _number(value: Any, default: float = 0.0) -> float:
    if isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return default


class Builder:
    """Makes the messages of one typestore."""

    def __init__(self, store: Any) -> None:
        self.store = store
        self.types = store.types

    def _new(self, msgtype: str, **fields: Any) -> Any:
        return self.types[msgtype](**fields)

    def stamp(self, seconds: float) -> Any:
        ns = to_ns(seconds)
        return self._new("builtin_interfaces/msg/Time", sec=min(ns // 1_000_000_000, 2**31 - 1),
                         nanosec=ns % 1_000_000_000)

    def header(self, seconds: float, frame: str) -> Any:
        return self._new("std_msgs/msg/Header", stamp=self.stamp(seconds), frame_id=frame)

    def trace(self, event: dict[str, Any]) -> Any:
        """A `TraceEvent` object (the wire's JSON, or the orchestrator's listener dict)."""
        end = _number(event.get("end"))
        seq = event.get("seq")
        return self._new(
            TRACE, stamp=self.stamp(end), seq=seq if isinstance(seq, int) and 0 <= seq < 2**64 else 0,
            lane=_text(event.get("lane")), node=_text(event.get("node")), kind=_text(event.get("kind")),
            start=_number(event.get("start")), end=end, duration_ms=_number(event.get("duration_ms")),
            value_json=json_text(event.get("value")), level=_text(event.get("level")) or "info",
            error=_text(event.get("error")), detail=_text(event.get("detail")),
        )

    def call(self, at: float, component: str, feature: str, call_id: str | None, args: list[Any] | None,
             ok: bool | None, value: Any, error: str | None, latency_ms: float | None) -> Any:
        """A `FeatureCall`: `at` when it was requested; `latency_ms` None when it had no reply."""
        code, _, message = (error or "").partition(": ")
        answered = latency_ms is not None
        return self._new(
            CALL, stamp=self.stamp(at), component=component, feature=feature, id=call_id or "",
            args_json=json_text(args if args is not None else []), answered=answered,
            ok=bool(ok) and answered, value_json=json_text(value) if ok else "",
            error_code=code if error else "", error_message=message if message else (error or ""),
            latency_ms=float(latency_ms) if latency_ms is not None else -1.0,
        )

    def status(self, at: float, component: str, data: Any) -> Any:
        fields = data if isinstance(data, dict) else {}
        features = fields.get("features")
        return self._new(
            STATUS, stamp=self.stamp(at), component=component,
            state=_text(fields.get("state")) or ("" if isinstance(data, dict) else _text(data)),
            impl=_text(fields.get("impl")), driver=_text(fields.get("driver")),
            features=[str(f) for f in features] if isinstance(features, list) else [],
            status_json=json_text(data),
        )

    def state(self, at: float, component: str, data: Any) -> Any:
        return self._new(STATE, stamp=self.stamp(at), component=component, state_json=json_text(data))

    def orchestrator(self, at: float, data: Any) -> Any:
        fields = data if isinstance(data, dict) else {}
        return self._new(
            ORCHESTRATOR, stamp=self.stamp(at),
            state=_text(fields.get("state")) or ("" if isinstance(data, dict) else _text(data)),
            reason=_text(fields.get("reason")), model=_text(fields.get("model")),
            call_timeout_s=_number(fields.get("call_timeout_s")), status_json=json_text(data),
        )

    def signal(self, at: float, name: str, payload: Any) -> Any:
        return self._new(SIGNAL, stamp=self.stamp(at), name=name, payload_json=json_text(payload))

    def _pose(self, x: float, y: float, heading: float) -> Any:
        return self._new(
            "geometry_msgs/msg/Pose",
            position=self._new("geometry_msgs/msg/Point", x=x, y=y, z=0.0),
            orientation=self._new("geometry_msgs/msg/Quaternion", x=0.0, y=0.0,
                                  z=math.sin(heading / 2.0), w=math.cos(heading / 2.0)),
        )

    def pose(self, at: float, x: float, y: float, heading: float) -> Any:
        """The car's pose on the track (metres, heading in radians from +x)."""
        return self._new(POSE, header=self.header(at, WORLD_FRAME), pose=self._pose(x, y, heading))

    def sonar(self, at: float, distance_cm: int | None) -> Any:
        """One HC-SR04 ping; no echo is +inf (REP 117: nothing within range)."""
        reading = math.inf if distance_cm is None else distance_cm / 100.0
        return self._new(RANGE, header=self.header(at, SONAR_FRAME), radiation_type=0,
                         field_of_view=SONAR_FIELD_OF_VIEW_RAD, min_range=SONAR_MIN_M,
                         max_range=SONAR_MAX_M, range=reading)

    def motors(self, at: float, duty: tuple[float, float], speed_mps: tuple[float, float]) -> Any:
        """The two motor sides: `effort` the signed duty cycle (%), `velocity` the speed (m/s)."""
        return self._new(JOINTS, header=self.header(at, WORLD_FRAME), name=["left", "right"],
                         position=_float64([]), velocity=_float64(speed_mps), effort=_float64(duty))

    def track(self, at: float, walls: list[list[tuple[float, float]]],
              goal: tuple[float, float, float, float] | None) -> Any:
        """The track's walls (one LINE_LIST marker) and its goal region (a flat box: centre x, y and
        size x, y in metres)."""
        points = []
        for line in walls:
            for (x0, y0), (x1, y1) in itertools.pairwise(line):
                points += [self._new("geometry_msgs/msg/Point", x=x0, y=y0, z=0.0),
                           self._new("geometry_msgs/msg/Point", x=x1, y=y1, z=0.0)]
        markers = [self._marker(at, "walls", 0, 5, self._pose(0.0, 0.0, 0.0), (0.02, 0.0, 0.0),
                                (0.2, 0.2, 0.25), points)]
        if goal is not None:
            gx, gy, size_x, size_y = goal
            markers.append(self._marker(at, "goal", 1, 1, self._pose(gx, gy, 0.0),
                                        (size_x, size_y, 0.01), (0.1, 0.7, 0.2), []))
        return self._new(MARKERS, markers=markers)

    def _marker(self, at: float, ns: str, marker_id: int, kind: int, pose: Any,
                scale: tuple[float, float, float], rgb: tuple[float, float, float], points: list[Any]) -> Any:
        r, g, b = rgb
        return self._new(
            "visualization_msgs/msg/Marker", header=self.header(at, WORLD_FRAME), ns=ns, id=marker_id,
            type=kind, action=0, pose=pose,
            scale=self._new("geometry_msgs/msg/Vector3", x=scale[0], y=scale[1], z=scale[2]),
            color=self._new("std_msgs/msg/ColorRGBA", r=r, g=g, b=b, a=1.0),
            lifetime=self._new("builtin_interfaces/msg/Duration", sec=0, nanosec=0), frame_locked=False,
            points=points, colors=[], texture_resource="",
            texture=self._new("sensor_msgs/msg/CompressedImage", header=self.header(at, ""), format="",
                              data=_uint8([])),
            uv_coordinates=[], text="", mesh_resource="",
            mesh_file=self._new("visualization_msgs/msg/MeshFile", filename="", data=_uint8([])),
            mesh_use_embedded_materials=False,
        )


def _uint8(values: list[int]) -> Any:
    import numpy  # rosbags' arrays of numbers are numpy arrays (numpy comes with rosbags)

    return numpy.array(values, dtype=numpy.uint8)


def _float64(values: Any) -> Any:
    import numpy

    return numpy.array(list(values), dtype=numpy.float64)
