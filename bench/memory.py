"""Resident memory of the hardware service processes, read from /proc of the real processes.

Starts a broker (Mosquitto when installed, else the embedded one) on a free port, then, one after
the other, `umlbot service KIND --deploy <car> --driver mock` for every kind and `umlbot service
all`, with the environment the systemd unit sets (its `Environment=` lines, e.g. glibc's
`MALLOC_MMAP_THRESHOLD_`, and the log level of deploy/umlbot.env.example). Each process is
measured once all its components are online and it has settled: VmRSS (resident set, what the
issue's target is about), VmHWM (its peak) and Pss (shared library pages split between the
processes that map them) from /proc/PID. The raw baselines of the same run are
a bare Python interpreter and a plain paho client connected to the broker.

The last output line is one JSON object: {"broker", "environment", "results": [{"process",
"components", "rss_mb", "hwm_mb", "pss_mb"}, ...], "kinds", "kinds_rss_mb", "all_rss_mb",
"max_service_rss_mb", "target_rss_mb"}.

    python bench/memory.py [--kinds motor,sonar,servo,gpio] [--settle 2] [--repeat 1]
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

REPO = Path(__file__).resolve().parent.parent
DEPLOYMENT = REPO / "models" / "robot_car" / "deployment.yaml"
UNIT = REPO / "deploy" / "systemd" / "umlbot-service@.service"
ENV_EXAMPLE = REPO / "deploy" / "umlbot.env.example"
ROBOT = "membench"
KINDS = ("motor", "sonar", "servo", "gpio")
#: components of the reference car by service kind
COMPONENTS = {"motor": {"LeftActuator", "RightActuator"}, "sonar": {"DistanceRead"},
              "servo": {"Sensor"}, "gpio": {"RaspberryPI"}}
TARGET_RSS_MB = 40.0

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
    """VmRSS, VmHWM (from /proc/PID/status) and Pss (from smaps_rollup) in MB."""
    values: dict[str, float] = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        key, _, rest = line.partition(":")
        if key in ("VmRSS", "VmHWM"):
            values[key] = int(rest.split()[0]) / 1024
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                values["Pss"] = int(line.split()[1]) / 1024
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


def measure_service(kind: str, port: int, watch: OnlineWatch, settle_s: float,
                    env: dict[str, str]) -> dict[str, Any]:
    components = set().union(*COMPONENTS.values()) if kind == "all" else COMPONENTS[kind]
    argv = [*umlbot(), "service", kind, "--deploy", str(DEPLOYMENT), "--driver", "mock",
            "--robot", ROBOT, "--broker", f"mqtt://127.0.0.1:{port}"]
    with tempfile.TemporaryFile() as log:
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=log, env={**os.environ, **env})
        try:
            if not watch.wait(lambda online: components <= online, 30.0):
                log.seek(0)
                raise RuntimeError(f"service {kind} did not come online: {log.read()[-2000:]!r}")
            time.sleep(settle_s)
            memory = proc_memory(proc.pid)
        finally:
            proc.terminate()
            proc.wait(15)
        if not watch.wait(lambda online: not components & online, 15.0):
            raise RuntimeError(f"service {kind} did not go offline")
    return {"process": f"umlbot service {kind}", "components": len(components), **_mb(memory)}


def measure_script(name: str, argv: list[str], settle_s: float, env: dict[str, str]) -> dict[str, Any]:
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                            env={**os.environ, **env})
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
    return {"rss_mb": round(memory["VmRSS"], 1), "hwm_mb": round(memory["VmHWM"], 1),
            "pss_mb": round(memory.get("Pss", float("nan")), 1)}


def median_of(runs: list[dict[str, Any]]) -> dict[str, Any]:
    first = dict(runs[0])
    for key in ("rss_mb", "hwm_mb", "pss_mb"):
        first[key] = round(statistics.median(run[key] for run in runs), 1)
    return first


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Resident memory of the umlbot service processes.")
    parser.add_argument("--kinds", default=",".join(KINDS), help="service kinds to measure one by one")
    parser.add_argument("--settle", type=float, default=2.0, help="seconds online before measuring")
    parser.add_argument("--repeat", type=int, default=1, help="measure each process this often (median)")
    args = parser.parse_args(argv)
    kinds = [k for k in args.kinds.split(",") if k]
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        parser.error(f"unknown kinds {unknown}; known: {', '.join(KINDS)}")

    env = unit_environment()  # the baselines too, so that they compare like with like
    results: list[dict[str, Any]] = []
    with run_broker() as (broker, port):
        bare = [sys.executable, "-c", "import time; time.sleep(60)", "bare"]
        results.append(median_of([measure_script("python (bare interpreter)", bare, args.settle, env)
                                  for _ in range(args.repeat)]))
        raw = [sys.executable, "-c", RAW_PAHO, str(port)]
        results.append(median_of([measure_script("python + paho client (raw baseline)", raw, args.settle, env)
                                  for _ in range(args.repeat)]))
        watch = OnlineWatch(port)
        try:
            for kind in [*kinds, "all"]:
                runs = [measure_service(kind, port, watch, args.settle, env) for _ in range(args.repeat)]
                results.append(median_of(runs))
                print(json.dumps(results[-1]), file=sys.stderr, flush=True)
        finally:
            watch.close()
    services = [r for r in results if r["process"] in {f"umlbot service {kind}" for kind in kinds}]
    summary = {
        "broker": broker,
        "environment": env,
        "results": results,
        "kinds_rss_mb": round(sum(r["rss_mb"] for r in services), 1),
        "kinds": kinds,
        "all_rss_mb": next(r["rss_mb"] for r in results if r["process"] == "umlbot service all"),
        "target_rss_mb": TARGET_RSS_MB,
        "max_service_rss_mb": max((r["rss_mb"] for r in services), default=None),
    }
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
