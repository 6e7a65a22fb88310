"""One MQTT connection: the only place that owns a paho client and its reconnects.

A supervisor thread connects, runs paho's network loop, and after a lost connection reconnects
with a bounded, jittered exponential back-off. Subscriptions are restored after every reconnect
and the `add_on_connect` callbacks run again (services republish their status there). Message
handlers run on a dispatcher thread, in arrival order, never on paho's network thread.
"""

from __future__ import annotations

import collections
import contextlib
import math
import os
import select
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from paho.mqtt.enums import CallbackAPIVersion, MQTTErrorCode, MQTTProtocolVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties
from paho.mqtt.subscribeoptions import SubscribeOptions

from umlbot.base.errors import BrokerRefused, BusError, ConfigError, LoginRefused, NotConnected
from umlbot.base.lazy import import_lean
from umlbot.base.logs import get_logger
from umlbot.services.bus.envelopes import parse_json, to_payload
from umlbot.services.bus.settings import BrokerSettings, make_client_id

if TYPE_CHECKING:
    import paho.mqtt.client as mqtt
else:
    # paho imports ssl (with OpenSSL's libssl and libcrypto, about 4 MB) for TLS, hashlib for
    # WebSockets, and urllib.request (2.6 MB with http.client) only to read proxy settings when
    # PySocks is installed: all deferred until used (docs/performance.md, "Memory"). Its socket
    # reads and writes name ssl's SSLWantReadError/SSLWantWriteError in `except` clauses: those
    # do not load ssl (only an SSL socket raises them, and making one imports ssl).
    mqtt = import_lean("paho.mqtt.client", deferred=("ssl", "urllib.request", "hashlib"),
                       unraised={"ssl": ("SSLWantReadError", "SSLWantWriteError")})

log = get_logger(__name__)

#: back-off after a lost or failed connection: doubles from MIN to MAX, each wait jittered.
RECONNECT_MIN_S = 0.1
RECONNECT_MAX_S = 5.0
#: while the broker stays unreachable, `mqtt_connect_failed` is logged as a warning on the first
#: failed attempt and then at most once per this many seconds (the attempts between at debug).
CONNECT_WARN_EVERY_S = 30.0
#: after its DISCONNECT, a connection reads (and drops) what the broker still sends until the
#: broker closes, at most this long: closing with unread data makes the kernel send a reset,
#: and a broker that gets it may drop the DISCONNECT and what came before it (the orchestrator's
#: final `stopped`), and publish the will (docs/security.md, "Faults and attacks tested").
GOODBYE_WAIT_S = 1.0
#: the MQTT 5 CONNACK reason "Unsupported Protocol Version"; paho also reports so the 3.1.1 answer
#: "unacceptable protocol version" that a 3.1.1-only broker (amqtt) gives an MQTT 5 CONNECT.
UNSUPPORTED_PROTOCOL = 132
#: brokers (host, port) whose refusal of MQTT 5 was logged in this process (logged once each).
_REFUSED_MQTT5: set[tuple[str, int]] = set()

#: CONNACK reasons that refuse the login itself (MQTT 5 codes; paho maps 3.1.1's return codes 4
#: "bad user name or password" and 5 "not authorised" onto 134 and 135): the same credentials
#: will be refused again, so `start()` gives up at once instead of retrying until its time-out.
LOGIN_REFUSED_CODES = frozenset({
    134,  # Bad user name or password
    135,  # Not authorized
    138,  # Banned
    140,  # Bad authentication method
})


@dataclass(frozen=True)
class Message:
    """A received MQTT message; MQTT 5 Response Topic and Correlation Data when present."""

    topic: str
    payload: bytes
    qos: int = 0
    retain: bool = False
    response_topic: str | None = None
    correlation_data: bytes | None = None

    def text(self) -> str:
        """The payload as UTF-8 text (raises UnicodeDecodeError)."""
        return self.payload.decode("utf-8")

    def json(self) -> Any:
        """The payload parsed as UTF-8 JSON (raises ValueError, also for too deep a nesting)."""
        return parse_json(self.payload)


@dataclass(frozen=True)
class Will:
    """The last will the broker publishes when this connection dies without saying goodbye."""

    topic: str
    payload: Any
    qos: int = 1
    retain: bool = True


Handler = Callable[[Message], None]
Callback = Callable[[], None]


@dataclass
class _Subscription:
    topic_filter: str
    handler: Handler
    qos: int
    inline: bool = False  # internal fast path: run on the network thread (must never block)


#: what one read of a `read_ahead` connection takes from the socket at most (bytes)
READ_AHEAD_BYTES = 65536
#: and how long its network thread pauses after each turn of paho's loop (seconds)
READ_AHEAD_PAUSE_S = 0.01


@dataclass
class _Counters:
    connects: int = 0
    disconnects: int = 0
    handler_errors: int = 0


