"""The orchestrator: runs a compiled model against the robot's services over MQTT, safely.

Life of a run (docs/semantics.md says the same for users):

1. connect (two connections: `control` carries the retained status with its last will
   `offline`, the subscriptions, the trace and the signals; `calls` carries feature calls only,
   so a burst of trace events never queues in front of a request); from then on, until the
   final status, a heartbeat on `…/orchestrator/heartbeat` (every `heartbeat_s` of wall time, sent
   from the event loop: a loop that hangs stops it) names the reply topic of its calls: the
   motors it commanded keep running while it comes (its lease) and stop within their
   `watchdog_s` once it stays away (docs/services.md, Safety);
2. wait, bounded by `startup_timeout_s`, until every used component's retained status is
   `online` (else `OrchestratorError` naming the missing ones);
3. stop every actuator (its implementation's `safe_stop` calls, from the compiled file), publish
   status `running` and start every component lane at once;
4. run until every lane ended, termination was requested (SIGINT/SIGTERM, `request_exit`, a
   message on `…/orchestrator/exit`: `Application.exit` becomes true, lanes get `grace_s` to
   finish) or a fault happened (a call timed out or got an error reply, an expression failed, a
   used component went `offline`, the broker connection was lost: fail-safe at once);
5. on every path: cancel the lanes, stop every actuator (after a lost broker: as soon as it is
   back, waiting at most `reconnect_wait_s`), flush the trace, publish the final status
   `stopped` or `failed` with the reason, disconnect.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import signal
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from umlbot.base.clock import Clock
from umlbot.base.errors import BusError, NotConnected, OrchestratorError
from umlbot.base.library import StopArg
from umlbot.base.logs import get_logger
from umlbot.compiler.compiled import CompiledModel
from umlbot.services.bus import (
    BrokerSettings,
    BusClient,
    BusConnection,
    ExitRequest,
    Message,
    OrchestratorStatus,
    Status,
    Topics,
    Will,
    dumps,
    parse_json,
)
from umlbot.services.orchestrator.engine import Engine, EngineStats, NodeFailed, used_components
from umlbot.services.orchestrator.expressions import Value
from umlbot.services.orchestrator.life import BROKER_LOST_REASON, Fault, FaultKind, Life, Phase
from umlbot.services.orchestrator.signals import SignalBoard
from umlbot.services.orchestrator.trace import Listener, TraceRecorder

log = get_logger(__name__)

#: seconds the lanes get to finish on their own after termination was requested.
DEFAULT_GRACE_S = 2.0
#: seconds to wait at start-up for every used component to be online.
DEFAULT_STARTUP_TIMEOUT_S = 10.0
#: seconds to wait for a lost broker to come back before giving up on the final stop calls.
DEFAULT_RECONNECT_WAIT_S = 10.0
#: seconds to wait for the first broker connection.
CONNECT_TIMEOUT_S = 5.0
#: time-out of each safe-stop call on the way out (the services stop on their own anyway).
FINAL_STOP_TIMEOUT_S = 1.0
#: after a reconnect, seconds to wait for the actuators' services to be back online.
ACTUATORS_BACK_TIMEOUT_S = 2.0
#: seconds cancelled lanes get to unwind.
LANE_CANCEL_TIMEOUT_S = 2.0
#: the heartbeat's period: at most this, and a quarter of the shortest `watchdog_s` among the
#: model's components (a motor stops when the heartbeat stays away that long) ...
HEARTBEAT_MAX_S = 0.25
#: ... but at least this
HEARTBEAT_MIN_S = 0.02

#: a lost broker connection this soon after a component went offline (or a call found no
#: connection) is reported as the cause: the broker went down and sent the last wills first.
BROKER_GONE_WINDOW_S = 5.0
BROKER_LOST = BROKER_LOST_REASON
#: an exit request's reason is cut to this many characters (it is logged and kept in the status).
MAX_REASON_CHARS = 200
EXIT_OK = 0
EXIT_FAULT = 1


def heartbeat_period_s(compiled: CompiledModel) -> float:
    """Seconds between two heartbeats: `HEARTBEAT_MAX_S`, or a quarter of the shortest positive
    `watchdog_s` in the model's component settings when that is shorter (`HEARTBEAT_MIN_S` at
    least)."""
    watchdogs = [
        float(value) for component in compiled.components.values()
        if isinstance(value := component.settings.get("watchdog_s"), int | float)
        and not isinstance(value, bool) and value > 0
    ]
    return max(HEARTBEAT_MIN_S, min([HEARTBEAT_MAX_S, *(w / 4 for w in watchdogs)]))


class _ExitWhileConnecting(Exception):
    """Termination was requested before the broker answered."""


def shorten(reason: str, limit: int = MAX_REASON_CHARS) -> str:
    """A reason cut to `limit` characters (an ellipsis and the full length say it was longer)."""
    if len(reason) <= limit:
        return reason
    return f"{reason[:limit]}… ({len(reason)} characters)"


class Orchestrator:
    """Executes one compiled model; `await run()` returns the exit code (0 ok, 1 fault).

    `run()` raises `OrchestratorError` when the run could not start (broker unreachable, components
    not online). `request_exit(reason)` may be called from any thread, before or during the run.
    """

    def __init__(
        self,
        compiled: CompiledModel,
        broker_settings: BrokerSettings,
        robot: str | None = None,
        clock: Clock | None = None,
        call_timeout_s: float | None = None,
        trace: bool = True,
        trace_file: str | Path | None = None,
        grace_s: float = DEFAULT_GRACE_S,
        startup_timeout_s: float = DEFAULT_STARTUP_TIMEOUT_S,
        reconnect_wait_s: float = DEFAULT_RECONNECT_WAIT_S,
        trace_listener: Listener | None = None,
        handle_signals: bool = True,
    ) -> None:
        self.model = compiled
        self.settings = broker_settings
        self.robot = robot or compiled.name
        self.topics = Topics(self.robot)
        self.clock = clock or Clock(1.0)
        self.call_timeout_s = compiled.call_timeout_s if call_timeout_s is None else call_timeout_s
        if not self.call_timeout_s > 0:
            raise OrchestratorError(f"the call time-out must be > 0 s, got {self.call_timeout_s!r}")
        self.trace_to_mqtt = trace
        self.trace_file = trace_file
        self.trace_listener = trace_listener
        self.grace_s = grace_s
        self.startup_timeout_s = startup_timeout_s
        self.reconnect_wait_s = reconnect_wait_s
        self.handle_signals = handle_signals
        #: wall seconds between two heartbeats (`heartbeat_period_s`)
        self.heartbeat_s = heartbeat_period_s(compiled)
        self._heartbeat: asyncio.Task[None] | None = None
        #: the run's phase, its first fault and why termination was requested (a state machine;
        #: `life.on_fault`/`life.on_move` let others hear of it)
        self.life = Life()
        self._broker_symptom_at: float | None = None  # when a fault came that a broker's end explains
        #: component -> the safety stop its service reported while the model ran (a motor's
        #: `stop_reason`: watchdog, orchestrator unresponsive, deadman …): why the car stood still
        self.safety_stops: dict[str, str] = {}
        self._stop_reasons: dict[str, str | None] = {}  # the last `stop_reason` each state said
        self._stop_reasons_seen: dict[str, str | None] = {}  # the same, on the dispatcher thread
        self.signals = SignalBoard.for_model(compiled)
        self.engine = Engine(compiled, self, self.signals, self.clock)
        self.used = sorted(used_components(compiled))
        self.actuators = self._actuator_stops()
        self.required = sorted(set(self.used) | {name for name, _, _ in self.actuators})
        self.availability: dict[str, str] = {}
        self.recorder: TraceRecorder | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._changed: asyncio.Event | None = None
        self._exit_deadline: float | None = None
        self._pending_exit: str | None = None
        self._lane_tasks: dict[str, asyncio.Task[None]] = {}
        self._closing = False
        self._connecting = False  # _connect() waits for the broker
        self._running = False
        self._control: BusConnection | None = None
        self._client: BusClient | None = None
        #: `time.perf_counter()` when the lanes started and when the last one ended (or was cancelled).
        self.lane_window: tuple[float, float] = (0.0, 0.0)

    @property
    def failure(self) -> str | None:
        """The reason of the fail-safe stop, None while nothing went wrong."""
        return self.life.fault.reason if self.life.fault is not None else None

    @property
    def exit_reason(self) -> str | None:
        """Why termination was requested, None until it was."""
        return self.life.exit_reason

    @property
    def state(self) -> str:
        """The run's phase, as its status says it: starting, running, stopping, stopped or failed."""
        return self.life.phase.value

    @property
    def stats(self) -> EngineStats:
        """Executed nodes, actions and their latencies so far."""
        return self.engine.stats

    # --- public control -----------------------------------------------------------------------------

    def request_exit(self, reason: str = "exit requested") -> None:
        """Ask the run to end: `Application.exit` becomes true, lanes get the grace period.

        Thread-safe; a second request ends the grace period at once.
        """
        loop = self._loop
        if loop is None:
            self._pending_exit = self._pending_exit or reason
            return
        try:
            current = asyncio.get_running_loop()
        except RuntimeError:
            current = None
        if current is loop:
            self._on_exit_request(reason)
        else:
            with contextlib.suppress(RuntimeError):  # the loop is already closed: nothing to end
                loop.call_soon_threadsafe(self._on_exit_request, reason)

    def run_sync(self) -> int:
        """`run()` in a fresh event loop (for callers without one)."""
        return asyncio.run(self.run())

    async def run(self) -> int:
        """Run the model to its end; returns 0 (ended or exit requested) or 1 (fail-safe stop)."""
        if self._running:
            raise OrchestratorError("this orchestrator is already running")
        self._running = True
        self._loop = asyncio.get_running_loop()
        self._changed = asyncio.Event()
        remove_handlers = self._install_signal_handlers()
        started = time.monotonic()
        start_error: OrchestratorError | None = None
        try:
            try:
                await self._connect()
            except _ExitWhileConnecting:  # nothing ran and no actuator was reached: nothing to stop
                self.life.move(Phase.STOPPED, self.exit_reason)
                log.info("orchestrator_finished", exit_code=EXIT_OK, failure=None,
                         exit_reason=self.exit_reason, nodes=0, actions=0,
                         wall_s=round(time.monotonic() - started, 3))
                return EXIT_OK
            self._heartbeat = asyncio.create_task(self._beat(), name="heartbeat")
            try:
                if self._pending_exit is not None:
                    self._on_exit_request(self._pending_exit)
                self._publish_status()
                await self._wait_online()
                if self.failure is None and self.exit_reason is None:
                    await self._stop_actuators(at_start=True)
                if self.failure is None and self.exit_reason is None:
                    self._enter(Phase.RUNNING)
                    log.info("orchestrator_running", robot=self.robot, model=self.model.name,
                             lanes=self.engine.component_lanes(), call_timeout_s=self.call_timeout_s)
                    await self._supervise()
            except OrchestratorError as exc:
                start_error = exc
                self._fail(Fault(FaultKind.START, str(exc), cause=exc))
            finally:
                code = await self._shut_down()
        finally:
            remove_handlers()
        log.info("orchestrator_finished", exit_code=code, failure=self.failure, exit_reason=self.exit_reason,
                 nodes=self.stats.nodes, actions=self.stats.actions, safety_stops=self.safety_stops,
                 wall_s=round(time.monotonic() - started, 3))
        if start_error is not None:
            raise start_error
        return code

    # --- Port (what the engine calls) ---------------------------------------------------------------

    async def call(self, component: str, feature: str, args: list[Value]) -> Value:
        """One feature call with the run's time-out."""
        client = self._client
        if client is None:
            raise NotConnected("the orchestrator is not connected")
        self.clock.call_started()  # a simulated clock stands still while a call is in flight
        try:
            return await client.acall(component, feature, *args, timeout=self.call_timeout_s)
        finally:
            self.clock.call_finished()

    def publish_signal(self, name: str, payload: Value) -> None:
        """Publish `…/signal/<name>` with the payload as JSON (QoS 1)."""
        control = self._control
        if control is None:
            raise NotConnected("the orchestrator is not connected")
        control.publish(self.topics.signal(name), dumps(payload).encode("utf-8"), qos=1)

    # --- start-up -----------------------------------------------------------------------------------

    async def _connect(self) -> None:
        will = Will(
            self.topics.orchestrator_status,
            OrchestratorStatus(state="offline", reason="orchestrator connection lost", model=self.model.name),
        )
        control = BusConnection(self.settings, role="orchestrator", will=will, robot=self.robot)
        client = BusClient(self.settings, self.robot, role="orchestrator-calls")
        self._control, self._client = control, client
        control.subscribe(f"{self.topics.base}/+/status", self._on_status_message)
        control.subscribe(f"{self.topics.base}/+/state", self._on_state_message)
        control.subscribe(self.topics.signals, self._on_signal_message)
        control.subscribe(self.topics.orchestrator_exit, self._on_exit_message)
        control.add_on_disconnect(lambda: self._to_loop(self._connection_lost, True))
        client.connection.add_on_disconnect(lambda: self._to_loop(self._connection_lost, False))
        control.add_on_connect(self._on_connected)
        client.connection.add_on_connect(self._on_connected)
        self._connecting = True
        try:
            await asyncio.gather(
                asyncio.to_thread(control.start, CONNECT_TIMEOUT_S),
                asyncio.to_thread(client.start, CONNECT_TIMEOUT_S),
            )
        except NotConnected as exc:
            await asyncio.to_thread(self._close_connections)
            if self.exit_reason is not None:
                raise _ExitWhileConnecting from exc
            raise OrchestratorError(str(exc)) from exc
        finally:
            self._connecting = False
        if self._closing:  # the exit request came as the connections were made
            await asyncio.to_thread(self._close_connections)
            raise _ExitWhileConnecting
        if self.trace_to_mqtt or self.trace_file is not None or self.trace_listener is not None:
            self.recorder = TraceRecorder(
                self._publish_trace if self.trace_to_mqtt else None, self.trace_file, self.trace_listener
            )
            self.engine.trace = self.recorder.record

    async def _wait_online(self) -> None:
        loop, changed = self._runtime()
        deadline = loop.time() + self.startup_timeout_s
        while True:
            missing = [c for c in self.required if self.availability.get(c) != "online"]
            if self.failure is not None or self.exit_reason is not None:
                return
            if not missing and self._connected():
                return
            remaining = deadline - loop.time()
            if remaining <= 0 and not self._connected():
                raise OrchestratorError(
                    f"lost the connection to the MQTT broker at {self.settings.url} during start-up "
                    f"and it did not come back within {self.startup_timeout_s:g} s"
                )
            if remaining <= 0:
                raise OrchestratorError(
                    f"component(s) not online after {self.startup_timeout_s:g} s: "
                    + ", ".join(self._describe_component(c) for c in missing)
                    + f" (robot {self.robot!r}, broker {self.settings.url}); "
                    "start their services with `umlbot service KIND --deploy FILE`"
                )
            changed.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(changed.wait(), remaining)

    def _connected(self) -> bool:
        return (self._control is not None and self._control.connected
                and self._client is not None and self._client.connected)

    def _describe_component(self, name: str) -> str:
        component = self.model.components.get(name)
        state = self.availability.get(name, "no status")
        service = f"{component.service} service, " if component is not None else ""
        return f"{name} ({service}{state})"

    # --- running ------------------------------------------------------------------------------------

    async def _supervise(self) -> None:
        try:
            self.lane_window = (time.perf_counter(), 0.0)
            await self._supervise_lanes()
        finally:
            self.lane_window = (self.lane_window[0], time.perf_counter())

    async def _supervise_lanes(self) -> None:
        loop, changed = self._runtime()
        for name in self.engine.component_lanes():
            task = asyncio.create_task(self._run_lane(name), name=f"lane:{name}")
            task.add_done_callback(lambda _task: changed.set())
            self._lane_tasks[name] = task
        while True:
            if self.failure is not None:
                return
            if all(task.done() for task in self._lane_tasks.values()):
                log.info("every lane ended")
                return
            timeout: float | None = None
            if self._exit_deadline is not None:
                timeout = self._exit_deadline - loop.time()
                if timeout <= 0:
                    running = sorted(n for n, t in self._lane_tasks.items() if not t.done())
                    log.info("grace period over: cancelling lanes", lanes=running)
                    return
            changed.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(changed.wait(), timeout)

    async def _run_lane(self, name: str) -> None:
        try:
            await self.engine.run_lane(name)
        except asyncio.CancelledError:
            raise
        except NodeFailed as exc:
            self._fail(Fault(FaultKind.NODE, str(exc), cause=exc.cause))
        except Exception as exc:  # a bug: still stop the robot safely
            log.exception("lane_crashed", lane=name)
            self._fail(Fault(FaultKind.INTERNAL, f"lane {name}: internal error: {exc!r}", cause=exc))

    def _fail(self, fault: Fault) -> None:
        """Fail-safe: remember the first fault and wake the supervisor (loop thread only)."""
        if self.life.fault is not None:
            return
        if fault.broker_symptom:
            self._broker_symptom_at = time.monotonic()  # maybe the broker going down: see _connection_lost
        self.engine.exit_requested = True
        # a warning: whoever ends the run reports the fault as its error (`umlbot run`: one
        # `error: fail-safe stop: …` line), so that --log-level ERROR prints it once
        log.warning("fail_safe_stop", reason=fault.reason, kind=fault.kind.value)
        self.life.fail(fault)
        if self._changed is not None:
            self._changed.set()

    def _on_exit_request(self, reason: str) -> None:
        loop, changed = self._runtime()
        if self.life.request_exit(reason):
            self.engine.exit_requested = True
            self._exit_deadline = loop.time() + self.grace_s
            log.info("exit_requested", reason=reason, grace_s=self.grace_s)
            if self._connecting:  # do not wait for a broker that may never answer
                self._closing = True
                loop.run_in_executor(None, self._close_connections)
            if self.life.phase is Phase.RUNNING:
                self._enter(Phase.STOPPING, reason)
        else:
            self._exit_deadline = loop.time()  # asked twice: no more grace
        changed.set()

    # --- shutting down ------------------------------------------------------------------------------

    async def _shut_down(self) -> int:
        self.engine.exit_requested = True
        tasks = [task for task in self._lane_tasks.values() if not task.done()]
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.wait(tasks, timeout=LANE_CANCEL_TIMEOUT_S)
        control, client = self._control, self._client
        if control is not None and client is not None:
            if not (control.connected and client.connected):
                log.warning("waiting for the broker to stop the actuators", wait_s=self.reconnect_wait_s)
                back = await asyncio.to_thread(self._wait_reconnected, self.reconnect_wait_s)
                if not back:
                    log.error("broker not back: actuators not stopped by the orchestrator "
                              "(the motor services stop on their own when the broker is lost)")
                else:  # the services reconnect too: give their retained status a moment to arrive
                    await self._wait_actuators_online(ACTUATORS_BACK_TIMEOUT_S)
            if control.connected and client.connected:
                await self._stop_actuators(at_start=False)
            if self.recorder is not None:
                self.recorder.close()  # the last trace events go out before the final status
        final = Phase.FAILED if self.failure is not None else Phase.STOPPED
        self._enter(final, self.failure or self.exit_reason or "every lane ended")
        self._closing = True
        if self._heartbeat is not None:
            self._heartbeat.cancel()  # after the final status: the motors stop by it at once
        if self.recorder is not None:
            self.recorder.close()
        if control is not None and client is not None and not (control.connected and client.connected):
            self._broker_lost()  # the connection went while the run shut down
        await asyncio.to_thread(self._close_connections)
        return EXIT_FAULT if self.failure is not None else EXIT_OK

    async def _wait_actuators_online(self, limit_s: float) -> None:
        loop, changed = self._runtime()
        deadline = loop.time() + limit_s
        names = {name for name, _, _ in self.actuators}
        while any(self.availability.get(name) != "online" for name in names):
            remaining = deadline - loop.time()
            if remaining <= 0:
                return
            changed.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(changed.wait(), remaining)

    def _wait_reconnected(self, timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        for connection in (self._control, self._client):
            if connection is None or self._closing:
                return False
            if not connection.wait_connected(max(0.0, deadline - time.monotonic())):
                return False
        return True

    def _close_connections(self) -> None:
        self._closing = True
        for connection in (self._client, self._control):
            if connection is not None:
                with contextlib.suppress(Exception):
                    connection.close()

    # --- actuators ----------------------------------------------------------------------------------

    def _actuator_stops(self) -> list[tuple[str, str, tuple[StopArg, ...]]]:
        """(component, feature, args) of every safe-stop call of the model's components, as the
        compiled file carries them (no library lookup: a plugin need not be installed here)."""
        return [(name, call.feature, tuple(call.args))
                for name, component in sorted(self.model.components.items())
                for call in component.safe_stop]

    async def _stop_actuators(self, at_start: bool) -> None:
        """Send every safe-stop call; at start a failure is a fault, at the end it is logged."""
        client = self._client
        if client is None or not self.actuators:
            return
        calls = [
            (name, feature, args) for name, feature, args in self.actuators
            if at_start or self.availability.get(name) == "online"
        ]
        skipped = sorted({name for name, _, _ in self.actuators} - {name for name, _, _ in calls})
        if skipped:
            log.warning("actuators offline, not stopped by the orchestrator", components=skipped)
        timeout = self.call_timeout_s if at_start else min(self.call_timeout_s, FINAL_STOP_TIMEOUT_S)
        results = await asyncio.gather(
            *(client.acall(name, feature, *args, timeout=timeout) for name, feature, args in calls),
            return_exceptions=True,
        )
        failures = [
            f"{name}.{feature}: {result}" for (name, feature, _), result in zip(calls, results, strict=True)
            if isinstance(result, BaseException)
        ]
        if failures and at_start:
            raise OrchestratorError("cannot stop the actuators at start-up: " + "; ".join(failures))
        if failures:
            log.error("actuator_stop_failed", failures=failures)
        else:
            log.info("actuators_stopped", components=sorted({name for name, _, _ in calls}))

    # --- MQTT handlers (dispatcher thread) ----------------------------------------------------------

    def _to_loop(self, function: Callable[..., object], *args: Any) -> None:
        loop = self._loop
        if loop is None or self._closing:
            return
        with contextlib.suppress(RuntimeError):  # loop closed: the run is over
            loop.call_soon_threadsafe(function, *args)

    def _on_status_message(self, message: Message) -> None:
        component = message.topic[len(self.topics.base) + 1:].split("/", 1)[0]
        if component not in self.model.components:
            return
        try:
            state = Status.model_validate_json(message.payload).state if message.payload else "offline"
        except ValueError:
            log.warning("bad component status", component=component, payload=message.payload[:200])
            return
        self._to_loop(self._on_status, component, state)

    def _on_status(self, component: str, state: str) -> None:
        previous = self.availability.get(component)
        self.availability[component] = state
        if previous != state:
            log.info("component_status", component=component, state=state)
        if (
            state != "online"
            and previous == "online"
            and component in self.required
            and self.life.active
        ):
            self._fail(Fault(FaultKind.COMPONENT_LOST, f"component {component} went {state}", component))
        if self._changed is not None:
            self._changed.set()

    def _on_state_message(self, message: Message) -> None:
        component = message.topic[len(self.topics.base) + 1:].split("/", 1)[0]
        if component not in self.model.components or b"stop_reason" not in message.payload:
            return
        try:
            data = parse_json(message.payload)
        except ValueError:
            return
        reason = data.get("stop_reason") if isinstance(data, dict) else None
        reason = reason if isinstance(reason, str) else None
        # the same reason as the last one handed over changes nothing on the loop (see
        # _on_stop_reason): a motor's state comes after every command, and waking the event loop
        # for each would cost every action a turn of it
        if reason == self._stop_reasons_seen.get(component):
            return
        self._stop_reasons_seen[component] = reason
        self._to_loop(self._on_stop_reason, component, reason, message.retain)

    def _on_stop_reason(self, component: str, reason: str | None, retained: bool) -> None:
        previous = self._stop_reasons.get(component)
        self._stop_reasons[component] = reason
        # a retained state is what was (another run's end); a new reason while the model runs is
        # a safety stop of this run
        if reason is None or reason == previous or retained or not self.life.active:
            return
        self.safety_stops[component] = reason
        log.warning("actuator_stopped_by_its_service", component=component, reason=reason)

    def _on_signal_message(self, message: Message) -> None:
        if message.retain:  # a retained signal is old news; only live occurrences count
            return
        name = message.topic.rsplit("/", 1)[-1]
        # a name the model does not accept is ignored on the loop (counted, logged rarely): not parsed
        payload = _signal_payload(message.payload) if self.signals.accepts(name) else None
        self._to_loop(self.signals.deliver, name, payload)

    def _on_exit_message(self, message: Message) -> None:
        if message.retain:  # a retained exit request would end every future run at once
            log.warning("ignoring a retained exit request", topic=message.topic)
            return
        if not message.payload:  # `mosquitto_pub -r -n` clearing a retained one: not a request
            log.debug("ignoring an empty message on the exit topic", topic=message.topic)
            return
        try:
            data = parse_json(message.payload)
        except ValueError as exc:
            log.warning("ignoring an exit request that is not JSON", topic=message.topic,
                        error=str(exc)[:MAX_REASON_CHARS], size=len(message.payload))
            return
        if not isinstance(data, dict):  # a request is a JSON object: `{}` or `{"reason": "..."}`
            log.warning("ignoring an exit request that is not a JSON object", topic=message.topic,
                        json_type=type(data).__name__, size=len(message.payload))
            return
        try:
            request = ExitRequest.model_validate(data)
        except ValidationError as exc:
            first = exc.errors()[0]
            field = ".".join(str(p) for p in first["loc"]) or "request"
            event = ("ignoring an exit request whose reason is not a string" if field == "reason"
                     else "ignoring an invalid exit request")
            log.warning(event, topic=message.topic, error=f"{field}: {first['msg']}",
                        size=len(message.payload))
            return
        reason = "exit requested over MQTT"
        if request.reason:
            reason = f"exit requested over MQTT: {shorten(request.reason)}"
        self.request_exit(reason)

    def _broker_lost(self) -> None:
        """The broker connection is gone: a fault that its end explains is reported as its end."""
        symptom_at = self._broker_symptom_at
        if symptom_at is not None and time.monotonic() - symptom_at < BROKER_GONE_WINDOW_S:
            # a broker that shuts down sends its clients' last wills first (amqtt does), and calls
            # fail as it goes: the component that "went offline" just before was the broker's end
            log.info("fail_safe_stop_reason", was=self.failure, now=BROKER_LOST)
            self.life.reclassify(Fault.broker_lost())
            self._broker_symptom_at = None

    def _connection_lost(self, control: bool) -> None:
        # before the lanes run, a lost connection is only a delay (the bus reconnects on its own
        # and the start-up keeps waiting, bounded); afterwards it is a fault
        if control:
            # what the components said is stale now: the control connection (which carries the
            # status subscription) gets their retained status again after its reconnect
            self.availability.clear()
        self._broker_lost()  # also while it shuts down: the fault it explains is named after it
        if self.life.active:
            self._fail(Fault.broker_lost())
        else:
            log.warning("connection to the broker lost during start-up; waiting for it", state=self.state)
        if self._changed is not None:
            self._changed.set()

    def _on_connected(self) -> None:
        self._to_loop(self._connected_again)

    def _connected_again(self) -> None:
        # a broker without persistence forgets retained messages: say again where we are
        if self._control is not None and self._control.connected:
            self._publish_status()
        if self._changed is not None:
            self._changed.set()

    # --- publishing ---------------------------------------------------------------------------------

    def _enter(self, phase: Phase, reason: str | None = None) -> None:
        """Move the run to `phase` and say so in the retained status."""
        self.life.move(phase, reason)
        self._publish_status()

    def _publish_status(self) -> None:
        """Publish the current phase (and the reason it was entered with) as the retained status."""
        state, reason = self.life.phase.value, self.life.reason
        control = self._control
        if control is None:
            return
        status = OrchestratorStatus.model_validate(
            {"state": state, "reason": reason, "model": self.model.name, "robot": self.robot,
             "source_hash": self.model.source_hash, "call_timeout_s": self.call_timeout_s,
             "since": time.time()}
        )
        try:
            control.publish(self.topics.orchestrator_status, status, qos=1, retain=True)
        except BusError as exc:
            log.warning("orchestrator status not published", state=state, error=str(exc))

    async def _beat(self) -> None:
        """Publish the heartbeat every `heartbeat_s` of wall time until cancelled.

        Wall time even under the simulator's clock: it says that this process and its event loop
        are alive (a frozen orchestrator freezes the simulated time with it).
        """
        control, client = self._control, self._client
        if control is None or client is None:
            return
        for seq in itertools.count():
            if control.connected:
                beat = {"reply_to": client.reply_topic, "seq": seq, "period_s": self.heartbeat_s}
                with contextlib.suppress(BusError):
                    control.publish(self.topics.orchestrator_heartbeat, dumps(beat).encode("utf-8"), qos=0)
            await asyncio.sleep(self.heartbeat_s)

    def _publish_trace(self, data: bytes) -> None:
        control = self._control
        if control is not None and control.connected:
            with contextlib.suppress(NotConnected):
                control.publish(self.topics.orchestrator_trace, data, qos=0)

    # --- helpers ------------------------------------------------------------------------------------

    def _runtime(self) -> tuple[asyncio.AbstractEventLoop, asyncio.Event]:
        if self._loop is None or self._changed is None:
            raise OrchestratorError("the orchestrator is not running")
        return self._loop, self._changed

    def _install_signal_handlers(self) -> Callable[[], None]:
        """SIGINT/SIGTERM request the exit (a second one ends the grace); returns the remover."""
        loop = self._loop
        in_main_thread = threading.current_thread() is threading.main_thread()
        if not self.handle_signals or loop is None or not in_main_thread:
            return lambda: None
        installed: list[signal.Signals] = []
        for signum in (signal.SIGINT, signal.SIGTERM):
            try:
                loop.add_signal_handler(signum, self.request_exit, f"{signum.name} received")
            except (NotImplementedError, RuntimeError, ValueError):
                continue
            installed.append(signum)

        def remove() -> None:
            for signum in installed:
                with contextlib.suppress(Exception):
                    loop.remove_signal_handler(signum)

        return remove


def _signal_payload(payload: bytes) -> Value:
    """A signal's payload: its JSON value, the raw text when it is not JSON, None when empty."""
    if not payload:
        return None
    try:
        return parse_json(payload)
    except ValueError:
        return payload.decode("utf-8", errors="replace")


def run_orchestrator(
    compiled: CompiledModel,
    broker_settings: BrokerSettings,
    robot: str | None = None,
    clock: Clock | None = None,
    call_timeout_s: float | None = None,
    trace: bool = True,
    trace_file: str | Path | None = None,
    grace_s: float = DEFAULT_GRACE_S,
    startup_timeout_s: float = DEFAULT_STARTUP_TIMEOUT_S,
    trace_listener: Listener | None = None,
    handle_signals: bool = True,
) -> int:
    """Run the orchestrator to its end in a fresh event loop; returns the exit code.

    Used by `umlbot run` and `umlbot sim`. Raises `OrchestratorError` when it cannot start.
    """
    orchestrator = Orchestrator(
        compiled,
        broker_settings,
        robot=robot,
        clock=clock,
        call_timeout_s=call_timeout_s,
        trace=trace,
        trace_file=trace_file,
        grace_s=grace_s,
        startup_timeout_s=startup_timeout_s,
        trace_listener=trace_listener,
        handle_signals=handle_signals,
    )
    return orchestrator.run_sync()
