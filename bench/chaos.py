"""Chaos: the robot car as real processes, with its broker restarted, its services killed and
frozen, and thousands of malformed payloads thrown at it.

Every process is what runs on the robot: `umlbot service KIND --driver mock` for the four kinds
and `umlbot run` on the compiled car, with the environment of the systemd units (so
`MALLOC_MMAP_THRESHOLD_` too), each with JSON logs in a temporary folder, on a broker this
script starts (Mosquitto and/or the embedded `umlbot broker`, each on a free port). An observer (a
plain paho client) records what the bus says; the services' own logs say when a motor stopped.

Scenarios (each on every broker of `--brokers`, the kill and frozen-motor scenarios on the first
one):

- `restart`: as the car starts moving, the broker is killed (SIGKILL: a crash, no wills) and
  comes back after `--outage` seconds; per trial: did both motors stop, how long after the
  broker went (their service's log), did the orchestrator fail safe (exit code 1, status
  `failed` once the broker is back), how long until every component was online again, and
  what was lost.
- `kill`: SIGKILL, then SIGSTOP, of each service kind mid-run; time from the signal to the
  orchestrator's retained status `failed`, max and p99; a SIGSTOPped service gets SIGCONT after.
- `frozen-motor`: the motor service on the sim driver, its world in this script at real time (the
  hardware's place: outside the service), SIGSTOPped for 5 s or SIGKILLed while both motors run:
  how long until they stop, with the deadman (`watchdog_s: 2`) and without it (`watchdog_s: 0`,
  the baseline: before the deadman a frozen service left them running for the whole pause); the
  stop reason the service reports after SIGCONT.
- `keepalive`: a service frozen by SIGSTOP (a hung process, a cut link) must be announced offline
  by the broker: the services connect with `keepalive=5` and the broker must publish the will
  within 1.5 x 5 s; per trial the time from SIGSTOP to the retained `offline`, and whether the
  service came back online after SIGCONT.
- `takeover`: a client that connects with a service's client id makes the broker drop the
  service (its will says offline, the run fails). How the car keeps its ids from others: an
  intruder listens to everything on `umlbot/<robot>/#` while the car drives and counts the fleet's
  client ids it sees in topics and payloads (0 expected); then, given a motor service's id (from
  the service's own debug log), it connects with it: the broker accepts or refuses, and the row
  says whether the service was dropped, the run failed, and when the service was back online.
  (These brokers have no users: the embedded broker refuses another *user's* client id only.)
- `fuzz`: `--fuzz N` malformed payloads (random bytes, invalid, huge, deeply nested JSON,
  NaN/Infinity, wrong types, unknown features, oversize) at every component's call topics and the
  orchestrator's signal and exit topics, with the car running (call time-out 10 s, so that load
  on the machine is not mistaken for a fault): process exits, tracebacks in any log, error
  replies against requests that named a reply topic, RSS growth, and a good call afterwards.
- `soak` (not in the default scenarios): every long-running process for `--soak-s` seconds
  (default 600) — `umlbot service all --driver mock`, `umlbot run` on a model that loops motor,
  servo and sonar calls as fast as they come back (trace on), `umlbot monitor` (its live view),
  `umlbot studio` with a page reading its WebSocket, and the broker — with the RSS of each
  sampled from /proc every `--soak-sample-s`; per process its RSS at the start, after the warm-up
  (`--soak-warmup-s`, default 300: the bounded records fill meanwhile, such as the studio's last
  100 000 trace events, about 60 MB, and the orchestrator's last 100 000 call latencies), at the
  end, its peak, growth after the warm-up and slope. A process that grows more than
  `--soak-max-growth-mb` (default 3) after the warm-up, or exits, fails the run (exit status 1).

The last output line is one JSON object: {"restart": [...], "kill": [...], "keepalive": [...],
"takeover": [...], "fuzz": [...], "frozen_motor": [...], "soak": [...]}.

    python bench/chaos.py [--trials 10] [--fuzz 10000] [--brokers mosquitto,amqtt]
                          [--kinds motor,sonar,servo,gpio]
                          [--scenarios restart,kill,keepalive,takeover,fuzz,frozen-motor,soak]
                          [--listen 5] [--soak-s 600] [--soak-warmup-s 300] [--soak-sample-s 5]
                          [--soak-max-growth-mb 3]
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import json
import math
import os
import random
import re
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion
from paho.mqtt.packettypes import PacketTypes
from paho.mqtt.properties import Properties

REPO = Path(__file__).resolve().parent.parent
MODEL = REPO / "models" / "robot_car"
ROBOT = "chaos"
KINDS = ("motor", "sonar", "servo", "gpio")
COMPONENTS = {"motor": ("LeftActuator", "RightActuator"), "sonar": ("DistanceRead",),
              "servo": ("Sensor",), "gpio": ("RaspberryPI",)}
ALL_COMPONENTS = frozenset(c for names in COMPONENTS.values() for c in names)
FEATURES = {"LeftActuator": ("enabled", "direction", "dutycycle"),
            "RightActuator": ("enabled", "direction", "dutycycle"),
            "DistanceRead": ("value",), "Sensor": ("angle",), "RaspberryPI": ("readPin", "writePin")}
MOTORS = COMPONENTS["motor"]
WATCHDOG_S = 2.0  # the car deployment's watchdog_s
CALL_TIMEOUT_S = 2.0  # the car model's call_timeout_s
REPLY_PREFIX = f"umlbot/{ROBOT}/_reply/chaos-fuzz"


def unit_environment() -> dict[str, str]:
    """The `Environment=` settings of the services' systemd unit: the processes run as there."""
    unit = (REPO / "deploy" / "systemd" / "umlbot-service@.service").read_text(encoding="utf-8")
    return dict(line.removeprefix("Environment=").split("=", 1) for line in unit.splitlines()
                if line.startswith("Environment="))


def umlbot(*args: str) -> list[str]:
    script = Path(sys.executable).parent / "umlbot"
    head = [str(script)] if script.exists() else [sys.executable, "-c", "from umlbot.cli import main; main()"]
    return [*head, *args]


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def port_accepts(port: int) -> bool:
    with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), timeout=0.2):
        return True
    return False


def wait_until(predicate: Callable[[], bool], timeout: float, interval: float = 0.02) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(interval)
    return predicate()


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return math.nan


def p99(values: list[float]) -> float | None:
    if not values:
        return None
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(0.99 * len(ordered)) - 1)]


# --- the broker ---------------------------------------------------------------------------------


