"""mqtts:// against a Mosquitto TLS listener with a throw-away CA; credentials stay out of logs."""

from __future__ import annotations

import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import structlog
from conftest import find_mosquitto, free_port, port_accepts, wait_until

from umlbot.base.errors import NotConnected
from umlbot.base.library import FeatureSpec
from umlbot.services.bus import (
    BrokerSettings,
    BusClient,
    BusConnection,
    ComponentServer,
    EmbeddedBroker,
    Feature,
    password_line,
)

pytestmark = pytest.mark.network


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True, timeout=60)


@pytest.fixture
def tls_broker(tmp_path: Path) -> Iterator[tuple[int, Path]]:
    """A Mosquitto TLS listener on 127.0.0.1 signed by a fresh CA; yields (port, CA file)."""
    if shutil.which("openssl") is None:
        pytest.fail("the openssl binary is needed to make test certificates")
    mosquitto = find_mosquitto()
    if mosquitto is None:
        pytest.fail("the mosquitto binary is required (apt-get install mosquitto)")
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-keyout", "ca.key", "-out", "ca.pem",
             "-days", "2", "-subj", "/CN=umlbot test CA", cwd=tmp_path)
    _openssl("req", "-newkey", "rsa:2048", "-nodes", "-keyout", "server.key", "-out", "server.csr",
             "-subj", "/CN=127.0.0.1", cwd=tmp_path)
    (tmp_path / "ext.cnf").write_text("subjectAltName=IP:127.0.0.1\n", encoding="utf-8")
    _openssl("x509", "-req", "-in", "server.csr", "-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial",
             "-out", "server.pem", "-days", "2", "-extfile", "ext.cnf", cwd=tmp_path)
    port = free_port()
    config = tmp_path / "mosquitto.conf"
    config.write_text(
        f"listener {port} 127.0.0.1\ncafile {tmp_path / 'ca.pem'}\ncertfile {tmp_path / 'server.pem'}\n"
        f"keyfile {tmp_path / 'server.key'}\nallow_anonymous true\npersistence false\n"
        # run as root, mosquitto would drop to user `mosquitto`, who cannot read pytest's tmp dirs
        "user root\n",
        encoding="utf-8",
    )
    proc = subprocess.Popen([mosquitto, "-c", str(config)], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        assert wait_until(lambda: port_accepts(port), 10.0), "TLS mosquitto did not start"
        yield port, tmp_path / "ca.pem"
    finally:
        proc.kill()
        proc.wait(5)


def test_calls_over_tls(tls_broker: tuple[int, Path]) -> None:
    port, ca = tls_broker
    settings = BrokerSettings.from_url(f"mqtts://127.0.0.1:{port}?ca={ca}")
    assert settings.tls
    features = [Feature(FeatureSpec("value", (), "int"), lambda: 99)]
    with ComponentServer(settings, "tlscar", "Sensor", "hcsr04", features), \
            BusClient(BrokerSettings.from_url(f"mqtts://127.0.0.1:{port}", ca_file=ca), "tlscar") as client:
        assert client.call("Sensor", "value") == 99


FRESH_TLS_CALL = """
import sys
from umlbot.services.bus import BrokerSettings, BusClient, ComponentServer, Feature
from umlbot.base.library import FeatureSpec
assert "ssl" not in sys.modules  # paho's ssl is deferred (umlbot.base.lazy): imported by the first TLS use
port, ca = int(sys.argv[1]), sys.argv[2]
features = [Feature(FeatureSpec("value", (), "int"), lambda: 7)]
with ComponentServer(BrokerSettings.from_url(f"mqtts://127.0.0.1:{port}?ca={ca}"), "tlscar", "Sensor",
                     "hcsr04", features), \
        BusClient(BrokerSettings.from_url(f"mqtts://127.0.0.1:{port}", ca_file=ca), "tlscar") as client:
    assert client.call("Sensor", "value") == 7
assert "ssl" in sys.modules
print("tls call ok")
"""


def test_tls_works_in_a_process_that_had_not_imported_ssl(tls_broker: tuple[int, Path]) -> None:
    port, ca = tls_broker
    result = subprocess.run([sys.executable, "-c", FRESH_TLS_CALL, str(port), str(ca)], capture_output=True,
                            text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout.splitlines()[-1] == "tls call ok"


def test_tls_refuses_an_unknown_ca_unless_insecure(tls_broker: tuple[int, Path]) -> None:
    port, _ = tls_broker
    strict = BusConnection(BrokerSettings.from_url(f"mqtts://127.0.0.1:{port}"), "test")
    with pytest.raises(NotConnected):
        strict.start(2.0)
    relaxed = BusConnection(BrokerSettings.from_url(f"mqtts://127.0.0.1:{port}?insecure=1"), "test")
    relaxed.start(5.0)
    assert relaxed.connected
    relaxed.close()


def test_passwords_never_reach_the_logs(tmp_path: Path) -> None:
    passwd = tmp_path / "passwd"
    passwd.write_text(password_line("robot", "right-one") + "\n", encoding="utf-8")
    port = free_port()
    with EmbeddedBroker(port=port, passwd_file=passwd), structlog.testing.capture_logs() as logs:
        good = BusConnection(BrokerSettings.from_url(f"mqtt://robot:right-one@127.0.0.1:{port}"), "test")
        good.start(5.0)
        good.close()
        bad = BusConnection(BrokerSettings.from_url(f"mqtt://robot:wrong-one@127.0.0.1:{port}"), "test")
        with pytest.raises(NotConnected) as info:
            bad.start(1.0)
    text = repr(logs) + str(info.value) + repr(good.settings) + repr(bad)
    assert logs, "expected connection log lines"
    assert "right-one" not in text and "wrong-one" not in text
    assert "robot:***@" in text
