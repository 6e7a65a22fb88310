"""Malformed wire input: every bad request gets its error reply and one warning, never a traceback.

The inputs are the ones a fuzz run found holes with (deep nesting that the JSON decoder answers
with RecursionError, integers too large for a float, oversize payloads), sent by raw paho clients
to a `ComponentServer` on real brokers; MQTT 5 Response Topics let even non-JSON bytes name where
the error reply goes (Mosquitto only: amqtt speaks MQTT 3.1.1).
"""

from __future__ import annotations

import json
import sys
import uuid
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import structlog
from conftest import BrokerProcess, RawClient
from paho.mqtt.enums import MQTTProtocolVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

from umlbot.base.catalog import implementations
from umlbot.base.library import FeatureSpec, Param
from umlbot.services.bus import BrokerSettings, BusClient, ComponentServer, Feature, Topics, parse_json
from umlbot.services.bus.server import parse_request

pytestmark = pytest.mark.network

ROBOT = "fuzzcar"
TOPICS = Topics(ROBOT)
DEEP = b"[" * 5000


def features(calls: list[tuple[Any, ...]]) -> list[Feature]:
    motor = implementations()["l298n"].features
    return [
        Feature(motor["dutycycle"], lambda percent: calls.append(("dutycycle", percent))),
        Feature(FeatureSpec("add", (Param("a", "float"), Param("b", "float")), "float"), lambda a, b: a + b),
        Feature(FeatureSpec("echo", (Param("text", "str"),), "str"), lambda text: text),
    ]


@pytest.fixture
def calls() -> list[tuple[Any, ...]]:
    return []


@pytest.fixture
def server(broker: BrokerProcess, calls: list[tuple[Any, ...]]) -> Iterator[ComponentServer]:
    srv = ComponentServer(BrokerSettings.from_url(broker.url), ROBOT, "Motor", "l298n", features(calls))
    srv.start(5.0)
    yield srv
    srv.stop()


def envelope(args: str, request_id: str, reply_to: str = "raw/replies") -> bytes:
    """A request envelope with `args` spliced in as raw JSON text (it may be deeply nested)."""
    return f'{{"id": "{request_id}", "reply_to": "{reply_to}", "args": {args}}}'.encode()


def test_parse_json_turns_deep_nesting_into_a_value_error() -> None:
    with pytest.raises(ValueError, match="nested too deeply"):
        parse_json(DEEP)
    with pytest.raises(ValueError):
        parse_json(b"\xff\xfe")
    assert parse_json(b'{"a": [1]}') == {"a": [1]}


def test_parse_request_answers_bad_json_for_deep_nesting() -> None:
    with pytest.raises(Exception) as info:
        parse_request(b'{"id": 7, "reply_to": "r/s", "args": ' + DEEP)
    assert getattr(info.value, "code", None) == "bad_json"
    assert "nested too deeply" in str(info.value)
    assert getattr(info.value, "request_id", None) == 7
    assert getattr(info.value, "reply_to", None) == "r/s"


def test_an_integer_too_long_to_convert_is_bad_json_in_words_of_ours() -> None:
    limit = sys.get_int_max_str_digits()
    for digits in ("9" * (limit + 700), "-" + "9" * (limit + 1)):
        with pytest.raises(ValueError) as caught:
            parse_json(f'{{"a": [{digits}]}}'.encode())
        assert str(caught.value) == f"integer too long: more than {limit} digits"
    assert parse_json(("9" * limit).encode()) == int("9" * limit)  # at the limit: a number
    with pytest.raises(Exception) as info:
        parse_request(envelope(f"[{'9' * 5000}]", "long"))
    assert getattr(info.value, "code", None) == "bad_json"
    assert str(info.value) == (f"payload is not UTF-8 JSON: integer too long: more than "
                               f"{limit} digits")
    assert "set_int_max_str_digits" not in str(info.value)
    assert getattr(info.value, "request_id", None) == "long"
    assert getattr(info.value, "reply_to", None) == "raw/replies"


