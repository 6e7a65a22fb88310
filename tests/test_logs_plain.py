"""Logs a person reads are plain sentences, also on a stderr that is not a terminal (under `make`,
in an editor); machines get JSON lines when they ask for them (issue 28 §5)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

SNIPPET = """
import sys
from umlbot.base.logs import configure_logging, get_logger
configure_logging(person=sys.argv[1] == "person", json={"ask": True, "no": None}[sys.argv[2]])
get_logger("umlbot.sim.runner").warning("default broker port taken, using a free one", port=1883,
                                        reason="[Errno 98] Address already in use")
"""


def log_line(*args: str, env: dict[str, str] | None = None) -> str:
    environment = {k: v for k, v in os.environ.items() if k not in ("UMLBOT_LOG_JSON", "UMLBOT_LOG_LEVEL")}
    done = subprocess.run([sys.executable, "-c", SNIPPET, *args], capture_output=True, text=True,
                          timeout=60, env={**environment, **(env or {})}, check=True)
    return done.stderr


def test_a_command_a_person_runs_logs_plain_sentences_on_a_stderr_that_is_no_terminal() -> None:
    said = log_line("person", "no")
    assert said == ("warning: default broker port taken, using a free one "
                    "(port 1883, reason [Errno 98] Address already in use)\n"), said
    assert "\x1b[" not in said  # no colour codes either


def test_json_lines_when_asked_for_and_for_the_services() -> None:
    for said in (log_line("person", "ask"), log_line("person", "no", env={"UMLBOT_LOG_JSON": "1"}),
                 log_line("service", "no")):  # a service under systemd or the orchestrator: JSON
        event = json.loads(said)
        assert event["event"] == "default broker port taken, using a free one" and event["port"] == 1883


def test_the_cli_marks_the_commands_a_person_runs() -> None:
    from umlbot.cli import PERSON_COMMANDS

    assert {"sim", "studio", "check"} <= PERSON_COMMANDS
    assert not {"run", "service", "broker", "monitor"} & PERSON_COMMANDS
