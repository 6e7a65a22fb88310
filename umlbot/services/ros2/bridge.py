"""The robot seen from ROS 2: a bridge between the robot's MQTT topics and ROS 2 (DDS).

Published (`/umlbot/<robot>/…`, umlbot's own types from `umlbot.base.rosmsg`, status and state
topics latched: transient local, the last one kept for readers that join later):

| ROS 2 topic | type | from MQTT |
|---|---|---|
| `/umlbot/<robot>/orchestrator/status` | `umlbot_msgs/msg/OrchestratorStatus` | `…/orchestrator/status` |
| `/umlbot/<robot>/orchestrator/trace` | `umlbot_msgs/msg/TraceEvent` | `…/orchestrator/trace` |
| `/umlbot/<robot>/<Component>/status` | `umlbot_msgs/msg/ComponentStatus` | `…/<Component>/status` |
| `/umlbot/<robot>/<Component>/state` | `umlbot_msgs/msg/ComponentState` | `…/<Component>/state` |
| `/umlbot/<robot>/<Component>/range` | `sensor_msgs/msg/Range` | a state with `distance_cm` (sonar) |

Served: the ROS 2 service `/umlbot/<robot>/call` (`umlbot_msgs/srv/CallFeature`): a feature call
over MQTT, its reply as the response (`ok`, `value_json`, `error_code`, `error_message`).
"""

from __future__ import annotations

import json
import math
import threading
import time
from typing import Any

from umlbot.base.errors import BusError, RemoteError
from umlbot.base.logs import get_logger
from umlbot.services.bus import BrokerSettings, BusClient, Message, parse_json, reply_value
from umlbot.services.ros2 import dds
from umlbot.services.ros2.msgtypes import Types

log = get_logger("umlbot.ros2.bridge")

#: what an HC-SR04 measures (SPEC §1): the Range message's limits and beam
SONAR_MIN_M, SONAR_MAX_M, SONAR_FOV_RAD = 0.02, 4.0, math.radians(15)
CALL_SERVICE_TYPE = "umlbot_msgs/srv/CallFeature"
#: how often calls past their time-out are answered
SWEEP_S = 0.05


def _stamp(sample: Any, now: float) -> None:
    sample.sec = int(now)
    sample.nanosec = int((now - int(now)) * 1e9)


#: one encoder made once (`json.dumps` with options makes one per call)
_ENCODE = json.JSONEncoder(separators=(",", ":"), allow_nan=False, default=str).encode


def _json(value: Any) -> str:
    return "" if value is None else _ENCODE(value)


