"""Resident memory of the hardware service processes, read from /proc of the real processes.

Starts a broker (Mosquitto when installed, else the embedded one) on a free port, then, one after
the other, `umlbot service KIND --deploy <car> --driver mock` for every kind and `umlbot service
all`, with the environment the systemd unit sets (its `Environment=` lines, e.g. glibc's
`MALLOC_MMAP_THRESHOLD_`, and the log level of deploy/umlbot.env.example). Each process is
measured once all its components are online and it has settled: Rss (resident set, what the
issue's target is about, counted exactly: see `proc_memory`), VmHWM (its peak) and Pss (shared
library pages split between the processes that map them) from /proc/PID. Then the process is
put to work — `--calls` rounds of every feature of each of its components, with an argument out
of range every tenth round (an error reply) — and measured again: `used_rss_mb` is what a
service that has served a run holds, and the target applies to it as to the idle figure. The raw
baselines of the same run are a bare Python interpreter and a plain paho client connected to the
broker.

The services are measured as installed: with their bytecode cached. `pip install`
(deploy/install.sh) compiles every module of umlbot and its plugins; a checkout run with
PYTHONDONTWRITEBYTECODE=1 (or a fresh one) compiles them from source at every start instead, and
the compiler's scratch memory stays resident (docs/performance.md, "Memory"). So the measured
processes run without that variable, and one unmeasured `umlbot service all` start first writes
the caches of everything a service imports (`"bytecode": "cached"` in the output).

The last output line is one JSON object: {"broker", "environment", "bytecode", "results":
[{"process", "components", "rss_mb", "used_rss_mb", "hwm_mb", "pss_mb"}, ...], "kinds", "kinds_rss_mb",
"all_rss_mb", "all_used_rss_mb", "max_service_rss_mb", "target_rss_mb"}.

    python bench/memory.py [--kinds motor,sonar,servo,gpio] [--settle 2] [--repeat 1] [--calls 100]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
from rpc import free_port, wait_port

from umlbot.base.errors import RemoteError
from umlbot.services.bus import BrokerSettings, BusClient

REPO = Path(__file__).resolve().parent.parent
DEPLOYMENT = REPO / "models" / "robot_car" / "deployment.yaml"
UNIT = REPO / "deploy" / "systemd" / "umlbot-service@.service"
ENV_EXAMPLE = REPO / "deploy" / "umlbot.env.example"
ROBOT = "membench"
KINDS = ("motor", "sonar", "servo", "gpio")
#: components of the reference car by service kind
COMPONENTS = {"motor": {"LeftActuator", "RightActuator"}, "sonar": {"DistanceRead"},
              "servo": {"Sensor"}, "gpio": {"RaspberryPI"}}
TARGET_RSS_MB = 28.0  # issue 25; 32.5 before the serving process left the CLI behind
#: one round of calls per component: (feature, good arguments, out-of-range arguments); the car's
#: RaspberryPI has no pins in its deployment, so every call to it is refused
WORKLOAD: dict[str, list[tuple[str, tuple[Any, ...] | None, tuple[Any, ...]]]] = {
    "LeftActuator": [("enabled", (True,), ("yes",)), ("direction", (True,), (2,)),
                     ("dutycycle", (40,), (400,))],
    "RightActuator": [("enabled", (True,), ("yes",)), ("direction", (False,), (2,)),
                      ("dutycycle", (60,), (-1,))],
    "DistanceRead": [("value", (), (1,))],
    "Sensor": [("angle", (90,), (999,))],
    "RaspberryPI": [("readPin", None, (4,)), ("writePin", None, (17, 1))],
}

#: a minimal hand-written MQTT component: what any Python service on paho costs at least
RAW_PAHO = """
import sys, threading
import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id="membench-raw")
client.on_connect = lambda c, u, f, rc, p=None: c.subscribe("membench/raw/#", 1)
client.connect("127.0.0.1", int(sys.argv[1]))
client.loop_start()
print("ready", flush=True)
threading.Event().wait()
"""


def unit_environment() -> dict[str, str]:
    """What the service unit puts in the environment: its `Environment=` lines and the log level
    of the installed umlbot.env (a quieter or differently tuned service would measure otherwise)."""
    env: dict[str, str] = {}
    for line in UNIT.read_text().splitlines():
        if line.startswith("Environment="):
            key, _, value = line.removeprefix("Environment=").partition("=")
            env[key] = value
    for line in ENV_EXAMPLE.read_text().splitlines():
        if line.startswith("UMLBOT_LOG_LEVEL="):
            env["UMLBOT_LOG_LEVEL"] = line.partition("=")[2]
    return env


@contextlib.contextmanager
def run_broker() -> Iterator[tuple[str, int]]:
    """Mosquitto when installed (it costs the services nothing), else the embedded broker."""
    port = free_port()
    mosquitto = shutil.which("mosquitto") or ("/usr/sbin/mosquitto" if os.path.exists("/usr/sbin/mosquitto")
                                              else None)
    if mosquitto:
        kind, argv = "mosquitto", [mosquitto, "-p", str(port)]
    else:
        kind, argv = "amqtt", [*umlbot(), "broker", "--port", str(port)]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_port(port)
        yield kind, port
    finally:
        proc.terminate()
        proc.wait(10)


def umlbot() -> list[str]:
    """The real `umlbot` entry point of this environment (a console script: its PID is Python's)."""
    script = Path(sys.executable).parent / "umlbot"
    return [str(script)] if script.exists() else [sys.executable, "-c", "from umlbot.cli import main; main()"]


def proc_memory(pid: int) -> dict[str, float]:
    """Rss and Pss (from smaps_rollup), VmRSS and VmHWM (from /proc/PID/status) in MB.

    Rss is what the target is about. smaps_rollup counts it exactly, page table by page table;
    VmRSS, since Linux 6.2, is read from per-CPU counters without folding them in: off by up to
    32 pages per CPU for each of its three parts (0.75 MB on a 2-CPU machine, 1.5 MB on a
    Raspberry Pi's four cores). One serving `service motor` here: VmRSS 31.8 MB, Rss 31.07 MB."""
    values: dict[str, float] = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, rest = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            values[key] = int(rest.split()[0]) / 1024
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            key, _, rest = line.partition(":")
            if key in ("Rss", "Pss"):
                values[key] = int(rest.split()[0]) / 1024
    values.setdefault("Rss", values["VmRSS"])  # no smaps_rollup (Linux < 4.14): the counters' figure
    values["VmHWM"] = max(values["VmHWM"], values["Rss"])  # a peak is at least the exact figure
    return values


class OnlineWatch:
    """Which components of the bench robot say `online` (retained status), from a paho client."""

    def __init__(self, port: int) -> None:
        self.online: set[str] = set()
        self.changed = threading.Condition()
        self.client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"membench-watch-{os.getpid()}")
        self.client.on_connect = lambda c, u, f, rc, p=None: c.subscribe(f"umlbot/{ROBOT}/+/status", 1)
        self.client.on_message = self._on_message
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def _on_message(self, client: mqtt.Client, userdata: Any, message: mqtt.MQTTMessage) -> None:
        component = message.topic.split("/")[2]
        try:
            state = json.loads(message.payload).get("state") if message.payload else "offline"
        except ValueError:
            state = None
        with self.changed:
            if state == "online":
                self.online.add(component)
            else:
                self.online.discard(component)
            self.changed.notify_all()

    def wait(self, predicate: Callable[[set[str]], bool], timeout: float) -> bool:
        with self.changed:
            return self.changed.wait_for(lambda: predicate(self.online), timeout)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def put_to_work(client: BusClient, components: set[str], rounds: int) -> None:
    """`rounds` rounds of every feature of `components`; every tenth round out of range (refused)."""
    for round_ in range(rounds):
        for component in sorted(components):
            for feature, good, bad in WORKLOAD[component]:
                if good is None or round_ % 10 == 9:
                    with contextlib.suppress(RemoteError):
                        client.call(component, feature, *bad)
                        raise RuntimeError(f"{component}.{feature}{bad} was not refused")
                else:
                    client.call(component, feature, *good)


