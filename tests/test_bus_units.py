"""Bus pieces that need no broker: URLs and settings, topics, envelopes, request parsing."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from umlbot.base.errors import ArgumentError, ConfigError
from umlbot.base.library import FeatureSpec, Param, check_args
from umlbot.services.bus import (
    BrokerSettings,
    ExitRequest,
    OrchestratorStatus,
    Reply,
    Status,
    Topics,
    TraceEvent,
    make_client_id,
    redact_url,
    resolve_broker_url,
    to_payload,
)
from umlbot.services.bus.server import _BadInput, parse_request


def test_resolve_broker_url_prefers_cli_then_env(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("UMLBOT_BROKER", raising=False)
    assert resolve_broker_url(None) == "mqtt://127.0.0.1:1883"
    monkeypatch.setenv("UMLBOT_BROKER", "mqtt://env-host:1884")
    assert resolve_broker_url(None) == "mqtt://env-host:1884"
    assert resolve_broker_url("mqtt://cli:1") == "mqtt://cli:1"


def test_settings_from_url_with_credentials_hide_the_password() -> None:
    settings = BrokerSettings.from_url("mqtt://robot:s3cr%40t@broker.local:1999")
    assert (settings.host, settings.port, settings.username) == ("broker.local", 1999, "robot")
    assert settings.password is not None and settings.password.get_secret_value() == "s3cr@t"
    assert settings.url == "mqtt://robot:***@broker.local:1999"
    assert "s3cr" not in repr(settings) and "s3cr" not in str(settings)
    assert settings.protocol == "auto"  # MQTT 5, falling back to 3.1.1 where refused
    assert BrokerSettings.from_url("mqtt://h?protocol=3.1.1").protocol == "3.1.1"
    assert BrokerSettings.from_url("mqtt://h?protocol=auto").protocol == "auto"


def test_settings_defaults_and_tls(tmp_path: Path) -> None:
    assert BrokerSettings.from_url("mqtt://h").port == 1883
    ca = tmp_path / "ca.pem"
    ca.write_text("x")
    tls = BrokerSettings.from_url(f"mqtts://h?ca={ca}&insecure=1&protocol=5")
    assert (tls.port, tls.tls, tls.ca_file, tls.insecure, tls.protocol) == (8883, True, ca, True, "5")
    assert BrokerSettings.from_url("mqtts://h", ca_file=ca).ca_file == ca


@pytest.mark.parametrize(
    ("url", "fragment"),
    [
        ("http://h:1883", "scheme"),
        ("mqtt://:1883", "no host"),
        ("mqtt://h:99999", "bad broker URL"),
        ("mqtt://h?colour=red", "unknown parameter"),
        ("mqtt://h?protocol=7", "protocol"),
        ("mqtts://h?ca=/does/not/exist.pem", "does not exist"),
        ("mqtt://h?ca=/etc/hostname", "mqtts"),
    ],
)
def test_bad_urls_are_config_errors(url: str, fragment: str) -> None:
    with pytest.raises(ConfigError, match=fragment):
        BrokerSettings.from_url(url)


def test_bad_url_error_never_shows_the_password() -> None:
    with pytest.raises(ConfigError) as info:
        BrokerSettings.from_url("http://user:hunter2@h:1883")
    assert "hunter2" not in str(info.value)
    assert "user:***@" in str(info.value)


def test_redact_url() -> None:
    assert redact_url("mqtt://u:p@h:1883") == "mqtt://u:***@h:1883"
    assert redact_url("mqtt://h:1883") == "mqtt://h:1883"


def test_client_id_says_who_it_is() -> None:
    first = make_client_id("service-LeftActuator", "car")
    second = make_client_id("service-LeftActuator", "car")
    assert first.startswith("umlbot-service-LeftActuator-car-")
    assert first != second
    assert "/" not in first and "+" not in first and "#" not in first
    # 128 random bits: nobody can guess a client id to take it over (docs/security.md)
    assert len(first.rsplit("-", 1)[1]) == 32 and int(first.rsplit("-", 1)[1], 16) >= 0


def test_reply_topics_name_the_user_and_a_token_not_the_client_id() -> None:
    topics = Topics("car")
    assert topics.reply("umlbot-operator", "ab12") == "umlbot/car/_reply/umlbot-operator/ab12"
    assert topics.reply(None, "ab12") == "umlbot/car/_reply/ab12"
    assert topics.reply("odd/user", "ab12") == "umlbot/car/_reply/ab12"  # not a topic level


def test_topics() -> None:
    topics = Topics("car")
    assert topics.base == "umlbot/car"
    assert topics.status("Sensor") == "umlbot/car/Sensor/status"
    assert topics.call("LeftActuator", "dutycycle") == "umlbot/car/LeftActuator/call/dutycycle"
    assert topics.state("Sensor") == "umlbot/car/Sensor/state"
    assert topics.signal("obstacle") == "umlbot/car/signal/obstacle"
    assert topics.orchestrator_status == "umlbot/car/orchestrator/status"
    assert topics.orchestrator_trace == "umlbot/car/orchestrator/trace"
    assert topics.orchestrator_exit == "umlbot/car/orchestrator/exit"
    assert topics.parse_call("umlbot/car/LeftActuator/call/dutycycle") == ("LeftActuator", "dutycycle")
    assert topics.parse_call("umlbot/other/LeftActuator/call/dutycycle") is None
    with pytest.raises(ConfigError):
        Topics("my/car")
    with pytest.raises(ConfigError):
        Topics("#")


def test_reply_wire_format() -> None:
    ok = json.loads(to_payload(Reply.success("7", None)))
    assert ok == {"id": "7", "ok": True, "value": None}
    bad = json.loads(to_payload(Reply.failure("8", "bad_args", "nope")))
    assert bad == {"id": "8", "ok": False, "error": {"code": "bad_args", "message": "nope"}}


def test_other_payloads() -> None:
    assert json.loads(to_payload(Status(state="offline"))) == {"state": "offline", "features": []}
    status = Status(state="online", impl="l298n", features=["enabled"])
    assert Status.model_validate_json(to_payload(status)) == status
    event = TraceEvent(lane="L", node="n1", kind="action", start=1.0, end=1.5, duration_ms=500.0, value=3)
    assert TraceEvent.model_validate_json(to_payload(event)) == event
    assert OrchestratorStatus(state="running", model="robot_car").state == "running"
    assert ExitRequest(reason="done").reason == "done"
    assert to_payload(b"\x00") == b"\x00" and to_payload("é") == "é".encode()
    assert to_payload([1, True]) == b"[1,true]"


@pytest.mark.parametrize(
    ("payload", "expected"),
    [
        (b"60", (None, None, [60])),
        (b"[60]", (None, None, [60])),
        (b"true", (None, None, [True])),
        (b"", (None, None, [])),
        (b"null", (None, None, [])),
        (b'"hello"', (None, None, ["hello"])),
        (b'{"x": 1}', (None, None, [{"x": 1}])),
        (b'{"id": "a", "reply_to": "r/t", "args": [1]}', ("a", "r/t", [1])),
        (b'{"id": 3}', (3, None, [])),
    ],
)
def test_parse_request(payload: bytes, expected: tuple[object, object, list[object]]) -> None:
    parsed = parse_request(payload)
    assert (parsed.request_id, parsed.reply_to, parsed.args) == expected


@pytest.mark.parametrize(
    ("payload", "code"),
    [
        (b"{not json", "bad_json"),
        (b"\xff\xfe", "bad_json"),
        (b'{"id": "a", "reply_to": "r", "args": [], "extra": 1}', "bad_request"),
        (b'{"id": "a", "reply_to": "r/+"}', "bad_request"),
        (b'{"id": "a", "reply_to": 5}', "bad_request"),
        (b'{"args": 5}', "bad_args"),
        (b'{"id": "a", "reply_to": "r/t", "args": "60"}', "bad_args"),
    ],
)
def test_parse_request_rejects(payload: bytes, code: str) -> None:
    with pytest.raises(_BadInput) as info:
        parse_request(payload)
    assert info.value.code == code


def test_bad_envelope_still_knows_where_to_answer() -> None:
    with pytest.raises(_BadInput) as info:
        parse_request(b'{"id": "a", "reply_to": "r/t", "args": [], "oops": true}')
    assert (info.value.request_id, info.value.reply_to) == ("a", "r/t")


SPEC = FeatureSpec(
    "mix",
    (Param("n", "int", 0, 100, "%"), Param("on", "bool"), Param("x", "float", -1.5, 1.5), Param("s", "str")),
)


def test_check_args_converts_and_accepts() -> None:
    assert check_args(SPEC, [60, True, 1, "a"]) == [60, True, 1.0, "a"]
    assert check_args(SPEC, [60.0, 1, -1.5, ""]) == [60, True, -1.5, ""]


@pytest.mark.parametrize(
    ("args", "code"),
    [
        ([60, True, 1], "bad_args"),
        ([60, True, 1, "a", 5], "bad_args"),
        (["60", True, 1, "a"], "bad_args"),
        ([60.5, True, 1, "a"], "bad_args"),
        ([True, True, 1, "a"], "bad_args"),
        ([60, "yes", 1, "a"], "bad_args"),
        ([60, 2, 1, "a"], "bad_args"),
        ([60, True, None, "a"], "bad_args"),
        ([60, True, 1, 5], "bad_args"),
        ([101, True, 1, "a"], "out_of_range"),
        ([-1, True, 1, "a"], "out_of_range"),
        ([50, True, 2.0, "a"], "out_of_range"),
    ],
)
def test_check_args_rejects(args: list[object], code: str) -> None:
    with pytest.raises(ArgumentError) as info:
        check_args(SPEC, args)
    assert info.value.code == code