def test_every_malformed_envelope_gets_an_error_reply(
    broker: BrokerProcess, server: ComponentServer, calls: list[tuple[Any, ...]],
    raw_client: Callable[..., RawClient],
) -> None:
    raw = raw_client(broker)
    raw.subscribe("raw/replies")
    cases = {
        # too deep for the decoder: the id and reply_to are salvaged from the top level
        "deep-args": ("dutycycle", envelope("[" * 5000, "deep-args"), "bad_json"),
        "deep-first": ("dutycycle", b'{"args": ' + b"[" * 5000 + b"]" * 5000 +
                       b', "id": "deep-first", "reply_to": "raw/replies"}', "bad_json"),
        "cut-short": ("dutycycle", envelope("[1, ", "cut-short"), "bad_json"),
        # the decoder takes it; the checks that look at it must not recurse
        "deep-arg": ("dutycycle", envelope("[" + "[" * 900 + "]" * 900 + "]", "deep-arg"), "bad_args"),
        "huge-int-float": ("add", envelope(f"[{'9' * 4000}, 1]", "huge-int-float"), "bad_args"),
        "huge-int-int": ("dutycycle", envelope(f"[{'9' * 4000}]", "huge-int-int"), "out_of_range"),
        "int-too-long": ("dutycycle", envelope(f"[{'9' * 5000}]", "int-too-long"), "bad_json"),
        "nan": ("add", envelope("[NaN, 1]", "nan"), "bad_args"),
        "infinity": ("add", envelope("[Infinity, -Infinity]", "infinity"), "bad_args"),
        "wrong-type": ("echo", envelope("[{\"a\": 1}]", "wrong-type"), "bad_args"),
        "unknown": ("fly", envelope("[]", "unknown"), "unknown_feature"),
        "oversize-deep": ("echo", envelope('["' + "x" * 300_000 + '"]', "oversize-deep"),
                          "payload_too_large"),
        "bad-envelope": ("echo", b'{"id": "bad-envelope", "reply_to": "raw/replies", "args": [1], "x": 2}',
                         "bad_request"),
        "bad-timeout": ("echo", b'{"id": "bad-timeout", "reply_to": "raw/replies", "args": [1], '
                                b'"timeout_s": -1}', "bad_request"),
    }
    with structlog.testing.capture_logs() as logs:
        raw.publish(TOPICS.call("Motor", "dutycycle"), b"[" * 300_000)  # oversize, no reply asked
        for feature, payload, _code in cases.values():
            raw.publish(TOPICS.call("Motor", feature), payload)
        replies = {}
        for _ in cases:
            reply = json.loads(raw.get(10.0, "raw/replies").payload)
            replies[reply["id"]] = reply
    assert {rid: r["error"]["code"] for rid, r in replies.items()} == {
        rid: code for rid, (_f, _p, code) in cases.items()
    }
    assert all(len(r["error"]["message"]) < 300 for r in replies.values())
    assert replies["int-too-long"]["error"]["message"] == (
        f"payload is not UTF-8 JSON: integer too long: more than {sys.get_int_max_str_digits()} digits")
    assert server.connection.counters.handler_errors == 0
    assert calls == []
    with BusClient(BrokerSettings.from_url(broker.url), ROBOT) as good:
        assert good.call("Motor", "add", 1, 2) == 3  # (its request says its time-out, `timeout_s`)
    rejected = [e for e in logs if e["event"] == "call_rejected"]
    assert len(rejected) == len(cases) + 1  # one warning line per bad request
    assert all(e["log_level"] == "warning" for e in rejected)
    assert not [e for e in logs if "exc_info" in e or e["log_level"] in ("error", "critical")]


def test_non_json_bytes_with_an_mqtt5_response_topic_get_bad_json(
    mosquitto_broker: BrokerProcess, calls: list[tuple[Any, ...]],
    raw_client: Callable[..., RawClient],
) -> None:
    settings = BrokerSettings.from_url(mosquitto_broker.url + "?protocol=5")
    srv = ComponentServer(settings, ROBOT, "Motor", "l298n", features(calls))
    srv.start(5.0)
    try:
        raw = raw_client(mosquitto_broker, MQTTProtocolVersion.MQTTv5)
        raw.subscribe("raw/v5")
        payloads = [DEEP, b"\xff\xfe\x00garbage", b'{"id": ', b"[" * 300_000]
        with structlog.testing.capture_logs() as logs:
            for i, payload in enumerate(payloads):
                props = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
                props.ResponseTopic = "raw/v5"
                props.CorrelationData = f"c{i}-{uuid.uuid4().hex[:4]}".encode()
                raw.publish(TOPICS.call("Motor", "dutycycle"), payload, properties=props)
            codes = [json.loads(raw.get(10.0, "raw/v5").payload)["error"]["code"] for _ in payloads]
        assert codes == ["bad_json", "bad_json", "bad_json", "payload_too_large"]
        assert srv.connection.counters.handler_errors == 0
        assert [e["event"] for e in logs] == ["call_rejected"] * len(payloads)
    finally:
        srv.stop()


def test_a_wildcard_mqtt5_response_topic_is_refused_and_the_request_not_run(
    mosquitto_broker: BrokerProcess, calls: list[tuple[Any, ...]],
    raw_client: Callable[..., RawClient],
) -> None:
    """A Response Topic is checked as the envelope's reply_to is: one warning, nothing run, and the
    error reply goes to the envelope's reply_to when it has a good one."""
    settings = BrokerSettings.from_url(mosquitto_broker.url + "?protocol=5")
    srv = ComponentServer(settings, ROBOT, "Motor", "l298n", features(calls))
    srv.start(5.0)
    try:
        raw = raw_client(mosquitto_broker, MQTTProtocolVersion.MQTTv5)
        raw.subscribe("raw/v5")
        with structlog.testing.capture_logs() as logs:
            for topic, payload in (("r5/#", b"50"), ("r5/+/x", envelope("[40]", "w1", "raw/v5"))):
                props = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
                props.ResponseTopic = topic
                raw.publish(TOPICS.call("Motor", "dutycycle"), payload, properties=props)
            reply = json.loads(raw.get(10.0, "raw/v5").payload)
            # the service is still there, and later calls run
            with BusClient(settings, ROBOT) as good:
                assert good.call("Motor", "add", 1, 2) == 3
        assert reply["id"] == "w1" and reply["error"]["code"] == "bad_request"
        assert "Response Topic" in reply["error"]["message"]
        assert calls == []
        assert srv.connection.counters.handler_errors == 0
        assert [e["event"] for e in logs if e["log_level"] != "debug"] == ["call_rejected"] * 2
        assert not [e for e in logs if "exc_info" in e]
    finally:
        srv.stop()


def test_args_that_are_not_a_list_are_refused(broker: BrokerProcess, server: ComponentServer,
                                                calls: list[tuple[Any, ...]],
                                                raw_client: Callable[..., RawClient]) -> None:
    raw = raw_client(broker)
    raw.subscribe("raw/replies")
    raw.publish(TOPICS.call("Motor", "dutycycle"), b'{"id": "a5", "reply_to": "raw/replies", "args": 5}')
    reply = json.loads(raw.get(10.0, "raw/replies").payload)
    assert reply["id"] == "a5" and reply["error"]["code"] == "bad_args"
    assert "JSON array" in reply["error"]["message"]
    assert calls == []
