"""Availability over broker outages and crashes: reconnects, fail-fast calls, last will."""

from __future__ import annotations

import json
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from conftest import BrokerProcess, RawClient, wait_until

from umlbot.base.errors import CallTimeout, NotConnected
from umlbot.base.library import FeatureSpec, Param
from umlbot.services.bus import BrokerSettings, BusClient, BusConnection, ComponentServer, Feature, Topics

pytestmark = pytest.mark.network

ROBOT = "testcar"
TOPICS = Topics(ROBOT)
RECONNECT_S = 15.0  # back-off tops out at 5 s, so two attempts fit easily


def _features() -> list[Feature]:
    def sleep(seconds: float) -> float:
        time.sleep(seconds)
        return seconds

    return [
        Feature(FeatureSpec("value", (), "int"), lambda: 42),
        Feature(FeatureSpec("sleep", (Param("seconds", "float", 0, 10),), "float"), sleep),
    ]


@pytest.fixture
def pair(broker: BrokerProcess) -> Iterator[tuple[ComponentServer, BusClient]]:
    settings = BrokerSettings.from_url(broker.url)
    server = ComponentServer(settings, ROBOT, "Sensor", "hcsr04", _features())
    client = BusClient(settings, ROBOT, role="test")
    server.start(5.0)
    client.start(5.0)
    yield server, client
    client.close()
    server.stop()


def test_broker_restart_reconnects_both_sides(
    broker: BrokerProcess, pair: tuple[ComponentServer, BusClient], raw_client: Callable[..., RawClient]
) -> None:
    server, client = pair
    assert client.call("Sensor", "value") == 42

    broker.stop()
    assert wait_until(lambda: not client.connected and not server.connected, 5.0)
    started = time.monotonic()
    with pytest.raises(NotConnected):
        client.call("Sensor", "value", timeout=5.0)
    assert time.monotonic() - started < 0.5  # fails fast, does not wait for the time-out

    broker.start()
    assert wait_until(lambda: client.connected and server.connected, RECONNECT_S)
    # the broker lost its retained messages (no persistence): the status must have been republished
    watcher = raw_client(broker)
    watcher.subscribe(TOPICS.status("Sensor"))
    assert json.loads(watcher.get(5.0, TOPICS.status("Sensor")).payload)["state"] == "online"
    # subscriptions were restored on both sides: calls work again
    assert wait_until(lambda: _call_ok(client), 5.0)
    assert client.call("Sensor", "value") == 42
    assert server.connection.counters.connects >= 2


def test_the_same_state_is_published_again_after_a_reconnect(
    broker: BrokerProcess, pair: tuple[ComponentServer, BusClient], raw_client: Callable[..., RawClient]
) -> None:
    """An unchanged state is not published twice on one connection, but a broker without
    persistence forgot it over its restart: the first one after the reconnect goes out."""
    server, _ = pair
    server.publish_state({"value": 42})
    broker.stop()
    assert wait_until(lambda: not server.connected, 5.0)
    broker.start()
    assert wait_until(lambda: server.connected, RECONNECT_S)
    server.publish_state({"value": 42})
    watcher = raw_client(broker)
    watcher.subscribe(TOPICS.state("Sensor"))
    assert json.loads(watcher.get(5.0, TOPICS.state("Sensor")).payload) == {"value": 42}


def _call_ok(client: BusClient) -> bool:
    try:
        return bool(client.call("Sensor", "value", timeout=0.5) == 42)
    except (NotConnected, CallTimeout):
        return False


def test_call_in_flight_fails_fast_when_the_broker_dies(
    broker: BrokerProcess, pair: tuple[ComponentServer, BusClient]
) -> None:
    _, client = pair
    outcome: list[BaseException | Any] = []

    def slow_call() -> None:
        try:
            outcome.append(client.call("Sensor", "sleep", 3.0, timeout=20.0))
        except BaseException as exc:
            outcome.append(exc)

    caller = threading.Thread(target=slow_call)
    started = time.monotonic()
    caller.start()
    time.sleep(0.3)
    broker.kill()
    caller.join(10.0)
    assert not caller.is_alive()
    assert len(outcome) == 1 and isinstance(outcome[0], NotConnected)
    assert time.monotonic() - started < 5.0


def test_async_calls_while_down_fail_fast(
    broker: BrokerProcess, pair: tuple[ComponentServer, BusClient]
) -> None:
    import asyncio

    _, client = pair
    broker.stop()
    assert wait_until(lambda: not client.connected, 5.0)

    async def attempt() -> None:
        await client.acall("Sensor", "value", timeout=5.0)

    started = time.monotonic()
    with pytest.raises(NotConnected):
        asyncio.run(attempt())
    assert time.monotonic() - started < 0.5


