"""Shared fixtures: real MQTT brokers on free ports, and raw paho clients that use no umlbot code.

`amqtt_broker` runs the embedded broker (`umlbot broker`) and `mosquitto_broker` the Mosquitto
binary, each in its own process so that a test can stop, restart (same port) or SIGKILL it;
`broker` is parametrised over both (ids "amqtt" and "mosquitto"). `raw_client` makes plain paho
clients that record what they receive.
"""

from __future__ import annotations

import contextlib
import os
import queue
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import paho.mqtt.client as mqtt
import pytest
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion
from paho.mqtt.properties import Properties

BrokerKind = Literal["amqtt", "mosquitto"]

START_TIMEOUT_S = 10.0
STOP_TIMEOUT_S = 5.0


def free_port() -> int:
    """A TCP port on loopback that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def port_accepts(port: int, host: str = "127.0.0.1") -> bool:
    """True when a TCP connection to host:port succeeds."""
    try:
        with socket.create_connection((host, port), timeout=0.2):
            return True
    except OSError:
        return False


def wait_until(predicate: Callable[[], bool], timeout: float = 5.0, interval: float = 0.02) -> bool:
    """Poll `predicate` until it is true or `timeout` seconds passed; returns the last result."""
    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(interval)


def find_mosquitto() -> str | None:
    """The Mosquitto binary on PATH or in /usr/sbin, or None."""
    found = shutil.which("mosquitto")
    if found:
        return found
    for candidate in ("/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto"):
        if os.access(candidate, os.X_OK):
            return candidate
    return None


@dataclass
class BrokerProcess:
    """A real MQTT broker in a child process, on a fixed port that survives restarts."""

    kind: BrokerKind
    port: int
    workdir: Path
    proc: subprocess.Popen[bytes] | None = field(default=None, repr=False)
    starts: int = 0

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    @property
    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def _argv(self) -> list[str]:
        if self.kind == "mosquitto":
            binary = find_mosquitto()
            if binary is None:
                raise RuntimeError("the mosquitto binary is not installed (apt-get install mosquitto)")
            config = self.workdir / "mosquitto.conf"
            config.write_text(
                f"listener {self.port} 127.0.0.1\n"
                "allow_anonymous true\n"
                "persistence false\n"
                "set_tcp_nodelay true\n"
                "log_dest stderr\n"
                "log_type error\n"
                "log_type warning\n",
                encoding="utf-8",
            )
            return [binary, "-c", str(config)]
        return [
            sys.executable,
            "-c",
            "from umlbot.cli import main; main()",
            "--log-level",
            "WARNING",
            "broker",
            "--port",
            str(self.port),
        ]

    def start(self) -> None:
        """Start (or restart) the broker on the same port; returns once it accepts connections."""
        if self.running:
            return
        self.starts += 1
        log = (self.workdir / f"{self.kind}-{self.starts}.log").open("wb")
        env = {**os.environ, "UMLBOT_LOG_LEVEL": "WARNING"}
        self.proc = subprocess.Popen(
            self._argv(), stdout=log, stderr=subprocess.STDOUT, cwd=self.workdir, env=env
        )
        log.close()
        deadline = time.monotonic() + START_TIMEOUT_S
        while not port_accepts(self.port):
            if self.proc.poll() is not None:
                raise RuntimeError(f"{self.kind} exited at start-up:\n{self.log_text()}")
            if time.monotonic() > deadline:
                self.kill()
                raise RuntimeError(f"{self.kind} did not listen on {self.port} in {START_TIMEOUT_S} s")
            time.sleep(0.02)

    def stop(self) -> None:
        """Stop the broker gracefully (SIGTERM), then wait for the port to be free."""
        if self.proc is None:
            return
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(STOP_TIMEOUT_S)
        self.proc = None

    def kill(self) -> None:
        """Kill the broker with SIGKILL (no goodbye to its clients)."""
        if self.proc is None:
            return
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(STOP_TIMEOUT_S)
        self.proc = None

    def restart(self) -> None:
        self.stop()
        self.start()

    def log_text(self) -> str:
        """Everything the broker printed, over all its starts."""
        return "\n".join(
            p.read_text(encoding="utf-8", errors="replace") for p in sorted(self.workdir.glob("*.log"))
        )


@pytest.fixture(autouse=True, scope="session")
def _session_cache_home(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The caches the product keeps under `$XDG_CACHE_HOME` (the studio's layouts, built C++
    programs) in a folder of the test session's own: no test reads what an earlier run or the
    user left in ~/.cache, nor writes there. A test that wants an empty one sets its own."""
    before = os.environ.get("XDG_CACHE_HOME")
    os.environ["XDG_CACHE_HOME"] = str(tmp_path_factory.mktemp("xdg-cache"))
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("XDG_CACHE_HOME", None)
        else:
            os.environ["XDG_CACHE_HOME"] = before


