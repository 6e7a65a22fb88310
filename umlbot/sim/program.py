"""The generated C++ orchestrator as the sim's engine (`umlbot sim --engine cpp`).

`ProgramOrchestrator` runs the program (`umlbot generate cpp`, built and cached by
`umlbot.codegen.cached_program`) as a child process against the sim's broker, and offers the
runner what it reads of the in-process `Orchestrator`: `run_sync`, `request_exit`, `failure`,
`stats` (actions and their latencies, from the program's trace file), `life.on_fault`,
`safety_stops`.

Given the run's `SimClock`, the program runs with `--sim-clock`: its sleeps take sim time, and
`ClockBridge` makes the program a participant of the event-driven clock as the in-process
orchestrator is: each of its sleeps is a deadline of the clock (woken over MQTT when it is due),
and while any of its lane threads has something to do (a node, a call in flight) the clock stands
still, as for a call in flight (`call_started`). A run is then the same at every `--speed` and
on a loaded machine. Without one (a wall-paced `Clock`), the program sleeps in wall time scaled
by `--speed`.
"""

from __future__ import annotations

import asyncio
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
from umlbot.sim.clock import SimClock

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


class ClockBridge:
    """The program's side of a `SimClock` (see the module docstring), on its own event loop thread.

    Topics: the program says `{"sleep": id, "s": seconds}`, `{"cancel": id}` and
    `{"busy": n, "woken": w}` on `umlbot/<robot>/sim/clock/program`; the bridge answers
    `{"wake": id, "now": t}` on `umlbot/<robot>/sim/clock/sim`. The clock counts as many calls in
    flight as the program has busy threads plus the wakes sent that it has not handled yet.
    """

    def __init__(self, clock: SimClock, broker_url: str, robot: str) -> None:
        self.clock = clock
        self.broker_url = broker_url
        self.robot = robot
        self.inbox = f"umlbot/{robot}/sim/clock/program"
        self.outbox = f"umlbot/{robot}/sim/clock/sim"
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="sim-clock-bridge", daemon=True)
        self._queue: asyncio.Queue[dict[str, Any]] | None = None
        self._sleeps: dict[int, asyncio.Task[None]] = {}
        self._busy = 0
        self._woken = 0
        self._sent = 0
        self._held = 0  # calls in flight the clock counts for the program
        self._connection: Any = None

    def start(self, timeout_s: float = 5.0) -> ClockBridge:
        from umlbot.services.bus import BrokerSettings, BusConnection

        self._thread.start()
        self._queue = asyncio.run_coroutine_threadsafe(self._make_queue(), self._loop).result(timeout_s)
        asyncio.run_coroutine_threadsafe(self._serve(), self._loop)
        connection = BusConnection(BrokerSettings.from_url(self.broker_url), "sim-clock", robot=self.robot)
        connection.subscribe(self.inbox, self._on_message, qos=0)
        connection.start(timeout_s)  # subscriptions made before start() are confirmed by then
        self._connection = connection
        return self

    def stop(self) -> None:
        if self._connection is not None:
            self._connection.close()
            self._connection = None
        if self._thread.is_alive():
            future = asyncio.run_coroutine_threadsafe(self._finish(), self._loop)
            with contextlib.suppress(Exception):
                future.result(5.0)
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout=5.0)
        if not self._loop.is_running():
            self._loop.close()

    async def _make_queue(self) -> asyncio.Queue[dict[str, Any]]:
        return asyncio.Queue()

    def _on_message(self, message: Any) -> None:  # the connection's dispatcher thread
        try:
            data = message.json()
        except ValueError:
            return
        if isinstance(data, dict) and self._queue is not None:
            with contextlib.suppress(RuntimeError):  # the loop is closed
                self._loop.call_soon_threadsafe(self._queue.put_nowait, data)

    async def _serve(self) -> None:
        """Handle the program's messages in their order."""
        assert self._queue is not None
        while True:
            data = await self._queue.get()
            if "sleep" in data:
                ident = int(data["sleep"])
                self._sleeps[ident] = asyncio.get_running_loop().create_task(
                    self._sleep(ident, float(data.get("s", 0.0))))
                await asyncio.sleep(0)  # the sleep's deadline is on the clock before what follows
            elif "cancel" in data:
                task = self._sleeps.pop(int(data["cancel"]), None)
                if task is not None:
                    task.cancel()
            elif "busy" in data:
                self._busy = max(0, int(data["busy"]))
                self._woken = int(data.get("woken", self._woken))
                self._balance()

    async def _sleep(self, ident: int, seconds: float) -> None:
        await self.clock.asleep(seconds)
        self._sleeps.pop(ident, None)
        self._sent += 1
        self._balance()  # busy from now on: the woken thread has something to do
        connection = self._connection
        if connection is not None:
            with contextlib.suppress(Exception):  # not connected: the run is ending
                connection.publish(self.outbox, {"wake": ident, "now": self.clock.now()}, qos=0)

    def _balance(self) -> None:
        want = self._busy + max(0, self._sent - self._woken)
        while self._held < want:
            self.clock.call_started()
            self._held += 1
        while self._held > want:
            self.clock.call_finished()
            self._held -= 1

    async def _finish(self) -> None:
        """Give the clock back what the program held, and end every task of this loop (the
        clock's ticker, if it runs here, included)."""
        self._sleeps.clear()
        self._busy = self._sent = self._woken = 0
        self._balance()
        tasks = [task for task in asyncio.all_tasks() if task is not asyncio.current_task()]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)


