"""The client side of the bus: call component features and wait for their replies.

A `BusClient` subscribes once to its own reply topic `umlbot/<robot>/_reply/<user>/<token>` and
matches replies to calls by id, so any number of calls may be in flight from several threads or
asyncio tasks at once. Calls fail fast with `NotConnected` while the broker is unreachable (also
the calls that were waiting when the connection dropped) and with `CallTimeout` when no reply
came in time; an error reply raises `RemoteError` with its code.
"""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, InvalidStateError
from concurrent.futures import TimeoutError as FutureTimeout
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    import asyncio

from umlbot.base.errors import CallTimeout, NotConnected, RemoteError
from umlbot.base.logs import get_logger
from umlbot.base.topics import Topics
from umlbot.services.bus.connection import BusConnection, Handler, Message
from umlbot.services.bus.envelopes import dumps, is_timeout, parse_json
from umlbot.services.bus.settings import BrokerSettings

log = get_logger(__name__)


class _Waiter(Protocol):
    """Who waits for a reply: a `concurrent.futures.Future` or an `acall`'s `_LoopWaiter`."""

    def set_result(self, result: dict[str, Any]) -> None: ...

    def set_exception(self, exception: BaseException | None) -> None: ...


class _LoopWaiter:
    """An `acall`'s reply hand-off: resolves its asyncio future on the event loop, in one hop.

    The network thread calls `set_result`/`set_exception`; each schedules the resolution with one
    `call_soon_threadsafe`, and the awaiting task runs on the loop's next turn. (Wrapping a
    `concurrent.futures.Future` and `asyncio.wait_for` takes two more turns of the loop and a
    helper future per call: about 0.05 ms of every orchestrator action on the 2-core machine,
    docs/performance.md, Orchestrator.)
    """

    __slots__ = ("_future", "_loop")

    def __init__(self, loop: asyncio.AbstractEventLoop, future: asyncio.Future[Any]) -> None:
        self._loop = loop
        self._future = future

    def set_result(self, result: dict[str, Any]) -> None:
        with contextlib.suppress(RuntimeError):  # the loop is closed: nobody waits any more
            self._loop.call_soon_threadsafe(_resolve, self._future, result)

    def set_exception(self, exception: BaseException | None) -> None:
        with contextlib.suppress(RuntimeError):
            self._loop.call_soon_threadsafe(_resolve, self._future, exception)


#: what a `request_then` callback gets: the request id, and the raw reply envelope or None and
#: the exception
ReplyCallback = Callable[[str, dict[str, Any] | None, BaseException | None], None]


class _CallbackWaiter:
    """A `request_then`'s reply hand-off: calls its function on the network thread, nothing else
    (no `Future`, its condition and its list of callbacks made and run for every call)."""

    __slots__ = ("_callback", "_request_id")

    def __init__(self, callback: ReplyCallback, request_id: str) -> None:
        self._callback = callback
        self._request_id = request_id

    def set_result(self, result: dict[str, Any]) -> None:
        self._callback(self._request_id, result, None)

    def set_exception(self, exception: BaseException | None) -> None:
        self._callback(self._request_id, None,
                       exception or NotConnected("the connection to the MQTT broker was lost"))


#: what an `acall`'s future resolves to when its time-out came first.
_TIMED_OUT: Any = object()


def _resolve(future: asyncio.Future[Any], outcome: Any) -> None:
    """On the loop: settle `future` unless it is done (cancelled, timed out or answered)."""
    if future.done():
        return
    if isinstance(outcome, BaseException):
        future.set_exception(outcome)
    else:
        future.set_result(outcome)


