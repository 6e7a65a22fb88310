"""Test helpers: brokers started with the shipped security files (deploy/mosquitto, deploy/amqtt).

The password files come from the recipe (deploy/broker_auth.py) for the reference robot car;
Mosquitto also gets the TLS listener of deploy/mosquitto/tls.conf with a throw-away CA.
"""

from __future__ import annotations

import os
import pwd
import queue
import shutil
import subprocess
import sys
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import paho.mqtt.client as mqtt
from conftest import find_mosquitto, free_port, port_accepts
from paho.mqtt.enums import CallbackAPIVersion, MQTTProtocolVersion

REPO = Path(__file__).resolve().parent.parent
DEPLOY = REPO / "deploy"
REFERENCE_DEPLOYMENT = DEPLOY / "mosquitto" / "reference-deployment.txt"
ROBOT = "car"


def make_auth(out: Path, *extra: str) -> dict[str, str]:
    """Run the password recipe for the reference car; returns role -> password."""
    result = subprocess.run(
        [sys.executable, str(DEPLOY / "broker_auth.py"), "--deployment", str(REFERENCE_DEPLOYMENT),
         "--robot", ROBOT, "--out", str(out), *extra],
        capture_output=True, text=True, timeout=120, check=False,
    )
    assert result.returncode == 0, result.stderr
    passwords: dict[str, str] = {}
    for env_file in out.glob("*.env"):
        for line in env_file.read_text(encoding="utf-8").splitlines():
            if line.startswith("UMLBOT_BROKER="):
                password = urlsplit(line.partition("=")[2]).password
                assert password
                passwords[env_file.stem] = password
    # The recipe prints no secret.
    for password in passwords.values():
        assert password not in result.stdout + result.stderr
    return passwords


@dataclass
class SecuredBroker:
    """A broker process started with the shipped security files."""

    kind: str
    port: int
    passwords: dict[str, str]
    log: Path
    proc: subprocess.Popen[bytes]
    tls_port: int | None = None
    ca_file: Path | None = None

    def log_text(self) -> str:
        return self.log.read_text(encoding="utf-8", errors="replace")