def process_environment(env: dict[str, str]) -> dict[str, str]:
    """The measured processes' environment: this one with the unit's on top, without
    PYTHONDONTWRITEBYTECODE: the services are measured with their bytecode cached, as installed."""
    inherited = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
    return {**inherited, **env}


def measure_service(kind: str, port: int, watch: OnlineWatch, settle_s: float,
                    env: dict[str, str], client: BusClient, rounds: int) -> dict[str, Any]:
    components = set().union(*COMPONENTS.values()) if kind == "all" else COMPONENTS[kind]
    argv = [*umlbot(), "service", kind, "--deploy", str(DEPLOYMENT), "--driver", "mock",
            "--robot", ROBOT, "--broker", f"mqtt://127.0.0.1:{port}"]
    with tempfile.TemporaryFile() as log:
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=log, env=env)
        try:
            if not watch.wait(lambda online: components <= online, 30.0):
                log.seek(0)
                raise RuntimeError(f"service {kind} did not come online: {log.read()[-2000:]!r}")
            time.sleep(settle_s)
            memory = proc_memory(proc.pid)
            put_to_work(client, components, rounds)
            time.sleep(settle_s)
            used = proc_memory(proc.pid)
        finally:
            proc.terminate()
            proc.wait(15)
        if not watch.wait(lambda online: not components & online, 15.0):
            raise RuntimeError(f"service {kind} did not go offline")
    return {"process": f"umlbot service {kind}", "components": len(components), **_mb(memory),
            "used_rss_mb": round(used["Rss"], 1), "hwm_mb": round(used["VmHWM"], 1)}


