"""`umlbot sim`: the whole robot on one machine — broker, world, services, orchestrator — and a report.

`run_sim(SimOptions(...))` compiles the model, starts the embedded broker (unless a broker URL is
given), the world and its loop, the services with the `sim` drivers (a service kind without one
on its `mock` driver: `sim_driver`), in this process or as `umlbot service KIND` child
processes with `processes=True` (which reach the world through
`umlbot.sim.sharing.WorldServer`), and the orchestrator in this process with the same clock. It
stops when the goal is reached, when the collision limit or the time-out is hit, when the
orchestrator ends or fails, or on Ctrl-C; on every path the world is halted at once (motors off,
time stopped: `World.halt`, no MQTT round trip that could time out), then the rest is torn down.
The result carries the summary; `plot` draws the picture.
"""

from __future__ import annotations

import contextlib
import math
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from umlbot.base.clock import Clock
from umlbot.base.errors import ConfigError, SimError
from umlbot.base.logs import get_logger
from umlbot.services.orchestrator import Orchestrator
from umlbot.services.simworld import attach_local_world
from umlbot.sim.clock import SimClock
from umlbot.sim.program import ProgramOrchestrator
from umlbot.sim.reach import goal_problem_at, start_problem
from umlbot.sim.sharing import WorldServer
from umlbot.sim.track import load_track, track_warnings
from umlbot.sim.world import CarSpec, World, WorldLoop, WorldSnapshot

#: `run_sim`'s `observe` hook: (world, broker URL, robot id) -> what to call when the run ended.
Observer = Callable[[World, str, str], Callable[[], None]]

log = get_logger(__name__)

#: The default embedded-broker port: the standard one, so any MQTT client can watch the run.
DEFAULT_PORT = 1883
#: Sim seconds before a run is given up.
DEFAULT_TIMEOUT_S = 600.0
#: A run ends (reason `timeout`) when its sim time has not moved for `WALL_STALL_S` wall seconds:
#: sim time stands still while a call is in flight or the model computes, and a model that never
#: waits would hold it for ever. A run whose sim time moves is not cut however slowly it moves
#: (a world that keeps up only 15x real time at --speed 100), so it ends the same at any speed.
WALL_STALL_S = 30.0
#: Only a safety net beyond that: `WALL_LIMIT_FACTOR` x timeout / min(speed, 1) +
#: `WALL_LIMIT_EXTRA_S` wall seconds, a run whose sim time creeps at under half real time.
WALL_LIMIT_FACTOR = 2.0
WALL_LIMIT_EXTRA_S = 60.0
#: Wall seconds the runner waits for the world's lock before it looks again (a long catch-up).
SNAPSHOT_WAIT_S = 0.05
#: Wall seconds the runner waits, at the end of a run, for the orchestrator to settle.
QUIET_WAIT_S = 2.0
#: A run that timed out with its world this many sim seconds behind the clock reports it.
WORLD_LAG_REPORT_S = 1.0


def wall_limit_s(timeout_s: float, speed: float) -> float:
    """The wall seconds a run with this sim-time `timeout_s` and `speed` may take at most (the
    safety net: it does not depend on how far above real time `speed` asks for)."""
    return WALL_LIMIT_FACTOR * timeout_s / min(speed, 1.0) + WALL_LIMIT_EXTRA_S