def _start(argv: list[str], port: int, log: Path, cwd: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as out:
        proc = subprocess.Popen(argv, stdout=out, stderr=subprocess.STDOUT, cwd=cwd)
    deadline = time.monotonic() + 15
    while not port_accepts(port):
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            proc.wait(5)
            raise RuntimeError(f"broker did not start:\n{log.read_text(errors='replace')}")
        time.sleep(0.05)
    return proc


def mosquitto_config(port: int, passwd: Path, tls: dict[str, Path] | None = None,
                     tls_port: int | None = None) -> str:
    """The shipped umlbot.conf (and tls.conf) with test paths and ports filled in."""
    text = (DEPLOY / "mosquitto" / "umlbot.conf").read_text(encoding="utf-8")
    text = text.replace("/etc/mosquitto/umlbot.passwd", str(passwd))
    text = text.replace("/etc/mosquitto/umlbot.acl", str(DEPLOY / "mosquitto" / "umlbot.acl"))
    assert "listener 1883 127.0.0.1" in text
    text = text.replace("listener 1883 127.0.0.1", f"listener {port} 127.0.0.1")
    if tls is not None:
        tls_text = (DEPLOY / "mosquitto" / "tls.conf").read_text(encoding="utf-8")
        tls_text = tls_text.replace("listener 8883", f"listener {tls_port} 127.0.0.1")
        for name, path in tls.items():
            tls_text = tls_text.replace(f"/etc/mosquitto/certs/{name}", str(path))
        text += "\n" + tls_text
    # Mosquitto started as root drops to the user `mosquitto`, which cannot read the test's
    # private files; `user` keeps the test's own user (ignored when not root).
    user = pwd.getpwuid(os.geteuid()).pw_name
    return text + f"\nuser {user}\npersistence false\nlog_dest stderr\nlog_type all\n"


def make_certificates(directory: Path) -> dict[str, Path]:
    """A CA and a server certificate for 127.0.0.1, as tls.conf describes."""
    openssl = shutil.which("openssl")
    assert openssl, "openssl is needed for the TLS test"

    def run(*args: str) -> None:
        subprocess.run([openssl, *args], cwd=directory, check=True, capture_output=True, timeout=60)

    run("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj", "/CN=umlbot test CA",
        "-keyout", "ca.key", "-out", "ca.crt")
    run("req", "-newkey", "rsa:2048", "-nodes", "-subj", "/CN=127.0.0.1", "-keyout", "server.key",
        "-out", "server.csr")
    (directory / "san.ext").write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n", encoding="utf-8")
    run("x509", "-req", "-in", "server.csr", "-CA", "ca.crt", "-CAkey", "ca.key", "-CAcreateserial",
        "-days", "2", "-extfile", "san.ext", "-out", "server.crt")
    return {name: directory / name for name in ("ca.crt", "server.crt", "server.key")}


def make_auth_files(directory: Path, certs: Path) -> AuthFiles:
    """The recipe's output in `directory` and a CA plus server certificate in `certs`."""
    return AuthFiles(directory, make_auth(directory), make_certificates(certs))


@dataclass(frozen=True)
class AuthFiles:
    """The recipe's output and TLS certificates, made once per module (hashing is slow)."""

    directory: Path
    passwords: dict[str, str]
    certs: dict[str, Path]


def start_secured(kind: str, workdir: Path, auth: AuthFiles) -> SecuredBroker:
    passwords = auth.passwords
    port = free_port()
    log = workdir / f"{kind}.log"
    if kind == "mosquitto":
        binary = find_mosquitto()
        assert binary, "the mosquitto binary is required (apt-get install mosquitto)"
        certs = auth.certs
        tls_port = free_port()
        config = workdir / "mosquitto.conf"
        config.write_text(
            mosquitto_config(port, auth.directory / "mosquitto.passwd", certs, tls_port), encoding="utf-8"
        )
        proc = _start([binary, "-c", str(config)], port, log, workdir)
        deadline = time.monotonic() + 10
        while not port_accepts(tls_port) and time.monotonic() < deadline:
            time.sleep(0.05)
        return SecuredBroker(kind, port, passwords, log, proc, tls_port, certs["ca.crt"])
    argv = [
        sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "DEBUG", "broker",
        "--port", str(port), "--passwd", str(auth.directory / "amqtt.passwd"),
        "--acl", str(DEPLOY / "amqtt" / "acl.yaml"),
    ]
    return SecuredBroker(kind, port, passwords, log, _start(argv, port, log, workdir))




def stop_broker(broker: SecuredBroker) -> None:
    broker.proc.terminate()
    try:
        broker.proc.wait(5)
    except subprocess.TimeoutExpired:
        broker.proc.kill()
        broker.proc.wait(5)


def url_of(broker: SecuredBroker, role: str) -> str:
    """The broker URL with the role's user and password."""
    return f"mqtt://umlbot-{role}:{broker.passwords[role]}@127.0.0.1:{broker.port}"


@dataclass
class Client:
    """A plain paho client that records the CONNACK and every message."""

    client: mqtt.Client
    client_id: str
    connack: Any = None
    connected: threading.Event = field(default_factory=threading.Event)
    messages: queue.Queue[mqtt.MQTTMessage] = field(default_factory=queue.Queue)
    granted: dict[int, list[Any]] = field(default_factory=dict)

    @property
    def accepted(self) -> bool:
        return self.connack is not None and not self.connack.is_failure

    def subscribe(self, topic: str, timeout: float = 5.0) -> bool:
        """Subscribe; True when the broker granted it (SUBACK not 0x80)."""
        done = threading.Event()
        _, mid = self.client.subscribe(topic, 1)
        deadline = time.monotonic() + timeout
        while mid not in self.granted and time.monotonic() < deadline:
            done.wait(0.02)
        assert mid in self.granted, f"no SUBACK for {topic}"
        return not any(code.is_failure for code in self.granted[mid])

    def publish(self, topic: str, payload: str, retain: bool = False) -> None:
        info = self.client.publish(topic, payload, qos=1, retain=retain)
        info.wait_for_publish(5.0)

    def received(self, topic_filter: str, timeout: float) -> list[mqtt.MQTTMessage]:
        """Messages matching the filter that arrive within `timeout` seconds."""
        got: list[mqtt.MQTTMessage] = []
        deadline = time.monotonic() + timeout
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                msg = self.messages.get(timeout=remaining)
            except queue.Empty:
                break
            if mqtt.topic_matches_sub(topic_filter, msg.topic):
                got.append(msg)
        return got

    def wait_for(self, topic: str, payload: str, timeout: float = 5.0) -> list[mqtt.MQTTMessage]:
        """Every message up to and including (topic, payload); fails after `timeout`."""
        seen: list[mqtt.MQTTMessage] = []
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            assert remaining > 0, f"{payload!r} on {topic} never arrived; saw {[m.topic for m in seen]}"
            try:
                msg = self.messages.get(timeout=remaining)
            except queue.Empty:
                continue
            seen.append(msg)
            if msg.topic == topic and msg.payload.decode() == payload:
                return seen


def connect_client(port: int, user: str | None = None, password: str | None = None,
                   client_id: str | None = None, will: str | None = None, ca: Path | None = None) -> Client:
    """A connected (or refused: see `accepted`) paho client; MQTT 3.1.1."""
    cid = client_id or f"test-{uuid.uuid4().hex[:8]}"
    paho = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=cid, protocol=MQTTProtocolVersion.MQTTv311)
    paho.reconnect_delay_set(30, 60)  # a refused client must not retry during the test
    rec = Client(paho, cid)
    if user is not None:
        paho.username_pw_set(user, password)
    if will is not None:
        paho.will_set(will, '{"state":"offline"}', qos=1, retain=True)
    if ca is not None:
        paho.tls_set(ca_certs=str(ca))

    def on_connect(client: mqtt.Client, userdata: Any, flags: Any, rc: Any, props: Any = None) -> None:
        rec.connack = rc
        rec.connected.set()

    def on_subscribe(client: mqtt.Client, userdata: Any, mid: int, codes: Any, props: Any = None) -> None:
        rec.granted[mid] = list(codes)

    def on_disconnect(client: mqtt.Client, userdata: Any, flags: Any, rc: Any, props: Any = None) -> None:
        if rec.connack is None:
            rec.connack = rc
            rec.connected.set()

    paho.on_connect = on_connect
    paho.on_subscribe = on_subscribe
    paho.on_disconnect = on_disconnect
    paho.on_message = lambda client, userdata, msg: rec.messages.put(msg)
    paho.connect("127.0.0.1", port, keepalive=30)
    paho.loop_start()
    if not rec.connected.wait(10):
        paho.loop_stop()
        raise AssertionError(f"no CONNACK from port {port}")
    return rec
