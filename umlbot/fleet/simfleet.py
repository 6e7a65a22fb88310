"""`umlbot sim MODEL --robots N`: N simulated cars, each its own robot on its own leaf Mosquitto,
every leaf bridged to one hub Mosquitto, all on loopback.

Each car is an `umlbot sim MODEL --broker <its leaf> --robot <id> --json` child process (a sim's
world is one per process), so a car runs as it would on its own Pi: its services and orchestrator
talk to its local broker only, and the hub sees it through the bridge. `SimFleet.run` waits for
every car to end (or for `stop`), then stops the cars (SIGINT: each stops its motors and
reports) and the brokers.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from umlbot.base.errors import ConfigError
from umlbot.fleet.brokers import LocalFleet
from umlbot.fleet.config import check_robot_id

#: wall seconds a car has to end after SIGINT before it is killed
CAR_STOP_S = 15.0


def robot_ids(prefix: str, count: int) -> list[str]:
    """`car1` … `carN`."""
    if count < 1:
        raise ConfigError(f"--robots must be at least 1, got {count}")
    return [check_robot_id(f"{prefix}{i}") for i in range(1, count + 1)]


@dataclass
class CarResult:
    """How one car's run ended: its `umlbot sim --json` summary (None if it printed none)."""

    robot: str
    exit_code: int
    summary: dict[str, Any] | None
    stderr_tail: str = ""

    @property
    def ok(self) -> bool:
        return self.exit_code == 0 and self.summary is not None


@dataclass
class SimFleet:
    """A hub, a leaf per car and the cars; `start`, then `run` (or `wait`), then `stop`."""

    model: Path
    robots: list[str]
    #: extra `umlbot sim` options for every car (track, speed, time-out, …)
    sim_args: list[str] = field(default_factory=list)
    hub_port: int | None = None
    #: where the leaves' bridges connect instead of the hub's port (the tests put a link there)
    bridge_port: int | None = None
    workdir: Path | None = None
    fleet: LocalFleet = field(init=False)
    cars: dict[str, subprocess.Popen[str]] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.fleet = LocalFleet(self.robots, self.workdir, self.hub_port, self.bridge_port)

    @property
    def hub_url(self) -> str:
        return self.fleet.hub.url

    def start(self) -> None:
        """The brokers, then every car (each on its own leaf)."""
        self.fleet.start()
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        env.pop("UMLBOT_BROKER", None)
        try:
            for robot in self.robots:
                argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "sim", str(self.model),
                        "--broker", self.fleet.leaf_url(robot), "--robot", robot, "--json", *self.sim_args]
                self.cars[robot] = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                                    text=True, env=env, start_new_session=True)
        except BaseException:
            self.stop()
            raise

    def wait(self, stop: threading.Event | None = None,
             on_result: Callable[[CarResult], None] | None = None) -> dict[str, CarResult]:
        """Until every car has ended (or `stop` is set: the rest are stopped), their results."""
        results: dict[str, CarResult] = {}
        readers = {robot: _Reader(proc) for robot, proc in self.cars.items()}
        while len(results) < len(self.cars):
            if stop is not None and stop.wait(0.1):
                self._interrupt([r for r in self.cars if r not in results])
                stop = None  # from now on wait for their reports
            elif stop is None:
                time.sleep(0.1)
            for robot, proc in self.cars.items():
                if robot not in results and proc.poll() is not None:
                    readers[robot].join()
                    results[robot] = readers[robot].result(robot, proc.returncode)
                    if on_result is not None:
                        on_result(results[robot])
        return results

    def _interrupt(self, robots: list[str]) -> None:
        for robot in robots:
            proc = self.cars[robot]
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + CAR_STOP_S
        for robot in robots:
            proc = self.cars[robot]
            try:
                proc.wait(max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)

    def stop(self) -> None:
        """Every car still running (SIGINT, then SIGKILL), then the brokers; safe to call twice."""
        self._interrupt(list(self.cars))
        for proc in self.cars.values():
            for stream in (proc.stdout, proc.stderr):
                if stream is not None:
                    stream.close()
        self.fleet.stop()

    def __enter__(self) -> SimFleet:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()


class _Reader:
    """Reads a car's output in threads, so that a full pipe never blocks it."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.out: list[str] = []
        self.err: list[str] = []
        self.threads = [threading.Thread(target=self._read, args=(proc.stdout, self.out), daemon=True),
                        threading.Thread(target=self._read, args=(proc.stderr, self.err), daemon=True)]
        for thread in self.threads:
            thread.start()

    @staticmethod
    def _read(stream: Any, into: list[str]) -> None:
        try:
            for line in stream:
                into.append(line)
                del into[:-200]  # the summary is the last line; keep the tail only
        except (OSError, ValueError):
            pass

    def join(self) -> None:
        for thread in self.threads:
            thread.join(5)

    def result(self, robot: str, code: int) -> CarResult:
        summary = None
        for line in reversed(self.out):
            try:
                data = json.loads(line)
            except ValueError:
                continue
            if isinstance(data, dict):
                summary = data
                break
        return CarResult(robot, code, summary, "".join(self.err)[-2000:])
