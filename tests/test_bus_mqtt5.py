"""MQTT 5: Response Topic and Correlation Data are honoured on Mosquitto (the default protocol); on
amqtt, which speaks only 3.1.1, the default falls back to 3.1.1."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator

import pytest
from conftest import BrokerProcess, RawClient
from paho.mqtt.enums import MQTTProtocolVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from umlbot.base.catalog import implementations
from umlbot.base.errors import RemoteError
from umlbot.base.library import FeatureSpec, Param
from umlbot.services.bus import BrokerSettings, BusClient, ComponentServer, Feature, Topics

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


def test_a_service_started_the_default_way_answers_an_mqtt5_request(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    """MQTT.js 5 (Node-RED) calling LeftActuator.dutycycle with a Response Topic and Correlation
    Data got no reply: the motor service spoke 3.1.1 unless its URL said `?protocol=5`, so the
    broker stripped the properties. It speaks MQTT 5 by default now."""
    from services_support import ROBOT, deployment, running

    with running("motor", deployment(), mosquitto_broker.url) as host:
        assert all(s.connection.protocol == "5" for s in host.servers.values())
        raw = raw_client(mosquitto_broker, MQTTProtocolVersion.MQTTv5)
        raw.subscribe("nodered/replies")
        raw.publish(Topics(ROBOT).call("LeftActuator", "dutycycle"), b"[30]",
                    properties=_props("nodered/replies", b"flow-1"))
        msg = raw.get(5.0, "nodered/replies")
        assert msg.properties.CorrelationData == b"flow-1"  # type: ignore[union-attr]
        assert json.loads(msg.payload) == {"id": "flow-1", "ok": True, "value": None}
        assert host.drivers["LeftActuator"].duty_cycle_percent == 30


def test_on_a_broker_that_refuses_mqtt5_the_default_falls_back_to_311_at_once() -> None:
    """The embedded broker (amqtt) speaks only 3.1.1: it answers an MQTT 5 CONNECT with CONNACK
    "unacceptable protocol version", and the connection goes on with 3.1.1 (logged once)."""
    import time

    import structlog
    from conftest import free_port

    from umlbot.services.bus import EmbeddedBroker

    features = [Feature(FeatureSpec("value", (), "int"), lambda: 5)]
    with EmbeddedBroker(port=free_port()) as broker, structlog.testing.capture_logs() as logs:
        settings = BrokerSettings.from_url(broker.url)
        assert settings.protocol == "auto"
        began = time.monotonic()
        with ComponentServer(settings, "car5", "Sensor", "hcsr04", features) as server, \
                BusClient(settings, "car5") as client:
            assert time.monotonic() - began < 2.0
            assert server.connection.protocol == client.connection.protocol == "3.1.1"
            assert client.call("Sensor", "value") == 5
    fallbacks = [e for e in logs if e["event"] == "mqtt_protocol_fallback"]
    assert len(fallbacks) == 1 and fallbacks[0]["protocol"] == "3.1.1"
    assert not [e for e in logs if e["event"] == "mqtt_connect_refused"]