class BusClient:
    """Calls features of one robot's components; `start()`, `close()`, context manager."""

    def __init__(
        self,
        settings: BrokerSettings,
        robot: str,
        role: str = "client",
        *,
        client_id: str | None = None,
    ) -> None:
        self.topics = Topics(robot)
        self.robot = robot
        self.connection = BusConnection(settings, role=role, robot=robot, client_id=client_id)
        token = os.urandom(8).hex()  # not the client id: that one is never published
        self.reply_topic = self.topics.reply(settings.username, token)
        self._pending: dict[str, _Waiter] = {}
        self._pending_lock = threading.Lock()
        self._ids = itertools.count(1)
        self._id_prefix = token[:6] + "-"
        self.connection.subscribe_inline(self.reply_topic, self._on_reply, qos=0)
        self.connection._add_on_disconnect_inline(self._fail_pending)

    @property
    def client_id(self) -> str:
        return self.connection.client_id

    @property
    def connected(self) -> bool:
        return self.connection.connected

    def wait_connected(self, timeout: float) -> bool:
        return self.connection.wait_connected(timeout)

    def start(self, timeout: float | None = 5.0) -> None:
        """Connect; raises NotConnected when the broker is not reached within `timeout`."""
        self.connection.start(timeout)

    def close(self) -> None:
        """Disconnect; calls still waiting fail with NotConnected. Safe to call twice."""
        self.connection.close()
        self._fail_pending()

    def __enter__(self) -> BusClient:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- calls ----------------------------------------------------------------------------------

    def _request(
        self, component: str, feature: str, args: tuple[Any, ...], timeout_s: float,
        ack_wait_s: float | None = None,
    ) -> tuple[str, Future[dict[str, Any]]]:
        future: Future[dict[str, Any]] = Future()
        return self._send(component, feature, args, timeout_s, future, ack_wait_s), future

    def _send(
        self, component: str, feature: str, args: tuple[Any, ...], timeout_s: float, waiter: _Waiter,
        ack_wait_s: float | None = None, *, request_id: str | None = None,
    ) -> str:
        """Publish the request; `waiter` gets the reply (or NotConnected). Returns the request id
        (`request_id`, else a new one)."""
        if not self.connection.connected:
            raise NotConnected(
                f"cannot call {component}.{feature}: not connected to the MQTT broker at "
                f"{self.connection.settings.url}"
            )
        if request_id is None:
            request_id = self.new_request_id()
        with self._pending_lock:
            self._pending[request_id] = waiter
        # the time-out goes with the request: a monitor reports it unanswered when this caller gives up
        request: dict[str, Any] = {"id": request_id, "reply_to": self.reply_topic, "args": args}
        if is_timeout(timeout_s):
            request["timeout_s"] = timeout_s
        payload = dumps(request).encode("utf-8")
        try:
            if ack_wait_s is None:
                self.connection.publish(self.topics.call(component, feature), payload, qos=0)
            else:
                self.connection.publish(self.topics.call(component, feature), payload, qos=1,
                                        wait_s=ack_wait_s)
        except BaseException:
            with self._pending_lock:
                self._pending.pop(request_id, None)
            raise
        return request_id

    def new_request_id(self) -> str:
        """A request id of this client's, never used before (for `request_then`)."""
        return f"{self._id_prefix}{next(self._ids)}"

    def call(self, component: str, feature: str, *args: Any, timeout: float = 2.0,
             acknowledged: bool = False) -> Any:
        """Call `component.feature(*args)`; return its value.

        Raises CallTimeout, RemoteError (with `.code`) or NotConnected. With `acknowledged`, the
        request goes out at QoS 1 and waits (within `timeout`) for the broker's acknowledgement,
        so that over MQTT 5 a refused publish (the broker's ACL) raises `BrokerRefused` at once
        instead of ending as a time-out; it costs a round trip, so the orchestrator does not.
        """
        started = time.monotonic()
        request_id, future = self._request(component, feature, args, timeout,
                                           timeout if acknowledged else None)
        try:
            reply = future.result(max(0.0, timeout - (time.monotonic() - started)))
        except FutureTimeout:
            with self._pending_lock:
                self._pending.pop(request_id, None)
            raise CallTimeout(component, feature, timeout) from None
        return _unwrap(reply, component, feature)

    def request_then(self, component: str, feature: str, *args: Any, timeout: float = 2.0,
                     then: ReplyCallback, request_id: str | None = None) -> str:
        """Send a call without waiting; `then(request_id, reply, None)` with the raw reply
        envelope, or `then(request_id, None, exception)` when the connection is lost, runs on the
        network thread (it must return at once; the ROS 2 bridge answers its DDS requests this
        way). Returns the request id:
        `request_id` (from `new_request_id()`, for a caller that notes it before the reply can
        come), else a new one; the caller times the call out with `forget(request_id)`.
        `reply_value` unwraps a reply."""
        if request_id is None:
            request_id = self.new_request_id()
        return self._send(component, feature, args, timeout, _CallbackWaiter(then, request_id),
                          request_id=request_id)

    def forget(self, request_id: str) -> bool:
        """Stop waiting for a request's reply; False when it had come (or was forgotten)."""
        with self._pending_lock:
            return self._pending.pop(request_id, None) is not None

    # the same signature as `call` on purpose, so the orchestrator can switch between them
    async def acall(self, component: str, feature: str, *args: Any, timeout: float = 2.0) -> Any:  # noqa: ASYNC109
        """The asyncio form of `call`: awaits the reply without blocking the event loop."""
        import asyncio  # here: a hardware service never calls it, and asyncio costs it ~2 MB

        loop = asyncio.get_running_loop()
        future: asyncio.Future[Any] = loop.create_future()
        request_id = self._send(component, feature, args, timeout, _LoopWaiter(loop, future))
        expiry = loop.call_later(timeout, _resolve, future, _TIMED_OUT)
        try:
            reply = await future
        finally:  # also when the awaiting task is cancelled: forget the call
            expiry.cancel()
            with self._pending_lock:
                self._pending.pop(request_id, None)
        if reply is _TIMED_OUT:
            raise CallTimeout(component, feature, timeout)
        return _unwrap(reply, component, feature)

    def send(self, component: str, feature: str, *args: Any) -> None:
        """Fire-and-forget call: no reply is asked for; raises NotConnected when offline."""
        self.connection.publish(self.topics.call(component, feature), {"args": list(args)}, qos=0)

    # -- passthrough ----------------------------------------------------------------------------

    def publish(self, topic: str, payload: Any, qos: int = 1, retain: bool = False) -> None:
        """Publish on this client's connection (see `BusConnection.publish`)."""
        self.connection.publish(topic, payload, qos=qos, retain=retain)

    def subscribe(self, topic_filter: str, handler: Handler, qos: int = 1) -> None:
        """Subscribe on this client's connection (see `BusConnection.subscribe`)."""
        self.connection.subscribe(topic_filter, handler, qos=qos)

    # -- replies (network thread: only resolves futures) ------------------------------------------

    def _on_reply(self, message: Message) -> None:
        try:
            reply = parse_json(message.payload)
        except ValueError:
            log.warning("bad_reply", topic=message.topic, reason="not JSON")
            return
        if not isinstance(reply, dict):
            return
        request_id = reply.get("id")
        with self._pending_lock:
            future = self._pending.pop(request_id, None) if isinstance(request_id, str) else None
        if future is not None:
            with contextlib.suppress(InvalidStateError):  # a future its caller cancelled
                future.set_result(reply)

    def _fail_pending(self) -> None:
        with self._pending_lock:
            pending, self._pending = self._pending, {}
        for future in pending.values():
            with contextlib.suppress(InvalidStateError):
                future.set_exception(NotConnected("the connection to the MQTT broker was lost"))


def _unwrap(reply: dict[str, Any], component: str, feature: str) -> Any:
    if reply.get("ok") is True:
        return reply.get("value")
    error = reply.get("error")
    if isinstance(error, dict):
        code, text = str(error.get("code", "internal")), str(error.get("message", ""))
        raise RemoteError(code, text, component, feature)
    try:
        text = json.dumps(reply)[:200]
    except (ValueError, RecursionError):
        text = "(not shown: nested too deeply)"
    raise RemoteError("bad_reply", f"malformed reply: {text}", component, feature)


def reply_value(reply: dict[str, Any], component: str, feature: str) -> Any:
    """A reply envelope's value; `RemoteError` for an error reply (`BusClient.request_then`)."""
    return _unwrap(reply, component, feature)