class Ros2Bridge:
    """Publishes one robot's status, states and trace on ROS 2 and serves its features as a ROS 2
    service; `start()`/`stop()` (idempotent), or `with`."""

    def __init__(self, settings: BrokerSettings, robot: str, domain_id: int = 0,
                 call_timeout_s: float = 2.0) -> None:
        dds.require()
        self.robot = robot
        self.domain_id = domain_id
        self.call_timeout_s = call_timeout_s
        self.prefix = f"/umlbot/{robot}"
        self.types = Types.load()
        self.builder = dds.TypeBuilder.of(self.types)
        self.bus = BusClient(settings, robot, role="ros2-bridge")
        self._pubs: dict[str, dds.Publication] = {}
        self._lock = threading.Lock()
        #: request id -> (deadline, ROS 2 request, component, feature) of calls in flight
        self._calls: dict[str, tuple[float, Any, str, str]] = {}
        self._calls_lock = threading.Lock()
        self._stop = threading.Event()
        self._sweeper = threading.Thread(target=self._sweep, name="ros2-bridge-sweeper", daemon=True)
        self._server: dds.ServiceServer | None = None
        self._started = self._stopped = False
        #: messages carried to ROS 2, by kind (status, state, range, trace)
        self.forwarded: dict[str, int] = {}
        topics = self.bus.topics
        self.bus.connection.subscribe(topics.orchestrator_status, self._on_orchestrator_status)
        self.bus.connection.subscribe(topics.orchestrator_trace, self._on_trace)
        self.bus.connection.subscribe(f"{topics.base}/+/status", self._on_component_status)
        self.bus.connection.subscribe(f"{topics.base}/+/state", self._on_component_state)

    # -- lifecycle ----------------------------------------------------------------------------------

    def start(self, timeout: float = 5.0) -> None:
        with self._lock:
            if self._started:
                return
            self._started = True
        self.bus.start(timeout)
        self._server = dds.ServiceServer(self.builder, self.domain_id, f"{self.prefix}/call",
                                         CALL_SERVICE_TYPE, self._call)
        self._sweeper.start()
        log.info("ros2_bridge_started", robot=self.robot, domain_id=self.domain_id,
                 call_service=f"{self.prefix}/call")

    def stop(self) -> None:
        with self._lock:
            if self._stopped:
                return
            self._stopped = True
        self._stop.set()
        if self._server is not None:
            self._server.close()
        self.bus.close()
        if self._sweeper.is_alive():
            self._sweeper.join(timeout=2.0)
        for pub in self._pubs.values():
            pub.close()
        log.info("ros2_bridge_stopped", robot=self.robot)

    def __enter__(self) -> Ros2Bridge:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    # -- MQTT -> ROS 2 ------------------------------------------------------------------------------

    def _pub(self, topic: str, typename: str, latched: bool) -> dds.Publication:
        with self._lock:
            pub = self._pubs.get(topic)
            if pub is None:
                pub = self._pubs[topic] = dds.Publication(self.builder, self.domain_id, topic, typename,
                                                          latched=latched)
            return pub

    def _send(self, kind: str, topic: str, typename: str, fields: dict[str, Any], latched: bool) -> None:
        pub = self._pub(topic, typename, latched)
        sample = pub.sample()
        stamp = sample.header.stamp if hasattr(sample, "header") else getattr(sample, "stamp", None)
        if stamp is not None:
            _stamp(stamp, time.time())
        for name, value in fields.items():
            dds.set_path(sample, name, value)
        pub.write(sample)
        self.forwarded[kind] = self.forwarded.get(kind, 0) + 1

    @staticmethod
    def _data(message: Message) -> Any:
        if not message.payload.strip():
            return None
        try:
            return parse_json(message.payload)
        except ValueError:
            return message.payload.decode("utf-8", "replace").strip()

    def _on_orchestrator_status(self, message: Message) -> None:
        data = self._data(message)
        if data is None:
            return
        status = data if isinstance(data, dict) else {"state": str(data)}
        timeout = status.get("call_timeout_s")
        self._send("status", f"{self.prefix}/orchestrator/status", "umlbot_msgs/msg/OrchestratorStatus", {
            "state": str(status.get("state", "")), "reason": str(status.get("reason") or ""),
            "model": str(status.get("model") or ""),
            "call_timeout_s": float(timeout) if isinstance(timeout, int | float) else 0.0,
            "status_json": _json(status)}, latched=True)

    def _on_trace(self, message: Message) -> None:
        data = self._data(message)
        events = data if isinstance(data, list) else [data]
        for event in events:
            if not isinstance(event, dict):
                continue
            try:
                fields = {
                    "seq": int(event.get("seq") or 0), "lane": str(event.get("lane", "")),
                    "node": str(event.get("node", "")), "kind": str(event.get("kind", "")),
                    "start": float(event.get("start", 0.0)), "end": float(event.get("end", 0.0)),
                    "duration_ms": float(event.get("duration_ms", 0.0)),
                    "value_json": _json(event.get("value")), "level": str(event.get("level", "info")),
                    "error": str(event.get("error") or ""), "detail": str(event.get("detail") or "")}
            except (TypeError, ValueError):
                log.debug("ros2_bridge_trace_unreadable", size=len(message.payload))
                continue
            self._send("trace", f"{self.prefix}/orchestrator/trace", "umlbot_msgs/msg/TraceEvent", fields,
                       latched=False)

    def _component(self, message: Message) -> str:
        return message.topic.split("/")[-2]

    def _on_component_status(self, message: Message) -> None:
        component = self._component(message)
        if component == "orchestrator":
            return
        data = self._data(message)
        if data is None:
            return
        status = data if isinstance(data, dict) else {"state": str(data)}
        features = status.get("features")
        self._send("status", f"{self.prefix}/{component}/status", "umlbot_msgs/msg/ComponentStatus", {
            "component": component, "state": str(status.get("state", "")),
            "impl": str(status.get("impl") or ""), "driver": str(status.get("driver") or ""),
            "features": [str(f) for f in features] if isinstance(features, list) else [],
            "status_json": _json(status)}, latched=True)

    def _on_component_state(self, message: Message) -> None:
        component = self._component(message)
        data = self._data(message)
        if data is None or component == "orchestrator":
            return
        self._send("state", f"{self.prefix}/{component}/state", "umlbot_msgs/msg/ComponentState",
                   {"component": component, "state_json": _json(data)}, latched=True)
        distance = data.get("distance_cm") if isinstance(data, dict) else None
        if isinstance(distance, int | float) and not isinstance(distance, bool):
            echo = data.get("echo", True)
            self._send("range", f"{self.prefix}/{component}/range", "sensor_msgs/msg/Range", {
                "header.frame_id": component, "radiation_type": 0, "field_of_view": SONAR_FOV_RAD,
                "min_range": SONAR_MIN_M, "max_range": SONAR_MAX_M,
                # REP 117: nothing in range is +inf
                "range": float(distance) / 100.0 if echo is not False else math.inf}, latched=False)

    # -- ROS 2 -> MQTT ------------------------------------------------------------------------------

    def _call(self, request: Any) -> Any:
        """A request on `/umlbot/<robot>/call` (on DDS's listener thread): the MQTT call goes out
        from this thread at once and is answered from the reply's callback on the connection's
        network thread (or by the sweeper at its time-out); no thread waits for it and nothing
        is queued between the two."""
        try:
            args = json.loads(request.args_json) if request.args_json.strip() else []
            if not isinstance(args, list):
                args = [args]
            timeout = request.timeout_s if request.timeout_s > 0 else self.call_timeout_s
            component, feature = str(request.component), str(request.feature)
        except ValueError as exc:
            return self._response(request, "bad_request", str(exc))
        # noted before it leaves: the reply may come before this thread runs again
        request_id = self.bus.new_request_id()
        with self._calls_lock:
            self._calls[request_id] = (time.monotonic() + timeout, request, component, feature)
        try:
            self.bus.request_then(component, feature, *args, timeout=timeout, then=self._answered,
                                  request_id=request_id)
        except (BusError, ValueError) as exc:
            with self._calls_lock:
                self._calls.pop(request_id, None)
            return self._response(request, "bad_request", str(exc))
        return None

    def _response(self, request: Any, code: str = "", message: str = "", value: Any = None) -> Any:
        assert self._server is not None
        if code:
            return self._server.response_of(request, error_code=code, error_message=message)
        return self._server.response_of(request, ok=True, value_json=_json(value))

    def _respond(self, request_id: str, request: Any, response: Any) -> None:
        if self._server is not None:
            try:
                self._server.respond(request, response)
            except Exception:  # DDS shutting down
                log.debug("ros2_bridge_respond_failed", request_id=request_id)

    def _answered(self, request_id: str, reply: dict[str, Any] | None, error: BaseException | None) -> None:
        """The MQTT reply came (on the network thread: only a DDS write here), or the connection
        was lost (`error`). Whoever takes the call out of `_calls` first answers it: this or the
        sweeper."""
        with self._calls_lock:
            entry = self._calls.pop(request_id, None)
        if entry is None:
            return
        _, request, component, feature = entry
        if reply is None:  # NotConnected: the broker went away
            response = self._response(request, "not_connected", str(error))
        else:
            try:
                response = self._response(request, value=reply_value(reply, component, feature))
            except RemoteError as exc:
                response = self._response(request, exc.code, exc.message)
        self._respond(request_id, request, response)

    def _sweep(self) -> None:
        """Answer the calls whose time-out passed without a reply."""
        while not self._stop.wait(SWEEP_S):
            now = time.monotonic()
            with self._calls_lock:
                late = [(rid, self._calls.pop(rid)) for rid, entry in list(self._calls.items())
                        if entry[0] <= now]
            for request_id, (_, request, component, feature) in late:
                self.bus.forget(request_id)
                self._respond(request_id, request, self._response(
                    request, "timeout", f"no reply from {component}.{feature} within the call's time-out"))
