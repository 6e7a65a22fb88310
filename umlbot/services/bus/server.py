"""The server side of the bus: one component's features, answered over MQTT.

A `ComponentServer` owns its own connection (MQTT allows one last will per connection, and the
will is what marks this component `offline`). It validates every request against the feature's
`FeatureSpec` (count, types, ranges) before the handler sees it, answers with a `Reply`, and
keeps serving whatever arrives: every bad input gets an error reply with a stable code and a log
line. Handlers run on the connection's dispatcher thread, one at a time, in arrival order.
"""

from __future__ import annotations

import contextlib
import contextvars
import json
import os
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final

from pydantic import ValidationError

from umlbot.base.errors import ArgumentError, BusError, DriverError, NotConnected, UmlbotError
from umlbot.base.library import FeatureSpec, check_args
from umlbot.base.logs import get_logger
from umlbot.base.topics import Topics, check_name, is_valid_publish_topic
from umlbot.services.bus.connection import BusConnection, Message, Will
from umlbot.services.bus.envelopes import (
    ENVELOPE_KEYS,
    CallRequest,
    Reply,
    Status,
    dumps,
    is_timeout,
    parse_json,
    to_payload,
)
from umlbot.services.bus.settings import BrokerSettings

log = get_logger(__name__)

#: requests larger than this are refused with `payload_too_large`.
MAX_REQUEST_BYTES = 256 * 1024
#: how much of an oversize request is read to find its id and reply_to.
SALVAGE_HEAD_BYTES = 4096
#: the status payload of a component that is gone (last will, and on a clean stop).
OFFLINE: Final[dict[str, str]] = {"state": "offline"}
#: how long a starting server waits for the retained status of its component (another server's?).
STATUS_WAIT_S = 1.0
#: how long it waits for the answer of the server that status names, before calling it stale.
ALIVE_WAIT_S = 1.0
#: the feature name of the liveness probe: every server answers it (ok, its instance), unlogged.
ALIVE_PROBE: Final = "_alive"
#: a status on our topic that we did not publish is logged at most once in this many seconds.
FOREIGN_STATUS_WARN_EVERY_S = 10.0


#: what a starting server sends itself to learn that the broker has sent any retained status.
_SYNC: Final = b"sync"

#: the reply topic of the request whose handler runs (see `caller()`).
_CALLER: contextvars.ContextVar[str | None] = contextvars.ContextVar("umlbot_caller", default=None)


def caller() -> str | None:
    """Who sent the request whose feature handler runs now: its reply topic (`reply_to`, else its
    MQTT 5 Response Topic); None for a fire-and-forget call, and outside a handler.

    The motor service tells the running orchestrator's commands (its reply topic is named in its
    heartbeat) from a direct caller's this way.
    """
    return _CALLER.get()


class ComponentTaken(UmlbotError, RuntimeError):
    """Another live server already serves this component on this robot."""


class FeatureError(UmlbotError):
    """Raised by a feature handler to answer with an error reply of the given code."""

    def __init__(self, code: str, message: str) -> None:
        super().__init__(f"{code}: {message}")
        self.code = code
        self.message = message


@dataclass(frozen=True)
class Feature:
    """A feature served by a component: its spec (arguments, ranges) and its handler.

    The handler receives the validated arguments positionally and returns a JSON-able value.
    """

    spec: FeatureSpec
    handler: Callable[..., Any]

    @property
    def name(self) -> str:
        return self.spec.name


@dataclass
class _Parsed:
    request_id: str | int | None
    reply_to: str | None
    args: list[Any]


class _BadInput(Exception):
    def __init__(self, code: str, message: str, request_id: str | int | None = None,
                 reply_to: str | None = None) -> None:
        super().__init__(message)
        self.code = code
        self.message = message
        self.request_id = request_id
        self.reply_to = reply_to


def _is_id(value: Any) -> bool:
    return isinstance(value, str | int) and not isinstance(value, bool)