class Broker:
    """Mosquitto or the embedded broker on a fixed port, restartable."""

    def __init__(self, kind: str, workdir: Path) -> None:
        self.kind = kind
        self.port = free_port()
        self.workdir = workdir
        self.proc: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def argv(self) -> list[str]:
        if self.kind == "mosquitto":
            binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
            config = self.workdir / "mosquitto.conf"
            config.write_text(f"listener {self.port} 127.0.0.1\nallow_anonymous true\npersistence false\n"
                              "set_tcp_nodelay true\nlog_dest stderr\nlog_type error\n", encoding="utf-8")
            return [binary, "-c", str(config)]
        return umlbot("--log-level", "WARNING", "broker", "--port", str(self.port))

    def start(self) -> None:
        with (self.workdir / f"broker-{self.kind}.log").open("ab") as log:
            self.proc = subprocess.Popen(self.argv(), stdout=log, stderr=subprocess.STDOUT)
        if not wait_until(lambda: port_accepts(self.port), 20.0):
            raise RuntimeError(f"{self.kind} did not start on port {self.port}")

    def kill(self) -> None:
        """A crash: SIGKILL, no goodbye to the clients (no wills, no clean disconnects)."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(10)
        self.proc = None

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        self.proc = None


# --- what the bus says --------------------------------------------------------------------------


class Observer:
    """A plain paho client that keeps the latest status and state of every component."""

    def __init__(self, port: int) -> None:
        self.lock = threading.Condition()
        self.status: dict[str, str] = {}
        self.state: dict[str, dict[str, Any]] = {}
        #: the orchestrator's status messages: (unix time received, state, reason)
        self.orchestrator: list[tuple[float, str, str | None]] = []
        self.client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"chaos-observer-{os.getpid()}")
        self.client.reconnect_delay_set(1, 1)
        self.client.on_connect = self._on_connect
        self.client.on_disconnect = self._on_disconnect
        self.client.on_message = self._on_message
        self.client.connect("127.0.0.1", port, keepalive=10)
        self.client.loop_start()

    def _on_connect(self, client: mqtt.Client, userdata: Any, flags: Any, rc: Any, props: Any = None) -> None:
        base = f"umlbot/{ROBOT}"
        client.subscribe([(f"{base}/+/status", 1), (f"{base}/+/state", 1)])

    def _on_disconnect(self, client: mqtt.Client, userdata: Any, flags: Any, rc: Any,
                       props: Any = None) -> None:
        with self.lock:  # what the broker said is stale now: learn it again after the reconnect
            self.status.clear()
            self.state.clear()
            self.lock.notify_all()

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        _, _, component, kind = message.topic.split("/", 3)
        try:
            data = json.loads(message.payload) if message.payload else {}
        except ValueError:
            return
        if not isinstance(data, dict):
            return
        with self.lock:
            if component == "orchestrator" and kind == "status":
                self.orchestrator.append((time.time(), str(data.get("state")), data.get("reason")))
            elif kind == "status":
                self.status[component] = str(data.get("state", "offline"))
            elif kind == "state":
                self.state[component] = data
            self.lock.notify_all()

    def wait(self, predicate: Callable[[Observer], bool], timeout: float) -> bool:
        with self.lock:
            return self.lock.wait_for(lambda: predicate(self), timeout)

    def online(self) -> set[str]:
        return {c for c, s in self.status.items() if s == "online"}

    def orchestrator_state(self) -> str | None:
        return self.orchestrator[-1][1] if self.orchestrator else None

    def motors_running(self) -> bool:
        return all(self.state.get(m, {}).get("running") for m in MOTORS)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


# --- the robot's processes ----------------------------------------------------------------------


@dataclass
class Proc:
    name: str
    popen: subprocess.Popen[bytes]
    log: Path
    started_at: float = field(default_factory=time.time)


class Fleet:
    """The four services and the orchestrator, each a real `umlbot` process."""

    def __init__(self, broker: Broker, workdir: Path, compiled: Path,
                 call_timeout_s: float | None = None, query: str = "", log_level: str = "INFO") -> None:
        self.broker = broker
        self.workdir = workdir
        self.compiled = compiled
        self.call_timeout_s = call_timeout_s
        self.services: dict[str, Proc] = {}
        self.run: Proc | None = None
        #: other long-running processes (the soak's `service all`, monitor and studio)
        self.others: list[Proc] = []
        self.counter = 0
        # MQTT 5 where the broker speaks it (the default), so that Response Topics name a reply
        # topic too; `query` adds URL parameters (e.g. keepalive=5)
        url = broker.url + (f"?{query}" if query else "")
        self.env = {**{k: v for k, v in os.environ.items() if not k.startswith("UMLBOT_")},
                    **unit_environment(), "UMLBOT_BROKER": url, "UMLBOT_LOG_LEVEL": log_level}
        self.trace: Path | None = None

    def _spawn(self, name: str, argv: list[str], quiet_stdout: bool = False) -> Proc:
        """Start one process, its log (stderr, and stdout unless `quiet_stdout`) in the workdir."""
        self.counter += 1
        log = self.workdir / f"{self.broker.kind}-{name}-{self.counter}.log"
        with log.open("wb") as out:
            popen = subprocess.Popen(argv, stdout=subprocess.DEVNULL if quiet_stdout else out,
                                     stderr=out if quiet_stdout else subprocess.STDOUT, env=self.env)
        return Proc(name, popen, log)

    def start_other(self, name: str, argv: list[str], quiet_stdout: bool = False) -> Proc:
        proc = self._spawn(name, argv, quiet_stdout)
        self.others.append(proc)
        return proc

    def start_service(self, kind: str) -> None:
        deployment = str(MODEL / "deployment.yaml")
        self.services[kind] = self._spawn(kind, umlbot("service", kind, "--deploy", deployment,
                                                       "--driver", "mock", "--robot", ROBOT))

    def start_run(self, trace_on_bus: bool = False) -> None:
        """The orchestrator, its trace in a file (`self.trace`), or with `trace_on_bus` published
        on MQTT as it is by default (what the monitor and the studio follow)."""
        extra = ["--call-timeout", str(self.call_timeout_s)] if self.call_timeout_s else []
        if trace_on_bus:
            self.trace = None
        else:
            self.trace = self.workdir / f"{self.broker.kind}-trace-{self.counter + 1}.jsonl"
            extra += ["--no-trace", "--trace", str(self.trace)]
        self.run = self._spawn("run", umlbot("run", str(self.compiled), "--robot", ROBOT,
                                             "--startup-timeout", "30", *extra))

    def all_processes(self) -> list[Proc]:
        return [*self.services.values(), *([self.run] if self.run else []), *self.others]

    def stop(self) -> None:
        for proc in [*([self.run] if self.run else []), *self.services.values(), *self.others]:
            if proc.popen.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(proc.popen.pid, signal.SIGCONT)
                proc.popen.terminate()
        for proc in self.all_processes():
            try:
                proc.popen.wait(15)
            except subprocess.TimeoutExpired:
                proc.popen.kill()
                proc.popen.wait(5)


def log_events(path: Path, event: str) -> list[dict[str, Any]]:
    """The JSON log lines of one process with this event name."""
    found = []
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        if f'"{event}"' not in line:
            continue
        with contextlib.suppress(ValueError):
            entry = json.loads(line)
            if entry.get("event") == event:
                found.append(entry)
    return found


def unix_time(entry: dict[str, Any]) -> float:
    return datetime.fromisoformat(str(entry["timestamp"]).replace("Z", "+00:00")).timestamp()


def count_tracebacks(paths: list[Path], offsets: dict[Path, int] | None = None) -> int:
    """Tracebacks in the logs (raw `Traceback` text or a JSON `exception`), after the offsets."""
    total = 0
    for path in paths:
        text = path.read_bytes()[(offsets or {}).get(path, 0):].decode("utf-8", "replace")
        total += text.count("Traceback (most recent call last)") + text.count('"exception":')
    return total


def compile_car(workdir: Path) -> Path:
    out = workdir / "robot_car.json"
    subprocess.run(umlbot("compile", str(MODEL), "-o", str(out)), check=True, capture_output=True,
                   timeout=120)
    return out


def ensure_driving(fleet: Fleet, observer: Observer, timeout: float = 40.0) -> None:
    """Every service online and a run going with both motors running (starts what is missing)."""
    for kind in KINDS:
        proc = fleet.services.get(kind)
        if proc is None or proc.popen.poll() is not None:
            fleet.start_service(kind)
    if not observer.wait(lambda o: o.online() >= ALL_COMPONENTS, timeout):
        raise RuntimeError(f"components not online: {sorted(ALL_COMPONENTS - observer.online())}")
    if fleet.run is None or fleet.run.popen.poll() is not None:
        with observer.lock:
            observer.orchestrator.clear()
        fleet.start_run()
    if not observer.wait(lambda o: o.orchestrator_state() == "running" and o.motors_running(), timeout):
        raise RuntimeError(f"the car did not start driving; orchestrator {observer.orchestrator_state()}, "
                           f"run log: {fleet.run.log.read_text()[-2000:] if fleet.run else ''}")


# --- scenario: broker restart -------------------------------------------------------------------


def broker_restart(broker: Broker, fleet: Fleet, observer: Observer, trials: int,
                   outage_s: float) -> dict[str, Any]:
    """With the car driving, the broker stops and comes back; what stopped, failed, came back."""
    rows: list[dict[str, Any]] = []
    for trial in range(trials):
        ensure_driving(fleet, observer)
        run = fleet.run
        assert run is not None
        # the car moves in bursts: pull the broker away at the start of one
        observer.wait(lambda o: not o.motors_running(), 10.0)
        if not observer.wait(lambda o: o.motors_running(), 10.0):
            raise RuntimeError("the motors did not start again")
        mark = len(observer.orchestrator)
        gone = time.time()
        broker.kill()
        time.sleep(outage_s)
        broker.start()
        back = time.monotonic()
        online = observer.wait(lambda o: o.online() >= ALL_COMPONENTS, 30.0)
        back_online_s = time.monotonic() - back if online else None
        try:
            run_code: int | None = run.popen.wait(30)
        except subprocess.TimeoutExpired:
            run_code = None
        finished = log_events(run.log, "orchestrator_finished")
        failure = str(finished[-1].get("failure")) if finished else None
        stops = {}
        for motor_proc in [fleet.services["motor"]]:
            for entry in log_events(motor_proc.log, "motor_stopped"):
                if unix_time(entry) >= gone - 0.01 and entry.get("component") not in stops:
                    stops[entry["component"]] = (unix_time(entry) - gone, entry.get("reason"))
        # the orchestrator says `failed` once the broker is back (its final stops sent)
        said_failed = observer.wait(
            lambda o, mark=mark: any(e[1] == "failed" for e in o.orchestrator[mark:]), 10.0)  # type: ignore[misc]
        restored = observer.wait(
            lambda o: all(o.state.get(m, {}).get("running") is False for m in MOTORS), 5.0)
        rows.append({
            "trial": trial,
            "motors_stopped": sorted(stops) == sorted(MOTORS),
            "motor_stop_s": round(max((s for s, _ in stops.values()), default=math.nan), 3),
            "stop_reasons": sorted({str(r) for _, r in stops.values()}),
            "orchestrator_exit_code": run_code,
            "orchestrator_failure": failure,
            "failed_status_published": said_failed,
            "back_online_s": None if back_online_s is None else round(back_online_s, 2),
            "motor_state_restored": restored,
        })
        print(json.dumps({"restart": broker.kind, **rows[-1]}), file=sys.stderr, flush=True)
    stop_times = [r["motor_stop_s"] for r in rows if not math.isnan(r["motor_stop_s"])]
    return {
        "broker": broker.kind,
        "trials": trials,
        "outage_s": outage_s,
        "motors_stopped_every_trial": all(r["motors_stopped"] for r in rows),
        "motor_stop_max_s": max(stop_times, default=None),
        "within_watchdog": all(s <= WATCHDOG_S for s in stop_times) and len(stop_times) == trials,
        "orchestrator_failed_safe_every_trial": all(
            r["orchestrator_exit_code"] == 1 and r["failed_status_published"] for r in rows),
        "back_online_every_trial": all(r["back_online_s"] is not None for r in rows),
        "back_online_max_s": max((r["back_online_s"] for r in rows if r["back_online_s"] is not None),
                                 default=None),
        # what a restart loses: the run (it fails safe and ends), and nothing of the components'
        # retained status and state (the services publish both again after their reconnect)
        "lost_runs": sum(1 for r in rows if r["orchestrator_exit_code"] == 1),
        "lost_motor_states": sum(1 for r in rows if not r["motor_state_restored"]),
        "failures": sorted({str(r["orchestrator_failure"]) for r in rows}),
        "rows": rows,
    }


# --- scenario: SIGKILL / SIGSTOP ----------------------------------------------------------------


def failed_call_start(trace: Path | None) -> float | None:
    """Unix time at which the call that failed the run was made (its trace event), if any."""
    if trace is None or not trace.exists():
        return None
    started = None
    for line in trace.read_text(encoding="utf-8", errors="replace").splitlines():
        with contextlib.suppress(ValueError):
            event = json.loads(line)
            if event.get("error") and started is None:
                started = float(event["start"])
    return started


def kill_and_freeze(broker: Broker, fleet: Fleet, observer: Observer, kinds: list[str],
                    trials: int) -> list[dict[str, Any]]:
    """SIGKILL, then SIGSTOP (and SIGCONT), of each service kind mid-run."""
    results = []
    for kind in kinds:
        for signum in (signal.SIGKILL, signal.SIGSTOP):
            to_safe: list[float] = []  # signal -> the orchestrator's fail_safe_stop (its log)
            to_failed: list[float] = []  # signal -> retained status `failed` (after the final stops)
            from_call: list[float] = []  # start of the unanswered call -> fail_safe_stop
            unaffected = 0
            reasons: set[str] = set()
            motors_stopped_after_cont: list[bool] = []
            for _trial in range(trials):
                ensure_driving(fleet, observer)
                service, run = fleet.services[kind], fleet.run
                assert run is not None
                mark = len(observer.orchestrator)
                sent = time.time()
                os.kill(service.popen.pid, signum)

                def has_failed(o: Observer, mark: int = mark) -> bool:
                    return any(e[1] == "failed" for e in o.orchestrator[mark:])

                # a component the model never calls is not needed: then the run just goes on
                failed = observer.wait(has_failed, CALL_TIMEOUT_S + 6.0)
                if signum == signal.SIGSTOP:
                    time.sleep(0.2)
                    os.kill(service.popen.pid, signal.SIGCONT)
                    if kind == "motor":  # frozen, it could not stop them; awake, it must at once
                        motors_stopped_after_cont.append(observer.wait(
                            lambda o: all(o.state.get(m, {}).get("running") is False for m in MOTORS), 5.0))
                else:
                    service.popen.wait(10)
                if not failed:
                    unaffected += observer.orchestrator_state() == "running" and run.popen.poll() is None
                    continue
                with observer.lock:
                    when = next(e[0] for e in observer.orchestrator[mark:] if e[1] == "failed")
                to_failed.append(when - sent)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    run.popen.wait(20)
                safe = log_events(run.log, "fail_safe_stop")
                if safe:
                    to_safe.append(unix_time(safe[0]) - sent)
                    reasons.add(str(safe[0].get("reason")))
                    call_start = failed_call_start(fleet.trace)
                    if call_start is not None and call_start >= sent - CALL_TIMEOUT_S:
                        from_call.append(unix_time(safe[0]) - call_start)
            row: dict[str, Any] = {
                "broker": broker.kind,
                "kind": kind,
                "signal": signal.Signals(signum).name,
                "trials": trials,
                "failed_safe": len(to_safe),
                "run_unaffected": unaffected,  # the model never called the component
                "to_fail_safe_max_s": _round(max(to_safe, default=None)),
                "to_fail_safe_p99_s": _round(p99(to_safe)),
                "to_fail_safe_median_s": _round(statistics.median(to_safe) if to_safe else None),
                "to_failed_status_max_s": _round(max(to_failed, default=None)),
                "to_failed_status_p99_s": _round(p99(to_failed)),
                # a frozen service is noticed by the first call it does not answer: from that
                # call's start (trace), the fail-safe comes after the call time-out
                "calls_timed_out": len(from_call),
                "from_call_max_s": _round(max(from_call, default=None)),
                "reasons": sorted(reasons),
            }
            if motors_stopped_after_cont:
                row["motors_stopped_after_sigcont"] = all(motors_stopped_after_cont)
            results.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
    return results


def _round(value: float | None) -> float | None:
    return None if value is None else round(value, 3)


# --- scenario: keep-alive -----------------------------------------------------------------------

KEEPALIVE_S = 5  # the smallest keep-alive a broker URL may ask for


def keepalive(broker: Broker, fleet: Fleet, observer: Observer, trials: int) -> dict[str, Any]:
    """SIGSTOP the sonar service mid-run: the broker must publish its will within 1.5 x keep-alive."""
    will_after: list[float | None] = []
    back_online: list[bool] = []
    component = COMPONENTS["sonar"][0]
    for _trial in range(trials):
        ensure_driving(fleet, observer)
        service = fleet.services["sonar"]
        sent = time.monotonic()
        os.kill(service.popen.pid, signal.SIGSTOP)
        offline = observer.wait(lambda o: o.status.get(component) == "offline", 4 * KEEPALIVE_S)
        will_after.append(time.monotonic() - sent if offline else None)
        os.kill(service.popen.pid, signal.SIGCONT)
        back_online.append(observer.wait(lambda o: o.status.get(component) == "online", 20.0))
        if fleet.run is not None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                fleet.run.popen.wait(20)
    seen = [w for w in will_after if w is not None]
    row: dict[str, Any] = {
        "broker": broker.kind,
        "keepalive_s": KEEPALIVE_S,
        "trials": trials,
        "will_published": len(seen),
        "will_after_max_s": _round(max(seen, default=None)),
        "will_after_median_s": _round(statistics.median(seen) if seen else None),
        "back_online_after_sigcont": sum(back_online),
    }
    print(json.dumps(row), file=sys.stderr, flush=True)
    return row


# --- scenario: client-id takeover ---------------------------------------------------------------

CLIENT_ID = re.compile(rb"umlbot-[A-Za-z0-9_]+-[A-Za-z0-9_]+-[A-Za-z0-9_-]+")


def fleet_client_ids(fleet: Fleet) -> set[str]:
    """The client ids the fleet's processes connected with (their debug log says them)."""
    ids = set()
    for proc in fleet.all_processes():
        for entry in log_events(proc.log, "mqtt_connected"):
            ids.add(str(entry["client_id"]))
    return ids