class _PahoClient(mqtt.Client):
    """paho's client with one lock around socket writes.

    Our own thread runs paho's network loop (not `loop_start`), so paho writes a packet directly
    from the thread that publishes it instead of waking the network thread first: a reply leaves
    the dispatcher thread at once. The lock keeps writes from several threads from interleaving.

    `on_acknowledged(mid, reason)` replaces paho's `on_publish`: it runs only when the broker
    acknowledges a QoS 1 or 2 publish. paho calls `on_publish` also for every QoS 0 packet
    written, and for it makes a reason code and a properties object (about 12 µs) on the
    publishing thread, twice in every call's round trip (docs/performance.md, RPC).
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._write_lock = threading.RLock()
        self.on_acknowledged: Callable[[int, Any], None] | None = None
        self._goodbye = False  # our DISCONNECT is queued: close the socket without a reset
        self._loop_thread: int | None = None  # the thread that runs `loop()`, noted by it
        #: read the socket in blocks of READ_AHEAD_BYTES (see `_sock_recv`); set before connecting
        self.read_ahead = False
        self._rbuf = b""
        self._rpos = 0

    def _create_socket_connection(self) -> Any:
        """paho's TCP connection, with an ASCII host name handed to the resolver as bytes.

        Python's `getaddrinfo` encodes every `str` host with the `idna` codec, which imports
        `encodings.idna` with `stringprep` and `unicodedata` (about 0.4 MB resident for the
        service's life: docs/performance.md, "Memory"); for an ASCII name whose labels are 1 to
        63 characters long that encoding is the name's ASCII bytes. Any other name (non-ASCII,
        or one the codec refuses) and a proxy go through paho as before."""
        host = self._host
        labels = host.split(".")
        if labels and not labels[-1]:
            labels.pop()  # a trailing dot ends the name
        if (not host.isascii() or not labels or not all(0 < len(label) < 64 for label in labels)
                or self._get_proxy()):
            return super()._create_socket_connection()
        address: Any = (host.encode("ascii"), self._port)  # getaddrinfo takes bytes too
        return socket.create_connection(address, timeout=self._connect_timeout,
                                        source_address=(self._bind_address, self._bind_port))

    def _messages_reconnect_reset_out(self) -> None:
        """Forget what the lost connection still owed the broker instead of sending it again.

        paho keeps every unacknowledged QoS 1/2 message and sends it again after a reconnect,
        also with a clean start. Ours start clean and republish what lasts (status, state) on
        every connect; an older message is stale there: a motor command sent again after the
        orchestrator failed the run, or a state older than the one just republished (a retained
        `running: true` over a stopped motor was seen). A waiter of a dropped message is told.
        """
        with self._out_message_mutex:
            dropped = list(self._out_messages.values())
            self._out_messages.clear()
            self._inflight_messages = 0
        for message in dropped:
            info = message.info
            with info._condition:
                info.rc = mqtt.MQTT_ERR_CONN_LOST
                info._condition.notify_all()

    def _sock_recv(self, bufsize: int) -> bytes:
        """paho reads a packet in three reads (its first byte, its length a byte at a time, the
        rest), each a system call after a `select`. With `read_ahead`, one read takes what the
        socket holds (up to READ_AHEAD_BYTES) and paho's reads are served from it; `loop_read`
        handles every whole packet in it before paho waits in `select` again."""
        if not self.read_ahead:
            data: bytes = super()._sock_recv(bufsize)
            return data
        buf, pos = self._rbuf, self._rpos
        if pos >= len(buf):
            buf, pos = super()._sock_recv(READ_AHEAD_BYTES), 0  # raises as paho's when nothing came
            if not buf:  # closed by the broker
                self._rbuf, self._rpos = b"", 0
                return buf
            self._rbuf = buf
        end = pos + bufsize
        self._rpos = end
        return buf[pos:end]

    def loop_read(self, max_packets: int = 1) -> MQTTErrorCode:
        rc: MQTTErrorCode = super().loop_read(max_packets)
        while (self.read_ahead and rc == MQTTErrorCode.MQTT_ERR_SUCCESS and self._sock is not None
               and self._rpos < len(self._rbuf)):
            rc = super().loop_read(max_packets)
        return rc

    def reconnect(self) -> MQTTErrorCode:
        self._rbuf, self._rpos = b"", 0  # nothing of the old connection is read on the new one
        rc: MQTTErrorCode = super().reconnect()
        return rc

    def _sock_close(self) -> None:
        self._rbuf, self._rpos = b"", 0
        sock = self._sock
        if sock is None or not self._goodbye:
            super()._sock_close()
            return
        # a graceful close: read until the broker closes (it does on DISCONNECT), then close
        self._sock = None
        self._goodbye = False
        try:
            _drain_until_closed(sock, GOODBYE_WAIT_S)
            self._call_socket_unregister_write(sock)
            self._call_socket_close(sock)
        finally:
            sock.close()

    def _do_on_publish(self, mid: int, reason_code: Any, properties: Any) -> MQTTErrorCode:
        # before paho marks the message published, so that whoever waits for it sees the reason
        if self.on_acknowledged is not None:
            self.on_acknowledged(mid, reason_code)
        rc: MQTTErrorCode = super()._do_on_publish(mid, reason_code, properties)
        return rc

    def _packet_write(self) -> MQTTErrorCode:
        with self._write_lock:
            return super()._packet_write()

    def loop(self, timeout: float = 1.0) -> MQTTErrorCode:
        self._loop_thread = threading.get_ident()
        rc: MQTTErrorCode = super().loop(timeout)
        if self.read_ahead:  # let the next messages gather in the socket: one wake-up, one read
            time.sleep(READ_AHEAD_PAUSE_S)
        return rc

    def _handle_publish(self) -> MQTTErrorCode:
        """An MQTT 5 PUBLISH without properties (every umlbot request and reply) decoded here,
        without the `Properties` object paho makes for each (its table of names, then parsing the
        empty block: about 17 µs of the ~21 paho takes per received message, against ~4 µs over
        MQTT 3.1.1; docs/performance.md, ROS 2). `message.properties` is None then, as over
        3.1.1. Anything else (properties, QoS 2, MQTT 3.1.1) is paho's own."""
        packet = self._in_packet["packet"]
        decoded = _decode_plain_publish(self._in_packet["command"], packet) \
            if self._protocol == MQTTProtocolVersion.MQTTv5 else None
        if decoded is None:
            rc: MQTTErrorCode = super()._handle_publish()
            return rc
        qos, mid, topic, payload = decoded
        message = mqtt.MQTTMessage(mid, topic)
        message.dup = bool(self._in_packet["command"] & 0x08)
        message.qos = qos
        message.retain = bool(self._in_packet["command"] & 0x01)
        message.payload = payload
        message.timestamp = mqtt.time_func()
        self._handle_on_message(message)
        if qos == 1 and not self._manual_ack:
            ack: MQTTErrorCode = self._send_puback(mid)
            return ack
        return MQTTErrorCode.MQTT_ERR_SUCCESS

    def _packet_queue(
        self, command: int, packet: bytes | bytearray, mid: int, qos: int, info: Any = None
    ) -> MQTTErrorCode:
        # paho would also wake the network thread for every packet; we wake it only when the
        # packet could not be written here (on the network thread inside a paho callback, or a
        # full socket buffer).
        if command & 0xF0 == mqtt.DISCONNECT:
            self._goodbye = True
        self._out_packet.append(
            {"command": command, "mid": mid, "qos": qos, "pos": 0, "to_process": len(packet),
             "packet": packet, "info": info}
        )
        # paho's test, "no callback runs", would also hold back a reply from the dispatcher
        # thread while the network thread is still in the callback that handed the request over
        # (the dispatcher, woken by a socket byte, runs at once): the reply then waited until the
        # network thread had left the callback and come round to its `select`, about 75 µs at
        # load 14 (docs/performance.md, ROS 2). Only the network thread itself, inside a
        # callback, leaves the write to its loop.
        on_loop = threading.get_ident() == self._loop_thread
        if not on_loop or self._in_callback_mutex.acquire(False):
            if on_loop:
                self._in_callback_mutex.release()
            rc = self.loop_write()
            if not self.want_write():
                return rc
        wake = self._sockpairW
        if wake is not None:
            with contextlib.suppress(BlockingIOError, OSError):
                wake.send(b"0")
        return MQTTErrorCode.MQTT_ERR_SUCCESS


