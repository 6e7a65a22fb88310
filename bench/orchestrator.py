"""Orchestrator overhead: model actions against raw paho request/reply, on amqtt and on Mosquitto.

For each broker (started by this script, in its own process on a free port) one mock motor
service runs as its own process (`umlbot service motor --driver mock`, as on the robot), and:

(a) latency: a model whose lane is a loop of `LeftActuator.dutycycle(50)` actions, run by the
    orchestrator, against a raw paho requester sending the same envelope to the same service
    (speaking the MQTT version the orchestrator's connections speak: `protocol`), in
    rotating blocks so that machine load hits every variant alike: `raw_p50_ms`/`raw_p99_ms`,
    `action_p50_ms`/`action_p99_ms` (`--no-trace`: the same MQTT traffic as the raw requester)
    and their ratios; `action_traced_…` and `ratio_traced_…` with the trace published (three
    events per loop iteration, batched into one JSON-array message per 20 ms window:
    `trace_events_per_message`);
(b) throughput: a loop over a fork of `--window` actions (half on each motor) then a join, untraced
    (`fork_actions_per_s`, completed actions per second) against the raw requester keeping the
    same number of requests in flight (`raw_publish_per_s`, completed request/replies per second);
(c) `node_steps_per_s`: datastore + decision nodes in a loop, no I/O, tracing off (the engine
    alone); `node_steps_traced_per_s` is the same with the trace recorder publishing every event
    on the broker (events beyond its queue are dropped and counted, never waited for).

The last output line is one JSON object: {"results": [{"broker", "protocol", "raw_p50_ms", "raw_p99_ms",
"action_p50_ms", "action_p99_ms", "ratio_p50", "ratio_p99", "action_traced_p50_ms",
"action_traced_p99_ms", "ratio_traced_p50", "ratio_traced_p99", "trace_events_per_message",
"fork_actions_per_s", "raw_publish_per_s", "node_steps_per_s", …}, …]}.

    python bench/orchestrator.py [--n 2000] [--blocks 12] [--window 8] [--brokers amqtt,mosquitto]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
from rpc import _nodelay, _raw_client, _subscribed, free_port, percentile, wait_port

from umlbot import UmlbotError
from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import CompiledModel
from umlbot.services.bus import BrokerSettings, BusClient, BusConnection
from umlbot.services.orchestrator import Engine, Orchestrator, TraceRecorder

ROBOT = "bench"
MOTORS = ("LeftActuator", "RightActuator")
TIMEOUT_S = 5.0

HEADER = """
name: bench
call_timeout_s: 5.0
components:
  RaspberryPI: {kind: system}
  LeftActuator: {kind: actuator}
  RightActuator: {kind: actuator}
deployment:
  driver: mock
  components:
    RaspberryPI: {impl: raspberrypi}
    LeftActuator: {impl: l298n, settings: {in1: 22, in2: 23, watchdog_s: 0}}
    RightActuator: {impl: l298n, settings: {in1: 24, in2: 25, watchdog_s: 0}}
"""

LOOP = """
lanes:
  - lane: RaspberryPI
    nodes:
      - {{id: start, kind: start}}
      - {{id: init, kind: datastore, name: n, value: 0}}
      - {{id: act, kind: action, call: LeftActuator.dutycycle(50)}}
      - {{id: count, kind: datastore, name: n, value: n + 1}}
      - {{id: again, kind: decision, branches: [{{if: n < {n}, then: act}}, {{else: end}}]}}
      - {{id: end, kind: end}}
"""

FORK = """
lanes:
  - lane: RaspberryPI
    nodes:
      - {{id: start, kind: start}}
      - {{id: init, kind: datastore, name: n, value: 0}}
      - {{id: fan, kind: fork, targets: [{targets}]}}
{actions}
      - {{id: joined, kind: join}}
      - {{id: count, kind: datastore, name: n, value: n + 1}}
      - {{id: again, kind: decision, branches: [{{if: n < {n}, then: fan}}, {{else: end}}]}}
      - {{id: end, kind: end}}