class WallGuard:
    """The wall-time bounds of a run: `check(wall_s, sim_s)`, called as the run goes on, says why
    the run must end (sim time stalled for `stall_s` wall seconds, or the safety net reached), or
    None. Times are passed in, so the bounds are tested without waiting for them."""

    def __init__(self, timeout_s: float, speed: float, stall_s: float = WALL_STALL_S) -> None:
        self.timeout_s, self.speed, self.stall_s = timeout_s, speed, stall_s
        self.limit_s = wall_limit_s(timeout_s, speed)
        self._sim_s = -math.inf
        self._moved_at = 0.0

    def check(self, wall_s: float, sim_s: float) -> str | None:
        """`wall_s`: wall seconds since the run started; `sim_s`: the sim clock's time."""
        if sim_s > self._sim_s:
            self._sim_s, self._moved_at = sim_s, wall_s
        if wall_s - self._moved_at >= self.stall_s:
            return (f"sim time stood still at {sim_s:.1f} s for {self.stall_s:g} s of wall time "
                    "(a call that never ends, or a model that never waits)")
        if wall_s >= self.limit_s:
            return (f"wall-time limit of {self.limit_s:g} s reached at {sim_s:.1f} s sim time "
                    f"(--timeout {self.timeout_s:g} at --speed {self.speed:g})")
        return None


@dataclass(frozen=True)
class SimOptions:
    """What `umlbot sim` was asked to do."""

    model: Path
    track: Path
    speed: float = 10.0
    broker_url: str | None = None
    #: embedded broker port; None = 1883, or any free port when 1883 is taken (0 = any free port)
    port: int | None = None
    timeout_s: float = DEFAULT_TIMEOUT_S  # sim seconds
    plot: Path | None = None
    processes: bool = False
    seed: int | None = None
    sonar_noise_cm: float = 0.0
    sonar_drop: float = 0.0  # share of pings whose echo is lost (0..1)
    max_collisions: int = 1
    progress_interval_s: float = 0.5  # wall seconds between progress reports
    #: wall seconds without sim time moving after which the run ends (`WallGuard`)
    stall_s: float = WALL_STALL_S
    #: also write the orchestrator's trace to this file (JSON lines, as `umlbot run --trace`)
    trace_file: Path | None = None
    #: python: the orchestrator in this process on the event-driven sim clock; cpp: the model's
    #: generated C++ program (`umlbot generate cpp`) as a child process on the same clock
    engine: str = "python"
    #: with engine cpp: this built program instead of generating and building one (cached)
    program: Path | None = None
    #: with engine cpp: the program and the world in wall time at `speed` (as before the program
    #: took part in the sim clock): the run then depends on the machine's load
    wall_clock: bool = False
    #: refuse a track whose goal a car of this width cannot reach (`umlbot.sim.reach`); off only
    #: for runs that must not end at the goal (tests of the time-out and collision paths)
    check_goal: bool = True
    #: the robot id in the topics (default: the model's name); a fleet runs each car as its own robot
    robot: str | None = None


@dataclass(frozen=True)
class Progress:
    """One progress report: sim time, pose, distance and the action being executed."""

    snapshot: WorldSnapshot
    action: str
    actions: int
    broker_url: str = ""
    #: service kind -> process id, with `processes=True` (empty otherwise).
    service_pids: dict[str, int] = field(default_factory=dict)
    #: the components on their mock driver (their service kind has no sim driver) -> service kind.
    mock_components: dict[str, str] = field(default_factory=dict)


@dataclass
class SimResult:
    """How a run ended, with the numbers of the summary."""

    track: str
    #: goal, collision, timeout, interrupted, orchestrator ended/failed, service failed
    reason: str
    goal_reached: bool
    collisions: int
    sim_s: float
    wall_s: float
    distance_m: float
    actions: int
    action_p50_ms: float | None
    action_p99_ms: float | None
    plot: Path | None = None
    failure: str | None = None
    final_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    broker_url: str = ""
    #: component -> the safety stop its service made while the model ran (`Orchestrator.safety_stops`)
    safety_stops: dict[str, str] = field(default_factory=dict)
    #: (sim time, side) of every motor the world's deadman stopped (its driver stopped renewing it)
    deadman_stops: list[tuple[float, str]] = field(default_factory=list)

    @property
    def stood_still(self) -> str | None:
        """Why the motors stopped before the run's end, in words, or None when nothing stopped them."""
        why = [f"{component}: {reason}" for component, reason in sorted(self.safety_stops.items())]
        why += [f"the {side} motor's driver stopped renewing it: the deadman stopped it at {t:.1f} s"
                for t, side in self.deadman_stops]
        return "; ".join(why) or None

    @property
    def ok(self) -> bool:
        """The run counts as a success: goal reached without a collision and nothing failed."""
        return self.goal_reached and self.collisions == 0 and self.failure is None

    def as_dict(self) -> dict[str, Any]:
        return {
            "track": self.track,
            "reason": self.reason,
            "goal": self.goal_reached,
            "collisions": self.collisions,
            "sim_s": round(self.sim_s, 3),
            "wall_s": round(self.wall_s, 3),
            "distance_m": round(self.distance_m, 3),
            "actions": self.actions,
            "action_p50_ms": _round(self.action_p50_ms),
            "action_p99_ms": _round(self.action_p99_ms),
            "plot": str(self.plot) if self.plot else None,
            "failure": self.failure,
            "safety_stops": dict(self.safety_stops),
            "deadman_stops": [[round(t, 3), side] for t, side in self.deadman_stops],
        }


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 3)


