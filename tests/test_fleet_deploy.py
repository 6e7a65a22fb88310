"""A fleet set up by the shipped tooling: deploy/fleet.py hub writes the hub's users and ACL,
deploy/install.sh --hub writes a robot's bridge; real Mosquitto processes, TLS on the hub.

Robot A's hub credentials cannot call robot B's features, publish B's status or read anything
outside umlbot/A/#; A's bridge carries A's retained status to the hub and the hub's requests
to A, once each.
"""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from secured_brokers import Client, connect_client, make_certificates

from umlbot.fleet import Mosquitto, free_port, hub_conf

REPO = Path(__file__).resolve().parent.parent
FLEET = REPO / "deploy" / "fleet.py"
INSTALL = REPO / "deploy" / "install.sh"
REFERENCE_DEPLOYMENT = REPO / "deploy" / "mosquitto" / "reference-deployment.txt"


def credentials(file: Path) -> tuple[str, str]:
    line = next(x for x in file.read_text(encoding="utf-8").splitlines() if x.startswith("UMLBOT_"))
    parts = urlsplit(line.partition("=")[2])
    assert parts.username and parts.password
    return unquote(parts.username), unquote(parts.password)


@dataclass
class HubSetup:
    hub: Mosquitto
    tls_port: int
    out: Path
    ca: Path

    def client(self, file: str) -> Client:
        user, password = credentials(self.out / file)
        client = connect_client(self.tls_port, user, password, ca=self.ca)
        assert client.accepted, f"{user} refused by the hub"
        return client


@pytest.fixture(scope="module")
def hub(tmp_path_factory: pytest.TempPathFactory) -> Iterator[HubSetup]:
    work = tmp_path_factory.mktemp("hub")
    tls_port = free_port()
    out = work / "hub"
    result = subprocess.run(
        [sys.executable, str(FLEET), "hub", "--robots", "alpha", "bravo", "--host", "127.0.0.1",
         "--tls-port", str(tls_port), "--out", str(out)],
        capture_output=True, text=True, timeout=120, check=False,
    )
    assert result.returncode == 0, result.stderr
    for name in ("robot-alpha.hub", "robot-bravo.hub", "viewer.env", "operator.env", "mosquitto.passwd"):
        assert (out / name).stat().st_mode & 0o077 == 0, f"{name} is readable by others"
        if name != "mosquitto.passwd":
            assert credentials(out / name)[1] not in result.stdout + result.stderr
    acl = (out / "mosquitto.acl").read_text(encoding="utf-8")
    assert "user umlbot-robot-alpha\ntopic readwrite umlbot/alpha/#\n" in acl
    certs_dir = work / "certs"
    certs_dir.mkdir()
    certs = make_certificates(certs_dir)
    config = hub_conf(out / "mosquitto.passwd", out / "mosquitto.acl", tls_port, None, certs,
                      tls_bind="127.0.0.1")
    broker = Mosquitto("hub", free_port(), config, work)
    broker.start()
    try:
        yield HubSetup(broker, tls_port, out, certs["ca.crt"])
    finally:
        broker.stop()


def test_hub_refuses_anonymous_and_wrong_passwords(hub: HubSetup) -> None:
    assert not connect_client(hub.tls_port, ca=hub.ca).accepted
    user, _ = credentials(hub.out / "robot-alpha.hub")
    assert not connect_client(hub.tls_port, user, "not-the-password", ca=hub.ca).accepted


def test_robot_cannot_act_as_another_robot(hub: HubSetup) -> None:
    viewer = hub.client("viewer.env")
    assert viewer.subscribe("umlbot/#")
    alpha = hub.client("robot-alpha.hub")
    # A calls B's motor and poses as B's motor and orchestrator: the hub drops all of it.
    alpha.publish("umlbot/bravo/LeftActuator/call/dutycycle", "60")
    alpha.publish("umlbot/bravo/LeftActuator/status", '{"state":"offline"}', retain=True)
    alpha.publish("umlbot/bravo/orchestrator/status", '{"state":"offline"}', retain=True)
    alpha.publish("umlbot/alpha/marker", "1")  # its own topics pass: everything before it was handled
    seen = viewer.wait_for("umlbot/alpha/marker", "1")
    assert [m.topic for m in seen if m.topic.startswith("umlbot/bravo/")] == []
    # nothing of B was retained either
    late = hub.client("viewer.env")
    assert late.subscribe("umlbot/bravo/#")
    assert late.received("umlbot/bravo/#", 0.5) == []


def test_robot_reads_only_its_own_topics(hub: HubSetup) -> None:
    alpha = hub.client("robot-alpha.hub")
    alpha.subscribe("umlbot/#")
    alpha.subscribe("#")
    bravo = hub.client("robot-bravo.hub")
    operator = hub.client("operator.env")
    bravo.publish("umlbot/bravo/LeftActuator/state", '{"dutycycle": 10}', retain=True)
    operator.publish("umlbot/bravo/LeftActuator/call/dutycycle", "30")
    operator.publish("umlbot/alpha/LeftActuator/call/dutycycle", "40")
    seen = alpha.wait_for("umlbot/alpha/LeftActuator/call/dutycycle", "40")
    assert [m.topic for m in seen if not m.topic.startswith("umlbot/alpha/")] == []


