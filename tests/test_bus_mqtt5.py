"""MQTT 5 on Mosquitto: Response Topic and Correlation Data are honoured (amqtt speaks only 3.1.1)."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator

import pytest
from conftest import BrokerProcess, RawClient
from paho.mqtt.enums import MQTTProtocolVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from services.bus import BrokerSettings, BusClient, ComponentServer, Feature, Topics
from umlbot.errors import RemoteError
from umlbot.library import FeatureSpec, Param, implementations

pytestmark = pytest.mark.network

TOPICS = Topics("car5")


@pytest.fixture
def server5(mosquitto_broker: BrokerProcess) -> Iterator[ComponentServer]:
    features = [
        Feature(implementations()["l298n"].features["dutycycle"], lambda percent: None),
        Feature(FeatureSpec("value", (), "int"), lambda: 17),
        Feature(FeatureSpec("echo", (Param("text", "str"),), "str"), lambda text: text),
    ]
    server = ComponentServer(
        BrokerSettings.from_url(mosquitto_broker.url + "?protocol=5"), "car5", "Sensor", "hcsr04", features
    )
    server.start(5.0)
    yield server
    server.stop()


def _props(response_topic: str, correlation: bytes) -> Properties:
    props = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
    props.ResponseTopic = response_topic
    props.CorrelationData = correlation
    return props


def test_raw_mqtt5_request_gets_reply_with_correlation_data(
    mosquitto_broker: BrokerProcess, server5: ComponentServer, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(mosquitto_broker, MQTTProtocolVersion.MQTTv5)
    raw.subscribe("v5/replies")
    raw.publish(TOPICS.call("Sensor", "value"), b"", properties=_props("v5/replies", b"\x01corr-7"))
    msg = raw.get(5.0, "v5/replies")
    assert msg.properties.CorrelationData == b"\x01corr-7"  # type: ignore[union-attr]
    reply = json.loads(msg.payload)
    assert reply["ok"] is True and reply["value"] == 17


def test_raw_mqtt5_bad_input_gets_error_reply(
    mosquitto_broker: BrokerProcess, server5: ComponentServer, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(mosquitto_broker, MQTTProtocolVersion.MQTTv5)
    raw.subscribe("v5/replies")
    # malformed JSON has no envelope to say where to answer; the Response Topic does
    raw.publish(TOPICS.call("Sensor", "dutycycle"), b"{oops", properties=_props("v5/replies", b"c1"))
    msg = raw.get(5.0, "v5/replies")
    assert msg.properties.CorrelationData == b"c1"  # type: ignore[union-attr]
    reply = json.loads(msg.payload)
    assert reply["id"] == "c1" and reply["ok"] is False and reply["error"]["code"] == "bad_json"
    raw.publish(TOPICS.call("Sensor", "dutycycle"), b"250", properties=_props("v5/replies", b"c2"))
    reply = json.loads(raw.get(5.0, "v5/replies").payload)
    assert reply["error"]["code"] == "out_of_range"
    # and the service still answers
    raw.publish(TOPICS.call("Sensor", "echo"), b'["still here"]', properties=_props("v5/replies", b"c3"))
    assert json.loads(raw.get(5.0, "v5/replies").payload)["value"] == "still here"


def test_umlbot_client_over_mqtt5(mosquitto_broker: BrokerProcess, server5: ComponentServer) -> None:
    with BusClient(BrokerSettings.from_url(mosquitto_broker.url + "?protocol=5"), "car5") as client:
        assert client.call("Sensor", "value") == 17
        with pytest.raises(RemoteError, match="out_of_range"):
            client.call("Sensor", "dutycycle", 101)
    # a 3.1.1 client talks to the MQTT 5 server through the same broker
    with BusClient(BrokerSettings.from_url(mosquitto_broker.url), "car5") as client:
        assert client.call("Sensor", "echo", "mixed") == "mixed"
