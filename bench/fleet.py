"""Fleet benchmark: N robots, each on its own leaf Mosquitto bridged to one hub Mosquitto.

- **latency**: for N = 1, 10, 50 (and 100 with `--sizes 1,10,50,100`) robots, every robot is a
  `ComponentServer` (a motor's `dutycycle`) and a `BusClient` calling it `--rate` times a second
  on its own leaf broker (the traffic of a car model at real time); every call and reply crosses
  that leaf's bridge to the hub. The robots other than the first run in `--workers` child
  processes; the first (the probe) runs here and its round trips are measured for `--seconds`.
  Per N: the probe's p50/p99 in ms and as a ratio to N = 1 (the baseline, measured in the same
  run), the hub's CPU (% of one core, from /proc) and the messages it received per second
  (`$SYS/broker/messages/received`). One leaf per robot at every N (no sharing).
  Target: p50 ratio <= 1.25 at N = 50.
- **studio**: a hub with `--studio-robots` robots (retained orchestrator and component statuses,
  each robot sending `--trace-rate` trace events a second: a publisher stands in for the cars),
  a real `umlbot studio models/robot_car --broker HUB --fleet` and Debian's Chromium showing the
  fleet view: every frame's duration (requestAnimationFrame to requestAnimationFrame) for
  `--seconds`, the page's long tasks, and the fleet table's own drawing time. Target: no frame
  over 100 ms.

The last output line is one JSON object {"latency": [...], "studio": {...}, "load_avg": [...]}.
Exit 1 when a target is missed. Loopback only.

    python bench/fleet.py [--sizes 1,10,50] [--rate 10] [--seconds 10] [--workers 2]
                          [--studio-robots 100] [--trace-rate 5] [--parts latency,studio]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion

from umlbot.base.catalog import implementations
from umlbot.base.logs import configure_logging
from umlbot.fleet import LocalFleet, Mosquitto, free_port
from umlbot.services.bus import BrokerSettings, BusClient, ComponentServer, Feature

REPO = Path(__file__).resolve().parent.parent
TIMEOUT_S = 5.0
WARMUP_S = 2.0
TARGETS = {"p50_ratio_at_50": 1.25, "max_frame_ms": 100.0}
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
COMPONENTS = ("DistanceRead", "LeftActuator", "RaspberryPI", "RightActuator", "Sensor")


def robot_ids(n: int) -> list[str]:
    return [f"r{i}" for i in range(1, n + 1)]


class Robot:
    """One robot's request/reply path: a motor's server and a caller, on the robot's leaf."""

    def __init__(self, robot: str, url: str) -> None:
        settings = BrokerSettings.from_url(url)
        spec = implementations()["l298n"].features["dutycycle"]
        self.server = ComponentServer(
            settings, robot, "Motor", "l298n", [Feature(spec, lambda percent: None)]
        )
        self.server.start(TIMEOUT_S)
        self.client = BusClient(settings, robot, role="bench")
        self.client.start(TIMEOUT_S)
        self.counter = 0

    def round_trip(self) -> float:
        self.counter += 1
        started = time.perf_counter()
        self.client.call("Motor", "dutycycle", self.counter % 100, timeout=TIMEOUT_S)
        return time.perf_counter() - started

    def close(self) -> None:
        self.client.close()
        self.server.stop()


def paced(robot: Robot, rate: float, stop: threading.Event, samples: list[float] | None) -> None:
    """Round trips at `rate` a second (a fixed schedule: a slow call does not shift the next)."""
    period = 1.0 / rate
    next_at = time.monotonic()
    while not stop.is_set():
        try:
            took = robot.round_trip()
            if samples is not None:
                samples.append(took)
        except Exception as exc:  # a lost reply is a figure too: counted as the time-out
            print(f"bench: call failed: {exc}", file=sys.stderr)
            if samples is not None:
                samples.append(TIMEOUT_S)
        next_at += period
        delay = next_at - time.monotonic()
        if delay > 0:
            stop.wait(delay)
        else:
            next_at = time.monotonic()


