"""`umlbot call` as a user runs it: a subprocess against a real broker and a test server."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest
from conftest import BrokerProcess, free_port

from umlbot.base.catalog import implementations
from umlbot.base.library import FeatureSpec, Param
from umlbot.commands.call import EXIT_ERROR_REPLY, EXIT_NOT_CONNECTED, EXIT_TIMEOUT, parse_arg
from umlbot.services.bus import BrokerSettings, ComponentServer, Feature

pytestmark = pytest.mark.network

received: list[tuple[str, Any]] = []


def _features() -> list[Feature]:
    motor = implementations()["l298n"].features
    return [
        Feature(motor["dutycycle"], lambda percent: received.append(("dutycycle", percent))),
        Feature(FeatureSpec("value", (), "int"), lambda: 42),
        Feature(FeatureSpec("echo", (Param("text", "str"),), "str"), lambda text: text),
    ]


@pytest.fixture
def served(broker: BrokerProcess) -> Iterator[BrokerProcess]:
    received.clear()
    settings = BrokerSettings.from_url(broker.url)
    server = ComponentServer(settings, "clicar", "LeftActuator", "l298n", _features())
    server.start(5.0)
    yield broker
    server.stop()


def run_call(
    broker_url: str, *args: str, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    environment = {**os.environ, "UMLBOT_LOG_LEVEL": "ERROR", **(env or {})}
    environment.pop("UMLBOT_BROKER", None)
    return subprocess.run(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "call", "--broker", broker_url, *args],
        capture_output=True,
        text=True,
        timeout=60,
        env=environment,
    )


def test_call_prints_the_reply_as_json(served: BrokerProcess) -> None:
    result = run_call(served.url, "--robot", "clicar", "LeftActuator.value")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == {"ok": True, "value": 42}
    result = run_call(served.url, "--robot", "clicar", "LeftActuator.dutycycle", "60")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == {"ok": True, "value": None}
    assert received == [("dutycycle", 60)]


def test_log_options_after_the_target_are_options_not_arguments(served: BrokerProcess) -> None:
    """`--log-level X` among the ARGS is the log option (as before the command name); it used
    to be sent as two more arguments. `--` still passes such a text as an argument."""
    result = run_call(served.url, "--robot", "clicar", "LeftActuator.dutycycle", "60", "--log-level", "ERROR",
                      "--no-log-json")
    assert result.returncode == 0, result.stderr
    assert received == [("dutycycle", 60)]
    result = run_call(served.url, "--robot", "clicar", "LeftActuator.echo", "--", "--log-level")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout) == {"ok": True, "value": "--log-level"}


def test_error_reply_exits_1_with_code_and_message(served: BrokerProcess) -> None:
    result = run_call(served.url, "--robot", "clicar", "LeftActuator.dutycycle", "150")
    assert result.returncode == EXIT_ERROR_REPLY
    assert result.stderr.strip().startswith("out_of_range: ")
    assert "150" in result.stderr
    assert json.loads(result.stdout)["error"]["code"] == "out_of_range"
    assert received == []


def test_robot_from_environment_and_string_args(amqtt_broker: BrokerProcess) -> None:
    server = ComponentServer(BrokerSettings.from_url(amqtt_broker.url), "envbot", "LeftActuator", "l298n",
                             _features())
    with server:
        env = {"UMLBOT_ROBOT": "envbot"}
        result = run_call(amqtt_broker.url, "LeftActuator.echo", "hello world", env=env)
        assert result.returncode == 0, result.stderr
        assert json.loads(result.stdout)["value"] == "hello world"
        result = run_call(amqtt_broker.url, "LeftActuator.echo", "60", env=env)
        assert result.returncode == EXIT_ERROR_REPLY  # 60 parses as JSON: a number, not a string
        assert result.stderr.startswith("bad_args: ")


def test_timeout_exits_3(amqtt_broker: BrokerProcess) -> None:
    result = run_call(amqtt_broker.url, "--robot", "nobody", "--timeout", "0.3", "Ghost.value")
    assert result.returncode == EXIT_TIMEOUT
    assert result.stderr.startswith("timeout: ")


def test_unreachable_broker_exits_4() -> None:
    result = run_call(f"mqtt://127.0.0.1:{free_port()}", "--connect-timeout", "0.3", "LeftActuator.value")
    assert result.returncode == EXIT_NOT_CONNECTED
    assert result.stderr.startswith("not_connected: ")


def test_bad_target_is_a_usage_error() -> None:
    result = run_call("mqtt://127.0.0.1:1", "nodot")
    assert result.returncode == 2
    assert "Component.feature" in result.stderr


def test_bad_broker_url_is_one_line_and_hides_the_password() -> None:
    result = run_call("http://user:hunter2@h:1", "A.b")
    assert result.returncode == 1
    assert "hunter2" not in result.stderr and "Traceback" not in result.stderr
    assert "scheme" in result.stderr


@pytest.mark.parametrize(
    ("text", "value"),
    [("60", 60), ("true", True), ("1.5", 1.5), ('"60"', "60"), ("[1, 2]", [1, 2]), ("left", "left"),
     ("", "")],
)
def test_parse_arg(text: str, value: Any) -> None:
    assert parse_arg(text) == value