def takeover(broker: Broker, fleet: Fleet, observer: Observer, listen_s: float) -> dict[str, Any]:
    """Can an intruder learn a client id from the bus, and what does one that knows it do?"""
    ensure_driving(fleet, observer)
    heard: list[tuple[str, bytes]] = []
    spy = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"chaos-spy-{os.getpid()}",
                      protocol=MQTTProtocolVersion.MQTTv5 if broker.kind == "mosquitto"
                      else MQTTProtocolVersion.MQTTv311)
    spy.on_connect = lambda c, u, f, rc, p=None: c.subscribe(f"umlbot/{ROBOT}/#", 0)
    spy.on_message = lambda c, u, m: heard.append((m.topic, bytes(m.payload)))
    spy.connect("127.0.0.1", broker.port, 30)
    spy.loop_start()
    from umlbot.services.bus import BrokerSettings, BusClient

    with BusClient(BrokerSettings.from_url(broker.url), ROBOT, role="chaos") as caller:
        caller.call("DistanceRead", "value", timeout=5.0)  # a caller's request and its reply too
        time.sleep(listen_s)
    spy.disconnect()
    spy.loop_stop()
    ids = fleet_client_ids(fleet) | {caller.client_id}
    leaked = {i for i in ids for topic, payload in heard if i in topic or i.encode() in payload}
    lookalikes = {m.decode() for _, payload in heard for m in CLIENT_ID.findall(payload)}
    motor_ids = [i for i in ids if "-service-LeftActuator-" in i]
    row: dict[str, Any] = {"broker": broker.kind, "messages_heard": len(heard),
                           "fleet_client_ids": len(ids), "client_ids_on_bus": len(leaked),
                           "id_like_strings_on_bus": sorted(lookalikes)[:5]}
    if motor_ids:
        mark = len(observer.orchestrator)
        accepted = threading.Event()
        refused: list[str] = []

        def on_connect(c: mqtt.Client, u: Any, f: Any, rc: Any, p: Any = None) -> None:
            if rc.is_failure:
                refused.append(str(rc))
            else:
                accepted.set()

        intruder = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=motor_ids[0],
                               protocol=MQTTProtocolVersion.MQTTv311)
        intruder.on_connect = on_connect
        intruder.reconnect_delay_set(30, 60)  # one attempt
        began = time.monotonic()
        intruder.connect("127.0.0.1", broker.port, 30)
        intruder.loop_start()
        dropped = observer.wait(lambda o: o.status.get("LeftActuator") == "offline", 3.0)

        def has_failed(o: Observer, m: int = mark) -> bool:
            return any(e[1] == "failed" for e in o.orchestrator[m:])

        failed = observer.wait(has_failed, 5.0)
        intruder.disconnect()
        intruder.loop_stop()
        back = observer.wait(lambda o: o.status.get("LeftActuator") == "online", 20.0)
        row.update({"intruder_accepted": accepted.is_set(), "intruder_refused": refused[:1],
                    "service_dropped": dropped, "run_failed": failed,
                    "service_online_after_s": _round(time.monotonic() - began) if back else None})
    print(json.dumps(row), file=sys.stderr, flush=True)
    return row