def worker(spec: str, rate: float) -> None:
    """`--worker id=url,...`: run those robots until stdin closes."""
    robots = [Robot(*item.split("=", 1)) for item in spec.split(",")]
    stop = threading.Event()
    threads = [threading.Thread(target=paced, args=(r, rate, stop, None), daemon=True) for r in robots]
    for thread in threads:
        thread.start()
    print("ready", flush=True)
    sys.stdin.read()  # until the bench closes our stdin
    stop.set()
    for thread in threads:
        thread.join(TIMEOUT_S)
    for robot in robots:
        robot.close()


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


class SysCounter:
    """The hub's `$SYS/broker/messages/received` (published every second: `sys_interval 1`)."""

    def __init__(self, port: int) -> None:
        self.values: list[tuple[float, int]] = []
        self.client = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=MQTTProtocolVersion.MQTTv311)
        self.client.on_message = lambda c, u, m: self.values.append((time.monotonic(), int(m.payload)))
        self.client.on_connect = lambda c, u, f, rc, p=None: c.subscribe("$SYS/broker/messages/received")
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def rate(self, since: float) -> float | None:
        seen = [(t, v) for t, v in self.values if t >= since]
        if len(seen) < 2 or seen[-1][0] <= seen[0][0]:
            return None
        return (seen[-1][1] - seen[0][1]) / (seen[-1][0] - seen[0][0])

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def measure_latency(n: int, rate: float, probe_rate: float, seconds: float, workers: int) -> dict[str, Any]:
    ids = robot_ids(n)
    fleet = LocalFleet(ids, hub_extra="sys_interval 1\n")
    fleet.start()
    children: list[subprocess.Popen[str]] = []
    probe: Robot | None = None
    counter: SysCounter | None = None
    try:
        others = ids[1:]
        chunks = [others[i::workers] for i in range(workers)] if others else []
        for chunk in (c for c in chunks if c):
            spec = ",".join(f"{r}={fleet.leaf_url(r)}" for r in chunk)
            children.append(
                subprocess.Popen(
                    [sys.executable, __file__, "--worker", spec, "--rate", str(rate)],
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    text=True,
                )
            )
        for child in children:
            assert child.stdout is not None
            if child.stdout.readline().strip() != "ready":
                raise RuntimeError("a bench worker did not start")
        probe = Robot(ids[0], fleet.leaf_url(ids[0]))
        counter = SysCounter(fleet.hub.port)
        stop = threading.Event()
        samples: list[float] = []
        warm = threading.Thread(target=paced, args=(probe, probe_rate, stop, None))
        warm.start()
        time.sleep(WARMUP_S)  # everybody at their pace before the measurement
        stop.set()
        warm.join()
        assert fleet.hub.proc is not None
        cpu0, t0 = cpu_seconds(fleet.hub.proc.pid), time.monotonic()
        stop = threading.Event()
        timer = threading.Timer(seconds, stop.set)
        timer.start()
        paced(probe, probe_rate, stop, samples)
        cpu1, t1 = cpu_seconds(fleet.hub.proc.pid), time.monotonic()
        msgs = counter.rate(t0)
        ordered = sorted(samples)
        return {
            "robots": n,
            "leaves": n,
            "robots_per_leaf": 1,
            "rate_per_robot": rate,
            "probe_rate": probe_rate,
            "calls": len(samples),
            "p50_ms": round(statistics.median(samples) * 1000, 3),
            "p99_ms": round(ordered[min(len(ordered) - 1, round(0.99 * (len(ordered) - 1)))] * 1000, 3),
            "hub_cpu_pct": round(100 * (cpu1 - cpu0) / (t1 - t0), 1),
            "hub_msgs_received_per_s": None if msgs is None else round(msgs, 1),
        }
    finally:
        if counter is not None:
            counter.close()
        if probe is not None:
            probe.close()
        for child in children:
            if child.stdin is not None:
                child.stdin.close()
        for child in children:
            try:
                child.wait(20)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait(5)
        fleet.stop()