def parse_request(payload: bytes, response_topic: str | None = None) -> _Parsed:
    """Turn a request payload into (id, reply_to, args): an envelope or a bare JSON value.

    A JSON object with any of the keys `id`, `reply_to`, `args` is an envelope; any other JSON
    value is the argument list (an array) or the only argument. An empty payload or `null` means
    no arguments.
    """
    if not payload.strip():
        return _Parsed(None, None, [])
    try:
        data = parse_json(payload)
    except ValueError as exc:
        request_id, reply_to = _salvage_envelope(payload)
        raise _BadInput("bad_json", f"payload is not UTF-8 JSON: {exc}", request_id, reply_to) from None
    if isinstance(data, dict) and ENVELOPE_KEYS & data.keys():
        # fast path for the well-formed envelope every umlbot client sends
        request_id, reply_to, args = data.get("id"), data.get("reply_to"), data.get("args", [])
        if (
            data.keys() <= ENVELOPE_KEYS
            and isinstance(args, list)
            and (request_id is None or _is_id(request_id))
            and (reply_to is None or (isinstance(reply_to, str) and is_valid_publish_topic(reply_to)))
            and ("timeout_s" not in data or is_timeout(data["timeout_s"]))
        ):
            return _Parsed(request_id, reply_to, args)
        # find where to answer before validating, so a bad envelope still gets its error reply
        reply_to = data.get("reply_to")
        reply_to = reply_to if isinstance(reply_to, str) and is_valid_publish_topic(reply_to) else None
        raw_id = data.get("id")
        request_id = raw_id if isinstance(raw_id, str | int) and not isinstance(raw_id, bool) else None
        if data.keys() <= ENVELOPE_KEYS and not isinstance(data.get("args", []), list):
            raise _BadInput("bad_args", "args must be a JSON array (the argument list, e.g. [60])",
                            request_id, reply_to)
        try:
            request = CallRequest.model_validate(data)
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(str(p) for p in first["loc"]) or "envelope"
            raise _BadInput("bad_request", f"bad request envelope: {where}: {first['msg']}",
                            request_id, reply_to) from None
        if request.reply_to is not None and not is_valid_publish_topic(request.reply_to):
            raise _BadInput("bad_request", "reply_to must be a topic without wildcards", request_id)
        return _Parsed(request.id, request.reply_to, request.args)
    if data is None:
        return _Parsed(None, None, [])
    return _Parsed(None, None, data if isinstance(data, list) else [data])