# --- scenario: fuzz -----------------------------------------------------------------------------


@dataclass
class Payload:
    topic: str
    body: bytes
    reply_id: str | None = None  # the id whose reply must come (a reply topic was named)
    response_topic: bool = False  # MQTT 5 Response Topic + Correlation Data


def _not_json(data: bytes) -> bytes:
    try:
        json.loads(data)
    except (ValueError, RecursionError):
        return data
    return b"\xff" + data


def fuzz_payloads(n: int, seed: int, mqtt5: bool) -> Iterator[Payload]:
    """`n` malformed payloads for the car's call, signal and exit topics; deterministic per seed."""
    rng = random.Random(seed)
    base = f"umlbot/{ROBOT}"
    components = sorted(FEATURES)

    def call_topic() -> str:
        component = rng.choice(components)
        feature = rng.choice([*FEATURES[component], "fly", "x" * 40, "dutycycle2"])
        return f"{base}/{component}/call/{feature}"

    def envelope(request_id: str, args: str, reply_to: str | None = None) -> bytes:
        reply = json.dumps(reply_to if reply_to is not None else f"{REPLY_PREFIX}/{request_id}")
        return f'{{"id": "{request_id}", "reply_to": {reply}, "args": {args}}}'.encode()

    bad_args = ["[NaN]", "[Infinity]", "[-Infinity]", "[1e400]", "[" + "9" * 4000 + "]", '["60"]',
                "[{}]", "[[1, 2]]", "[null]", "[true, false, 3]", '"notalist"', "{\"a\": 1}",
                "[" * 300 + "]" * 300, '["\\ud800"]', "[-1]", "[250]"]  # invalid for every feature
    for i in range(n):
        rid = f"f{seed}-{i}"
        roll = rng.random()
        if i % 50 == 49:  # exit topic: never a JSON object that is a valid request
            yield Payload(f"{base}/orchestrator/exit", rng.choice(
                [b"", b"[]", b"null", b"1", b'"stop"', b"[" * 5000, b'{"reason": 5}', b"\xff\xfe",
                 bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 64)))]))
        elif i % 50 == 48:  # signals the car does not accept: ignored (a warning line a minute at most)
            yield Payload(f"{base}/signal/chaos_{rng.randint(0, 9)}", rng.choice(
                [b"[" * 5000, b"{" * 3000, b"\xff" * 100, b"x" * 200_000, b"NaN", b"1e999", b""]))
        elif roll < 0.15:  # random bytes, with a response topic when the protocol has one
            body = _not_json(bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 300))))
            yield Payload(call_topic(), body, rid if mqtt5 else None, response_topic=mqtt5)
        elif roll < 0.30:  # invalid JSON after a readable id and reply_to
            yield Payload(call_topic(), envelope(rid, rng.choice(
                ["[1, ", "[1 2]", "[", "{]", "[1,]", "[01]", "['x']",
                 "[" * rng.choice([100, 1000, 5000, 50000])])), rid)
        elif roll < 0.40:  # deep nesting with no envelope to answer to
            depth = rng.choice([1000, 5000, 100_000])
            body = rng.choice([b"[" * depth, b'{"a":' * depth, b"[" * depth + b"]" * depth])
            yield Payload(call_topic(), body, rid if mqtt5 else None, response_topic=mqtt5)
        elif roll < 0.70:  # a valid envelope with bad arguments (or for an unknown feature)
            component = rng.choice(components)
            feature = rng.choice([*FEATURES[component], "fly"])
            args = rng.choice(bad_args)
            yield Payload(f"{base}/{component}/call/{feature}", envelope(rid, args), rid)
        elif roll < 0.80:  # bad envelopes: ids, reply topics, extra keys
            yield Payload(call_topic(), rng.choice([
                f'{{"id": "{rid}", "reply_to": "{REPLY_PREFIX}/{rid}", "args": [], "x": 1}}'.encode(),
                f'{{"id": "{rid}", "reply_to": "{REPLY_PREFIX}/{rid}", "args": 5}}'.encode(),
                f'{{"id": [1], "reply_to": "{REPLY_PREFIX}/{rid}"}}'.encode(),
                b'{"id": "w", "reply_to": "a/#", "args": []}',
                b'{"id": "e", "reply_to": "", "args": []}',
                b'{"id": "n", "reply_to": 42, "args": []}',
            ]), None)
        elif roll < 0.99:  # wrong types as bare payloads (fire-and-forget: no reply to count)
            yield Payload(call_topic(), rng.choice([b"NaN", b"Infinity", b'"text"', b"{}", b'{"a": [1]}',
                                                     b"[[[]]]", b"1e400", b"-0", b"true false"]))
        else:  # oversize: over the 256 KiB limit, up to 1 MB
            size = rng.choice([300_000, 1_048_576])
            yield Payload(call_topic(), envelope(rid, json.dumps(["x" * size])), rid)


