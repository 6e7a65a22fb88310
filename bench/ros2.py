"""ROS 2 figures, each against the sum of its hops measured raw in the same run (docs/ros2.md):

- **call**: a ROS 2 node calls a umlbot feature through the bridge (`umlbot ros2-bridge`, its
  service `/umlbot/<robot>/call`) -> MQTT -> a sonar service (`umlbot service sonar`, mock driver)
  and back; the raw hops: a paho request/reply (requester here, responder in a child process,
  TCP_NODELAY, QoS 0) plus a cyclonedds request/reply (rmw_cyclonedds layout, server in a child
  process on cyclonedds' own reader, writer and serialiser). Also umlbot's own MQTT call
  (BusClient -> the same sonar service), and the bridge's call answered by the raw paho
  responder instead of the sonar service (`bridge_call_raw_responder`: the bridge alone between
  the two raw hops), to show where the time goes.
- **publish**: a feature that becomes a ROS 2 publish (`Base.drive` of a `ros2_twist` component,
  `umlbot service ros2`) until the Fast DDS peer (tests/ros2_peer) has the Twist; the raw hops:
  umlbot's MQTT call to the sonar plus a cyclonedds publish seen by the same peer.
- **rss**: the bridge process's resident memory after the run.

Kinds are measured in alternating blocks. DDS stays on loopback (domain chosen at random).
The last output line is one JSON object.

    python bench/ros2.py [--n 600] [--blocks 6]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import queue
import random
import shutil
import signal
import socket
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

from umlbot.base.logs import configure_logging
from umlbot.services.bus import BrokerSettings, BusClient
from umlbot.services.ros2 import dds
from umlbot.services.ros2.msgtypes import Types, dds_topic_name

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
from ros2_support import build_peer  # type: ignore[import-not-found,unused-ignore]  # noqa: E402

ROBOT = "bench"
TIMEOUT_S = 5.0
UMLBOT = [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "WARNING"]

RAW_RESPONDER = """
import json, socket, sys, threading
import paho.mqtt.client as mqtt
from paho.mqtt.enums import CallbackAPIVersion
c = mqtt.Client(CallbackAPIVersion.VERSION2, client_id="bench-raw-responder")
c.on_socket_open = lambda c, u, s: s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
ready = threading.Event()
def on_message(client, userdata, msg):
    request = json.loads(msg.payload)
    client.publish(request["reply_to"], json.dumps({"id": request["id"], "ok": True, "value": 100}), qos=0)
c.on_message = on_message
c.on_subscribe = lambda *a: ready.set()
c.connect("127.0.0.1", int(sys.argv[1]), 30)
c.subscribe([("bench/raw/request", 0), ("umlbot/bench/Raw/call/value", 0)])
c.loop_start()
ready.wait(10)
print("ready", flush=True)
sys.stdin.read()
"""

# cyclonedds as it comes (its DataReader/DataWriter and its own serialiser), not umlbot's
# ServiceServer: the raw hop stays the library's, whatever umlbot's service code does
RAW_DDS_SERVER = """
import sys
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from umlbot.services.ros2 import dds
from umlbot.services.ros2.msgtypes import Types
builder = dds.TypeBuilder.of(Types.load())
dp = dds.participant(int(sys.argv[1]))
requests = dds.shared_topic(dp, "rq/bench/rawRequest", builder.cls("std_srvs/srv/Trigger_Request", True))
replies = dds.shared_topic(dp, "rr/bench/rawReply", builder.cls("std_srvs/srv/Trigger_Response", True))
Response = replies.data_type
writer = DataWriter(dp, replies, qos=dds.qos(True))
def on_data(reader):
    for request in reader.take(N=32):
        if isinstance(request, requests.data_type):
            writer.write(Response(rmw_guid=request.rmw_guid, rmw_seq=request.rmw_seq, success=True,
                                  message="100"))