class ComponentServer:
    """Serves one component's features on `umlbot/<robot>/<component>/call/<feature>`.

    `start()` connects and publishes the retained status `online` (again after every reconnect);
    the last will sets `{"state":"offline"}`; `stop()` publishes `offline` itself and disconnects.
    A status on its topic that it did not publish (someone else's retained `offline`) is replaced
    with its own at once while it serves (docs/security.md, "Faults and attacks tested").
    The status names an `instance` token, never the client id (which no one else may learn).
    """

    def __init__(
        self,
        settings: BrokerSettings,
        robot: str,
        component: str,
        impl_id: str,
        features: list[Feature],
        *,
        client_id: str | None = None,
        max_request_bytes: int = MAX_REQUEST_BYTES,
        driver: str | None = None,
    ) -> None:
        self.topics = Topics(robot)
        self.component = check_name("component", component)
        self.impl_id = impl_id
        #: the driver the component runs with, said in its status (None: not said)
        self.driver = driver
        self.features = {f.name: f for f in features}
        self.max_request_bytes = max_request_bytes
        self.calls_served = 0
        self.calls_failed = 0
        self._since: float | None = None
        self._status_lock = threading.Lock()
        self._stopping = False
        self._status_topic = self.topics.status(component)
        self._call_prefix = self.topics.calls(component)[:-1]  # ".../call/"
        self._claimed = False  # the component is ours: no other live server (see claim())
        self._retained: dict[str, Any] | None = None  # the last status seen on our status topic
        self._published: bytes | None = None  # the payload of our last `online` status
        self._state_lock = threading.Lock()
        self._state_sent: bytes | None = None  # the last state published, on connection number …
        self._state_connects = 0  # … this (a reconnect publishes it again: the broker may have lost it)
        self._foreign_warned = -FOREIGN_STATUS_WARN_EVERY_S
        #: this server's name in its status and liveness answers (random: not the client id)
        self.instance = os.urandom(8).hex()
        self._status_seen = threading.Event()
        self._synced = threading.Event()  # our own message came back: the retained status is in
        self._alive_answer = threading.Event()
        self.connection = BusConnection(
            settings,
            role=f"service-{component}",
            will=Will(self._status_topic, OFFLINE),
            robot=robot,
            client_id=client_id,
        )
        self._log = log.bind(robot=robot, component=component)

    @property
    def connected(self) -> bool:
        return self.connection.connected

    def start(self, timeout: float | None = 5.0) -> None:
        """Connect, claim the component, subscribe to the calls and publish the status.

        Raises NotConnected on time-out, ComponentTaken when another server serves it.
        """
        self.connect(timeout)
        self.claim(STATUS_WAIT_S, 5.0 if timeout is None else timeout)

    def connect(self, timeout: float | None = 5.0) -> None:
        """Connect and read the component's retained status; no calls are served yet."""
        self._since = time.time()
        self.connection.subscribe(self._status_topic, self._on_status, qos=1)
        self.connection.subscribe(self._alive_reply_topic, self._on_alive_answer, qos=0)
        self.connection.add_on_connect(self._publish_online)
        self.connection.start(timeout)

    def claim(self, status_wait_s: float = STATUS_WAIT_S, timeout: float = 5.0) -> None:
        """Serve the component unless another server does: its retained status names another
        client online that answers the liveness probe (ComponentTaken). A status whose client
        does not answer is stale (a broker that kept it over a restart) and is replaced."""
        # the broker sends a retained status right after the subscription, before it handles a
        # later publish of ours: our own message back on our topic means none is coming
        with contextlib.suppress(BusError):
            self.connection.publish(self._alive_reply_topic, _SYNC, qos=0)
        deadline = time.monotonic() + status_wait_s
        while not (self._status_seen.is_set() or self._synced.is_set()):
            if time.monotonic() >= deadline:
                break
            self._status_seen.wait(0.005)
        other = self._other_client()
        if other is not None:
            self.connection.publish(self.topics.call(self.component, ALIVE_PROBE),
                                    {"id": "alive", "reply_to": self._alive_reply_topic}, qos=0)
            if self._alive_answer.wait(ALIVE_WAIT_S):
                raise ComponentTaken(
                    f"component {self.component} of robot {self.topics.robot!r} is already served by "
                    f"the running instance {other} (its retained status is online and it answers); "
                    "stop that service first, or serve this one under another --robot")
            self._log.warning("stale_status_replaced", other_instance=other)
        self.connection.subscribe(self.topics.calls(self.component), self._on_request, qos=1,
                                  wait_s=timeout)
        with self._status_lock:
            self._claimed = True
        self._publish_online()

    @property
    def _alive_reply_topic(self) -> str:
        return f"{self.topics.base}/{self.component}/_alive/{self.instance}"

    def _other_client(self) -> str | None:
        """The instance of another server that the retained status says is online, else None."""
        status = self._retained
        if status is None or status.get("state") != "online":
            return None
        other = status.get("instance")
        if not isinstance(other, str) or other == self.instance:
            return None
        return other

    def _on_status(self, message: Message) -> None:
        try:
            data = parse_json(message.payload) if message.payload else None
        except ValueError:
            data = None
        self._retained = data if isinstance(data, dict) else None
        self._status_seen.set()
        if message.payload != self._published and self._claimed and not self._stopping:
            # someone else's status on our topic (a retained `offline` would stop runs and block
            # the next start until we restart): ours replaces it at once
            now = time.monotonic()
            if now - self._foreign_warned >= FOREIGN_STATUS_WARN_EVERY_S:
                self._foreign_warned = now
                self._log.warning("foreign_status_replaced",
                                  payload=message.payload[:80].decode("utf-8", "replace"))
            with contextlib.suppress(BusError):
                self._publish_online()

    def _on_alive_answer(self, message: Message) -> None:
        if message.payload == _SYNC:
            self._synced.set()
        else:
            self._alive_answer.set()

    def stop(self) -> None:
        """Publish `offline` (retained) if the status is ours, then disconnect; safe to call twice."""
        with self._status_lock:
            stopping, self._stopping = self._stopping, True
            # offline only over our own online: not before claim(), not over another server's
            if not stopping and self._claimed and self.connection.connected and self._other_client() is None:
                with contextlib.suppress(BusError):  # not connected, or refused by the broker
                    self.connection.publish(self._status_topic, OFFLINE, qos=1, retain=True, wait_s=2.0)
        self.connection.close()

    def __enter__(self) -> ComponentServer:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def status(self) -> Status:
        """The status this server publishes while online."""
        return Status(
            state="online",
            impl=self.impl_id,
            features=sorted(self.features),
            instance=self.instance,
            since=self._since,
            driver=self.driver,
        )

    def publish_state(self, state: dict[str, Any]) -> None:
        """Publish the component's current state (retained) on `…/<component>/state`; nothing
        before claim(): a server that may not serve the component leaves its state alone. A state
        equal to the one this connection last published is not published again (after a
        reconnect it is)."""
        if not self._claimed:
            return
        payload = to_payload(state)
        connects = self.connection.counters.connects
        with self._state_lock:
            # the broker holds this very state (retained) since this connection published it:
            # publishing it again says nothing new, and costs every subscriber (the orchestrator,
            # a monitor) a message per command (a model repeating `dutycycle(50)` in a loop)
            if payload == self._state_sent and connects == self._state_connects:
                return
            try:
                self.connection.publish(self.topics.state(self.component), payload, qos=1, retain=True)
            except NotConnected:
                self._log.debug("state_not_published", reason="not connected")
                return
            self._state_sent, self._state_connects = payload, connects

    def _publish_online(self) -> None:
        with self._status_lock:  # never after stop() said offline, never before claim()
            if self._stopping or not self._claimed:
                return
            payload = to_payload(self.status())
            self._published = payload
            self.connection.publish(self._status_topic, payload, qos=1, retain=True)
        self._log.info("component_online", impl=self.impl_id, features=sorted(self.features))

    # -- request handling (dispatcher thread) --------------------------------------------------------

    def _on_request(self, message: Message) -> None:
        feature_name = message.topic[len(self._call_prefix):]
        response_topic = message.response_topic
        correlation = message.correlation_data
        request_id: str | int | None = _correlation_id(correlation)
        reply_to: str | None = None
        if message.retain:  # a request kept by a broker (or a fleet hub, across its bridge) is stale:
            # it would run again on every (re)subscription
            log.warning("ignoring a retained request", topic=message.topic)
            return
        if feature_name == ALIVE_PROBE:  # another server checks whether we are alive: yes
            self._answer_alive(message)
            return
        bad_response_topic = response_topic is not None and not is_valid_publish_topic(response_topic)
        if bad_response_topic:
            response_topic = None  # never published to: a wildcard is no topic
        try:
            if len(message.payload) > self.max_request_bytes:
                # only the head: a client puts id and reply_to first, and a copy of a megabyte
                # for each refused request would only grow the service's heap
                salvaged_id, reply_to = _salvage_envelope(message.payload[:SALVAGE_HEAD_BYTES])
                request_id = salvaged_id if salvaged_id is not None else request_id
                raise _BadInput(
                    "payload_too_large",
                    f"request of {len(message.payload)} bytes exceeds the limit of "
                    f"{self.max_request_bytes} bytes",
                    request_id,
                    reply_to,
                )
            parsed = parse_request(message.payload)
            request_id = parsed.request_id if parsed.request_id is not None else request_id
            reply_to = parsed.reply_to
            if bad_response_topic:
                raise _BadInput("bad_request", "the MQTT 5 Response Topic must be a topic without wildcards")
            feature = self.features.get(feature_name)
            if feature is None:
                known = ", ".join(sorted(self.features)) or "none"
                raise _BadInput("unknown_feature",
                                f"{self.component} has no feature {feature_name!r} (it has: {known})")
            args = check_args(feature.spec, parsed.args)
        except RecursionError:  # a value nested deeper than the checks can walk (the decoder could)
            self._fail(feature_name, request_id, reply_to, response_topic, correlation, "bad_args",
                       "arguments nested too deeply")
            return
        except ArgumentError as bad:
            self._fail(feature_name, request_id, reply_to, response_topic, correlation, bad.code, bad.message)
            return
        except _BadInput as bad:
            if bad.request_id is not None:
                request_id = bad.request_id
            reply_to = bad.reply_to or reply_to
            self._fail(feature_name, request_id, reply_to, response_topic, correlation, bad.code, bad.message)
            return
        token = _CALLER.set(reply_to or response_topic)
        try:
            value = feature.handler(*args)
            if reply_to is not None or response_topic is not None:
                reply = {"id": request_id, "ok": True, "value": value}
                self._send(reply, reply_to, response_topic, correlation)
        except FeatureError as exc:
            self._fail(feature_name, request_id, reply_to, response_topic, correlation, exc.code, exc.message)
            return
        except DriverError as exc:
            self._fail(feature_name, request_id, reply_to, response_topic, correlation,
                       "driver_error", str(exc))
            return
        except Exception:
            # the traceback goes to the log only; the caller learns that it was our fault
            self._log.exception("feature_failed", feature=feature_name, request_id=request_id)
            self._fail(feature_name, request_id, reply_to, response_topic, correlation, "internal",
                       f"internal error in {self.component}.{feature_name} (see the service log)",
                       logged=True)
            return
        finally:
            _CALLER.reset(token)
        self.calls_served += 1

    def _answer_alive(self, message: Message) -> None:
        with contextlib.suppress(_BadInput, RecursionError):
            reply_to = parse_request(message.payload).reply_to
            if reply_to is not None:
                reply = Reply.success("alive", {"instance": self.instance})
                self._send(reply.wire(), reply_to, None, None)

    def _fail(self, feature: str, request_id: str | int | None, reply_to: str | None,
              response_topic: str | None, correlation: bytes | None, code: str, message: str,
              logged: bool = False) -> None:
        self.calls_failed += 1
        if not logged:
            self._log.warning("call_rejected", feature=feature, code=code, error=message,
                              request_id=request_id, reply=bool(reply_to or response_topic))
        self._send(Reply.failure(request_id, code, message).wire(), reply_to, response_topic, correlation)

    def _send(self, reply: dict[str, Any], reply_to: str | None, response_topic: str | None,
              correlation: bytes | None) -> None:
        """Answer on reply_to and/or the MQTT 5 response topic; nothing for fire-and-forget calls.

        `reply` is the wire form of a `Reply`.
        """
        if reply_to is None and response_topic is None:
            return
        try:
            payload = dumps(reply).encode("utf-8")
        except (TypeError, ValueError):
            self._log.error("reply_not_serialisable", value_type=type(reply.get("value")).__name__)
            failure = Reply.failure(reply["id"], "internal", "the feature returned a value that is not JSON")
            payload = dumps(failure.wire()).encode("utf-8")
        try:
            if response_topic is not None:
                self.connection.publish(response_topic, payload, qos=0, correlation_data=correlation)
            if reply_to is not None and reply_to != response_topic:
                self.connection.publish(reply_to, payload, qos=0)
        except NotConnected:
            self._log.warning("reply_lost", reason="not connected", request_id=reply["id"])