class ProgramOrchestrator:
    """A generated orchestrator program run as a child process (see the module docstring)."""

    def __init__(self, program: Path, compiled: CompiledModel, broker_url: str, robot: str, speed: float,
                 trace_file: Path, listener: Callable[[dict[str, Any]], None] | None = None,
                 clock: SimClock | None = None) -> None:
        self.program = program
        self.components = frozenset(compiled.components)
        timing = ["--sim-clock"] if clock is not None else ["--speed", repr(speed)]
        self.argv = [str(program), "--broker", broker_url, "--robot", robot, *timing,
                     "--trace", str(trace_file), "--log-level", "WARNING"]
        self.bridge = ClockBridge(clock, broker_url, robot) if clock is not None else None
        self.trace_file = trace_file
        self.listener = listener
        self.stats = ProgramStats()
        self.life = _Life()
        self.safety_stops: dict[str, str] = {}
        self.failure: str | None = None
        self._proc: subprocess.Popen[str] | None = None
        self._exits = 0
        self._lock = threading.Lock()
        self._position = 0  # how far the trace file has been read
        self._reading = threading.Lock()

    def run_sync(self) -> int:
        """Run the program to its end, following its trace; returns its exit code."""
        if self.bridge is not None:
            self.bridge.start()
        try:
            return self._run()
        finally:
            if self.bridge is not None:
                self.bridge.stop()

    def _run(self) -> int:
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
        while proc.poll() is None:
            self._read_trace()
            time.sleep(0.02)
        reader.join(timeout=5)
        self._read_trace()
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

    def settle(self, quiet_s: float = 0.1, timeout_s: float = 2.0) -> None:
        """Read the trace as far as the program wrote it, once the file stopped growing for
        `quiet_s` (it ships its trace every 20 ms): `stats` then count every action it made."""
        deadline = time.monotonic() + timeout_s
        size, since = -1, time.monotonic()
        while time.monotonic() < deadline:
            try:
                now_size = self.trace_file.stat().st_size
            except OSError:
                return
            if now_size != size:
                size, since = now_size, time.monotonic()
            elif time.monotonic() - since >= quiet_s:
                break
            time.sleep(0.02)
        self._read_trace()

    def _read_trace(self) -> None:
        with self._reading:
            self._position = self._follow(self._position)

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