def _decode_plain_publish(command: int, packet: bytes | bytearray) -> tuple[int, int, bytes, bytes] | None:
    """(qos, packet id, topic, payload) of an MQTT 5 PUBLISH (`command`: its fixed header's first
    byte; `packet`: what follows the remaining length) whose property block is empty and whose QoS
    is 0 or 1; None for any other (paho decodes it, and says what is wrong with a malformed one).
    """
    qos = (command & 0x06) >> 1
    if qos > 1 or len(packet) < 3:
        return None
    end = 2 + ((packet[0] << 8) | packet[1])  # after the topic
    at = end + 2 if qos else end  # the property length, after the packet id of QoS 1
    if len(packet) <= at or packet[at] != 0 or end == 2:  # properties, cut short, or no topic
        return None  # (an empty topic is a topic alias: paho's)
    mid = (packet[end] << 8) | packet[end + 1] if qos else 0
    return qos, mid, bytes(packet[2:end]), bytes(packet[at + 1:])


def _drain_until_closed(sock: Any, timeout: float) -> None:
    """Read and drop what arrives on `sock` until the peer closes it or `timeout` passes."""
    deadline = time.monotonic() + timeout
    while (remaining := deadline - time.monotonic()) > 0:
        try:
            readable, _, _ = select.select([sock], [], [], remaining)
            if not readable:
                return
            if not sock.recv(65536):
                return  # the broker closed its side
        except BlockingIOError:
            continue
        except OSError as exc:
            if type(exc).__name__ in ("SSLWantReadError", "SSLWantWriteError"):
                continue
            return


#: a piece of work for the dispatcher thread: a function and its arguments.
_Work = tuple[Callable[..., None], tuple[Any, ...]]


