"""The generated C++ orchestrator as the sim's engine (`umlbot sim --engine cpp`).

`ProgramOrchestrator` runs the program (`umlbot generate cpp`, built and cached by
`umlbot.codegen.cached_program`) as a child process against the sim's broker, and offers the
runner what it reads of the in-process `Orchestrator`: `run_sync`, `request_exit`, `failure`,
`stats` (actions and their latencies, from the program's trace file), `life.on_fault`,
`safety_stops`. The program lives in wall time, so the world runs on a wall-paced `Clock` at the
run's speed (the program's sleeps are scaled by `--speed` as well), not on the event-driven
`SimClock` the in-process orchestrator shares: a run is then paced by the machine, as on a robot.
"""

from __future__ import annotations

import collections
import contextlib
import json
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from umlbot.base.logs import get_logger
from umlbot.compiler.compiled import CompiledModel

log = get_logger(__name__)

FaultListener = Callable[[Any], None]


@dataclass
class ProgramStats:
    """What the program executed, read from its trace: feature-call actions and their latencies."""

    actions: int = 0
    action_latency_s: collections.deque[float] = field(
        default_factory=lambda: collections.deque(maxlen=100_000))


class _Life:
    def __init__(self) -> None:
        self.listeners: list[FaultListener] = []

    def on_fault(self, listener: FaultListener) -> None:
        self.listeners.append(listener)


class ProgramOrchestrator:
    """A generated orchestrator program run as a child process (see the module docstring)."""

    def __init__(self, program: Path, compiled: CompiledModel, broker_url: str, robot: str, speed: float,
                 trace_file: Path, listener: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.program = program
        self.components = frozenset(compiled.components)
        self.argv = [str(program), "--broker", broker_url, "--robot", robot, "--speed", repr(speed),
                     "--trace", str(trace_file), "--log-level", "WARNING"]
        self.trace_file = trace_file
        self.listener = listener
        self.stats = ProgramStats()
        self.life = _Life()
        self.safety_stops: dict[str, str] = {}
        self.failure: str | None = None
        self._proc: subprocess.Popen[str] | None = None
        self._exits = 0
        self._lock = threading.Lock()

    def run_sync(self) -> int:
        """Run the program to its end, following its trace; returns its exit code."""
        with self._lock:
            self._proc = subprocess.Popen(self.argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                          text=True, env={**os.environ, "UMLBOT_BROKER": ""})
            if self._exits:  # asked to end before it started
                self._proc.send_signal(signal.SIGTERM)
        proc = self._proc
        assert proc.stderr is not None
        errors: list[str] = []
        reader = threading.Thread(target=lambda: errors.extend(proc.stderr or []), daemon=True)
        reader.start()
        position = 0
        while proc.poll() is None:
            position = self._follow(position)
            time.sleep(0.02)
        reader.join(timeout=5)
        self._follow(position)
        code = proc.returncode
        if code != 0:
            lines = [line.strip() for line in errors if line.startswith("error: ")]
            text = lines[-1].removeprefix("error: ") if lines else f"exit status {code}"
            self.failure = text.removeprefix("fail-safe stop: ")
            for listener in self.life.listeners:
                with contextlib.suppress(Exception):
                    listener(self.failure)
        return code

    def request_exit(self, reason: str = "exit requested") -> None:
        """SIGTERM the program (a second call ends its grace period, as a second SIGTERM does)."""
        with self._lock:
            self._exits += 1
            if self._proc is not None and self._proc.poll() is None:
                log.info("sim_program_exit", reason=reason)
                self._proc.send_signal(signal.SIGTERM)

    def _follow(self, position: int) -> int:
        """Read the trace lines written since `position` (whole lines only)."""
        try:
            with self.trace_file.open("rb") as handle:
                handle.seek(position)
                chunk = handle.read()
        except OSError:
            return position
        end = chunk.rfind(b"\n") + 1
        for line in chunk[:end].splitlines():
            try:
                event = json.loads(line)
            except ValueError:
                continue
            component = str(event.get("detail", "")).split(".", 1)[0]
            if event.get("kind") == "action" and component in self.components:
                self.stats.actions += 1
                self.stats.action_latency_s.append(float(event.get("duration_ms", 0.0)) / 1000.0)
            if self.listener is not None:
                self.listener(event)
        return position + end