def measure_script(name: str, argv: list[str], settle_s: float, env: dict[str, str]) -> dict[str, Any]:
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)
    try:
        assert proc.stdout is not None
        if argv[-1] != "bare":
            proc.stdout.readline()  # "ready"
        time.sleep(settle_s)
        memory = proc_memory(proc.pid)
    finally:
        proc.terminate()
        proc.wait(10)
    return {"process": name, "components": 0, **_mb(memory)}


def _mb(memory: dict[str, float]) -> dict[str, float]:
    return {"rss_mb": round(memory["Rss"], 1), "hwm_mb": round(memory["VmHWM"], 1),
            "pss_mb": round(memory.get("Pss", float("nan")), 1)}


def median_of(runs: list[dict[str, Any]]) -> dict[str, Any]:
    first = dict(runs[0])
    for key in ("rss_mb", "used_rss_mb", "hwm_mb", "pss_mb"):
        if key in first:
            first[key] = round(statistics.median(run[key] for run in runs), 1)
    return first


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Resident memory of the umlbot service processes.")
    parser.add_argument("--kinds", default=",".join(KINDS), help="service kinds to measure one by one")
    parser.add_argument("--settle", type=float, default=2.0, help="seconds online before measuring")
    parser.add_argument("--repeat", type=int, default=1, help="measure each process this often (median)")
    parser.add_argument("--calls", type=int, default=100,
                        help="rounds of calls to every feature before the second measurement")
    args = parser.parse_args(argv)
    kinds = [k for k in args.kinds.split(",") if k]
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        parser.error(f"unknown kinds {unknown}; known: {', '.join(KINDS)}")

    env = unit_environment()  # the baselines too, so that they compare like with like
    run_env = process_environment(env)
    results: list[dict[str, Any]] = []
    with run_broker() as (broker, port):
        bare = [sys.executable, "-c", "import time; time.sleep(60)", "bare"]
        results.append(median_of([measure_script("python (bare interpreter)", bare, args.settle, run_env)
                                  for _ in range(args.repeat)]))
        raw = [sys.executable, "-c", RAW_PAHO, str(port)]
        results.append(median_of([measure_script("python + paho client (raw baseline)", raw, args.settle,
                                                 run_env) for _ in range(args.repeat)]))
        watch = OnlineWatch(port)
        client = BusClient(BrokerSettings.from_url(f"mqtt://127.0.0.1:{port}"), ROBOT)
        client.start(10.0)
        try:
            # writes the bytecode caches of everything a service imports (as installed); not measured
            measure_service("all", port, watch, 0.0, run_env, client, 1)
            for kind in [*kinds, "all"]:
                runs = [measure_service(kind, port, watch, args.settle, run_env, client, args.calls)
                        for _ in range(args.repeat)]
                results.append(median_of(runs))
                print(json.dumps(results[-1]), file=sys.stderr, flush=True)
        finally:
            client.close()
            watch.close()
    services = [r for r in results if r["process"] in {f"umlbot service {kind}" for kind in kinds}]
    summary = {
        "broker": broker,
        "environment": env,
        "bytecode": "cached",
        "results": results,
        "kinds_rss_mb": round(sum(r["rss_mb"] for r in services), 1),
        "kinds": kinds,
        "all_rss_mb": next(r["rss_mb"] for r in results if r["process"] == "umlbot service all"),
        "all_used_rss_mb": next(r["used_rss_mb"] for r in results if r["process"] == "umlbot service all"),
        "target_rss_mb": TARGET_RSS_MB,
        "max_service_rss_mb": max((max(r["rss_mb"], r["used_rss_mb"]) for r in services), default=None),
    }
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