def fuzz(broker: Broker, fleet: Fleet, observer: Observer, n: int, seed: int) -> dict[str, Any]:
    ensure_driving(fleet, observer)
    processes = fleet.all_processes()
    offsets = {p.log: p.log.stat().st_size for p in processes}
    rss_before = {p.name: rss_mb(p.popen.pid) for p in processes}
    mqtt5 = broker.kind == "mosquitto"
    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id="chaos-fuzz",
                         protocol=MQTTProtocolVersion.MQTTv5 if mqtt5 else MQTTProtocolVersion.MQTTv311)
    replies: dict[str, dict[str, Any]] = {}
    lock = threading.Condition()

    def on_message(c: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        try:
            reply = json.loads(message.payload)
        except ValueError:
            return
        key = message.topic.rsplit("/", 1)[-1]
        props = getattr(message, "properties", None)
        correlation = getattr(props, "CorrelationData", None) if props is not None else None
        if correlation:
            key = correlation.decode()
        with lock:
            replies[key] = reply
            lock.notify_all()

    client.on_message = on_message
    client.connect("127.0.0.1", broker.port, keepalive=30)
    client.loop_start()
    subscribed = threading.Event()
    client.on_subscribe = lambda *args: subscribed.set()
    client.subscribe(f"{REPLY_PREFIX}/#", 0)
    subscribed.wait(10)
    expected: set[str] = set()
    counts = {"calls": 0, "signals": 0, "exit": 0}
    began = time.monotonic()
    for payload in fuzz_payloads(n, seed, mqtt5):
        props = None
        if payload.response_topic:
            props = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
            props.ResponseTopic = f"{REPLY_PREFIX}/v5"
            props.CorrelationData = (payload.reply_id or "").encode()
        info = client.publish(payload.topic, payload.body, qos=1, properties=props)
        info.wait_for_publish(30)
        if payload.reply_id is not None:
            expected.add(payload.reply_id)
        kind = ("exit" if payload.topic.endswith("/exit")
                else "signals" if "/signal/" in payload.topic else "calls")
        counts[kind] += 1
    with lock:
        lock.wait_for(lambda: expected <= set(replies), 60.0)
        got = {k: replies[k] for k in expected if k in replies}
    sent_s = time.monotonic() - began
    client.disconnect()
    client.loop_stop()
    time.sleep(1.0)
    alive = {p.name: p.popen.poll() is None for p in processes}
    rss_after = {p.name: rss_mb(p.popen.pid) for p in processes if alive[p.name]}
    # a good call to every component works afterwards, and the run is still going
    good = good_calls(broker)
    still_running = observer.orchestrator_state() == "running"
    errors = sum(1 for r in got.values() if r.get("ok") is False)
    return {
        "broker": broker.kind,
        "payloads": n,
        "seed": seed,
        "mqtt5_response_topics": mqtt5,
        **counts,
        "seconds": round(sent_s, 1),
        "process_exits": sum(1 for ok in alive.values() if not ok),
        "tracebacks": count_tracebacks([p.log for p in processes], offsets),
        "requests_naming_a_reply_topic": len(expected),
        "replies": len(got),
        "error_replies": errors,
        "rss_growth_max_mb": round(max(rss_after[name] - rss_before[name] for name in rss_after), 1),
        "rss_growth_mb": {name: round(rss_after[name] - rss_before[name], 1) for name in rss_after},
        "good_calls_after": good,
        "run_still_going": still_running,
    }


def good_calls(broker: Broker) -> bool:
    from umlbot.base.errors import RemoteError
    from umlbot.services.bus import BrokerSettings, BusClient

    with BusClient(BrokerSettings.from_url(broker.url), ROBOT, role="chaos") as bus:
        try:
            bus.call("Sensor", "angle", 90, timeout=5.0)
            bus.call("LeftActuator", "direction", True, timeout=5.0)
            distance = bus.call("DistanceRead", "value", timeout=5.0)
            try:  # the car's deployment gives the gpio service no pin: its answer is a refusal
                bus.call("RaspberryPI", "readPin", 5, timeout=5.0)
            except RemoteError as exc:
                if exc.code != "out_of_range":
                    raise
            return isinstance(distance, int)
        except Exception as exc:  # the figure says no; the reason goes to stderr
            print(f"good call failed: {exc!r}", file=sys.stderr)
            return False


# --- scenario: soak -----------------------------------------------------------------------------

#: the soak's model: the car's components, one lane calling both motors, the servo and the sonar in
#: a loop as fast as the calls come back (the mock sonar always reads 100 cm)
SOAK_LANE = """\
lane: RaspberryPI
nodes:
  - {id: start, kind: start}
  - {id: left_on, kind: action, call: LeftActuator.enabled(true)}
  - {id: left_power, kind: action, call: LeftActuator.dutycycle(40)}
  - {id: right_on, kind: action, call: RightActuator.enabled(true)}
  - {id: right_power, kind: action, call: RightActuator.dutycycle(60)}
  - {id: look_left, kind: action, call: Sensor.angle(135)}
  - {id: left, kind: datastore, name: left, value: DistanceRead.value()}
  - {id: look_right, kind: action, call: Sensor.angle(45)}
  - {id: again, kind: decision, branches: [{if: left >= 0, then: left_on}, {else: end}]}
  - {id: end, kind: end}
"""


def soak_model(workdir: Path) -> tuple[Path, Path]:
    """The soak's model folder (the car's components and deployment, `SOAK_LANE`) and its compiled file."""
    folder = workdir / "soak"
    (folder / "activities").mkdir(parents=True, exist_ok=True)
    car = (MODEL / "model.yaml").read_text(encoding="utf-8")
    (folder / "model.yaml").write_text(car.replace("\nname: car\n", "\nname: soak\n"), encoding="utf-8")
    shutil.copy(MODEL / "deployment.yaml", folder / "deployment.yaml")
    (folder / "activities" / "main.yaml").write_text(SOAK_LANE, encoding="utf-8")
    out = workdir / "soak.json"
    subprocess.run(umlbot("compile", str(folder), "-o", str(out)), check=True, capture_output=True,
                   timeout=120)
    return folder, out


class PageReader:
    """A studio page as the browser opens it: a WebSocket on `/ws` read as fast as frames come."""

    def __init__(self, port: int) -> None:
        self.url = f"http://127.0.0.1:{port}/ws"
        self.frames = 0
        self.bytes = 0
        #: events received by type (`trace`, `call`, …)
        self.events: collections.Counter[str] = collections.Counter()
        self.error: str | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="soak-page", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        import asyncio

        try:
            asyncio.run(self._read())
        except Exception as exc:  # the figure says so; the soak goes on
            self.error = repr(exc)

    async def _read(self) -> None:
        import aiohttp

        async with aiohttp.ClientSession() as session, session.ws_connect(self.url, max_msg_size=0) as ws:
            while not self._stop.is_set():
                try:
                    message = await ws.receive(timeout=0.5)
                except TimeoutError:
                    continue
                if message.type != aiohttp.WSMsgType.TEXT:
                    return
                self.frames += 1
                self.bytes += len(message.data)
                frame = json.loads(message.data)
                if frame.get("type") == "events":
                    self.events.update(str(event.get("type")) for event in frame["events"])

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)


