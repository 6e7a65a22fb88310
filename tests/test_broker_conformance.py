"""MQTT 3.1.1 behaviours both brokers must have: each test runs on the embedded broker and on Mosquitto.

The behaviours of Eclipse Paho's interoperability client tests (keep-alive, offline message
queueing, redelivery on reconnect) and the string rules of MQTT-1.5.3, written with raw packets
on a socket where a paho client would hide what the broker does (it answers, acknowledges, pings).
"""

from __future__ import annotations

import socket
import struct
import time
import uuid
from collections.abc import Callable, Iterator

import paho.mqtt.client as mqtt
import pytest
from conftest import BrokerProcess, RawClient
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion

pytestmark = pytest.mark.network

CONNECT, CONNACK, PUBLISH, PUBACK, PUBREC, PUBREL, SUBSCRIBE, SUBACK = 1, 2, 3, 4, 5, 6, 8, 9


def _string(raw: bytes) -> bytes:
    return struct.pack("!H", len(raw)) + raw


def _packet(kind: int, flags: int, body: bytes) -> bytes:
    length, encoded = len(body), bytearray()
    while True:
        byte, length = length % 128, length // 128
        encoded.append(byte | (0x80 if length else 0))
        if not length:
            break
    return bytes([kind << 4 | flags]) + bytes(encoded) + body


class RawSocket:
    """An MQTT 3.1.1 client on a bare socket: it sends only what a test tells it to."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=5.0)
        self.buffer = b""

    def connect(self, client_id: str, *, keepalive: int = 30, clean: bool = True,
                will: tuple[str, bytes] | None = None) -> tuple[int, int]:
        """Send CONNECT; (session present, return code) of the CONNACK."""
        flags = (0x02 if clean else 0) | (0x04 | 0x20 if will else 0)  # will: QoS 0, retained
        payload = _string(client_id.encode())
        if will:
            payload += _string(will[0].encode()) + _string(will[1])
        self.sock.sendall(_packet(CONNECT, 0, _string(b"MQTT") + bytes([4, flags])
                                  + struct.pack("!H", keepalive) + payload))
        kind, _, body = self.read()
        assert kind == CONNACK, kind
        return body[0], body[1]

    def subscribe(self, topic_filter: bytes, qos: int, packet_id: int = 1) -> None:
        body = struct.pack("!H", packet_id) + _string(topic_filter) + bytes([qos])
        self.sock.sendall(_packet(SUBSCRIBE, 2, body))

    def publish(self, topic: bytes, payload: bytes, qos: int = 0, packet_id: int = 1) -> None:
        header = _string(topic) + (struct.pack("!H", packet_id) if qos else b"")
        self.sock.sendall(_packet(PUBLISH, qos << 1, header + payload))

    def read(self, timeout: float = 5.0) -> tuple[int, int, bytes]:
        """(packet type, flags, body) of the next packet; ConnectionError once the broker closed."""
        self.sock.settimeout(timeout)
        while True:
            if len(self.buffer) >= 2:
                length, multiplier, pos = 0, 1, 1
                while pos < len(self.buffer):
                    byte = self.buffer[pos]
                    length += (byte & 0x7F) * multiplier
                    multiplier *= 128
                    pos += 1
                    if not byte & 0x80:
                        if len(self.buffer) >= pos + length:
                            first, body = self.buffer[0], self.buffer[pos:pos + length]
                            self.buffer = self.buffer[pos + length:]
                            return first >> 4, first & 0x0F, body
                        break
            chunk = self.sock.recv(65536)
            if not chunk:
                raise ConnectionError("the broker closed the connection")
            self.buffer += chunk

    def closed_by_broker(self, timeout: float) -> bool:
        """True when the broker closes the connection within `timeout` (packets before are read)."""
        deadline = time.monotonic() + timeout
        try:
            while time.monotonic() < deadline:
                self.read(max(0.01, deadline - time.monotonic()))
        except (ConnectionError, ConnectionResetError):
            return True
        except TimeoutError:
            return False
        return False

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def raw_socket(broker: BrokerProcess) -> Iterator[Callable[[], RawSocket]]:
    made: list[RawSocket] = []

    def make() -> RawSocket:
        made.append(RawSocket(broker.port))
        return made[-1]

    yield make
    for raw in made:
        raw.close()


def _publishes(raw: RawSocket, count: int, timeout: float = 5.0) -> list[tuple[int, bytes]]:
    """The next `count` PUBLISH packets: (flags, topic) each."""
    got: list[tuple[int, bytes]] = []
    deadline = time.monotonic() + timeout
    while len(got) < count:
        kind, flags, body = raw.read(max(0.01, deadline - time.monotonic()))
        if kind == PUBLISH:
            (length,) = struct.unpack("!H", body[:2])
            got.append((flags, body[2:2 + length]))
    return got


def test_a_silent_client_is_disconnected_and_its_will_published(
    broker: BrokerProcess, raw_socket: Callable[[], RawSocket], raw_client: Callable[..., RawClient]
) -> None:
    """MQTT-3.1.2-24: no packet for 1.5 x keep-alive ends the connection, and the will goes out."""
    topic = f"conformance/will/{uuid.uuid4().hex[:8]}"
    watcher = raw_client(broker)
    watcher.subscribe(topic, qos=0)
    frozen = raw_socket()
    assert frozen.connect("frozen-service", keepalive=2, will=(topic, b"offline")) == (0, 0)
    connected = time.monotonic()
    will = watcher.get(timeout=8.0, topic=topic)  # 1.5 x 2 s, and the broker's own tick
    waited = time.monotonic() - connected
    assert will.payload == b"offline"
    assert 2.0 <= waited <= 7.0, waited  # Mosquitto checks keep-alives on its own tick: 6.06 s seen
    assert frozen.closed_by_broker(1.0)


def test_a_client_that_pings_keeps_its_connection(
    broker: BrokerProcess, raw_socket: Callable[[], RawSocket]
) -> None:
    alive = raw_socket()
    alive.connect("pinging-service", keepalive=2)
    for _ in range(4):  # 4 s: twice the keep-alive
        time.sleep(1.0)
        alive.sock.sendall(_packet(12, 0, b""))  # PINGREQ
        assert alive.read(2.0)[0] == 13  # PINGRESP


@pytest.mark.parametrize("topic", [b"robot/\xff/status", b"robot/\x00/status", b"robot/\xed\xa0\x80"],
                         ids=["ill-formed", "U+0000", "surrogate"])
def test_a_topic_that_is_not_utf8_closes_the_connection(
    broker: BrokerProcess, raw_socket: Callable[[], RawSocket], topic: bytes
) -> None:
    """MQTT-1.5.3-1/-2: a PUBLISH whose topic is not well-formed UTF-8 (or holds U+0000) closes
    the connection; it is neither acknowledged nor delivered."""
    raw = raw_socket()
    raw.connect(f"bad-topic-{uuid.uuid4().hex[:6]}")
    raw.publish(topic, b"x", qos=1)
    assert raw.closed_by_broker(3.0)


def test_a_topic_filter_that_is_not_utf8_closes_the_connection(
    broker: BrokerProcess, raw_socket: Callable[[], RawSocket]
) -> None:
    raw = raw_socket()
    raw.connect(f"bad-filter-{uuid.uuid4().hex[:6]}")
    raw.subscribe(b"robot/\xc3/#", qos=0)
    assert raw.closed_by_broker(3.0)


def _paho(port: int, client_id: str, clean: bool) -> tuple[mqtt.Client, list[mqtt.MQTTMessage], list[int]]:
    """A paho client that notes its messages and the CONNACK's session-present flags."""
    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=client_id,
                         protocol=MQTTProtocolVersion.MQTTv311, clean_session=clean)
    messages: list[mqtt.MQTTMessage] = []
    present: list[int] = []
    client.on_message = lambda c, u, m: messages.append(m)
    client.on_connect = lambda c, u, flags, rc, p=None: present.append(int(flags.session_present))
    client.connect("127.0.0.1", port, 30)
    client.loop_start()
    deadline = time.monotonic() + 5
    while not present and time.monotonic() < deadline:
        time.sleep(0.01)
    assert present, "no CONNACK"
    return client, messages, present