FRAMES = """
window.__frames = []; window.__longTasks = [];
(() => { let last = 0; const tick = (t) => { if (last) window.__frames.push(t - last); last = t;
  requestAnimationFrame(tick); }; requestAnimationFrame(tick); })();
new PerformanceObserver((list) => {
  for (const entry of list.getEntries()) window.__longTasks.push(entry.duration);
}).observe({type: "longtask", buffered: true});
"""


def fake_fleet(port: int, robots: int, trace_rate: float, stop: threading.Event) -> None:
    """Publish what `robots` cars would show on a hub: statuses (retained), then trace events."""
    client = mqtt.Client(CallbackAPIVersion.VERSION2, protocol=MQTTProtocolVersion.MQTTv311)
    client.connect("127.0.0.1", port)
    client.loop_start()
    ids = robot_ids(robots)
    for robot in ids:
        client.publish(
            f"umlbot/{robot}/orchestrator/status",
            json.dumps({"state": "running", "model": "car", "robot": robot}),
            qos=1,
            retain=True,
        )
        for component in COMPONENTS:
            client.publish(
                f"umlbot/{robot}/{component}/status",
                json.dumps({"state": "online", "impl": "mock", "features": []}),
                qos=1,
                retain=True,
            )
    lanes = ("Glance", "MoveForward", "RaspberryPI", "Stop")
    period = 1.0 / (trace_rate * robots)
    seq = 0
    next_at = time.monotonic()
    while not stop.is_set():
        seq += 1
        robot = ids[seq % robots]
        now = time.time()
        event = {
            "lane": lanes[seq % len(lanes)],
            "node": f"n{seq % 7}",
            "kind": "action",
            "start": now - 0.001,
            "end": now,
            "duration_ms": 1.0,
            "seq": seq,
        }
        client.publish(f"umlbot/{robot}/orchestrator/trace", json.dumps(event), qos=0)
        next_at += period
        delay = next_at - time.monotonic()
        if delay > 0:
            stop.wait(delay)
    client.disconnect()
    client.loop_stop()