def memory_trend(samples: list[tuple[float, float]], warmup_s: float) -> dict[str, Any]:
    """RSS figures of one process from `(seconds since the start, MB)` samples: at the start, at
    the end of the warm-up, at the end and their peak; `growth_mb`, the median of the last three
    samples less that of the first three after the warm-up; `slope_mb_per_min`, the least-squares
    slope after the warm-up."""
    after = [(t, mb) for t, mb in samples if t >= warmup_s] or samples[-1:]
    head = statistics.median(mb for _, mb in after[:3])
    tail = statistics.median(mb for _, mb in after[-3:])
    slope = (statistics.linear_regression([t for t, _ in after], [mb for _, mb in after]).slope * 60
             if len(after) >= 2 and len({t for t, _ in after}) >= 2 else 0.0)
    return {
        "first_mb": round(samples[0][1], 1),
        "start_mb": round(after[0][1], 1),
        "end_mb": round(samples[-1][1], 1),
        "peak_mb": round(max(mb for _, mb in samples), 1),
        "growth_mb": round(tail - head, 2),
        "slope_mb_per_min": round(slope, 3),
    }


def soak(broker: Broker, fleet: Fleet, observer: Observer, model_dir: Path, duration_s: float,
         warmup_s: float, sample_s: float, max_growth_mb: float) -> dict[str, Any]:
    """Every long-running process for `duration_s`: the model loops calls as fast as it can with
    the trace on, a monitor and a studio (a page attached) follow; RSS of each sampled."""
    deployment = str(model_dir / "deployment.yaml")
    services = fleet.start_other("services", umlbot("service", "all", "--deploy", deployment,
                                                    "--driver", "mock", "--robot", ROBOT))
    if not observer.wait(lambda o: o.online() >= ALL_COMPONENTS, 40.0):
        raise RuntimeError(f"components not online: {sorted(ALL_COMPONENTS - observer.online())}; "
                           f"services log: {services.log.read_text()[-2000:]}")
    monitor = fleet.start_other("monitor", umlbot("monitor", "--robot", ROBOT), quiet_stdout=True)
    studio_port = free_port()
    studio = fleet.start_other("studio", umlbot("studio", str(model_dir), "--robot", ROBOT,
                                                "--port", str(studio_port), "--log-level", "WARNING"))
    if not wait_until(lambda: port_accepts(studio_port), 60.0):
        raise RuntimeError(f"the studio did not start: {studio.log.read_text()[-2000:]}")
    page = PageReader(studio_port)
    fleet.start_run(trace_on_bus=True)
    run = fleet.run
    assert run is not None and broker.proc is not None
    if not observer.wait(lambda o: o.orchestrator_state() == "running", 40.0):
        raise RuntimeError(f"the soak model did not start: {run.log.read_text()[-2000:]}")
    processes = {"broker": broker.proc.pid, "services": services.popen.pid, "orchestrator": run.popen.pid,
                 "monitor": monitor.popen.pid, "studio": studio.popen.pid}
    offsets = {p.log: p.log.stat().st_size for p in fleet.all_processes()}
    samples: dict[str, list[tuple[float, float]]] = {name: [] for name in processes}
    began = time.monotonic()
    while True:
        now = time.monotonic() - began
        for name, pid in processes.items():
            with contextlib.suppress(OSError):
                samples[name].append((now, rss_mb(pid)))
        if now >= duration_s or any(p.popen.poll() is not None for p in fleet.all_processes()):
            break
        time.sleep(min(sample_s, max(0.0, duration_s - now)))
    elapsed = time.monotonic() - began
    alive = {p.name: p.popen.poll() is None for p in fleet.all_processes()}
    state = observer.orchestrator_state()
    page.close()
    fleet.stop()
    finished = log_events(run.log, "orchestrator_finished")
    actions = int(finished[-1].get("actions", 0)) if finished else 0
    trends = {name: memory_trend(points, warmup_s) for name, points in samples.items() if points}
    worst = max(trends.values(), key=lambda t: t["growth_mb"])["growth_mb"] if trends else math.nan
    return {
        "broker": broker.kind,
        "duration_s": round(elapsed, 1),
        "warmup_s": warmup_s,
        "sample_s": sample_s,
        "actions": actions,
        "actions_per_s": round(actions / elapsed, 1) if elapsed else None,
        "orchestrator_state": state,
        "process_exits": sum(1 for ok in alive.values() if not ok),
        "tracebacks": count_tracebacks([p.log for p in fleet.all_processes()], offsets),
        "page_frames": page.frames,
        "page_events": dict(page.events),
        "page_mb": round(page.bytes / 1e6, 1),
        "page_error": page.error,
        "max_growth_mb": worst,
        "limit_mb": max_growth_mb,
        "flat": len(trends) == len(processes) and all(t["growth_mb"] <= max_growth_mb
                                                     for t in trends.values()),
        "processes": trends,
    }