def _broker(kind: BrokerKind, tmp_path_factory: pytest.TempPathFactory) -> Iterator[BrokerProcess]:
    if kind == "mosquitto" and find_mosquitto() is None:
        pytest.fail("the mosquitto binary is required (apt-get install mosquitto)")
    process = BrokerProcess(kind, free_port(), tmp_path_factory.mktemp(kind))
    process.start()
    try:
        yield process
    finally:
        process.kill()


@pytest.fixture
def amqtt_broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[BrokerProcess]:
    """The embedded amqtt broker (`umlbot broker`) in a child process on a free port."""
    yield from _broker("amqtt", tmp_path_factory)


@pytest.fixture
def mosquitto_broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[BrokerProcess]:
    """A Mosquitto with its own config (loopback, anonymous, no persistence) on a free port."""
    yield from _broker("mosquitto", tmp_path_factory)


@pytest.fixture(params=["amqtt", "mosquitto"])
def broker(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[BrokerProcess]:
    """Each test using it runs once on amqtt and once on Mosquitto."""
    yield from _broker(request.param, tmp_path_factory)


class RawClient:
    """A plain paho client (no umlbot code) that queues every message it receives."""

    def __init__(
        self,
        port: int,
        protocol: MQTTProtocolVersion = MQTTProtocolVersion.MQTTv311,
        client_id: str | None = None,
    ) -> None:
        self.protocol = protocol
        self.messages: queue.Queue[mqtt.MQTTMessage] = queue.Queue()
        self._connected = False
        self.client = mqtt.Client(
            CallbackAPIVersion.VERSION2,
            client_id=client_id or f"raw-{uuid.uuid4().hex[:8]}",
            protocol=protocol,
        )
        self.client.on_message = self._on_message
        self.client.on_connect = self._on_connect
        self.client.connect("127.0.0.1", port, keepalive=30)
        self.client.loop_start()
        if not wait_until(lambda: self._connected, 5.0):
            self.close()
            raise RuntimeError(f"raw paho client could not connect to port {port}")

    def _on_connect(self, client: mqtt.Client, userdata: Any, flags: Any, rc: Any, props: Any = None) -> None:
        self._connected = not rc.is_failure

    def _on_message(self, client: mqtt.Client, userdata: Any, msg: mqtt.MQTTMessage) -> None:
        self.messages.put(msg)

    def subscribe(self, topic: str, qos: int = 1, timeout: float = 5.0) -> None:
        """Subscribe and wait for the SUBACK."""
        result, _mid = self.client.subscribe(topic, qos)
        assert result == mqtt.MQTT_ERR_SUCCESS
        # paho has no blocking subscribe; a round trip through the broker proves the SUBACK came
        probe = f"umlbot-test/probe/{uuid.uuid4().hex}"
        self.client.subscribe(probe, 1)
        self.client.publish(probe, b"", qos=1)
        deadline = time.monotonic() + timeout
        pending: list[mqtt.MQTTMessage] = []
        try:
            while True:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"subscription to {topic} not confirmed")
                try:
                    msg = self.messages.get(timeout=remaining)
                except queue.Empty:
                    continue
                if msg.topic == probe:
                    break
                pending.append(msg)
        finally:
            self.client.unsubscribe(probe)
            for msg in pending:
                self.messages.put(msg)

    def publish(
        self,
        topic: str,
        payload: bytes | str,
        qos: int = 1,
        retain: bool = False,
        properties: Properties | None = None,
    ) -> None:
        info = self.client.publish(topic, payload, qos=qos, retain=retain, properties=properties)
        info.wait_for_publish(5.0)

    def get(self, timeout: float = 5.0, topic: str | None = None) -> mqtt.MQTTMessage:
        """The next message (on `topic`, if given); raises TimeoutError after `timeout` s."""
        deadline = time.monotonic() + timeout
        skipped: list[mqtt.MQTTMessage] = []
        try:
            while True:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"no message on {topic or 'any topic'} within {timeout} s")
                try:
                    msg = self.messages.get(timeout=remaining)
                except queue.Empty:
                    continue
                if topic is None or mqtt.topic_matches_sub(topic, msg.topic):
                    return msg
                skipped.append(msg)
        finally:
            for msg in skipped:
                self.messages.put(msg)

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.client.disconnect()
        self.client.loop_stop()