reader = DataReader(dp, requests, qos=dds.qos(True), listener=dds.Listener(on_data_available=on_data))
print("ready", flush=True)
sys.stdin.read()
"""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def percentile(samples: list[float], q: float) -> float:
    ordered = sorted(samples)
    return ordered[min(len(ordered) - 1, max(0, round(q / 100 * (len(ordered) - 1))))]


@contextlib.contextmanager
def child(argv: list[str], ready: str | None = "ready", env: dict[str, str] | None = None,
          wait: Callable[[], bool] | None = None) -> Iterator[subprocess.Popen[str]]:
    proc = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            text=True, env=env)
    try:
        if ready is not None:
            assert proc.stdout is not None
            line = proc.stdout.readline()
            if ready not in line:
                raise RuntimeError(f"{argv[-1]} did not start: {line!r}")
        if wait is not None:
            deadline = time.monotonic() + 30
            while not wait():
                if time.monotonic() > deadline:
                    raise RuntimeError(f"{argv} did not come up")
                time.sleep(0.05)
        yield proc
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


@contextlib.contextmanager
def mosquitto() -> Iterator[int]:
    port = free_port()
    with tempfile.TemporaryDirectory() as tmp:
        config = Path(tmp) / "mosquitto.conf"
        config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n"
                          "set_tcp_nodelay true\n")
        binary = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
        proc = subprocess.Popen([binary, "-c", str(config)], stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 10
            while True:
                with contextlib.suppress(OSError), socket.create_connection(("127.0.0.1", port), 0.2):
                    break
                if time.monotonic() > deadline:
                    raise RuntimeError("mosquitto did not start")
                time.sleep(0.02)
            yield port
        finally:
            proc.terminate()
            proc.wait(10)


def _nodelay(client: Any, userdata: Any, sock: Any) -> None:
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)


class RawMqtt:
    """A paho requester; the responder is a child process."""

    def __init__(self, port: int) -> None:
        self.client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"bench-raw-req-{os.getpid()}")
        self.client.on_socket_open = _nodelay
        self.got = threading.Event()
        self.expected = ""
        subscribed = threading.Event()

        def on_message(client: Any, userdata: Any, msg: Any) -> None:
            if json.loads(msg.payload)["id"] == self.expected:
                self.got.set()

        self.client.on_message = on_message
        self.client.on_subscribe = lambda *a: subscribed.set()
        self.client.connect("127.0.0.1", port, 30)
        self.client.subscribe("bench/raw/reply", 0)
        self.client.loop_start()
        if not subscribed.wait(TIMEOUT_S):
            raise RuntimeError("raw requester not subscribed")
        self.counter = 0

    def round_trip(self) -> float:
        self.counter += 1
        self.expected = f"r{self.counter}"
        self.got.clear()
        payload = json.dumps({"id": self.expected, "reply_to": "bench/raw/reply", "args": []})
        started = time.perf_counter()
        self.client.publish("bench/raw/request", payload.encode(), qos=0)
        if not self.got.wait(TIMEOUT_S):
            raise RuntimeError("raw MQTT round trip timed out")
        return time.perf_counter() - started

    def close(self) -> None:
        self.client.disconnect()
        self.client.loop_stop()


class PeerLines:
    """The Fast DDS peer's stdout, line by line, with arrival times."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.proc = proc
        self.lines: queue.Queue[tuple[float, str]] = queue.Queue()
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put((time.perf_counter(), line.strip()))

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def wait_for(self, needle: str) -> float:
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline:
            try:
                at, line = self.lines.get(timeout=0.5)
            except queue.Empty:
                continue
            if needle in line:
                return at
        raise RuntimeError(f"the Fast DDS peer never printed {needle!r}")


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def twist_hex(builder: dds.TypeBuilder, linear: float) -> str:
    sample = builder.default("geometry_msgs/msg/Twist")
    sample.linear.x = linear
    return str(sample.serialize(use_version_2=False).hex())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=600, help="round trips per kind")
    parser.add_argument("--blocks", type=int, default=6)
    args = parser.parse_args()
    configure_logging("WARNING", False)
    domain = random.randint(30, 220)
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
    env.pop("CYCLONEDDS_URI", None)
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    builder = dds.TypeBuilder.of(Types.load())
    peer_exe = build_peer()
    with tempfile.TemporaryDirectory() as tmp, mosquitto() as port:
        url = f"mqtt://127.0.0.1:{port}"
        deploy = Path(tmp) / "deployment.yaml"
        deploy.write_text(json.dumps({"robot": ROBOT, "driver": "mock", "components": {
            "Sonar": {"impl": "hcsr04", "settings": {"mock_distance_cm": 100}},
            "Base": {"impl": "ros2_twist", "driver": "dds", "settings": {"topic": "/bench/cmd_vel"}}}}))
        bus = BusClient(BrokerSettings.from_url(url), ROBOT, role="bench")
        bus.start(TIMEOUT_S)

        def online(component: str) -> Callable[[], bool]:
            def check() -> bool:
                try:
                    bus.call(component, "value" if component == "Sonar" else "stop", timeout=0.5)
                    return True
                except Exception:
                    return False
            return check

        service = [*UMLBOT, "service", "sonar", "--deploy", str(deploy), "--broker", url]
        ros2_service = [*UMLBOT, "service", "ros2", "--deploy", str(deploy), "--broker", url]
        bridge_argv = [*UMLBOT, "ros2-bridge", "--broker", url, "--robot", ROBOT, "--domain-id", str(domain)]
        with child(service, None, env, online("Sonar")), child(ros2_service, None, env, online("Base")), \
                child([sys.executable, "-c", RAW_RESPONDER, str(port)], env=env), \
                child([sys.executable, "-c", RAW_DDS_SERVER, str(domain)], env=env), \
                child(bridge_argv, None, env) as bridge, \
                child([str(peer_exe), str(domain)], None, env) as peer_proc:
            peer = PeerLines(peer_proc)
            peer.wait_for("ready")
            peer.send(f"sub {dds_topic_name('/bench/cmd_vel')} geometry_msgs::msg::dds_::Twist_")
            peer.wait_for("subscribed")
            raw_mqtt = RawMqtt(port)
            raw_dds = dds.ServiceClient(builder, domain, "/bench/raw", "std_srvs/srv/Trigger")
            via_bridge = dds.ServiceClient(builder, domain, f"/umlbot/{ROBOT}/call",
                                           "umlbot_msgs/srv/CallFeature")
            raw_pub = dds.Publication(builder, domain, "/bench/cmd_vel", "geometry_msgs/msg/Twist")
            for client in (raw_dds, via_bridge):
                if not client.wait_for_server(20):
                    raise RuntimeError(f"no server for {client.service}")
            deadline = time.monotonic() + 20
            while raw_pub.matched() == 0 and time.monotonic() < deadline:
                time.sleep(0.05)
            counter = [0]
            replied: list[float] = []  # publish_via_umlbot: until the MQTT reply

            def dds_raw() -> float:
                started = time.perf_counter()
                raw_dds.call(raw_dds.request(), TIMEOUT_S)
                return time.perf_counter() - started

            def bridge_call() -> float:
                request = via_bridge.request()
                request.component, request.feature = "Sonar", "value"
                started = time.perf_counter()
                reply = via_bridge.call(request, TIMEOUT_S)
                elapsed = time.perf_counter() - started
                if not reply.ok:
                    raise RuntimeError(f"bridge call failed: {reply.error_code} {reply.error_message}")
                return elapsed

            def bridge_call_raw_responder() -> float:
                request = via_bridge.request()
                request.component, request.feature = "Raw", "value"  # the raw paho responder
                started = time.perf_counter()
                reply = via_bridge.call(request, TIMEOUT_S)
                elapsed = time.perf_counter() - started
                if not reply.ok or reply.value_json != "100":
                    raise RuntimeError(f"bridge call failed: {reply.error_code} {reply.error_message}")
                return elapsed

            def umlbot_call() -> float:
                started = time.perf_counter()
                bus.call("Sonar", "value", timeout=TIMEOUT_S)
                return time.perf_counter() - started

            def publish_via_umlbot() -> float:
                counter[0] += 1
                linear = round(counter[0] % 1000 / 1000 + 0.001, 3)
                needle = twist_hex(builder, linear)[8:40]
                started = time.perf_counter()
                bus.call("Base", "drive", linear, 0.0, timeout=TIMEOUT_S)
                replied.append(time.perf_counter() - started)
                return peer.wait_for(needle) - started

            def publish_raw() -> float:
                counter[0] += 1
                linear = round(counter[0] % 1000 / 1000 + 0.001, 3)
                sample = raw_pub.sample()
                sample.linear.x = linear
                needle = twist_hex(builder, linear)[8:40]
                started = time.perf_counter()
                raw_pub.write(sample)
                return peer.wait_for(needle) - started

            kinds: dict[str, Callable[[], float]] = {
                "mqtt_raw": raw_mqtt.round_trip, "dds_raw": dds_raw, "bridge_call": bridge_call,
                "bridge_call_raw_responder": bridge_call_raw_responder,
                "umlbot_mqtt_call": umlbot_call, "publish_via_umlbot": publish_via_umlbot,
                "dds_publish_raw": publish_raw,
            }
            samples: dict[str, list[float]] = {name: [] for name in kinds}
            for trip in kinds.values():  # warm-up
                for _ in range(30):
                    trip()
            per_block = max(1, args.n // args.blocks)
            order = list(kinds.items())
            for block in range(args.blocks):
                for name, trip in (order if block % 2 == 0 else order[::-1]):
                    samples[name].extend(trip() for _ in range(per_block))
            bridge_rss = rss_mb(bridge.pid)
            raw_mqtt.close()
            for entity in (raw_dds, via_bridge, raw_pub):
                entity.close()
        bus.close()
    figures = {name: {"p50_ms": round(percentile(s, 50) * 1000, 4),
                      "p99_ms": round(percentile(s, 99) * 1000, 4)} for name, s in samples.items()}

    def ratio(measured: str, *hops: str, q: str) -> float:
        return round(figures[measured][q] / sum(figures[h][q] for h in hops), 3)

    figures["publish_via_umlbot_reply"] = {"p50_ms": round(percentile(replied, 50) * 1000, 4),
                                           "p99_ms": round(percentile(replied, 99) * 1000, 4)}
    result = {
        "n": len(samples["bridge_call"]),
        "figures": figures,
        "call_vs_raw_hops": {"p50": ratio("bridge_call", "mqtt_raw", "dds_raw", q="p50_ms"),
                             "p99": ratio("bridge_call", "mqtt_raw", "dds_raw", q="p99_ms")},
        "bridge_alone_vs_raw_hops": {  # the same call, answered by the raw paho responder
            "p50": ratio("bridge_call_raw_responder", "mqtt_raw", "dds_raw", q="p50_ms"),
            "p99": ratio("bridge_call_raw_responder", "mqtt_raw", "dds_raw", q="p99_ms")},
        "call_vs_umlbot_mqtt_plus_dds": {
            "p50": ratio("bridge_call", "umlbot_mqtt_call", "dds_raw", q="p50_ms"),
            "p99": ratio("bridge_call", "umlbot_mqtt_call", "dds_raw", q="p99_ms")},
        "publish_vs_raw_hops": {
            "p50": ratio("publish_via_umlbot", "umlbot_mqtt_call", "dds_publish_raw", q="p50_ms"),
            "p99": ratio("publish_via_umlbot", "umlbot_mqtt_call", "dds_publish_raw", q="p99_ms")},
        "bridge_rss_mb": round(bridge_rss, 1),
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