# --- scenario: frozen motor service -------------------------------------------------------------

#: how long a SIGSTOPped motor service stays frozen (the pause of the issue that found it)
FREEZE_S = 5.0
#: a deadman stops a motor `watchdog_s` after the last renewal it got; a renewal the service sent
#: just before the signal may reach the world this long after it
IN_FLIGHT_S = 0.01
#: a 400 m x 400 m hall: the car drives straight for a whole trial and meets no wall
HALL = """
name: hall
start: {x: 0.0, y: 0.0, heading_deg: 90}
goal: {x_min: -1.0, x_max: 1.0, y_min: 190.0, y_max: 192.0}
walls:
  - [[-200.0, -200.0], [200.0, -200.0], [200.0, 200.0], [-200.0, 200.0], [-200.0, -200.0]]
"""


def frozen_motor(broker: Broker, observer: Observer, workdir: Path, trials: int) -> list[dict[str, Any]]:
    """The motor service frozen (SIGSTOP for `FREEZE_S`, then SIGCONT) or killed (SIGKILL) while
    both motors run: how long they keep running.

    The motors are the simulated world's, kept in this process (where the hardware is: outside
    the service), at real time (`Clock(1.0)`); the service is `umlbot service motor --driver sim`,
    commanded by a direct caller that repeats `dutycycle` every 0.5 s (its command watchdog).
    With the deadman (`watchdog_s: 2`) the world stops a motor whose driver stops renewing it;
    the baseline (`watchdog_s: 0`, no deadman, the motors' state before the deadman existed) runs
    on for the whole pause: a watchdog inside the frozen process cannot act.
    """
    from umlbot.base.deployment import load_deployment

    rows = []
    for watchdog_s in (WATCHDOG_S, 0.0):
        deployment = load_deployment(MODEL / "deployment.yaml")
        for name in MOTORS:
            deployment.components[name].settings["watchdog_s"] = watchdog_s
        deploy_file = workdir / f"frozen-motor-{watchdog_s:g}.json"
        deploy_file.write_text(deployment.model_dump_json(), encoding="utf-8")
        for signum in (signal.SIGSTOP, signal.SIGKILL):
            stops: list[float] = []  # signal -> both motors stopped (world time)
            reasons: set[str] = set()
            for trial in range(trials):
                log = workdir / f"frozen-motor-{watchdog_s:g}-{signal.Signals(signum).name}-{trial}.log"
                stop_s, said = _freeze_trial(broker, observer, deploy_file, log, signum)
                if stop_s is not None:
                    stops.append(stop_s)
                reasons |= said
            row: dict[str, Any] = {
                "broker": broker.kind,
                "deadman": watchdog_s > 0,
                "watchdog_s": watchdog_s,
                "signal": signal.Signals(signum).name,
                "trials": trials,
                "pause_s": FREEZE_S,
                "stopped": len(stops),
                "ran_the_whole_pause": trials - len(stops),
                "stop_max_s": _round(max(stops, default=None)),
                "stop_p99_s": _round(p99(stops)),
                "stop_median_s": _round(statistics.median(stops) if stops else None),
                # from the signal: a renewal already on its way may land after it (a few ms)
                "within_watchdog": len(stops) == trials and all(s <= WATCHDOG_S + IN_FLIGHT_S for s in stops),
            }
            if reasons:
                row["stop_reasons_after_sigcont"] = sorted(reasons)
            rows.append(row)
            print(json.dumps({"frozen_motor": row}), file=sys.stderr, flush=True)
    return rows