class _Mailbox:
    """The dispatcher thread's queue of work: first in, first out; `put` never blocks.

    The dispatcher is woken by a byte on a socket pair, not by a lock: paho's network thread sends
    it in a system call made without the GIL, so the dispatcher takes the GIL and runs the handler
    at once. Woken by a lock, it would wake while the network thread still holds the GIL, sleep
    again, and run only once that thread has finished its loop and waits in `select`: about 25 µs
    of every request on a 2-core machine (docs/performance.md, RPC).
    """

    def __init__(self) -> None:
        self._items: collections.deque[_Work | None] = collections.deque()
        self._wake_r: socket.socket | None = None
        self._wake_w: socket.socket | None = None

    def open(self) -> None:
        """Make the wake-up socket pair; before the dispatcher thread starts."""
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_w.setblocking(False)

    def put(self, item: _Work | None) -> None:
        self._items.append(item)
        wake = self._wake_w
        if wake is not None:
            # a full buffer holds wake-ups enough already; a closed pair has nobody left to wake
            with contextlib.suppress(OSError):
                wake.send(b"\0")

    def get(self) -> _Work | None:
        """The next item, waiting for it; None also when the mailbox was closed."""
        while True:
            try:
                return self._items.popleft()
            except IndexError:
                pass
            if self._wake_r is None:
                return None
            try:
                # an item put since the popleft above is followed by its byte: recv returns
                if not self._wake_r.recv(4096):
                    return None
            except OSError:
                return None

    def close(self) -> None:
        """Close the socket pair; safe to call twice."""
        for sock in (self._wake_r, self._wake_w):
            if sock is not None:
                sock.close()


