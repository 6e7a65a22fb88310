"""The connection decodes an MQTT 5 PUBLISH without properties itself (no paho `Properties` object
per message, docs/performance.md "ROS 2"): the same topic, packet id and payload as paho's
decoder, and paho's decoder still for everything else."""

from __future__ import annotations

import queue
import struct
from collections.abc import Iterator
from typing import Any

import pytest
from conftest import BrokerProcess
from hypothesis import given, settings
from hypothesis import strategies as st
from paho.mqtt import _packet
from paho.mqtt.enums import MQTTProtocolVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from umlbot.services.bus import BrokerSettings, BusConnection, Message
from umlbot.services.bus.connection import _decode_plain_publish


def _publish_packet(topic: bytes, qos: int, mid: int, properties: Properties | None, payload: bytes) -> bytes:
    """What follows the fixed header of an MQTT 5 PUBLISH, as the standard lays it out."""
    packet = struct.pack("!H", len(topic)) + topic
    if qos:
        packet += struct.pack("!H", mid)
    packet += properties.pack() if properties is not None else b"\x00"  # type: ignore[no-untyped-call]
    return packet + payload


def _properties(response_topic: str | None, correlation: bytes | None) -> Properties | None:
    if response_topic is None and correlation is None:
        return None
    props = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
    if response_topic is not None:
        props.ResponseTopic = response_topic
    if correlation is not None:
        props.CorrelationData = correlation
    return props


#: what an MQTT UTF-8 string may hold (no NUL, no surrogates: paho refuses them)
_MQTT_CHARACTERS = st.characters(exclude_categories=["Cs"], exclude_characters="\x00")


@settings(max_examples=300, deadline=None)  # a loaded machine must not fail it on time
@given(
    topic=st.text(min_size=1, max_size=80).map(lambda t: t.encode("utf-8")),
    qos=st.sampled_from([0, 1, 2]),
    mid=st.integers(1, 65535),
    flags=st.sampled_from([0, 0x01, 0x08, 0x09]),
    response_topic=st.none() | st.text(_MQTT_CHARACTERS, min_size=1, max_size=20),
    correlation=st.none() | st.binary(min_size=1, max_size=16),
    payload=st.binary(max_size=300),
)
def test_plain_publish_decoded_as_paho_does(topic: bytes, qos: int, mid: int, flags: int,
                                            response_topic: str | None, correlation: bytes | None,
                                            payload: bytes) -> None:
    properties = _properties(response_topic, correlation)
    command = 0x30 | (qos << 1) | flags
    packet = _publish_packet(topic, qos, mid, properties, payload)
    paho = _packet.decode_publish(command, packet, MQTTProtocolVersion.MQTTv5)
    assert (paho.topic, paho.payload) == (topic, payload)  # the packet is what the standard says
    ours = _decode_plain_publish(command, bytearray(packet))
    if properties is not None or qos == 2:
        assert ours is None  # paho's decoder: the properties, QoS 2's handshake
    else:
        assert ours == (paho.qos, paho.mid, paho.topic, paho.payload)
        assert all(type(part) is bytes for part in ours[2:])


@pytest.mark.parametrize(("command", "packet"), [
    (0x30, b""), (0x30, b"\x00"), (0x30, b"\x00\x05ab"), (0x30, b"\x00\x02ab"),
    (0x32, b"\x00\x02ab\x00\x01"),  # QoS 1: the packet id, then nothing
    (0x30, b"\x00\x00\x00{}"),  # an empty topic: a topic alias
    (0x34, b"\x00\x02ab\x00\x01\x00{}"),  # QoS 2
])
def test_short_or_topicless_publish_left_to_paho(command: int, packet: bytes) -> None:
    assert _decode_plain_publish(command, packet) is None
    assert _decode_plain_publish(0x32, b"\x00\x02ab\x00\x01\x00{}") == (1, 1, b"ab", b"{}")


@pytest.fixture
def connection5(mosquitto_broker: BrokerProcess) -> Iterator[BusConnection]:
    connection = BusConnection(BrokerSettings.from_url(mosquitto_broker.url + "?protocol=5"), "decode-test")
    yield connection
    connection.close()


def test_messages_through_the_broker_with_and_without_properties(
    connection5: BusConnection, monkeypatch: pytest.MonkeyPatch
) -> None:
    got: queue.Queue[Message] = queue.Queue()
    connection5.subscribe("decode/#", got.put, qos=1)
    connection5.start(5.0)
    calls: list[Any] = []
    paho_decode = _packet.decode_publish

    def spy(*args: Any) -> Any:
        calls.append(args)
        return paho_decode(*args)

    monkeypatch.setattr(_packet, "decode_publish", spy)
    connection5.publish("decode/plain0", b'{"id":"a"}', qos=0)
    connection5.publish("decode/plain1", b"\xff\x00binary", qos=1)
    connection5.publish("decode/kept", b"retained", qos=1, retain=True)
    connection5.publish("decode/props", b"with", qos=1, response_topic="decode-reply/r",
                        correlation_data=b"\x01\x02")
    by_topic = {m.topic: m for m in (got.get(timeout=5) for _ in range(4))}
    assert by_topic["decode/plain0"] == Message("decode/plain0", b'{"id":"a"}', 0, False, None, None)
    assert by_topic["decode/plain1"] == Message("decode/plain1", b"\xff\x00binary", 1, False, None, None)
    assert by_topic["decode/props"] == Message("decode/props", b"with", 1, False, "decode-reply/r",
                                               b"\x01\x02")
    assert by_topic["decode/kept"].payload == b"retained"
    # only the message with properties went through paho's decoder
    assert len(calls) == 1 and b"decode/props" in bytes(calls[0][1])
    # a retained message sent when a subscription is made comes with its retain flag
    late: queue.Queue[Message] = queue.Queue()
    connection5.subscribe("decode/kept", late.put, qos=1, wait_s=5.0)
    retained = late.get(timeout=5)
    assert (retained.payload, retained.retain) == (b"retained", True)
    connection5.publish("decode/kept", b"", qos=1, retain=True)  # leave no retained message behind