@pytest.fixture
def raw_client() -> Iterator[Callable[..., RawClient]]:
    """Factory `raw_client(broker_or_port, protocol=mqtt.MQTTv311)`; all clients closed afterwards."""
    made: list[RawClient] = []

    def make(
        target: BrokerProcess | int,
        protocol: MQTTProtocolVersion = MQTTProtocolVersion.MQTTv311,
        client_id: str | None = None,
    ) -> RawClient:
        port = target if isinstance(target, int) else target.port
        client = RawClient(port, protocol, client_id)
        made.append(client)
        return client

    yield make
    for client in made:
        client.close()


#: A component service in its own process (so a test can SIGKILL it): `Motor`-like features.
_SERVER_SCRIPT = """
import sys, threading
from umlbot.services.bus import BrokerSettings, ComponentServer, Feature
from umlbot.base.library import FeatureSpec, Param
from umlbot.base.catalog import implementations
from umlbot.base.logs import configure_logging
configure_logging()
url, robot, component = sys.argv[1:4]
motor = implementations()["l298n"].features
features = [
    Feature(motor["dutycycle"], lambda percent: None),
    Feature(motor["enabled"], lambda on: None),
    Feature(FeatureSpec("value", (), "int"), lambda: 42),
    Feature(FeatureSpec("echo", (Param("text", "str"),), "str"), lambda text: text),
]
server = ComponentServer(BrokerSettings.from_url(url), robot, component, "l298n", features)
server.start(10.0)
print("ready", flush=True)
threading.Event().wait()
"""


def spawn_test_server(url: str, robot: str, component: str, timeout: float = 15.0) -> subprocess.Popen[str]:
    """Start a component server in a child process; returns once it is online."""
    proc = subprocess.Popen(
        [sys.executable, "-c", _SERVER_SCRIPT, url, robot, component],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env={**os.environ, "UMLBOT_LOG_LEVEL": "WARNING"},
    )
    ready: queue.Queue[str] = queue.Queue()

    def read() -> None:
        assert proc.stdout is not None
        ready.put(proc.stdout.readline())

    threading.Thread(target=read, daemon=True).start()
    try:
        line = ready.get(timeout=timeout)
    except queue.Empty:
        proc.kill()
        proc.wait(5)
        raise RuntimeError("the test server did not come online") from None
    if line.strip() != "ready":
        proc.kill()
        proc.wait(5)
        raise RuntimeError(f"the test server failed to start: {line!r}")
    return proc


@pytest.fixture
def server_process(broker: BrokerProcess) -> Iterator[Callable[[str, str], subprocess.Popen[str]]]:
    """Factory `server_process(robot, component)`: a component server process on `broker`."""
    made: list[subprocess.Popen[str]] = []

    def make(robot: str, component: str) -> subprocess.Popen[str]:
        proc = spawn_test_server(broker.url, robot, component)
        made.append(proc)
        return proc

    yield make
    for proc in made:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)


@pytest.fixture
def car(tmp_path: Path) -> Iterator[tuple[Path, Any]]:
    """A copy of the reference car in `tmp_path`, edited by a studio in this process
    (`studio_support.Editor`)."""
    from robot_run import CAR_MODEL
    from studio_support import Editor

    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    editor = Editor(root)
    try:
        yield root, editor
    finally:
        editor.thread.stop()