def percentile(values: list[float], q: float) -> float | None:
    """The q-th percentile (0..100, nearest rank) or None for no values."""
    if not values:
        return None
    ordered = sorted(values)
    rank = max(1, math.ceil(q / 100.0 * len(ordered)))
    return ordered[min(rank, len(ordered)) - 1]


@dataclass
class _Watch:
    """What the runner learns from the orchestrator's trace listener."""

    components: frozenset[str]
    action: str = ""
    lock: threading.Lock = field(default_factory=threading.Lock)

    def on_event(self, event: dict[str, Any]) -> None:
        if event.get("kind") != "action":
            return
        detail = str(event.get("detail", ""))
        if detail.split(".", 1)[0] in self.components:
            with self.lock:
                self.action = detail


def sim_driver(service: str) -> str:
    """The driver a service kind runs in the simulator: its `sim` driver when it has one (motor,
    sonar, servo, a plugin's), else its `mock` driver (gpio, a plugin's kind without a sim
    driver); `SimError` when it has neither."""
    from umlbot.base.registry import known_drivers

    known = known_drivers(service)
    for driver in ("sim", "mock"):
        if driver in known:
            return driver
    raise SimError(f"the {service} service kind has neither a sim nor a mock driver (known: "
                   f"{', '.join(known)}); umlbot sim cannot run its components")


def sim_deployment(compiled: Any, robot: str | None = None) -> Any:
    """The deployment the services run with in the simulator: each component on `sim_driver`;
    the robot id is `robot`, or the model's name."""
    from umlbot.base.deployment import ComponentDeployment, Deployment

    components = {
        name: ComponentDeployment(impl=comp.impl, driver=sim_driver(comp.service),
                                  settings=dict(comp.settings))
        for name, comp in compiled.components.items()
    }
    return Deployment(robot=robot or compiled.name, driver="sim", components=components)


def mock_components(deployment: Any) -> dict[str, str]:
    """The components of a sim deployment that run on their mock driver -> their service kind."""
    return {name: comp.implementation.service for name, comp in sorted(deployment.components.items())
            if comp.driver == "mock"}


def _deployment_yaml(deployment: Any) -> str:
    import json

    # JSON is YAML: the child processes read it with the ordinary deployment loader
    return json.dumps(deployment.model_dump(mode="json"), indent=1, sort_keys=True)


