"""Test helpers: the robot car as real processes (services, orchestrator, monitor) on a broker.

Used by the monitor and security tests: every process is `umlbot …` in a child process, broker
credentials travel in the environment (`UMLBOT_BROKER`), and stdout lines are collected on a
thread so a test can wait for one with a bounded time-out.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
CAR_MODEL = REPO / "models" / "robot_car"
CAR_DEPLOYMENT = CAR_MODEL / "deployment.yaml"
SERVICE_KINDS = ("motor", "sonar", "servo", "gpio")
CAR_COMPONENTS = {"RaspberryPI", "LeftActuator", "RightActuator", "Sensor", "DistanceRead"}


def umlbot_argv(*args: str) -> list[str]:
    """The argv that runs `umlbot ARGS` with the interpreter running the tests."""
    return [sys.executable, "-c", "from umlbot.cli import main; main()", *args]


def compile_car(workdir: Path) -> Path:
    """The reference robot car compiled into `workdir`."""
    out = workdir / "robot_car.json"
    result = subprocess.run(umlbot_argv("compile", str(CAR_MODEL), "-o", str(out)),
                            capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr
    return out


class Proc:
    """A child `umlbot` process; stdout lines are queued, stderr goes to a log file."""

    def __init__(self, name: str, argv: list[str], workdir: Path, broker_url: str,
                 extra_env: dict[str, str] | None = None) -> None:
        self.name = name
        self.log = workdir / f"{name}.log"
        inherited = {k: v for k, v in os.environ.items() if k != "UMLBOT_ROBOT"}
        env = {**inherited, "UMLBOT_BROKER": broker_url, "UMLBOT_LOG_LEVEL": "DEBUG", **(extra_env or {})}
        with self.log.open("wb") as err:
            self.popen = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=err, cwd=workdir, env=env)
        self.lines: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        self._reader = threading.Thread(target=self._read, name=f"read-{name}", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.popen.stdout is not None
        for raw in self.popen.stdout:
            self.lines.put(raw.decode("utf-8", errors="replace").rstrip("\n"))

    def wait_line(self, predicate: Callable[[dict[str, Any]], bool], timeout: float = 15.0) -> dict[str, Any]:
        """The next JSON stdout line (kept in `seen`) for which `predicate` holds."""
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"{self.name}: no matching line within {timeout} s; "
                                     f"last lines: {self.seen[-5:]}\nlog:\n{self.log_text()[-3000:]}")
            try:
                line = self.lines.get(timeout=min(remaining, 0.2))
            except queue.Empty:
                if self.popen.poll() is not None and self.lines.empty():
                    raise AssertionError(f"{self.name} exited ({self.popen.returncode}):\n"
                                         f"{self.log_text()[-3000:]}") from None
                continue
            self.seen.append(line)
            try:
                event = json.loads(line)
            except ValueError:
                continue
            if isinstance(event, dict) and predicate(event):
                return event

    def drain(self, quiet_s: float = 0.3) -> list[dict[str, Any]]:
        """Every JSON line that arrives until none came for `quiet_s` seconds."""
        events: list[dict[str, Any]] = []
        while True:
            try:
                line = self.lines.get(timeout=quiet_s)
            except queue.Empty:
                return events
            self.seen.append(line)
            try:
                events.append(json.loads(line))
            except ValueError:
                continue

    def events(self) -> list[dict[str, Any]]:
        """Every JSON line seen so far."""
        out = []
        for line in self.seen:
            try:
                out.append(json.loads(line))
            except ValueError:
                continue
        return out

    def stop(self, timeout: float = 10.0) -> int:
        """SIGTERM, wait (SIGKILL after `timeout`); returns the exit code."""
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGTERM)
            try:
                self.popen.wait(timeout)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(5)
        self._reader.join(5)
        return self.popen.returncode

    def log_text(self) -> str:
        return self.log.read_text(encoding="utf-8", errors="replace")


@contextmanager
def processes() -> Iterator[list[Proc]]:
    """A list to add processes to; all of them are stopped at the end."""
    made: list[Proc] = []
    try:
        yield made
    finally:
        for proc in reversed(made):
            proc.stop()
            if proc.popen.stdout is not None:
                proc.popen.stdout.close()


def start_services(made: list[Proc], workdir: Path, url_for: Callable[[str], str], robot: str = "car",
                   driver: str = "mock") -> list[Proc]:
    """The four hardware services of the car, each with the broker URL `url_for(kind)`."""
    started = []
    for kind in SERVICE_KINDS:
        proc = Proc(kind, umlbot_argv("service", kind, "--deploy", str(CAR_DEPLOYMENT), "--driver", driver,
                                      "--robot", robot), workdir, url_for(kind))
        made.append(proc)
        started.append(proc)
    return started