def _freeze_trial(broker: Broker, observer: Observer, deploy_file: Path, log: Path,
                  signum: int) -> tuple[float | None, set[str]]:
    """One trial of `frozen_motor`: (seconds from the signal until both motors stopped, None when
    they ran for the whole pause; the stop reasons the service gave after SIGCONT)."""
    from umlbot.base.clock import Clock
    from umlbot.services.bus import BrokerSettings, BusClient
    from umlbot.sim import World, WorldLoop, WorldServer, parse_track

    clock = Clock(1.0)
    world = World(parse_track(HALL), clock=clock)
    loop = WorldLoop(world, clock)
    server = WorldServer(world).start()
    loop.start()
    env = {**{k: v for k, v in os.environ.items() if not k.startswith("UMLBOT_")}, **unit_environment(),
           "UMLBOT_BROKER": broker.url, "UMLBOT_LOG_LEVEL": "INFO", **server.env}
    with log.open("wb") as out:
        service = subprocess.Popen(umlbot("service", "motor", "--deploy", str(deploy_file), "--driver", "sim",
                                          "--robot", ROBOT), stdout=out, stderr=subprocess.STDOUT, env=env)
    keep = threading.Event()

    def running() -> bool:
        return any(world.motor(side).enabled for side in ("left", "right"))

    def keeper(bus: BusClient) -> None:  # a direct caller: a command every 0.5 s
        while not keep.wait(0.5):
            for name in MOTORS:
                with contextlib.suppress(Exception):  # frozen or dead: no reply
                    bus.call(name, "dutycycle", 60, timeout=0.3)

    stop_s: float | None = None
    reasons: set[str] = set()
    try:
        if not observer.wait(lambda o: set(MOTORS) <= o.online(), 30.0):
            raise RuntimeError(f"the motor service did not come online: {log.read_text()[-2000:]}")
        with BusClient(BrokerSettings.from_url(broker.url), ROBOT, role="chaos-keeper") as bus:
            for name in MOTORS:
                bus.call(name, "dutycycle", 60, timeout=5.0)
                bus.call(name, "enabled", True, timeout=5.0)
            thread = threading.Thread(target=keeper, args=(bus,), daemon=True)
            thread.start()
            time.sleep(1.0)
            os.kill(service.pid, signum)
            sent = world.time_s()  # from now on it renews nothing (a renewal it sent before may land)
            wait_until(lambda: not running(), FREEZE_S)
            if not running():
                stop_s = max(t for t, _ in world.deadman_stops) - sent
            if signum == signal.SIGSTOP:
                os.kill(service.pid, signal.SIGCONT)
                observer.wait(lambda o: all(o.state.get(m, {}).get("running") is False for m in MOTORS), 5.0)
                with observer.lock:
                    reasons = {str(observer.state.get(m, {}).get("stop_reason")) for m in MOTORS}
            keep.set()
            thread.join(5)
    finally:
        keep.set()
        if service.poll() is None:
            os.kill(service.pid, signal.SIGCONT)
            service.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            service.wait(15)
        if service.poll() is None:
            service.kill()
            service.wait(5)
        loop.stop()
        server.stop()
        observer.wait(lambda o: not set(MOTORS) & o.online(), 10.0)
    return stop_s, reasons


# --- main ---------------------------------------------------------------------------------------


@contextlib.contextmanager
def robot(kind: str, workdir: Path, compiled: Path, call_timeout_s: float | None = None,
          query: str = "", log_level: str = "INFO") -> Iterator[tuple[Broker, Fleet, Observer]]:
    broker = Broker(kind, workdir)
    broker.start()
    fleet = Fleet(broker, workdir, compiled, call_timeout_s, query, log_level)
    observer = Observer(broker.port)
    try:
        yield broker, fleet, observer
    finally:
        fleet.stop()
        observer.close()
        broker.stop()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Chaos runs against the robot car's real processes.")
    parser.add_argument("--trials", type=int, default=10, help="trials per broker restart and per kill/stop")
    parser.add_argument("--fuzz", type=int, default=10_000, help="malformed payloads per fuzz run")
    parser.add_argument("--brokers", default="mosquitto,amqtt", help="brokers, e.g. mosquitto,amqtt")
    parser.add_argument("--kinds", default=",".join(KINDS), help="service kinds to SIGKILL and SIGSTOP")
    parser.add_argument("--scenarios", default="restart,kill,keepalive,takeover,fuzz,frozen-motor",
                        help="which of restart, kill, keepalive, takeover, fuzz, frozen-motor, soak (soak is "
                             "not in the default: 10 min a broker)")
    parser.add_argument("--listen", type=float, default=5.0, help="seconds the takeover spy listens")
    parser.add_argument("--outage", type=float, default=1.0, help="seconds the broker stays down")
    parser.add_argument("--seed", type=int, default=1, help="seed of the fuzzed payloads")
    parser.add_argument("--soak-s", type=float, default=600.0, help="seconds the soak runs (per broker)")
    parser.add_argument("--soak-warmup-s", type=float, default=300.0,
                        help="seconds of the soak before its memory must stay flat (the bounded "
                             "records fill: the studio's 100 000 trace events, ...)")
    parser.add_argument("--soak-sample-s", type=float, default=5.0, help="seconds between two RSS samples")
    parser.add_argument("--soak-max-growth-mb", type=float, default=3.0,
                        help="RSS growth after the warm-up that fails the soak (any process)")
    args = parser.parse_args(argv)
    brokers = [b for b in args.brokers.split(",") if b]
    kinds = [k for k in args.kinds.split(",") if k]
    scenarios = {s for s in args.scenarios.split(",") if s}
    if set(brokers) - {"mosquitto", "amqtt"} or set(kinds) - set(KINDS) or \
            scenarios - {"restart", "kill", "keepalive", "takeover", "fuzz", "frozen-motor", "soak"}:
        parser.error("unknown broker, kind or scenario")

    from umlbot.base.logs import configure_logging

    configure_logging("WARNING")
    out: dict[str, Any] = {"restart": [], "kill": [], "keepalive": [], "takeover": [], "fuzz": [],
                           "frozen_motor": [], "soak": []}
    with tempfile.TemporaryDirectory(prefix="umlbot-chaos-") as tmp:
        workdir = Path(tmp)
        compiled = compile_car(workdir)
        for index, kind in enumerate(brokers):
            if "restart" in scenarios:
                with robot(kind, workdir, compiled) as (broker, fleet, observer):
                    out["restart"].append(broker_restart(broker, fleet, observer, args.trials, args.outage))
            if "kill" in scenarios and index == 0:
                with robot(kind, workdir, compiled) as (broker, fleet, observer):
                    out["kill"] = kill_and_freeze(broker, fleet, observer, kinds, args.trials)
            if "keepalive" in scenarios:
                with robot(kind, workdir, compiled, query=f"keepalive={KEEPALIVE_S}") as \
                        (broker, fleet, observer):
                    out["keepalive"].append(keepalive(broker, fleet, observer, args.trials))
            if "takeover" in scenarios:
                with robot(kind, workdir, compiled, log_level="DEBUG") as (broker, fleet, observer):
                    out["takeover"].append(takeover(broker, fleet, observer, args.listen))
            if "frozen-motor" in scenarios and index == 0:
                with robot(kind, workdir, compiled) as (broker, _fleet, observer):
                    out["frozen_motor"] = frozen_motor(broker, observer, workdir, args.trials)
            if "fuzz" in scenarios and args.fuzz > 0:
                with robot(kind, workdir, compiled, call_timeout_s=10.0) as (broker, fleet, observer):
                    out["fuzz"].append(fuzz(broker, fleet, observer, args.fuzz, args.seed))
                    print(json.dumps(out["fuzz"][-1]), file=sys.stderr, flush=True)
            if "soak" in scenarios:
                model_dir, soak_compiled = soak_model(workdir)
                with robot(kind, workdir, soak_compiled) as (broker, fleet, observer):
                    out["soak"].append(soak(broker, fleet, observer, model_dir, args.soak_s,
                                            args.soak_warmup_s, args.soak_sample_s, args.soak_max_growth_mb))
                    print(json.dumps(out["soak"][-1]), file=sys.stderr, flush=True)
    print(json.dumps(out))
    # the soak fails the run: a process whose memory grows, or that died
    return 1 if any(not row["flat"] or row["process_exits"] for row in out["soak"]) else 0


if __name__ == "__main__":
    sys.exit(main())