class _Services:
    """The services of the run: in-process `ServiceHost`s, or `umlbot service` child processes."""

    def __init__(self, deployment: Any, broker_url: str, processes: bool, world: World) -> None:
        self.deployment = deployment
        self.broker_url = broker_url
        self.processes = processes
        self.world = world
        self.kinds = sorted({c.implementation.service for c in deployment.components.values()})
        self.hosts: list[Any] = []
        self.children: dict[str, subprocess.Popen[bytes]] = {}
        self.server: WorldServer | None = None
        self._tmp: tempfile.TemporaryDirectory[str] | None = None

    def start(self) -> None:
        if self.processes:
            self._start_processes()
        else:
            self._start_in_process()

    def _start_in_process(self) -> None:
        from umlbot.services.bus import BrokerSettings
        from umlbot.services.host import ServiceHost

        attach_local_world(self.world)
        settings = BrokerSettings.from_url(self.broker_url)
        for kind in self.kinds:
            host = ServiceHost(kind, self.deployment, settings, self.deployment.robot)
            self.hosts.append(host)
            host.start()

    def _start_processes(self) -> None:
        self.server = WorldServer(self.world).start()
        self._tmp = tempfile.TemporaryDirectory(prefix="umlbot-sim-")
        deploy_file = Path(self._tmp.name) / "deployment.yaml"
        deploy_file.write_text(_deployment_yaml(self.deployment), encoding="utf-8")
        import logging

        level = logging.getLevelName(logging.getLogger().getEffectiveLevel())
        env = {**os.environ, **self.server.env, "UMLBOT_BROKER": self.broker_url, "UMLBOT_LOG_LEVEL": level}
        for kind in self.kinds:
            argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "service", kind,
                    "--deploy", str(deploy_file), "--broker", self.broker_url,
                    "--robot", str(self.deployment.robot)]
            self.children[kind] = subprocess.Popen(argv, env=env, stdin=subprocess.DEVNULL)
            log.info("service_process_started", kind=kind, pid=self.children[kind].pid)

    def wait_online(self, timeout_s: float = 30.0) -> None:
        """Wait until every served component's retained status says `online` (child processes)."""
        if not self.children:
            return
        from umlbot.services.bus import BrokerSettings, BusConnection, Message, Topics

        topics = Topics(str(self.deployment.robot))
        pending = set(self.deployment.components)
        done = threading.Event()
        lock = threading.Lock()

        def on_status(message: Message) -> None:
            try:
                state = message.json().get("state")
            except (ValueError, AttributeError):
                return
            component = message.topic.rsplit("/", 2)[-2]
            with lock:
                if state == "online":
                    pending.discard(component)
                if not pending:
                    done.set()

        connection = BusConnection(BrokerSettings.from_url(self.broker_url), "sim-runner",
                                   robot=str(self.deployment.robot))
        try:
            connection.start(timeout_s)
            for name in list(pending):
                connection.subscribe(topics.status(name), on_status)
            deadline = time.monotonic() + timeout_s
            while not done.wait(0.05):
                dead = self.check_children()
                if dead is not None:
                    raise SimError(dead)
                if time.monotonic() > deadline:
                    raise SimError(f"service processes not online within {timeout_s:g} s: {sorted(pending)}")
        finally:
            connection.close()

    def check_children(self) -> str | None:
        """The first child service that died, as a message, or None."""
        for kind, child in self.children.items():
            code = child.poll()
            if code is not None:
                return f"the {kind} service process exited with code {code}"
        return None

    def stop(self) -> None:
        """Stop every service (their motors stop with them); idempotent."""
        for host in reversed(self.hosts):
            with contextlib.suppress(Exception):
                host.stop()
        self.hosts.clear()
        for child in self.children.values():
            if child.poll() is None:
                child.send_signal(signal.SIGTERM)
                child.send_signal(signal.SIGCONT)  # a frozen one (SIGSTOP) gets the SIGTERM too
        for kind, child in self.children.items():
            try:
                child.wait(timeout=10)
            except subprocess.TimeoutExpired:
                log.warning("service_process_killed", kind=kind, pid=child.pid)
                child.kill()
                child.wait(timeout=5)
        self.children.clear()
        if self.server is not None:
            self.server.stop()
            self.server = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
        attach_local_world(None)