def _correlation_id(correlation: bytes | None) -> str | None:
    if correlation is None:
        return None
    try:
        return correlation.decode("utf-8")
    except UnicodeDecodeError:
        return correlation.hex()


#: JSON text in runs: a string, a run of opening brackets, of closing ones, or anything else.
_RUNS = re.compile(r'"(?:[^"\\]|\\.)*"|[\[{]+|[\]}]+|[^"\[\]{}]+')
_WHITESPACE = re.compile(r"[ \t\n\r]*")
_DECODER = json.JSONDecoder()


def _skip_ws(text: str, pos: int) -> int:
    match = _WHITESPACE.match(text, pos)
    return match.end() if match else pos


def _skip_value(text: str, pos: int) -> int:
    """The index after the JSON value at `pos`, without decoding it (any depth); -1 if cut short."""
    if not text.startswith(("[", "{"), pos):
        try:
            return _DECODER.raw_decode(text, pos)[1]
        except ValueError:
            return -1
    depth = 0
    for run in _RUNS.finditer(text, pos):
        token = run.group()
        if token[0] in "[{":
            depth += len(token)
        elif token[0] in "]}":
            if depth <= len(token):
                return run.start() + depth
            depth -= len(token)
    return -1


def _salvage_envelope(payload: bytes) -> tuple[str | int | None, str | None]:
    """Best effort: the `id` and `reply_to` of a request that cannot be decoded as a whole.

    For a request nested too deeply for the decoder, cut short, or too large to take: only the
    top-level object is read, values other than `id` and `reply_to` are skipped undecoded, so the
    caller still gets its error reply (e.g. to `{"id": 1, "reply_to": "r", "args": [[[[…`).
    """
    text = payload.decode("utf-8", "replace")
    found: dict[str, Any] = {}
    pos = _skip_ws(text, 0)
    if not text.startswith("{", pos):
        return None, None
    pos += 1
    while len(found) < 2:
        pos = _skip_ws(text, pos)
        try:
            key, pos = _DECODER.raw_decode(text, pos)
        except ValueError:
            break
        pos = _skip_ws(text, pos)
        if not isinstance(key, str) or not text.startswith(":", pos):
            break
        pos = _skip_ws(text, pos + 1)
        if key in ("id", "reply_to"):
            try:
                found[key], pos = _DECODER.raw_decode(text, pos)
            except (ValueError, RecursionError):
                break
        else:
            pos = _skip_value(text, pos)
            if pos < 0:
                break
        pos = _skip_ws(text, pos)
        if not text.startswith(",", pos):
            break
        pos += 1
    raw_id, reply_to = found.get("id"), found.get("reply_to")
    request_id = raw_id if _is_id(raw_id) else None
    if not (isinstance(reply_to, str) and is_valid_publish_topic(reply_to)):
        reply_to = None
    return request_id, reply_to