def test_messages_are_queued_for_a_persistent_session_while_it_is_away(broker: BrokerProcess) -> None:
    """clean session 0: QoS 1 and 2 messages published while the client is away are delivered
    when it comes back (QoS 0 may be), as ordinary messages; the CONNACK says the session is there."""
    prefix = f"conformance/queued/{uuid.uuid4().hex[:8]}"
    away, _, present = _paho(broker.port, "persistent-reader", clean=False)
    away.subscribe(f"{prefix}/#", 2)
    time.sleep(0.3)
    away.disconnect()
    away.loop_stop()
    writer, _, _ = _paho(broker.port, "writer", clean=True)
    for qos in (0, 1, 2):
        writer.publish(f"{prefix}/qos{qos}", f"qos {qos}", qos=qos).wait_for_publish(5)
    writer.disconnect()
    writer.loop_stop()
    time.sleep(0.3)
    back, messages, present = _paho(broker.port, "persistent-reader", clean=False)
    try:
        assert present == [1], "the broker forgot the session"
        deadline = time.monotonic() + 5
        while len({m.topic for m in messages}) < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        topics = {m.topic for m in messages}
        everything = {f"{prefix}/qos{qos}" for qos in (0, 1, 2)}
        assert {f"{prefix}/qos1", f"{prefix}/qos2"} <= topics <= everything, topics
        assert not any(m.retain for m in messages)
    finally:
        back.disconnect()
        back.loop_stop()


def test_unacknowledged_messages_are_sent_again_on_reconnect(
    broker: BrokerProcess, raw_socket: Callable[[], RawSocket], raw_client: Callable[..., RawClient]
) -> None:
    """MQTT-4.4.0-1: QoS 1 and 2 messages the client did not acknowledge before its connection
    dropped are sent again, with DUP set, when it reconnects with clean session 0."""
    prefix = f"conformance/redeliver/{uuid.uuid4().hex[:8]}"
    slow = raw_socket()
    slow.connect("slow-reader", clean=False)
    slow.subscribe(f"{prefix}/#".encode(), qos=2)
    assert slow.read()[0] == SUBACK
    writer = raw_client(broker)
    writer.publish(f"{prefix}/one", b"1", qos=1)
    writer.publish(f"{prefix}/two", b"2", qos=2)
    first = _publishes(slow, 2)
    assert {topic for _, topic in first} == {f"{prefix}/one".encode(), f"{prefix}/two".encode()}
    slow.close()  # gone without acknowledging either
    time.sleep(0.5)
    again = raw_socket()
    assert again.connect("slow-reader", clean=False) == (1, 0)
    resent = _publishes(again, 2)
    assert {topic for _, topic in resent} == {f"{prefix}/one".encode(), f"{prefix}/two".encode()}
    assert all(flags & 0x08 for flags, _ in resent), "DUP not set on a message sent again"