def test_start_without_broker_raises_not_connected() -> None:
    from conftest import free_port

    connection = BusConnection(BrokerSettings.from_url(f"mqtt://127.0.0.1:{free_port()}"), "test")
    started = time.monotonic()
    with pytest.raises(NotConnected, match="cannot connect"):
        connection.start(0.5)
    assert time.monotonic() - started < 3.0
    connection.close()  # already closed by the failed start; twice is fine


def test_sigkill_of_a_server_process_leaves_offline_status(
    broker: BrokerProcess,
    server_process: Callable[[str, str], subprocess.Popen[str]],
    raw_client: Callable[..., RawClient],
) -> None:
    proc = server_process(ROBOT, "Doomed")
    watcher = raw_client(broker)
    watcher.subscribe(TOPICS.status("Doomed"))
    assert json.loads(watcher.get(5.0, TOPICS.status("Doomed")).payload)["state"] == "online"
    proc.kill()
    proc.wait(5.0)
    assert json.loads(watcher.get(10.0, TOPICS.status("Doomed")).payload) == {"state": "offline"}
    # retained: a late subscriber sees offline too
    late = raw_client(broker)
    late.subscribe(TOPICS.status("Doomed"))
    assert json.loads(late.get(5.0, TOPICS.status("Doomed")).payload) == {"state": "offline"}


def test_an_unreachable_broker_is_retried_and_the_outage_logged_again_now_and_then(
    caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import logging

    from conftest import free_port

    from umlbot.services.bus import connection as connection_module

    caplog.set_level(logging.DEBUG)
    monkeypatch.setattr(connection_module, "CONNECT_WARN_EVERY_S", 0.6)
    connection = BusConnection(BrokerSettings.from_url(f"mqtt://127.0.0.1:{free_port()}"), "test",
                               reconnect_min_s=0.05, reconnect_max_s=0.1)
    connection.start(timeout=None)  # in the background, as the studio does
    try:
        assert wait_until(lambda: connection.connect_failures >= 12, timeout=10.0)
        assert connection.connect_problem == "Connection refused"
        assert connection.next_attempt_at is not None and connection.next_attempt_at <= time.time() + 0.2
        time.sleep(0.7)
    finally:
        connection.close()
    # the log goes through stdlib logging once configured (caplog), else structlog prints it
    printed = capsys.readouterr()
    lines = [line for line in (printed.out + printed.err).splitlines() if "mqtt_connect_failed" in line]
    failed = lines + [f"[{r.levelname.lower()}] {r.msg}" for r in caplog.records
                      if "mqtt_connect_failed" in str(r.msg)]
    warnings = [line for line in failed if "[warning" in line]
    # every attempt is logged; the first as a warning, then one per CONNECT_WARN_EVERY_S
    assert len(failed) >= 12
    assert 2 <= len(warnings) < len(failed) // 2, (len(warnings), len(failed))


def test_a_message_the_lost_broker_never_acknowledged_is_not_sent_again_after_the_reconnect(
    broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    """paho keeps every unacknowledged QoS 1 message and sends it again after a reconnect. Our
    connections start clean and republish what matters (status, state); anything older is stale:
    a motor command sent again after the orchestrator failed the run, or a state older than the
    one republished at the reconnect (seen: a retained `running: true` over a stopped motor)."""
    connection = BusConnection(BrokerSettings.from_url(broker.url), "test", reconnect_max_s=0.5)
    connection.start(5.0)
    try:
        assert broker.proc is not None
        broker.proc.send_signal(signal.SIGSTOP)  # frozen: the socket takes the packet, no PUBACK
        connection.publish("umlbot-test/stale", b"stale", qos=1, retain=True)
        broker.kill()  # the connection is lost with the message unacknowledged
        assert wait_until(lambda: not connection.connected, 5.0)
        broker.start()
        assert wait_until(lambda: connection.connected, RECONNECT_S)
        connection.publish("umlbot-test/fresh", b"fresh", qos=1, retain=True, wait_s=5.0)
        watcher = raw_client(broker)
        watcher.subscribe("umlbot-test/#")
        assert watcher.get(5.0, "umlbot-test/fresh").payload == b"fresh"
        with pytest.raises(TimeoutError):
            watcher.get(1.0, "umlbot-test/stale")
    finally:
        connection.close()
