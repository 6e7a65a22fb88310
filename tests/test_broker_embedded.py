"""The embedded broker: in-process start/stop, a taken port, passwords, ACLs, `umlbot broker` signals."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import structlog
from conftest import free_port, port_accepts, wait_until

from umlbot.base.errors import ConfigError, NotConnected
from umlbot.base.library import FeatureSpec
from umlbot.services.bus import BrokerSettings, BusClient, BusConnection, ComponentServer, Feature, Message
from umlbot.services.bus.broker import (
    BrokerAcl,
    BrokerLimits,
    EmbeddedBroker,
    broker_config,
    load_acl,
    password_line,
)

pytestmark = pytest.mark.network


@pytest.fixture
def embedded() -> Iterator[EmbeddedBroker]:
    broker = EmbeddedBroker(port=free_port())
    broker.start()
    yield broker
    broker.stop()


def test_embedded_broker_serves_calls_in_process(embedded: EmbeddedBroker) -> None:
    assert embedded.running and embedded.url == f"mqtt://127.0.0.1:{embedded.port}"
    settings = BrokerSettings.from_url(embedded.url)
    features = [Feature(FeatureSpec("value", (), "int"), lambda: 7)]
    with ComponentServer(settings, "car", "Sensor", "hcsr04", features), BusClient(settings, "car") as client:
        assert client.call("Sensor", "value") == 7
    embedded.stop()
    embedded.stop()  # twice is fine
    assert not port_accepts(embedded.port)


def test_a_new_client_gets_retained_messages_only_for_its_own_subscriptions(embedded: EmbeddedBroker) -> None:
    settings = BrokerSettings.from_url(embedded.url)
    watched: set[str] = set()
    both = threading.Event()

    def watch(message: Message) -> None:
        watched.add(message.topic)
        if len(watched) == 2:
            both.set()

    watcher = BusConnection(settings, "test", client_id="watcher")  # holds a filter matching both
    watcher.subscribe("umlbot/car/+/status", watch)
    watcher.start(3.0)
    try:
        with BusConnection(settings, "test", client_id="retainer") as publisher:
            publisher.publish("umlbot/car/Motor/status", b'{"state":"online"}', retain=True)
            publisher.publish("umlbot/car/Sonar/status", b'{"state":"online"}', retain=True)
            assert both.wait(5.0)  # the broker has both (and keeps them: retained)
        got: list[str] = []
        done = threading.Event()

        def keep(message: Message) -> None:
            got.append(message.topic)
            done.set()

        # 3.1.1 from the start: a fall-back from MQTT 5 would replace the paho client hooked below
        newcomer = BusConnection(BrokerSettings.from_url(embedded.url + "?protocol=3.1.1"), "test",
                                 client_id="newcomer")
        newcomer.subscribe("umlbot/car/Sonar/status", keep)
        raw_topics: list[str] = []
        dispatch = newcomer._client.on_message
        assert dispatch is not None

        def every_publish(client: Any, userdata: Any, message: Any) -> None:
            raw_topics.append(message.topic)
            dispatch(client, userdata, message)

        newcomer._client.on_message = every_publish
        newcomer.start(3.0)
        try:
            assert done.wait(5.0)
            time.sleep(0.3)  # anything else amqtt would send arrives meanwhile
        finally:
            newcomer.close()
        # before the fix amqtt also sent umlbot/car/Motor/status (the watcher's filter matches it)
        assert raw_topics == ["umlbot/car/Sonar/status"]
    finally:
        watcher.close()


def test_loopback_by_default() -> None:
    broker = EmbeddedBroker(port=free_port())
    assert broker.host == "127.0.0.1"
    config = broker_config(broker.host, broker.port)
    assert config["listeners"]["default"]["bind"] == f"127.0.0.1:{broker.port}"


def test_taken_port_is_a_clear_config_error() -> None:
    with socket.socket() as squatter:
        squatter.bind(("127.0.0.1", 0))
        squatter.listen()
        port = squatter.getsockname()[1]
        with pytest.raises(ConfigError) as info:
            EmbeddedBroker(port=port).start()
    message = str(info.value)
    assert str(port) in message and "--port" in message and "--broker" in message


def _connect(url: str) -> BusConnection:
    connection = BusConnection(BrokerSettings.from_url(url), "test")
    connection.start(3.0)
    return connection


def test_password_file_refuses_anonymous_and_wrong_passwords(tmp_path: Path) -> None:
    passwd = tmp_path / "passwd"
    passwd.write_text(password_line("robot", "s3cret") + "\n", encoding="utf-8")
    port = free_port()
    with EmbeddedBroker(port=port, passwd_file=passwd):
        good = _connect(f"mqtt://robot:s3cret@127.0.0.1:{port}")
        assert good.connected
        good.close()
        for url in (f"mqtt://127.0.0.1:{port}", f"mqtt://robot:wrong@127.0.0.1:{port}"):
            with pytest.raises(NotConnected) as info:
                _connect(url)
            assert "s3cret" not in str(info.value) and "wrong" not in str(info.value)


def test_missing_password_file_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="does not exist"):
        EmbeddedBroker(port=free_port(), passwd_file=tmp_path / "nope").start()


def test_acl_limits_subscribe_and_publish(tmp_path: Path) -> None:
    passwd = tmp_path / "passwd"
    passwd.write_text(
        password_line("alice", "a") + "\n" + password_line("bob", "b") + "\n", encoding="utf-8"
    )
    acl_file = tmp_path / "acl.yaml"
    acl_file.write_text(
        "acl:\n  alice: ['umlbot/#']\n  bob: ['other/#']\n"
        "publish_acl:\n  alice: ['umlbot/#']\n  bob: ['other/#']\n",
        encoding="utf-8",
    )
    port = free_port()
    with EmbeddedBroker(port=port, passwd_file=passwd, acl=acl_file):
        alice = _connect(f"mqtt://alice:a@127.0.0.1:{port}")
        bob = _connect(f"mqtt://bob:b@127.0.0.1:{port}")
        try:
            alice_got: list[Message] = []
            bob_got: list[Message] = []
            alice_event, bob_event = threading.Event(), threading.Event()
            def recorder(got: list[Message], event: threading.Event) -> Callable[[Message], None]:
                def handler(message: Message) -> None:
                    got.append(message)
                    event.set()

                return handler

            alice.subscribe("umlbot/#", recorder(alice_got, alice_event))
            bob.subscribe("umlbot/#", recorder(bob_got, bob_event))  # refused by the ACL
            time.sleep(0.3)
            bob.publish("umlbot/car/x", b"from bob")  # dropped by the publish ACL
            alice.publish("umlbot/car/x", b"from alice")
            assert alice_event.wait(5.0)
            time.sleep(0.3)
            assert [m.payload for m in alice_got] == [b"from alice"]
            assert bob_got == []
        finally:
            alice.close()
            bob.close()


def test_acl_file_accepts_only_acl_and_publish_acl(tmp_path: Path) -> None:
    good = tmp_path / "good.yaml"
    good.write_text(json.dumps({"acl": {"u": ["a/#"]}, "publish_acl": {"u": ["a/b"]}}), encoding="utf-8")
    assert load_acl(good) == BrokerAcl(acl={"u": ["a/#"]}, publish_acl={"u": ["a/b"]})
    bad = tmp_path / "bad.yaml"
    bad.write_text("subscribe-acl:\n  u: ['a/#']\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="allowed keys: acl, publish_acl"):
        load_acl(bad)
    only_publish = tmp_path / "only_publish.yaml"
    only_publish.write_text("publish_acl:\n  u: ['a/#']\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="no client could subscribe"):
        load_acl(only_publish)
    with pytest.raises(ConfigError, match="cannot read"):
        load_acl(tmp_path / "missing.yaml")


def _umlbot(*args: str) -> list[str]:
    return [sys.executable, "-c", "from umlbot.cli import main; main()", *args]


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_umlbot_broker_shuts_down_cleanly_on_signals(sig: signal.Signals) -> None:
    port = free_port()
    proc = subprocess.Popen(
        _umlbot("broker", "--port", str(port)), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "UMLBOT_LOG_LEVEL": "INFO"},
    )
    try:
        assert wait_until(lambda: port_accepts(port), 10.0)
        client = BusClient(BrokerSettings.from_url(f"mqtt://127.0.0.1:{port}"), "car")
        client.start(5.0)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=10.0)
        assert proc.returncode == 0, err
        assert "broker_stopped" in err
        assert "Traceback" not in err
        assert not port_accepts(port)
        assert wait_until(lambda: not client.connected, 5.0)
        client.close()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)


def test_umlbot_broker_on_a_taken_port_says_what_to_do() -> None:
    with socket.socket() as squatter:
        squatter.bind(("127.0.0.1", 0))
        squatter.listen()
        port = squatter.getsockname()[1]
        result = subprocess.run(_umlbot("broker", "--port", str(port)), capture_output=True, text=True,
                                timeout=30)
    assert result.returncode == 1
    assert f"port {port}" in result.stderr and "--port" in result.stderr
    assert "Traceback" not in result.stderr


def test_hash_password_prints_a_password_file_line() -> None:
    result = subprocess.run(_umlbot("broker", "--hash-password", "robot"), input="pw\npw\n",
                            capture_output=True, text=True, timeout=30)
    assert result.returncode == 0, result.stderr
    user, _, digest = result.stdout.strip().partition(":")
    assert user == "robot" and digest.startswith("$argon2")


def test_port_0_reports_the_port_the_system_gave() -> None:
    with EmbeddedBroker(port=0) as broker:
        assert broker.port != 0
        assert broker.url == f"mqtt://127.0.0.1:{broker.port}"
        assert port_accepts(broker.port)
    proc = subprocess.Popen([str(Path(sys.executable).with_name("umlbot")), "broker", "--port", "0"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        assert proc.stderr is not None
        line = ""
        while "listening on" not in line:
            line = proc.stderr.readline()
            assert line, "the broker ended without saying where it listens"
        port = int(line.rsplit(":", 1)[1])
        assert port != 0 and port_accepts(port)
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(10)


def test_a_retained_message_over_the_limit_is_delivered_but_not_kept(raw_client: Callable[..., Any]) -> None:
    """6 x 10 MB retained took the broker from 43 to 137 MB: past `max_retained_bytes` (and past
    `max_retained_total` for all of them) a message is still delivered, not retained, and logged."""
    limits = BrokerLimits(max_retained_bytes=1000, max_retained_total=2500)
    with EmbeddedBroker(port=free_port(), limits=limits) as broker, \
            structlog.testing.capture_logs() as logs:
        live = raw_client(broker.port)
        live.subscribe("big/#", qos=0)
        publisher = raw_client(broker.port)
        publisher.publish("big/small", b"s" * 1000, retain=True)
        publisher.publish("big/huge", b"h" * 1001, retain=True)
        assert live.get(topic="big/huge").payload == b"h" * 1001  # delivered all the same
        publisher.publish("big/second", b"2" * 1000, retain=True)
        publisher.publish("big/third", b"3" * 1000, retain=True)  # 3000 > 2500 in all
        newcomer = raw_client(broker.port)
        newcomer.subscribe("big/#", qos=0)
        time.sleep(0.3)
        kept = set()
        while not newcomer.messages.empty():
            kept.add(newcomer.messages.get().topic)
        assert kept == {"big/small", "big/second"}
    refused = [e for e in logs if e["event"] == "broker_retained_refused"]
    assert [(e["topic"], e["size"]) for e in refused] == [("big/huge", 1001), ("big/third", 1000)]
    assert "1000 bytes" in refused[0]["reason"] and "2500 bytes" in refused[1]["reason"]


def test_an_offline_session_queues_at_most_max_queued_messages() -> None:
    import paho.mqtt.client as mqtt
    from paho.mqtt.enums import CallbackAPIVersion

    with EmbeddedBroker(port=free_port(), limits=BrokerLimits(max_queued_messages=3)) as broker, \
            structlog.testing.capture_logs() as logs:
        away = mqtt.Client(CallbackAPIVersion.VERSION2, client_id="away", clean_session=False)
        away.connect("127.0.0.1", broker.port)
        away.loop_start()
        away.subscribe("q/#", 1)
        time.sleep(0.3)
        away.disconnect()
        away.loop_stop()
        writer = mqtt.Client(CallbackAPIVersion.VERSION2, client_id="writer")
        writer.connect("127.0.0.1", broker.port)
        writer.loop_start()
        for n in range(10):
            writer.publish(f"q/{n}", str(n), qos=1).wait_for_publish(5)
        writer.disconnect()
        writer.loop_stop()
        got: list[str] = []
        back = mqtt.Client(CallbackAPIVersion.VERSION2, client_id="away", clean_session=False)
        back.on_message = lambda c, u, m: got.append(m.topic)
        back.connect("127.0.0.1", broker.port)
        back.loop_start()
        assert wait_until(lambda: len(got) >= 3, 5.0)
        time.sleep(0.3)
        back.disconnect()
        back.loop_stop()
    assert sorted(got) == ["q/0", "q/1", "q/2"]  # the first three; the newer seven dropped
    assert [e["limit"] for e in logs if e["event"] == "broker_queue_full"] == [3]


def test_exposure_warns_when_other_hosts_reach_a_broker_without_users_or_acl(tmp_path: Path) -> None:
    passwd = tmp_path / "passwd"
    passwd.write_text(password_line("robot", "pw") + "\n", encoding="utf-8")
    acl = {"acl": {"robot": ["umlbot/#"]}}
    assert EmbeddedBroker("127.0.0.1").exposure() is None
    assert EmbeddedBroker("localhost").exposure() is None
    assert EmbeddedBroker("::1").exposure() is None
    for host in ("0.0.0.0", "::", "192.0.2.7"):
        assert "no users" in (EmbeddedBroker(host).exposure() or "")
        assert "without an ACL" in (EmbeddedBroker(host, passwd_file=passwd).exposure() or "")
        assert EmbeddedBroker(host, passwd_file=passwd, acl=acl).exposure() is None


def test_umlbot_broker_bound_to_every_interface_says_so_and_warns() -> None:
    """`--bind 0.0.0.0` used to print `listening on mqtt://127.0.0.1:…` and warn of nothing. Run in
    a network namespace of its own (`unshare -n`: loopback only), so nothing outside can reach it."""
    unshare = shutil.which("unshare")
    assert unshare is not None, "unshare (util-linux) is needed"
    proc = subprocess.Popen([unshare, "-n", *_umlbot("broker", "--bind", "0.0.0.0", "--port", "0")],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            env={**os.environ, "UMLBOT_LOG_LEVEL": "ERROR"})
    try:
        assert proc.stderr is not None
        lines = [proc.stderr.readline(), proc.stderr.readline()]
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(10)
    assert lines[0].startswith("umlbot broker listening on 0.0.0.0:"), lines
    assert "on this machine mqtt://127.0.0.1:" in lines[0]
    assert lines[1].startswith("WARNING: the broker listens on 0.0.0.0, reachable from other hosts, and has "
                               "no users"), lines
    assert "--passwd and --acl" in lines[1]
