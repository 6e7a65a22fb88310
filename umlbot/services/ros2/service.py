"""The `ros2` service kind: each feature of a ROS 2 component reads a topic, publishes on one or
calls a ROS 2 service (`umlbot.services.ros2.mapping`).

What a read answers (`ros2_range`'s `value()` and every generic `read`):

- the latest message's field (times `scale`; `returns: int` rounds): a range in metres becomes
  centimetres. A `sensor_msgs/msg/Range` of +inf (REP 117: nothing in range) answers its
  `max_range`, -inf (too close) its `min_range`;
- no message yet: it waits up to `first_s` (default 2 s) for one, then replies the error
  `no_reading`;
- a message older than `stale_s` (default 1 s): the error `stale`, with its age; a NaN: the
  error `bad_reading`. The orchestrator treats an error reply like any failed call.

A publish returns once the message is written (DDS delivers it to every matched reader; no
reader is not an error). A service call waits `timeout_s` for a server and its reply: no server
or no reply is the error `timeout`.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

from umlbot.base.errors import ConfigError, UmlbotError
from umlbot.base.library import Implementation
from umlbot.services.bus import Feature, FeatureError
from umlbot.services.component_service import ComponentService
from umlbot.services.ros2 import dds
from umlbot.services.ros2.driver import Ros2Node
from umlbot.services.ros2.mapping import FeatureMap, SignalMap, TopicWrite, preset, scaled
from umlbot.services.ros2.msgtypes import BASE_TYPES

#: in the sim: how long a publish waits for the world's acknowledgement, a read for a new reading
CONFIRM_S = 2.0


class Ros2Service(ComponentService):
    """One ROS 2 component on the bus."""

    kind = "ros2"

    def __init__(self, component: str, impl: Implementation, driver: Any,
                 settings: Mapping[str, Any] | None = None) -> None:
        node: Ros2Node = driver
        try:
            self.maps: dict[str, FeatureMap] = preset(impl.id, node.settings)
        except ValueError as exc:
            raise ConfigError(f"{component}: {exc}") from None
        # the handlers depend on the settings: this instance's, read by the base class's check
        self.__dict__["handlers"] = {name: name for name in self.maps}
        super().__init__(component, impl, driver, settings)
        self.node = node
        self._state: dict[str, Any] = {}
        self._calls: dict[str, Callable[..., Any]] = {}
        #: signal name -> its ROS 2 writer (`to_ros`): `matched()` says how many readers it found
        self.signal_writers: dict[str, dds.Publication] = {}
        for name, fmap in sorted(self.maps.items()):
            self._calls[name] = self._open(name, fmap)

    def _open(self, name: str, fmap: FeatureMap) -> Callable[..., Any]:
        if fmap.read is not None:
            read = fmap.read
            sub = self.node.subscribe(read)
            is_range = self.impl.id == "ros2_range"

            def do_read() -> Any:
                last = sub.last
                if self.node.confirm:  # the sim: a reading taken after the call began
                    last = sub.wait(max(read.first_s, CONFIRM_S), after=last.count)
                elif last.count == 0:
                    last = sub.wait(read.first_s)
                if last.count == 0:
                    bad = f" ({last.bad} sample(s) could not be read: {last.error})" if last.bad else ""
                    raise FeatureError("no_reading", f"no {read.type} on {read.topic} yet (waited "
                                       f"{read.first_s:g} s){bad}")
                age = time.monotonic() - last.at
                if age > read.stale_s:
                    raise FeatureError("stale", f"the last {read.type} on {read.topic} is {age:.2f} s old "
                                       f"(stale after {read.stale_s:g} s)")
                value = dds.get_path(last.sample, read.field)
                if isinstance(value, float) and math.isinf(value) and is_range:
                    value = last.sample.max_range if value > 0 else last.sample.min_range
                if isinstance(value, float) and not math.isfinite(value):
                    raise FeatureError("bad_reading", f"{read.field} of the last {read.type} on "
                                       f"{read.topic} is {value}")
                result = scaled(value, read.scale, fmap.returns)
                self._record(name, result)
                return result

            return do_read
        if fmap.publish is not None:
            write = fmap.publish
            pub = self.node.publisher(write)
            params = [p.name for p in fmap.params]

            def do_publish(*args: Any) -> None:
                sample = pub.sample()
                for path, value in write.constants.items():
                    dds.set_path(sample, path, value)
                by_name = dict(zip(params, args, strict=True))
                for path, param in write.fields.items():
                    dds.set_path(sample, path, by_name[param])
                if not pub.write(sample, CONFIRM_S if self.node.confirm else 0.0):
                    self.log.warning("ros2_publish_unconfirmed", topic=write.topic, readers=pub.matched())
                self._record(name, by_name or None)

            return do_publish
        call = fmap.call
        assert call is not None
        client = self.node.client(call)
        params = [p.name for p in fmap.params]
        lock = threading.Lock()  # one call at a time per feature: replies come in order

        def do_call(*args: Any) -> Any:
            request = client.request()
            for path, value in call.constants.items():
                dds.set_path(request, path, value)
            by_name = dict(zip(params, args, strict=True))
            for path, param in call.fields.items():
                dds.set_path(request, path, by_name[param])
            with lock:
                try:
                    reply = client.call(request, call.timeout_s)
                except dds.ServiceTimeout as exc:
                    raise FeatureError("timeout", str(exc)) from None
            result = None if call.reply is None else dds.get_path(reply, call.reply)
            message = getattr(reply, "message", None)
            self._record(name, result, **({"message": message} if isinstance(message, str) else {}))
            return result

        return do_call

    # -- signals ----------------------------------------------------------------------------------

    def on_server(self, server: Any) -> None:
        """Carry the mapped signals between `…/signal/<name>` and their ROS 2 topics."""
        for name, signal in sorted(self.node.settings.signals.items()):
            topic = server.topics.signal(name)
            if signal.direction == "to_ros":
                pub = self.node.publisher(TopicWrite(topic=signal.topic, type=signal.type))
                self.signal_writers[name] = pub
                server.connection.subscribe(topic, self._to_ros(name, signal, pub))
            else:
                self.node.subscribe_signal(signal, self._from_ros(name, signal, server, topic))

    def _to_ros(self, name: str, signal: SignalMap, pub: dds.Publication) -> Callable[[Any], None]:
        types = self.node.types

        def forward(message: Any) -> None:
            if message.retain:  # an old occurrence: signals are live traffic only
                return
            try:
                payload = json.loads(message.payload) if message.payload.strip() else None
                sample = pub.sample()
                pairs = ([(signal.field, payload)] if signal.field is not None else
                         [(path, _key(payload, key)) for path, key in signal.fields.items()])
                for path, value in pairs:
                    found = types.scalar_field(signal.type, path)
                    dds.set_path(sample, path, _as_field(value, found.base or "string", path))
                pub.write(sample)
                self.log.debug("ros2_signal_sent", signal=name, topic=signal.topic, readers=pub.matched())
            except (ValueError, TypeError) as exc:
                self.log.warning("ros2_signal_refused", signal=name, topic=signal.topic, error=str(exc),
                                 payload=message.payload[:80].decode("utf-8", "replace"))

        return forward

    def _from_ros(self, name: str, signal: SignalMap, server: Any, topic: str) -> Callable[[Any], None]:
        def forward(sample: Any) -> None:
            if signal.field is not None:
                payload = dds.get_path(sample, signal.field)
            elif signal.fields:
                payload = {key: dds.get_path(sample, path) for path, key in signal.fields.items()}
            else:
                payload = None
            try:
                server.connection.publish(topic, json.dumps(payload), qos=1)
            except (UmlbotError, ValueError) as exc:  # no broker now, or NaN: the occurrence is lost
                self.log.warning("ros2_signal_lost", signal=name, error=str(exc))

        return forward

    def _record(self, feature: str, value: Any, **more: Any) -> None:
        with self.lock:
            self._state[feature] = {"value": value, **more}
        self.changed()

    def features(self) -> list[Feature]:
        return [Feature(fmap.spec(name), self._guarded(self._calls[name]))
                for name, fmap in sorted(self.maps.items())]

    def state(self) -> dict[str, Any]:
        with self.lock:
            return dict(self._state)

    def safe_stop(self, reason: str) -> None:
        """A component with a `stop` feature that publishes (a `ros2_twist` base) publishes it."""
        stop = self.maps.get("stop")
        if stop is not None and stop.publish is not None and not stop.params and not self.node.closed:
            self._calls["stop"]()
            self.log.info("safe_stop", reason=reason)


def _key(payload: Any, key: str) -> Any:
    if not isinstance(payload, dict) or key not in payload:
        raise ValueError(f"the payload has no key {key!r}")
    return payload[key]


def _as_field(value: Any, base: str, path: str) -> Any:
    """A JSON value as a field of ROS type `base` takes it; ValueError when it does not fit."""
    kind, low, high = BASE_TYPES[base]
    if kind == "float" and isinstance(value, int | float) and not isinstance(value, bool):
        value = float(value)
    ok = {"bool": isinstance(value, bool), "str": isinstance(value, str),
          "int": isinstance(value, int) and not isinstance(value, bool),
          "float": isinstance(value, float)}[kind]
    if not ok or (low is not None and value < low) or (high is not None and value > high):
        raise ValueError(f"{value!r} does not fit field {path!r} ({base})")
    return value
