"""Helpers for the compiler tests: a small valid one-file model and a way to check variants of it."""

from __future__ import annotations

import re
from pathlib import Path

from umlbot.base.diagnostics import Diagnostic
from umlbot.compiler.api import CheckResult, check_model

HEADER = """\
name: t
components:
  Pi: {kind: system}
  Motor:
    kind: actuator
    ports: {drive: enabled}
  Servo: {kind: actuator}
  Sonar: {kind: sensor}
deployment:
  driver: mock
  components:
    Pi: {impl: raspberrypi}
    Motor: {impl: l298n}
    Servo: {impl: servo}
    Sonar: {impl: hcsr04}
lanes:
"""

#: a valid main lane; tests replace its middle line or add lanes after it.
MAIN = """\
  - lane: Pi
    nodes:
      - {id: start, kind: start}
      - {id: go, kind: action, call: Motor.enabled(true)}
      - {id: end, kind: end}
"""


#: what the error of a file that cannot be read ends with when checks of the other files that
#: depend on it were left out.
LEFT_OUT = (r" \((?:1 check that depends|[0-9]+ checks that depend) on this file (?:was|were) left out "
            r"until it can be read\)")


def with_left_out(line: str) -> re.Pattern[str]:
    """`line` (an error of a file that cannot be read) followed by the left-out note."""
    return re.compile(re.escape(line) + LEFT_OUT)


def check_text(tmp_path: Path, text: str, name: str = "model.yaml") -> CheckResult:
    """Write `text` as a one-file model and check it."""
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return check_model(path)


def position(text: str, needle: str, nth: int = 0) -> tuple[int, int]:
    """1-based (line, column) of the `nth` occurrence of `needle` in `text`."""
    index = -1
    for _ in range(nth + 1):
        index = text.index(needle, index + 1)
    before = text[:index]
    return before.count("\n") + 1, index - (before.rfind("\n") + 1) + 1


def errors_of(result: CheckResult) -> list[Diagnostic]:
    return [d for d in result.diagnostics if d.severity == "error"]


def at(diagnostic: Diagnostic) -> tuple[int, int]:
    return diagnostic.location.line, diagnostic.location.column