def _start_broker(options: SimOptions) -> tuple[Any, str]:
    """The embedded broker (or None) and the URL everybody connects to.

    An explicitly requested port that is taken is an error naming the way out; the default port
    (1883, so any MQTT client can watch) falls back to a free one when it is taken.
    """
    if options.broker_url is not None:
        return None, options.broker_url
    from umlbot.services.bus import EmbeddedBroker

    port = DEFAULT_PORT if options.port is None else (options.port or _free_port())
    broker = EmbeddedBroker("127.0.0.1", port)
    try:
        broker.start()
    except ConfigError as exc:
        if options.port is not None:
            raise SimError(
                f"cannot start the embedded broker on 127.0.0.1:{port}: {exc}. If a broker already "
                f"runs there, use it: --broker mqtt://127.0.0.1:{port}; or pick another port: "
                "--port 0 (any free port)"
            ) from exc
        log.warning("default broker port taken, using a free one", port=port, reason=str(exc))
        broker = EmbeddedBroker("127.0.0.1", _free_port())
        broker.start()
    return broker, broker.url


def _free_port() -> int:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def run_sim(
    options: SimOptions,
    on_progress: Callable[[Progress], None] | None = None,
    stop: threading.Event | None = None,
    observe: Observer | None = None,
    trace_listener: Callable[[dict[str, Any]], None] | None = None,
) -> SimResult:
    """Run one simulation to its end (see the module docstring); `stop` ends it early (Ctrl-C).

    `observe(world, broker_url, robot)` is called once the broker runs, before anything else
    starts (the studio follows the run this way); the function it returns is called when the run
    has ended, before the broker stops. `trace_listener` gets every trace event of the run (on
    the orchestrator's loop: it must not block), e.g. a recording's.
    """
    from umlbot.compiler.api import compile_model
    from umlbot.services.bus import BrokerSettings
    if not options.speed > 0:
        raise SimError(f"--speed must be > 0, got {options.speed}")
    if options.plot is not None:  # before the run, not after it
        from umlbot.sim.plot import check_plot_path

        check_plot_path(options.plot)
    track = load_track(options.track)
    for warning in track_warnings(track):
        log.warning(f"{options.track}: {warning}")
    car = CarSpec()
    # a start on a wall is refused by the world; a goal the car cannot get to would only show
    # as a time-out, minutes later
    problem = start_problem(track, car.length_m, car.width_m)
    if problem is None and options.check_goal:
        problem = goal_problem_at(track, car.width_m)
    if problem is not None:
        message = f"{options.track}: {problem.message}"
        if options.plot is not None:
            from umlbot.sim.plot import plot_track

            picture = plot_track(track, options.plot, problem.message, problem.spot, car)
            message += f" (the track is drawn in {picture})"
        raise SimError(message)
    try:
        world = World(track, car, sonar_noise_cm=options.sonar_noise_cm, sonar_drop=options.sonar_drop,
                      seed=options.seed)
    except ValueError as exc:
        raise SimError(f"{options.track}: {exc}") from exc
    compiled = compile_model(options.model)
    program: Path | None = None
    if options.engine == "cpp":  # generated and built once per model (cached), before anything runs
        from umlbot.codegen import BuildError, cached_program

        try:
            program = options.program or cached_program(compiled)
        except BuildError as exc:
            raise SimError(f"--engine cpp: {exc}") from exc
    elif options.engine != "python":
        raise SimError(f"--engine must be python or cpp, got {options.engine!r}")
    deployment = sim_deployment(compiled, options.robot)
    on_mock = mock_components(deployment)
    if on_mock:
        log.info("sim_mock_drivers", components=on_mock,
                 why="no sim driver for their service kind: they run on its mock driver")
    stop = stop or threading.Event()
    broker, url = _start_broker(options)
    finish_observing: Callable[[], None] | None = None
    services = _Services(deployment, url, options.processes, world)
    loop: WorldLoop | None = None
    orchestrator: Any = None
    orch_thread: threading.Thread | None = None
    orch_outcome: dict[str, Any] = {}
    watch = _Watch(frozenset(compiled.components))
    wall_start = time.monotonic()
    guard = WallGuard(options.timeout_s, options.speed, options.stall_s)
    reason = "interrupted"
    failure: str | None = None
    actions_at_end = 0
    ros2_drivers: Any = None
    trace_dir: Path | None = None  # the generated program's trace, when the user keeps none
    try:
        if observe is not None:
            finish_observing = observe(world, url, deployment.robot)
        if any(comp.implementation.service == "ros2" for comp in deployment.components.values()):
            from umlbot.sim.ros2_world import Ros2WorldDrivers  # the world plays the ROS 2 drivers

            ros2_drivers = Ros2WorldDrivers(world, deployment)
            ros2_drivers.start()
        services.start()
        services.wait_online()
        # the world moves with the clock from now on: start-up time is not sim time
        clock: Clock
        if options.engine == "cpp" and options.wall_clock:  # the program and the world in wall time
            clock = Clock(options.speed)
        else:  # the generated program too takes part in the clock (--sim-clock, `ClockBridge`)
            clock = SimClock(options.speed)
            clock.limit_s = options.timeout_s  # time ends there: the run ends at the time-out exactly
        world.clock = clock
        # the world ends the run itself, at the sim time it happens, not when the runner looks
        world.halt_at_goal = True
        world.max_collisions = options.max_collisions
        listener = watch.on_event if trace_listener is None else _both(watch.on_event, trace_listener)
        if program is not None:
            trace_file = options.trace_file
            if trace_file is None:  # the program's trace is where the runner counts its actions
                trace_dir = Path(tempfile.mkdtemp(prefix="umlbot-sim-"))
                trace_file = trace_dir / "trace.jsonl"
            orchestrator = ProgramOrchestrator(program, compiled, url, deployment.robot, options.speed,
                                               trace_file, listener,
                                               clock if isinstance(clock, SimClock) else None)
        else:
            orchestrator = Orchestrator(
                compiled, BrokerSettings.from_url(url), robot=deployment.robot, clock=clock,
                trace_listener=listener, handle_signals=False, trace_file=options.trace_file,
            )
        # a fail-safe stop halts the world at once, in the orchestrator's thread: its own stop
        # calls go through the broker and may time out while the car drives on
        orchestrator.life.on_fault(lambda _fault: world.halt())

        def run_orchestrator() -> None:
            try:
                orch_outcome["code"] = orchestrator.run_sync()
            except Exception as exc:  # reported in the result; the runner tears down
                orch_outcome["error"] = str(exc)

        loop = WorldLoop(world, clock)
        loop.start()
        orch_thread = threading.Thread(target=run_orchestrator, name="sim-orchestrator", daemon=True)
        orch_thread.start()
        next_report = 0.0
        while True:
            if stop.wait(0.02):
                reason = "interrupted"
                break
            if orchestrator.failure is not None:  # at once, not when its shut-down has ended
                reason, failure = "orchestrator failed", orchestrator.failure
                break
            # the clock, not the world: a world that fell behind holds its lock while it catches up
            sim_now = clock.now()
            snap = world.try_snapshot(SNAPSHOT_WAIT_S)
            if snap is not None and snap.goal_reached:
                reason = "goal"
                break
            if snap is not None and snap.collisions >= options.max_collisions:
                reason = "collision"
                break
            if sim_now >= options.timeout_s:
                reason = "timeout"
                break
            cut = guard.check(time.monotonic() - wall_start, sim_now)
            if cut is not None:
                reason, failure = "timeout", cut
                break
            if not orch_thread.is_alive():
                failure = orch_outcome.get("error") or orchestrator.failure
                reason = "orchestrator failed" if failure else "orchestrator ended"
                break
            dead = services.check_children()
            if dead is not None:
                reason, failure = "service failed", dead
                break
            now = time.monotonic()
            if on_progress is not None and snap is not None and now >= next_report:
                next_report = now + options.progress_interval_s
                with watch.lock:
                    action = watch.action
                pids = {kind: child.pid for kind, child in services.children.items()}
                on_progress(Progress(snap, action, orchestrator.stats.actions, url, pids, on_mock))
    except KeyboardInterrupt:
        reason = "interrupted"
    finally:
        _catch_up(world)
        world.halt()  # motors off and time stopped at once, whatever the services still do
        final = world.snapshot()
        wall_s = time.monotonic() - wall_start
        sim_clock = world.clock if isinstance(world.clock, SimClock) else None
        if sim_clock is not None and orchestrator is not None:
            # the orchestrator finishes what it does at the halted time (calls, decisions) and
            # then waits: its action count is that of the model, not of when the runner looked
            sim_clock.wait_quiet(QUIET_WAIT_S)
            if isinstance(orchestrator, ProgramOrchestrator):
                orchestrator.settle()  # its trace, where its actions are counted, is read late
            actions_at_end = orchestrator.stats.actions
            sim_clock.release()  # pending sleeps return: the lanes see the exit and end
        elif orchestrator is not None:
            actions_at_end = orchestrator.stats.actions
        if world.clock is not None and reason == "timeout" and failure is None:
            behind = world.clock.now() - final.time_s
            if behind > WORLD_LAG_REPORT_S:
                failure = (f"the world fell {behind:.1f} s of sim time behind the clock "
                           f"(it cannot keep up at --speed {options.speed:g})")
        if orchestrator is not None:
            orchestrator.request_exit(f"simulation ended: {reason}")
            if orch_thread is not None:
                orch_thread.join(timeout=10)
                if orch_thread.is_alive():
                    orchestrator.request_exit("simulation ended")  # a second request ends the grace
                    orch_thread.join(timeout=5)
        if trace_dir is not None:
            shutil.rmtree(trace_dir, ignore_errors=True)
        services.stop()
        if ros2_drivers is not None:
            ros2_drivers.stop()
        if loop is not None:
            loop.stop()
        if finish_observing is not None:
            finish_observing()
        if broker is not None:
            broker.stop()
    latencies = list(orchestrator.stats.action_latency_s) if orchestrator is not None else []
    result = SimResult(
        track=track.name,
        reason=reason,
        goal_reached=final.goal_reached,
        collisions=final.collisions,
        sim_s=final.time_s,
        wall_s=wall_s,
        distance_m=final.distance_m,
        actions=actions_at_end,
        action_p50_ms=_ms(statistics.median(latencies)) if latencies else None,
        action_p99_ms=_ms(percentile(latencies, 99)),
        failure=failure,
        broker_url=url,
        final_pose=(final.pose.x, final.pose.y, math.degrees(final.pose.heading)),
        safety_stops=dict(orchestrator.safety_stops) if orchestrator is not None else {},
        deadman_stops=[(t, side) for t, side in world.deadman_stops],
    )
    if options.plot is not None:
        from umlbot.sim.plot import plot_run

        result.plot = plot_run(world, options.plot)
    log.info("sim_finished", **result.as_dict())
    return result


def _both(first: Callable[[dict[str, Any]], None],
          second: Callable[[dict[str, Any]], None]) -> Callable[[dict[str, Any]], None]:
    def both(event: dict[str, Any]) -> None:
        first(event)
        second(event)

    return both


def _catch_up(world: World) -> None:
    """Bring a world that is not halted up to its clock, when it is at most a little behind.

    The world loop follows the clock 10 ms of wall time late: without this a run would end up
    to 0.1 s of sim time (at speed 10) before the time-out it reports. A world far behind (it
    cannot keep up) is not caught up: that would drive the car on for as long as it takes.
    """
    if world.clock is None or world.halted:
        return
    snap = world.try_snapshot(SNAPSHOT_WAIT_S)
    now = world.clock.now()
    if snap is not None and now - snap.time_s <= WORLD_LAG_REPORT_S:
        world.advance_to(now)


def _ms(seconds: float | None) -> float | None:
    return None if seconds is None else seconds * 1000.0