"""

STEPS = """
lanes:
  - lane: RaspberryPI
    nodes:
      - {{id: start, kind: start}}
      - {{id: init, kind: datastore, name: n, value: 0}}
      - {{id: count, kind: datastore, name: n, value: n + 1}}
      - {{id: again, kind: decision, branches: [{{if: n < {n}, then: count}}, {{else: end}}]}}
      - {{id: end, kind: end}}
"""


@contextlib.contextmanager
def run_broker(kind: str) -> Iterator[str]:
    """Start a broker process on a free port; yield its URL; stop it.

    Mosquitto gets `set_tcp_nodelay true`: without it, replies that follow each other closely
    wait for delayed ACKs (40 ms on Linux) and every p99 measures that instead of umlbot.
    """
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        if kind == "mosquitto":
            binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
            config = Path(tmp) / "mosquitto.conf"
            config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n"
                              "set_tcp_nodelay true\n")
            argv = [binary, "-c", str(config)]
        else:
            argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "WARNING",
                    "broker", "--port", str(port)]
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            wait_port(port)
            yield f"mqtt://127.0.0.1:{port}"
        finally:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)


def compile_text(text: str) -> CompiledModel:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.yaml"
        path.write_text(HEADER + text, encoding="utf-8")
        return compile_model(path)


def fork_model(window: int, iterations: int) -> CompiledModel:
    names = [f"a{i}" for i in range(window)]
    actions = "\n".join(
        f"      - {{id: {name}, kind: action, call: {MOTORS[i % 2]}.dutycycle(50), next: joined}}"
        for i, name in enumerate(names)
    )
    return compile_text(FORK.format(targets=", ".join(names), actions=actions, n=iterations))


@contextlib.contextmanager
def motor_service(url: str) -> Iterator[None]:
    """`umlbot service motor --driver mock` in its own process, online when this yields."""
    with tempfile.TemporaryDirectory() as tmp:
        deployment = Path(tmp) / "deployment.yaml"
        deployment.write_text(
            "driver: mock\ncomponents:\n"
            "  LeftActuator: {impl: l298n, settings: {in1: 22, in2: 23, watchdog_s: 0}}\n"
            "  RightActuator: {impl: l298n, settings: {in1: 24, in2: 25, watchdog_s: 0}}\n",
            encoding="utf-8",
        )
        proc = subprocess.Popen(
            [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "WARNING", "service",
             "motor", "--deploy", str(deployment), "--broker", url, "--robot", ROBOT],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
        try:
            client = BusClient(BrokerSettings.from_url(url), ROBOT, role="bench-probe")
            client.start(TIMEOUT_S)
            try:
                deadline = time.monotonic() + 15.0
                while True:
                    try:
                        client.call("RightActuator", "dutycycle", 0, timeout=0.5)
                        client.call("LeftActuator", "dutycycle", 0, timeout=0.5)
                        break
                    except UmlbotError:
                        if time.monotonic() > deadline or proc.poll() is not None:
                            raise RuntimeError("the mock motor service did not come up") from None
            finally:
                client.close()
            yield
        finally:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)


class RawRequester:
    """A paho client sending umlbot request envelopes to the mock service: the baseline."""

    def __init__(self, url: str, protocol: str = "3.1.1") -> None:
        port = int(url.rsplit(":", 1)[1])
        self.client = _raw_client(port, "requester", protocol)
        self.client.on_socket_open = _nodelay
        self.reply_topic = f"umlbot/{ROBOT}/_reply/raw-{os.getpid()}"
        self.topics = [f"umlbot/{ROBOT}/{c}/call/dutycycle" for c in ("LeftActuator", "RightActuator")]
        self.cond = threading.Condition()
        self.replies: set[str] = set()
        self.client.on_message = self._on_reply
        _subscribed(self.client, self.reply_topic)
        self.counter = 0
        self.protocol = protocol

    def _on_reply(self, client: mqtt.Client, userdata: Any, msg: mqtt.MQTTMessage) -> None:
        reply_id = json.loads(msg.payload)["id"]
        with self.cond:
            self.replies.add(reply_id)
            self.cond.notify_all()

    def _send(self, topic: str) -> str:
        self.counter += 1
        request_id = f"r{self.counter}"
        payload = json.dumps({"id": request_id, "reply_to": self.reply_topic, "args": [50]},
                             separators=(",", ":")).encode()
        self.client.publish(topic, payload, qos=0)
        return request_id

    def _wait(self, request_id: str) -> None:
        with self.cond:
            if not self.cond.wait_for(lambda: request_id in self.replies, TIMEOUT_S):
                raise RuntimeError("raw round trip timed out")
            self.replies.discard(request_id)

    def round_trip(self) -> float:
        started = time.perf_counter()
        self._wait(self._send(self.topics[0]))
        return time.perf_counter() - started

    def throughput(self, window: int, total: int) -> float:
        """Completed request/replies per second with `window` requests in flight at a time."""
        started = time.perf_counter()
        done = 0
        while done < total:
            ids = [self._send(self.topics[i % 2]) for i in range(window)]
            for request_id in ids:
                self._wait(request_id)
            done += window
        return done / (time.perf_counter() - started)

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


def spoken_protocol(url: str) -> str:
    """The MQTT version umlbot's connections speak on this broker ("5", or "3.1.1" after a
    refusal): the raw requester speaks the same, so that the ratio compares the same traffic
    (MQTT 5 costs paho, raw or not, more per packet: docs/performance.md, RPC)."""
    connection = BusConnection(BrokerSettings.from_url(url), role="bench-protocol", robot=ROBOT)
    connection.start(TIMEOUT_S)
    try:
        return connection.protocol
    finally:
        connection.close()


def run_model(url: str, model: CompiledModel, trace: bool = True) -> Orchestrator:
    orchestrator = Orchestrator(model, BrokerSettings.from_url(url), robot=ROBOT, trace=trace,
                                handle_signals=False, startup_timeout_s=15.0)
    code = orchestrator.run_sync()
    if code != 0:
        raise RuntimeError(f"the orchestrator failed: {orchestrator.failure}")
    return orchestrator


class _NoPort:
    async def call(self, component: str, feature: str, args: list[Any]) -> Any:
        raise RuntimeError("no I/O in this model")

    def publish_signal(self, name: str, payload: Any) -> None:
        raise RuntimeError("no I/O in this model")


def node_steps_per_s(url: str | None, iterations: int) -> tuple[float, int]:
    """Nodes per second of the datastore + decision loop; with `url`, traced onto that broker."""
    model = compile_text(STEPS.format(n=iterations))
    engine = Engine(model, _NoPort())
    connection: BusConnection | None = None
    if url is not None:
        connection = BusConnection(BrokerSettings.from_url(url), role="bench-trace", robot=ROBOT)
        connection.start(TIMEOUT_S)

    async def run() -> tuple[float, int]:
        recorder: TraceRecorder | None = None
        if connection is not None:
            topic = f"umlbot/{ROBOT}/orchestrator/trace"
            conn = connection
            recorder = TraceRecorder(lambda data: conn.publish(topic, data, qos=0))
            engine.trace = recorder.record
        started = time.perf_counter()
        await engine.run_lane("RaspberryPI")
        elapsed = time.perf_counter() - started
        dropped = 0
        if recorder is not None:
            recorder.close(timeout=0.0)
            dropped = recorder.dropped
        return elapsed, dropped

    try:
        elapsed, dropped = asyncio.run(run())
    finally:
        if connection is not None:
            connection.close()
    return engine.stats.nodes / elapsed, dropped


def measure(kind: str, n: int, blocks: int, window: int, steps: int) -> dict[str, Any]:
    per_block = max(1, n // blocks)
    loop_model = compile_text(LOOP.format(n=per_block))
    with run_broker(kind) as url, motor_service(url):
        raw = RawRequester(url, spoken_protocol(url))
        try:
            for _ in range(100):
                raw.round_trip()
            run_model(url, compile_text(LOOP.format(n=100)))  # warm-up
            raw_samples: list[float] = []
            action_samples: list[float] = []
            traced_samples: list[float] = []
            trace_events = trace_messages = 0
            variants = ["raw", "model", "traced"]
            for block in range(blocks):
                for variant in variants[block % 3:] + variants[:block % 3]:
                    if variant == "raw":
                        raw_samples.extend(raw.round_trip() for _ in range(per_block))
                    else:
                        orchestrator = run_model(url, loop_model, trace=variant == "traced")
                        (traced_samples if variant == "traced" else action_samples).extend(
                            orchestrator.stats.action_latency_s)
                        if orchestrator.recorder is not None:
                            trace_events += orchestrator.recorder.shipped
                            trace_messages += orchestrator.recorder.messages
            iterations = max(1, n // window)
            raw_rates: list[float] = []
            fork_rates: list[float] = []
            fork = fork_model(window, iterations)
            for _ in range(3):
                raw_rates.append(raw.throughput(window, iterations * window))
                began = time.perf_counter()
                orchestrator = run_model(url, fork, trace=False)
                # run_model includes start-up and shut-down; count only the lanes' time
                fork_rates.append(orchestrator.stats.actions / _lane_seconds(orchestrator, began))
        finally:
            raw.close()
        traced, dropped = node_steps_per_s(url, steps)
    untraced, _ = node_steps_per_s(None, steps)
    result: dict[str, Any] = {
        "broker": kind,
        "protocol": raw.protocol,
        "n": len(raw_samples),
        "raw_p50_ms": round(percentile(raw_samples, 50) * 1000, 4),
        "raw_p99_ms": round(percentile(raw_samples, 99) * 1000, 4),
        "action_p50_ms": round(percentile(action_samples, 50) * 1000, 4),
        "action_p99_ms": round(percentile(action_samples, 99) * 1000, 4),
        "action_traced_p50_ms": round(percentile(traced_samples, 50) * 1000, 4),
        "action_traced_p99_ms": round(percentile(traced_samples, 99) * 1000, 4),
        "trace_events_per_message": round(trace_events / max(1, trace_messages), 1),
        "fork_window": window,
        "fork_actions_per_s": round(max(fork_rates)),
        "raw_publish_per_s": round(max(raw_rates)),
        "node_steps_per_s": round(untraced),
        "node_steps_traced_per_s": round(traced),
        "trace_events_dropped": dropped,
    }
    result["ratio_p50"] = round(result["action_p50_ms"] / result["raw_p50_ms"], 3)
    result["ratio_p99"] = round(result["action_p99_ms"] / result["raw_p99_ms"], 3)
    result["ratio_traced_p50"] = round(result["action_traced_p50_ms"] / result["raw_p50_ms"], 3)
    result["ratio_traced_p99"] = round(result["action_traced_p99_ms"] / result["raw_p99_ms"], 3)
    result["fork_vs_raw"] = round(result["fork_actions_per_s"] / result["raw_publish_per_s"], 3)
    return result


def _lane_seconds(orchestrator: Orchestrator, began: float) -> float:
    """Wall seconds the lanes ran (start-up and shut-down excluded), else the whole run."""
    first, last = orchestrator.lane_window
    return (last - first) if last > first else time.perf_counter() - began


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--n", type=int, default=4000, help="actions per variant and broker")
    parser.add_argument("--blocks", type=int, default=12, help="rotating measurement blocks")
    parser.add_argument("--window", type=int, default=8, help="actions in one fork")
    parser.add_argument("--steps", type=int, default=100_000, help="loop iterations for node_steps_per_s")
    parser.add_argument("--brokers", default="amqtt,mosquitto")
    options = parser.parse_args()
    results = []
    for kind in options.brokers.split(","):
        result = measure(kind.strip(), options.n, options.blocks, options.window, options.steps)
        print(
            f"{kind:10s} MQTT {result['protocol']:5s} "
            f"raw p50 {result['raw_p50_ms']:.3f} p99 {result['raw_p99_ms']:.3f} ms | "
            f"action p50 {result['action_p50_ms']:.3f} p99 {result['action_p99_ms']:.3f} ms | "
            f"ratio p50 {result['ratio_p50']:.2f} p99 {result['ratio_p99']:.2f} "
            f"(traced {result['ratio_traced_p50']:.2f}/{result['ratio_traced_p99']:.2f}, "
            f"{result['trace_events_per_message']} events/message) | "
            f"fork {result['fork_actions_per_s']}/s vs raw {result['raw_publish_per_s']}/s | "
            f"nodes {result['node_steps_per_s']}/s (traced {result['node_steps_traced_per_s']}/s)",
            flush=True,
        )
        results.append(result)
    print(json.dumps({"results": results}))


if __name__ == "__main__":
    main()
