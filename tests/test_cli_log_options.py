"""`--log-level` and `--log-json` work after the command name as before it (the later one wins)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import BrokerProcess

REPO = Path(__file__).resolve().parent.parent


def umlbot(*args: str) -> subprocess.CompletedProcess[str]:
    environment = {k: v for k, v in os.environ.items() if k != "UMLBOT_LOG_LEVEL"}
    return subprocess.run([sys.executable, "-c", "from umlbot.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=90, env=environment, check=False)


def levels(stderr: str) -> set[str]:
    return {json.loads(line)["level"] for line in stderr.splitlines() if line.startswith("{")}


def test_a_log_level_after_the_command_name_is_accepted() -> None:
    result = umlbot("check", str(REPO / "models" / "robot_car"), "--log-level", "DEBUG")
    assert result.returncode == 0, result.stderr  # was: "No such option '--log-level'" (exit 2)
    assert "robot_car: ok:" in result.stderr


def test_a_bad_log_level_after_the_command_name_is_a_bad_command_line() -> None:
    result = umlbot("check", str(REPO / "models" / "robot_car"), "--log-level", "LOUD")
    assert result.returncode == 2
    assert "Invalid value for '--log-level'" in result.stderr


@pytest.mark.parametrize(("before", "after", "debug_shown"), [
    ([], ["--log-level", "DEBUG", "--log-json"], True),
    (["--log-json"], ["--log-level", "DEBUG"], True),  # the two places combine
    (["--log-level", "DEBUG", "--log-json"], [], True),
    (["--log-level", "DEBUG", "--log-json"], ["--log-level", "WARNING"], False),  # after wins
])
def test_log_options_work_on_either_side_of_the_command_name(
        mosquitto_broker: BrokerProcess, before: list[str], after: list[str], debug_shown: bool) -> None:
    result = umlbot(*before, "monitor", "--json", "--duration", "0.3", "--broker", mosquitto_broker.url,
                    *after)
    assert result.returncode == 0, result.stderr
    assert result.stderr.startswith("{") or not debug_shown, result.stderr  # JSON lines
    assert ("debug" in levels(result.stderr)) == debug_shown, result.stderr  # mqtt_connected is debug