class BusConnection:
    """A robust MQTT connection with a last will, reconnects and a dispatcher thread.

    `start(timeout)` returns once connected (or raises NotConnected and cleans up); `close()` is
    idempotent; the object is a context manager. `publish` never blocks on the network.
    """

    def __init__(
        self,
        settings: BrokerSettings,
        role: str,
        will: Will | None = None,
        *,
        robot: str = "any",
        client_id: str | None = None,
        reconnect_min_s: float = RECONNECT_MIN_S,
        reconnect_max_s: float = RECONNECT_MAX_S,
        read_ahead: bool = False,
    ) -> None:
        self.settings = settings
        self.role = role
        self.will = will
        self.client_id = client_id or make_client_id(role, robot)
        self.reconnect_min_s = reconnect_min_s
        self.reconnect_max_s = max(reconnect_max_s, reconnect_min_s)
        self.counters = _Counters()
        #: protocol "auto": MQTT 5 until the broker refuses it, then 3.1.1 (logged once)
        self._auto = settings.protocol == "auto"
        self._mqtt5 = settings.protocol != "3.1.1"
        self._fall_back = False  # the broker refused MQTT 5: the supervisor reconnects with 3.1.1
        #: read the socket in blocks rather than paho's three reads a packet (`_PahoClient`): for a
        #: subscriber of many messages (the recorder), where a few µs of latency do not matter
        self.read_ahead = read_ahead
        self._client = self._make_client()
        self._lock = threading.RLock()
        self._subacks = threading.Condition(self._lock)
        self._pending_subacks: dict[int, list[str]] = {}  # SUBSCRIBE mid -> its topic filters
        self._refused_publishes: dict[int, str] = {}  # PUBLISH mid -> the broker's reason (MQTT 5)
        #: topic filter -> reason, for every subscription the broker refused (e.g. its ACL)
        self.refused_subscriptions: dict[str, str] = {}
        self._subscriptions: list[_Subscription] = []
        self._route_cache: dict[str, tuple[list[_Subscription], list[_Subscription]]] = {}
        self._on_connect: list[Callback] = []
        self._on_disconnect: list[Callback] = []
        self._on_disconnect_inline: list[Callback] = []
        self._connected = threading.Event()
        self._lost = threading.Event()
        self._closing = threading.Event()
        self._supervisor: threading.Thread | None = None
        self._dispatch_queue = _Mailbox()
        self._dispatcher: threading.Thread | None = None
        self._closed = False
        self._last_error: str | None = None
        #: failed connection attempts since the last success (0 while connected).
        self.connect_failures = 0
        #: why the last attempt failed, in a few words ("Connection refused"); None once connected.
        self.connect_problem: str | None = None
        #: when (time.time()) the next attempt starts, while the broker is unreachable.
        self.next_attempt_at: float | None = None
        self._start_waiting = False  # start() waits for the first connection
        self._login_refused: str | None = None  # CONNACK reason while start() waits, see start()
        self._accepted = False

    # -- set-up ---------------------------------------------------------------------------------

    def _make_client(self) -> mqtt.Client:
        protocol = MQTTProtocolVersion.MQTTv5 if self._mqtt5 else MQTTProtocolVersion.MQTTv311
        client = _PahoClient(
            CallbackAPIVersion.VERSION2,
            client_id=self.client_id,
            protocol=protocol,
            clean_session=None if self._mqtt5 else True,
            reconnect_on_failure=False,  # the supervisor owns reconnects (jittered back-off)
        )
        settings = self.settings
        if settings.username is not None:
            password = settings.password.get_secret_value() if settings.password is not None else None
            client.username_pw_set(settings.username, password)
        if settings.tls:
            import ssl

            try:
                client.tls_set(
                    ca_certs=str(settings.ca_file) if settings.ca_file else None,
                    certfile=str(settings.certfile) if settings.certfile else None,
                    keyfile=str(settings.keyfile) if settings.keyfile else None,
                    cert_reqs=ssl.CERT_NONE if settings.insecure else ssl.CERT_REQUIRED,
                )
            except (OSError, ssl.SSLError) as exc:
                raise ConfigError(f"broker {settings.url}: cannot set up TLS: {exc}") from exc
            if settings.insecure:
                client.tls_insecure_set(True)
        if self.will is not None:
            client.will_set(
                self.will.topic, to_payload(self.will.payload), qos=self.will.qos, retain=self.will.retain
            )
        client.read_ahead = self.read_ahead
        client.on_connect = self._handle_connect
        client.on_disconnect = self._handle_disconnect
        client.on_message = self._handle_message
        client.on_socket_open = self._handle_socket_open
        client.on_subscribe = self._handle_subscribe
        client.on_acknowledged = self._handle_acknowledged
        return client

    # -- public API -----------------------------------------------------------------------------

    @property
    def protocol(self) -> str:
        """The MQTT version this connection speaks (or tries first): "5" or "3.1.1"."""
        return "5" if self._mqtt5 else "3.1.1"

    @property
    def connected(self) -> bool:
        """True while the broker has accepted this connection."""
        return self._connected.is_set()

    def wait_connected(self, timeout: float) -> bool:
        """Wait up to `timeout` seconds for a connection; True when connected."""
        return self._connected.wait(timeout)

    def start(self, timeout: float | None = 5.0) -> None:
        """Connect in the background; with a timeout, wait for the first connection.

        Raises NotConnected (after cleaning up) when the broker was not reached in time, and at
        once LoginRefused (a NotConnected) when the broker refuses the login: a wrong user or
        password does not become right by waiting. Without a timeout a refused login is retried
        with the back-off, as after a lost connection (the broker's password file may change).
        """
        if self._closed:
            raise BusError("this connection was closed; make a new one")
        if self._supervisor is not None:
            return
        self._dispatch_queue.open()
        self._dispatcher = threading.Thread(
            target=self._dispatch_loop, name=f"bus-dispatch-{self.role}", daemon=True
        )
        self._dispatcher.start()
        self._supervisor = threading.Thread(
            target=self._supervise, name=f"bus-connect-{self.role}", daemon=True
        )
        self._start_waiting = timeout is not None
        self._supervisor.start()
        if timeout is None:
            return
        deadline = time.monotonic() + timeout
        try:
            connected = self._wait_connected_or_closed(deadline)
        finally:
            self._start_waiting = False
        if self._login_refused is not None and not connected:
            self.close(timeout=0.5)
            raise LoginRefused(self.settings.url, self.settings.username, self._login_refused)
        if self._closing.is_set() and not connected:  # close() from another thread: give up now
            raise NotConnected(f"closed while connecting to the MQTT broker at {self.settings.url}")
        if not connected:
            reason = self._last_error or "no answer"
            # the connect thread may sit in a TCP or TLS handshake: do not wait for it long
            self.close(timeout=0.5)
            hint = "is it running? (umlbot broker, or --broker / UMLBOT_BROKER)"
            if self.settings.tls and "refused" not in reason.lower():
                # something answered, but no TLS handshake came of it: a plain listener, most likely
                hint = (f"is that port TLS? (mqtts:// needs a TLS listener; a plain one is "
                        f"mqtt://); {hint}")
            raise NotConnected(
                f"cannot connect to the MQTT broker at {self.settings.url} within {timeout:g} s "
                f"({reason}); {hint}"
            )
        if not self.wait_subscribed(max(0.0, deadline - time.monotonic())):
            self.close()
            raise NotConnected(
                f"the MQTT broker at {self.settings.url} did not confirm the subscriptions "
                f"within {timeout:g} s"
            )

    def _wait_connected_or_closed(self, deadline: float) -> bool:
        """Wait for the first connection until `deadline`; False as soon as close() was called."""
        while not self._connected.wait(min(0.1, max(0.0, deadline - time.monotonic()))):
            if self._closing.is_set() or self._login_refused is not None or time.monotonic() >= deadline:
                return False
        return True

    def wait_subscribed(self, timeout: float) -> bool:
        """Wait until the broker acknowledged every subscription sent so far; False on time-out."""
        with self._subacks:
            return self._subacks.wait_for(lambda: not self._pending_subacks, timeout)

    def close(self, timeout: float = 5.0) -> None:
        """Disconnect cleanly (no last will) and stop the threads; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self._closing.set()
        with contextlib.suppress(Exception):
            self._client.disconnect()
        self._lost.set()
        # is_alive: a signal (KeyboardInterrupt) inside start()'s Thread.start() leaves a thread
        # that join() refuses; a thread that did start sees _closing / the None and ends
        if self._supervisor is not None and self._supervisor.is_alive() \
                and self._supervisor is not threading.current_thread():
            self._supervisor.join(timeout)
        self._dispatch_queue.put(None)
        if self._dispatcher is not None and self._dispatcher.is_alive() \
                and self._dispatcher is not threading.current_thread():
            self._dispatcher.join(timeout)
        if self._dispatcher is None or not self._dispatcher.is_alive():
            self._dispatch_queue.close()  # else the dispatcher closes it when it ends
        self._connected.clear()

    def __enter__(self) -> BusConnection:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def publish(
        self,
        topic: str,
        payload: Any,
        qos: int = 1,
        retain: bool = False,
        *,
        response_topic: str | None = None,
        correlation_data: bytes | None = None,
        wait_s: float | None = None,
    ) -> None:
        """Send a message; raises NotConnected while there is no connection.

        `payload` may be bytes, str, a pydantic model or anything JSON-able. The MQTT 5 properties
        are sent only on an MQTT 5 connection. With `wait_s`, wait that long at most for the
        broker's acknowledgement (QoS 1) before returning.
        """
        if not self._connected.is_set():
            raise NotConnected(f"not connected to the MQTT broker at {self.settings.url}")
        properties = None
        if self._mqtt5 and (response_topic is not None or correlation_data is not None):
            properties = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
            if response_topic is not None:
                properties.ResponseTopic = response_topic
            if correlation_data is not None:
                properties.CorrelationData = correlation_data
        info = self._client.publish(topic, to_payload(payload), qos=qos, retain=retain, properties=properties)
        if info.rc == mqtt.MQTT_ERR_NO_CONN:
            raise NotConnected(f"not connected to the MQTT broker at {self.settings.url}")
        if info.rc == mqtt.MQTT_ERR_PAYLOAD_SIZE:
            raise BusError(f"payload of {len(to_payload(payload))} bytes is too large for MQTT")
        if wait_s is not None and qos > 0:
            with contextlib.suppress(RuntimeError, ValueError):
                info.wait_for_publish(wait_s)
            # on_acknowledged (which notes a refusal) runs before paho marks the message published
            refused = self._refused_publishes.pop(info.mid, None) if info.is_published() else None
            if refused is not None:
                raise BrokerRefused(f"the publish to {topic}", refused)

    def subscribe(
        self, topic_filter: str, handler: Handler, qos: int = 1, wait_s: float | None = None
    ) -> None:
        """Call `handler(message)` on the dispatcher thread for every message matching the filter.

        The subscription survives reconnects. Several handlers may share a filter. Subscriptions
        made before `start()` are confirmed by the broker before `start()` returns; for later
        ones, `wait_s` waits that long at most for the broker's confirmation.
        """
        self._add_subscription(_Subscription(topic_filter, handler, qos))
        if wait_s is not None and self._connected.is_set():
            self.wait_subscribed(wait_s)

    def subscribe_inline(self, topic_filter: str, handler: Handler, qos: int = 1) -> None:
        """As `subscribe`, but `handler` runs on the network thread itself, in paho's callback: it
        must never block nor take long (it holds up every other message and the keep-alive). For
        a handler that only hands the message on (a non-blocking append to a queue), it saves the
        dispatcher thread's wake-up per message."""
        self._add_subscription(_Subscription(topic_filter, handler, qos, inline=True))

    def _add_subscription(self, subscription: _Subscription) -> None:
        with self._lock:
            already = any(s.topic_filter == subscription.topic_filter for s in self._subscriptions)
            self._subscriptions.append(subscription)
            self._route_cache.clear()
            if not already and self._connected.is_set():
                # under the lock, so that the SUBACK cannot be handled before its mid is noted
                wanted = [(subscription.topic_filter, self._options(subscription.qos))]
                rc, mid = self._client.subscribe(wanted)
                if rc == mqtt.MQTT_ERR_SUCCESS and mid is not None:
                    self._pending_subacks[mid] = [subscription.topic_filter]

    def _options(self, qos: int) -> Any:
        """A subscription's options: over MQTT 5, Retain As Published, so that a handler sees a
        message that was retained as retained even when the broker passes it on live (a Mosquitto
        bridge hands the hub's retained messages to the robot's broker that way on every
        reconnect: a stale request must still look stale)."""
        if self._mqtt5:
            return SubscribeOptions(qos=qos, retainAsPublished=True)
        return qos

    def unsubscribe(self, topic_filter: str) -> None:
        """Drop every handler of this filter and tell the broker."""
        with self._lock:
            self._subscriptions = [s for s in self._subscriptions if s.topic_filter != topic_filter]
            self._route_cache.clear()
        if self._connected.is_set():
            self._client.unsubscribe(topic_filter)

    def add_on_connect(self, callback: Callback) -> None:
        """Run `callback()` (on the dispatcher thread) after every successful (re)connect.

        When already connected, it also runs once now.
        """
        with self._lock:
            self._on_connect.append(callback)
            connected = self._connected.is_set()
        if connected:
            self._dispatch_queue.put((callback, ()))

    def add_on_disconnect(self, callback: Callback) -> None:
        """Run `callback()` (on the dispatcher thread) after every lost connection."""
        with self._lock:
            self._on_disconnect.append(callback)

    def _add_on_disconnect_inline(self, callback: Callback) -> None:
        """Internal: run `callback()` on the network thread at once when the connection drops."""
        with self._lock:
            self._on_disconnect_inline.append(callback)

    # -- paho callbacks (network thread: never block here) ------------------------------------------

    def _handle_socket_open(self, client: mqtt.Client, userdata: Any, sock: Any) -> None:
        with contextlib.suppress(OSError, AttributeError):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def _handle_connect(
        self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any, properties: Any = None
    ) -> None:
        if reason.is_failure and self._auto and self._mqtt5 and \
                getattr(reason, "value", None) == UNSUPPORTED_PROTOCOL:
            self._fall_back = True  # the supervisor connects again at once, with MQTT 3.1.1
            self._lost.set()
            return
        if reason.is_failure:
            self._last_error = f"broker refused the connection: {reason}"
            self.connect_problem = f"the broker refused the connection: {reason}"
            if self._start_waiting and getattr(reason, "value", None) in LOGIN_REFUSED_CODES:
                # start() raises LoginRefused, which says all of it: no log line besides
                self._login_refused = str(reason)
                self._closing.set()  # no further attempt; start() closes the connection
                return
            log.warning("mqtt_connect_refused", broker=self.settings.url, client_id=self.client_id,
                        reason=str(reason))
            return
        with self._lock:
            filters: dict[str, int] = {}
            for sub in self._subscriptions:
                filters[sub.topic_filter] = max(filters.get(sub.topic_filter, 0), sub.qos)
            callbacks = list(self._on_connect)
            self._pending_subacks.clear()
            if filters:
                rc, mid = client.subscribe([(f, self._options(q)) for f, q in filters.items()])
                if rc == mqtt.MQTT_ERR_SUCCESS and mid is not None:
                    self._pending_subacks[mid] = list(filters)
        self.counters.connects += 1
        self._last_error = None
        self.connect_problem = None
        self.connect_failures = 0
        self.next_attempt_at = None
        self._accepted = True
        self._connected.set()
        for callback in callbacks:
            self._dispatch_queue.put((callback, ()))
        # The first connect is routine (debug); a reconnect is worth an info line.
        reconnect = self.counters.connects > 1
        (log.info if reconnect else log.debug)(
            "mqtt_connected", broker=self.settings.url, client_id=self.client_id, reconnect=reconnect
        )

    def _handle_subscribe(
        self, client: mqtt.Client, userdata: Any, mid: int, reasons: Any, properties: Any = None
    ) -> None:
        with self._subacks:
            filters = self._pending_subacks.pop(mid, [])
            self._subacks.notify_all()
        for topic_filter, reason in zip(filters, reasons, strict=False):
            if getattr(reason, "is_failure", False):
                # typically the broker's ACL: the handlers of this filter will never be called.
                # MQTT 5 names the reason ("Not authorized"); 3.1.1 only says "Unspecified error".
                self.refused_subscriptions[topic_filter] = str(reason)
                log.warning("mqtt_subscription_refused", broker=self.settings.url,
                            client_id=self.client_id, topic_filter=topic_filter, reason=str(reason))
            else:
                self.refused_subscriptions.pop(topic_filter, None)

    def _handle_acknowledged(self, mid: int, reason: Any) -> None:
        if getattr(reason, "is_failure", False):  # only MQTT 5 acknowledgements carry a reason
            if len(self._refused_publishes) >= 256:  # nobody waited for these: forget the oldest
                self._refused_publishes.pop(next(iter(self._refused_publishes)))
            self._refused_publishes[mid] = str(reason)
        elif self._refused_publishes:
            self._refused_publishes.pop(mid, None)  # a message id used again

    def _handle_disconnect(
        self, client: mqtt.Client, userdata: Any, flags: Any, reason: Any, properties: Any = None
    ) -> None:
        was_connected = self._connected.is_set()
        self._connected.clear()
        with self._subacks:
            self._pending_subacks.clear()
            self._subacks.notify_all()
        self._lost.set()
        if was_connected:
            self.counters.disconnects += 1
            self.connect_problem = f"connection lost ({reason})" if reason is not None else "connection lost"
            with self._lock:
                callbacks = list(self._on_disconnect)
                inline = list(self._on_disconnect_inline)
            for callback in inline:
                try:
                    callback()
                except Exception:
                    log.exception("bus_handler_failed", client_id=self.client_id)
            for callback in callbacks:
                self._dispatch_queue.put((callback, ()))
            if not self._closing.is_set():
                log.warning("mqtt_disconnected", broker=self.settings.url, client_id=self.client_id,
                            reason=str(reason))

    def _handle_message(self, client: mqtt.Client, userdata: Any, msg: mqtt.MQTTMessage) -> None:
        topic = msg.topic
        routes = self._route_cache.get(topic)
        if routes is None:
            routes = self._routes(topic)
        inline, queued = routes
        if not inline and not queued:
            return
        response_topic = correlation = None
        if self._mqtt5:
            props = getattr(msg, "properties", None)
            if props is not None:
                response_topic = getattr(props, "ResponseTopic", None)
                correlation = getattr(props, "CorrelationData", None)
        message = Message(topic, bytes(msg.payload), msg.qos, bool(msg.retain), response_topic, correlation)
        for sub in inline:
            try:
                sub.handler(message)
            except Exception:
                self.counters.handler_errors += 1
                log.exception("bus_handler_failed", topic=topic, client_id=self.client_id)
        for sub in queued:
            self._dispatch_queue.put((sub.handler, (message,)))

    def _routes(self, topic: str) -> tuple[list[_Subscription], list[_Subscription]]:
        with self._lock:
            matching = [s for s in self._subscriptions if mqtt.topic_matches_sub(s.topic_filter, topic)]
            routes = ([s for s in matching if s.inline], [s for s in matching if not s.inline])
            if len(self._route_cache) > 4096:
                self._route_cache.clear()
            self._route_cache[topic] = routes
        return routes

    # -- threads --------------------------------------------------------------------------------

    def _dispatch_loop(self) -> None:
        try:
            while True:
                item = self._dispatch_queue.get()
                if item is None:
                    return
                function, args = item
                try:
                    function(*args)
                except Exception:
                    self.counters.handler_errors += 1
                    log.exception("bus_handler_failed", client_id=self.client_id,
                                  handler=getattr(function, "__qualname__", repr(function)))
        finally:
            self._dispatch_queue.close()

    def _network_loop(self) -> None:
        """paho's network loop on this thread until the connection is lost or closed."""
        client = self._client
        while not self._lost.is_set() and not self._closing.is_set():
            try:
                rc = client.loop(timeout=1.0)
            except Exception:  # a bug in a callback must not kill the connection thread
                log.exception("mqtt_loop_failed", client_id=self.client_id)
                rc = mqtt.MQTT_ERR_UNKNOWN
            if rc != mqtt.MQTT_ERR_SUCCESS:
                break
        if self._closing.is_set():  # close() raced with a (re)connect: say goodbye here
            with contextlib.suppress(Exception):
                client.disconnect()
        if self._connected.is_set():  # lost without paho calling on_disconnect
            self._handle_disconnect(client, None, None, "connection lost")
        # the next reconnect() closes the old socket and drops unsent packets

    def _use_mqtt311(self) -> None:
        """The broker refused MQTT 5: a new paho client speaking 3.1.1 (supervisor thread)."""
        broker = (self.settings.host, self.settings.port)
        if broker not in _REFUSED_MQTT5:  # once per broker and process, not per connection
            # (each connection still tries 5 first: the broker behind an address may change)
            _REFUSED_MQTT5.add(broker)
            log.debug("mqtt_protocol_fallback", broker=self.settings.url, protocol="3.1.1",
                     reason="the broker refused MQTT 5")
        old = self._client
        self._fall_back = False
        self._mqtt5 = False
        self._client = self._make_client()
        sock = old.socket()
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.close()

    def _supervise(self) -> None:
        delay = self.reconnect_min_s
        first = True
        failures = 0
        warned_at = -math.inf
        while not self._closing.is_set():
            self._lost.clear()
            self._accepted = False
            try:
                if first:
                    self._client.connect(self.settings.host, self.settings.port, self.settings.keepalive_s)
                else:
                    self._client.reconnect()
            except OSError as exc:  # ssl.SSLError is an OSError
                self._last_error = f"{type(exc).__name__}: {exc}"
                if self._closing.is_set():  # start() gave up meanwhile and said why
                    break
                failures += 1
                self.connect_failures = failures
                self.connect_problem = exc.strerror or str(exc) or type(exc).__name__
                # a warning on the first failure of an outage and then once per
                # CONNECT_WARN_EVERY_S while it lasts, the other attempts at debug level; while
                # start() waits only at debug level (its NotConnected says the same)
                now = time.monotonic()
                warn = not self._start_waiting and (failures == 1 or now - warned_at >= CONNECT_WARN_EVERY_S)
                if warn:
                    warned_at = now
                (log.warning if warn else log.debug)(
                    "mqtt_connect_failed", broker=self.settings.url, client_id=self.client_id,
                    error=self._last_error, attempt=failures, retrying=True)
            else:
                first = False
                failures = 0
                self._network_loop()
                if self._accepted:
                    delay = self.reconnect_min_s
                if self._fall_back:
                    self._use_mqtt311()
                    first = True
                    continue
            if self._closing.is_set():
                break
            # full jitter in [delay/2, delay]: reconnecting services do not all hit the broker at once
            pause = delay / 2 + delay / 2 * int.from_bytes(os.urandom(4), "big") / 2**32  # (random: 0.2 MB)
            self.next_attempt_at = time.time() + pause
            self._closing.wait(pause)
            delay = min(delay * 2, self.reconnect_max_s)
        self._connected.clear()
