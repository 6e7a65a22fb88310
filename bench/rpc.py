"""Request/reply latency: raw paho against the umlbot bus, on the embedded amqtt and on Mosquitto.

For each broker (both started by this script, each in its own process on a free port) it runs N
sequential round trips with a responder and a requester written directly on paho (TCP_NODELAY,
QoS 0, a JSON envelope like umlbot's), and N through `ComponentServer` + `BusClient`. The two
are measured in alternating blocks so that drift in machine load hits both alike. The last output
line is one JSON object: {"results": [{"broker", "raw_p50_ms", "raw_p99_ms", "umlbot_p50_ms",
"umlbot_p99_ms", "ratio_p50", "ratio_p99"}, ...]}.

    python bench/rpc.py [--n 2000] [--blocks 10] [--brokers amqtt,mosquitto] [--protocol auto]

`--protocol` goes into umlbot's broker URL (`auto`, the default: MQTT 5 where the broker speaks
it, else 3.1.1); the raw baseline speaks the MQTT version umlbot's connection ended up with
(the `protocol` of each result).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
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
from pathlib import Path
from typing import Any

import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion

from umlbot.base.catalog import implementations
from umlbot.base.logs import configure_logging
from umlbot.services.bus import BrokerSettings, BusClient, ComponentServer, Feature

ROBOT = "bench"
TIMEOUT_S = 5.0


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def wait_port(port: int, timeout: float = 15.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), timeout=0.2):
            return
        time.sleep(0.02)
    raise RuntimeError(f"broker on port {port} did not start")


@contextlib.contextmanager
def run_broker(kind: str) -> Iterator[str]:
    """Start a broker process; yield its URL; stop it."""
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        if kind == "mosquitto":
            binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
            config = Path(tmp) / "mosquitto.conf"
            config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
            argv = [binary, "-c", str(config)]
        else:
            argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "WARNING",
                    "broker", "--port", str(port)]
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            wait_port(port)
            yield f"mqtt://127.0.0.1:{port}"
        finally:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)


def _nodelay(client: mqtt.Client, userdata: Any, sock: Any) -> None:
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


def _raw_client(port: int, name: str, protocol: str = "3.1.1") -> mqtt.Client:
    version = MQTTProtocolVersion.MQTTv5 if protocol == "5" else MQTTProtocolVersion.MQTTv311
    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"bench-raw-{name}-{os.getpid()}",
                         protocol=version)
    client.on_socket_open = _nodelay
    connected = threading.Event()
    client.on_connect = lambda c, u, f, rc, p=None: connected.set()
    client.connect("127.0.0.1", port, 30)
    client.loop_start()
    if not connected.wait(TIMEOUT_S):
        raise RuntimeError("raw paho client could not connect")
    return client


def _subscribed(client: mqtt.Client, topic: str) -> None:
    done = threading.Event()
    client.on_subscribe = lambda c, u, mid, rcs, p=None: done.set()
    client.subscribe(topic, 0)
    if not done.wait(TIMEOUT_S):
        raise RuntimeError(f"no SUBACK for {topic}")


class RawPair:
    """Responder and requester written directly on paho: the baseline."""

    def __init__(self, url: str, protocol: str) -> None:
        port = int(url.rsplit(":", 1)[1])
        self.request_topic = f"umlbot/{ROBOT}/RawMotor/call/dutycycle"
        self.reply_topic = f"umlbot/{ROBOT}/_reply/raw-{os.getpid()}"
        self.responder = _raw_client(port, "responder", protocol)
        self.requester = _raw_client(port, "requester", protocol)

        def respond(client: mqtt.Client, userdata: Any, msg: mqtt.MQTTMessage) -> None:
            request = json.loads(msg.payload)
            reply = json.dumps({"id": request["id"], "ok": True, "value": None}, separators=(",", ":"))
            client.publish(request["reply_to"], reply.encode(), qos=0)

        self.responder.on_message = respond
        _subscribed(self.responder, self.request_topic)
        self.got = threading.Event()
        self.expected = ""

        def on_reply(client: mqtt.Client, userdata: Any, msg: mqtt.MQTTMessage) -> None:
            if json.loads(msg.payload)["id"] == self.expected:
                self.got.set()

        self.requester.on_message = on_reply
        _subscribed(self.requester, self.reply_topic)
        self.counter = 0

    def round_trip(self) -> float:
        self.counter += 1
        self.expected = f"r{self.counter}"
        self.got.clear()
        request = {"id": self.expected, "reply_to": self.reply_topic, "args": [self.counter % 100]}
        payload = json.dumps(request, separators=(",", ":")).encode()
        started = time.perf_counter()
        self.requester.publish(self.request_topic, payload, qos=0)
        if not self.got.wait(TIMEOUT_S):
            raise RuntimeError("raw round trip timed out")
        return time.perf_counter() - started

    def close(self) -> None:
        for client in (self.requester, self.responder):
            client.disconnect()
            client.loop_stop()


class UmlbotPair:
    """The same round trip through ComponentServer and BusClient."""

    def __init__(self, url: str) -> None:
        settings = BrokerSettings.from_url(url)
        spec = implementations()["l298n"].features["dutycycle"]
        features = [Feature(spec, lambda percent: None)]
        self.server = ComponentServer(settings, ROBOT, "Motor", "l298n", features)
        self.server.start(TIMEOUT_S)
        self.client = BusClient(settings, ROBOT, role="bench")
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


def percentile(samples: list[float], q: float) -> float:
    ordered = sorted(samples)
    index = min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))
    return ordered[index]


def measure(kind: str, n: int, blocks: int, warmup: int, protocol: str) -> dict[str, Any]:
    with run_broker(kind) as url:
        bus = UmlbotPair(f"{url}?protocol={protocol}")
        spoken = bus.client.connection.protocol
        raw = RawPair(url, spoken)
        try:
            for _ in range(warmup):
                raw.round_trip()
                bus.round_trip()
            raw_samples: list[float] = []
            bus_samples: list[float] = []
            per_block = max(1, n // blocks)
            runs: list[tuple[Callable[[], float], list[float]]] = [
                (raw.round_trip, raw_samples), (bus.round_trip, bus_samples)
            ]
            for block in range(blocks):
                order = runs if block % 2 == 0 else runs[::-1]
                for trip, samples in order:
                    samples.extend(trip() for _ in range(per_block))
        finally:
            bus.close()
            raw.close()
    raw_p50, raw_p99 = percentile(raw_samples, 50) * 1000, percentile(raw_samples, 99) * 1000
    bus_p50, bus_p99 = percentile(bus_samples, 50) * 1000, percentile(bus_samples, 99) * 1000
    result: dict[str, Any] = {
        "broker": kind,
        "protocol": spoken,
        "n": len(raw_samples),
        "raw_p50_ms": round(raw_p50, 4),
        "raw_p99_ms": round(raw_p99, 4),
        "umlbot_p50_ms": round(bus_p50, 4),
        "umlbot_p99_ms": round(bus_p99, 4),
        "ratio_p50": round(bus_p50 / raw_p50, 3),
        "ratio_p99": round(bus_p99 / raw_p99, 3),
        "raw_mean_ms": round(statistics.fmean(raw_samples) * 1000, 4),
        "umlbot_mean_ms": round(statistics.fmean(bus_samples) * 1000, 4),
    }
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=2000, help="round trips per variant and broker")
    parser.add_argument("--blocks", type=int, default=10, help="alternating measurement blocks")
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--brokers", default="amqtt,mosquitto")
    parser.add_argument("--protocol", default="auto", choices=["auto", "5", "3.1.1"],
                        help="the MQTT version in umlbot's broker URL")
    options = parser.parse_args()
    configure_logging("WARNING")  # logs to stderr; stdout stays for the figures
    results = []
    for kind in options.brokers.split(","):
        result = measure(kind.strip(), options.n, options.blocks, options.warmup, options.protocol)
        print(
            f"{kind:10s} MQTT {result['protocol']:5s} "
            f"raw p50 {result['raw_p50_ms']:.3f} ms p99 {result['raw_p99_ms']:.3f} ms | "
            f"umlbot p50 {result['umlbot_p50_ms']:.3f} ms p99 {result['umlbot_p99_ms']:.3f} ms | "
            f"ratio p50 {result['ratio_p50']:.2f} p99 {result['ratio_p99']:.2f}",
            flush=True,
        )
        results.append(result)
    print(json.dumps({"results": results}))


if __name__ == "__main__":
    main()