def measure_studio(
    robots: int, trace_rate: float, seconds: float, workdir: Path, fleet: bool
) -> dict[str, Any]:
    """The page's frames for `seconds` under the hub's traffic; `fleet=False` is the baseline: the
    same page and traffic without the fleet view."""
    from playwright.sync_api import sync_playwright

    hub = Mosquitto(
        "hub", free_port(), "allow_anonymous true\npersistence false\nset_tcp_nodelay true\n", workdir
    )
    hub.start()
    stop = threading.Event()
    publisher = threading.Thread(target=fake_fleet, args=(hub.port, robots, trace_rate, stop), daemon=True)
    publisher.start()
    env = {k: v for k, v in os.environ.items() if k not in ("UMLBOT_BROKER", "UMLBOT_ROBOT")}
    studio = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from umlbot.cli import main; main()",
            "studio",
            str(REPO / "models" / "robot_car"),
            "--broker",
            hub.url,
            *(["--fleet"] if fleet else []),
            "--port",
            "0",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=env,
    )
    try:
        assert studio.stdout is not None
        url = None
        while url is None:
            line = studio.stdout.readline()
            if not line:
                raise RuntimeError("umlbot studio did not print its URL")
            match = re.search(r"umlbot studio: (http://\S+)", line)
            url = match.group(1) if match else None
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1600, "height": 1000})
                page.add_init_script(FRAMES)
                page.goto(url)
                page.wait_for_function("window.__studio && window.__studio.ready === true", timeout=60_000)
                if fleet:
                    page.wait_for_function(
                        f"document.querySelectorAll('#fleet-robots tbody tr').length === {robots}",
                        timeout=60_000,
                    )
                time.sleep(2.0)  # the diagram's first layout is done
                page.evaluate("window.__frames = []; window.__longTasks = []")
                draws: list[float] = []
                end = time.monotonic() + seconds
                while time.monotonic() < end:
                    value = page.evaluate("document.querySelector('#fleet')?.dataset.drawMs")
                    if value is not None:
                        draws.append(float(value))
                    time.sleep(0.5)
                frames: list[float] = page.evaluate("window.__frames")
                long_tasks: list[float] = page.evaluate("window.__longTasks")
                rows = page.evaluate("document.querySelectorAll('#fleet-robots tbody tr').length")
                (REPO / "out").mkdir(exist_ok=True)
                if fleet:
                    page.screenshot(path=str(REPO / "out" / "bench-fleet-view.png"))
            finally:
                browser.close()
        ordered = sorted(frames)
        return {
            "robots": robots,
            "rows_shown": rows,
            "trace_events_per_s": robots * trace_rate,
            "frames": len(frames),
            "max_frame_ms": round(ordered[-1], 1) if ordered else None,
            "p99_frame_ms": round(ordered[min(len(ordered) - 1, round(0.99 * (len(ordered) - 1)))], 1)
            if ordered
            else None,
            "long_tasks": len(long_tasks),
            "max_long_task_ms": round(max(long_tasks), 1) if long_tasks else None,
            "table_draw_max_ms": round(max(draws), 2) if draws else None,
        }
    finally:
        stop.set()
        studio.terminate()
        try:
            studio.wait(15)
        except subprocess.TimeoutExpired:
            studio.kill()
        hub.stop()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--sizes", default="1,10,50", help="numbers of robots (the first is the baseline)")
    parser.add_argument("--rate", type=float, default=10.0, help="calls a second each robot makes")
    parser.add_argument(
        "--probe-rate",
        type=float,
        default=50.0,
        help="calls a second of the measured robot (more samples; the same at every N)",
    )
    parser.add_argument("--seconds", type=float, default=10.0, help="measured seconds per size")
    parser.add_argument("--workers", type=int, default=2, help="processes running the other robots")
    parser.add_argument("--studio-robots", type=int, default=100)
    parser.add_argument(
        "--trace-rate", type=float, default=5.0, help="trace events a second per robot (studio)"
    )
    parser.add_argument("--parts", default="latency,studio")
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    args = parser.parse_args()
    configure_logging("ERROR")
    if args.worker:
        worker(args.worker, args.rate)
        return 0
    parts = {p.strip() for p in args.parts.split(",") if p.strip()}
    result: dict[str, Any] = {"targets": TARGETS}
    ok = True
    if "latency" in parts:
        sizes = [int(s) for s in args.sizes.split(",")]
        rows = []
        for n in sizes:
            row = measure_latency(n, args.rate, args.probe_rate, args.seconds, args.workers)
            rows.append(row)
            print(json.dumps(row), file=sys.stderr, flush=True)
        base = rows[0]
        for row in rows:
            row["p50_ratio"] = round(row["p50_ms"] / base["p50_ms"], 2)
            row["p99_ratio"] = round(row["p99_ms"] / base["p99_ms"], 2)
        result["latency"] = rows
        at50 = next((r for r in rows if r["robots"] == 50), None)
        if at50 is not None:
            ok = ok and at50["p50_ratio"] <= TARGETS["p50_ratio_at_50"]
    if "studio" in parts:
        with tempfile.TemporaryDirectory() as tmp:
            result["studio_baseline"] = measure_studio(
                args.studio_robots, args.trace_rate, args.seconds, Path(tmp), fleet=False
            )
            studio = result["studio"] = measure_studio(
                args.studio_robots, args.trace_rate, args.seconds, Path(tmp), fleet=True
            )
        ok = ok and studio["max_frame_ms"] is not None and studio["max_frame_ms"] <= TARGETS["max_frame_ms"]
    result["load_avg"] = [round(x, 2) for x in os.getloadavg()]
    result["cores"] = os.cpu_count()
    result["ok"] = ok
    print(json.dumps(result))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