def test_operator_cannot_pose_as_a_robot(hub: HubSetup) -> None:
    viewer = hub.client("viewer.env")
    assert viewer.subscribe("umlbot/#")
    operator = hub.client("operator.env")
    operator.publish("umlbot/alpha/LeftActuator/status", '{"state":"offline"}')
    operator.publish("umlbot/alpha/orchestrator/exit", '{"reason":"test"}')
    seen = viewer.wait_for("umlbot/alpha/orchestrator/exit", '{"reason":"test"}')
    assert [m.topic for m in seen if m.topic.endswith("/status")] == []


def test_install_writes_a_bridge_that_works_over_tls(hub: HubSetup, tmp_path: Path) -> None:
    root = tmp_path / "root"
    result = subprocess.run(
        ["bash", str(INSTALL), "--root", str(root), "--no-venv", "--python", sys.executable,
         "--robot", "alpha",
         "--deployment", str(REFERENCE_DEPLOYMENT), "--hub", f"mqtts://127.0.0.1:{hub.tls_port}",
         "--hub-credentials", str(hub.out / "robot-alpha.hub"), "--hub-ca", str(hub.ca)],
        capture_output=True, text=True, timeout=180, check=False,
    )
    assert result.returncode == 0, result.stderr
    conf_file = root / "etc/mosquitto/conf.d/umlbot-bridge.conf"
    assert conf_file.stat().st_mode & 0o777 == 0o640
    _, password = credentials(hub.out / "robot-alpha.hub")
    assert password not in result.stdout + result.stderr
    assert (root / "etc/mosquitto/certs/umlbot-hub-ca.crt").read_bytes() == hub.ca.read_bytes()
    conf = conf_file.read_text(encoding="utf-8")
    assert "topic # out 1 umlbot/alpha/ umlbot/alpha/" in conf
    assert f"remote_password {password}" in conf
    ca_path = "/etc/mosquitto/certs/umlbot-hub-ca.crt"
    conf = conf.replace(ca_path, str(root / ca_path.lstrip("/")))
    leaf = Mosquitto("leaf-alpha", free_port(), "allow_anonymous true\n" + conf, tmp_path)
    viewer = hub.client("viewer.env")
    assert viewer.subscribe("umlbot/alpha/#")
    operator = hub.client("operator.env")
    leaf.start()
    try:
        local = connect_client(leaf.port)
        assert local.subscribe("umlbot/#")
        # the bridge is up once the leaf says so on the hub
        viewer.wait_for("umlbot/alpha/_bridge/connected", "1", timeout=15)
        local.publish("umlbot/alpha/LeftActuator/status", '{"state":"online"}', retain=True)
        viewer.wait_for("umlbot/alpha/LeftActuator/status", '{"state":"online"}')
        # a request from the hub reaches the robot once, and does not come back to the hub
        operator.publish("umlbot/alpha/LeftActuator/call/dutycycle", "55")
        local.wait_for("umlbot/alpha/LeftActuator/call/dutycycle", "55")
        again = local.received("umlbot/alpha/LeftActuator/call/#", 0.5)
        assert again == []
        on_hub = viewer.received("umlbot/alpha/LeftActuator/call/#", 0.5)
        assert len(on_hub) == 1  # the hub's own copy; never a second one echoed by the bridge
        # a status the hub holds for the robot never flows into the robot
        operator_status = hub.client("robot-alpha.hub")
        operator_status.publish("umlbot/alpha/Sensor/status", '{"state":"offline"}', retain=True)
        assert local.received("umlbot/alpha/Sensor/status", 0.5) == []
    finally:
        leaf.stop()


def test_the_bridge_works_on_a_robot_broker_with_users(hub: HubSetup, tmp_path: Path) -> None:
    """A robot installed with --secure (every client logs in, the ACL of deploy/mosquitto): its
    broker's bridge still carries the status out and the hub's requests in."""
    from secured_brokers import make_auth, mosquitto_config

    from umlbot.fleet import Hub, bridge_conf

    passwords = make_auth(tmp_path / "auth")
    port = free_port()
    secured = mosquitto_config(port, tmp_path / "auth" / "mosquitto.passwd")
    # Mosquitto() adds the listener and the user to run as
    secured = "\n".join(line for line in secured.splitlines()
                         if line != f"listener {port} 127.0.0.1" and not line.startswith("user ")) + "\n"
    user, password = credentials(hub.out / "robot-alpha.hub")
    bridge = bridge_conf("alpha", Hub("127.0.0.1", hub.tls_port, True, user, password, hub.ca))
    leaf = Mosquitto("leaf-secured", port, secured + bridge, tmp_path)
    viewer = hub.client("viewer.env")
    assert viewer.subscribe("umlbot/alpha/#")
    operator = hub.client("operator.env")
    leaf.start()
    try:
        viewer.wait_for("umlbot/alpha/_bridge/connected", "1", timeout=15)
        motor = connect_client(port, "umlbot-motor", passwords["motor"])
        assert motor.accepted
        assert motor.subscribe("umlbot/alpha/LeftActuator/call/#")
        motor.publish("umlbot/alpha/LeftActuator/status", '{"state":"online"}', retain=True)
        viewer.wait_for("umlbot/alpha/LeftActuator/status", '{"state":"online"}')
        operator.publish("umlbot/alpha/LeftActuator/call/dutycycle", "35")
        motor.wait_for("umlbot/alpha/LeftActuator/call/dutycycle", "35")
    finally:
        leaf.stop()
