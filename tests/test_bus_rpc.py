"""Request/reply over real brokers (amqtt and Mosquitto): umlbot client and raw paho clients."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import queue
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import pytest
from conftest import BrokerProcess, RawClient, wait_until

from umlbot.base.catalog import implementations
from umlbot.base.errors import CallTimeout, DriverError, NotConnected, RemoteError
from umlbot.base.library import FeatureSpec, Param
from umlbot.services.bus import (
    BrokerSettings,
    BusClient,
    ComponentServer,
    Feature,
    FeatureError,
    Message,
    Topics,
    reply_value,
)

pytestmark = pytest.mark.network

ROBOT = "testcar"
TOPICS = Topics(ROBOT)


class Probe:
    """A fake component: records what it was asked and fails on demand."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.called = threading.Event()

    def record(self, name: str) -> Callable[..., Any]:
        def handler(*args: Any) -> Any:
            self.calls.append((name, args))
            self.called.set()
            return None

        return handler

    def features(self) -> list[Feature]:
        motor = implementations()["l298n"].features

        def boom() -> None:
            raise ZeroDivisionError("secret internal detail")

        def refuse() -> None:
            raise FeatureError("out_of_range", "the wall is too close")

        def driver() -> None:
            raise DriverError("pigpio daemon not reachable")

        def unjsonable() -> object:
            return object()

        def sleep(seconds: float) -> float:
            time.sleep(seconds)
            return seconds

        return [
            Feature(motor["dutycycle"], self.record("dutycycle")),
            Feature(motor["enabled"], self.record("enabled")),
            Feature(FeatureSpec("value", (), "int"), lambda: 42),
            Feature(FeatureSpec("echo", (Param("text", "str"),), "str"), lambda text: text),
            Feature(
                FeatureSpec("add", (Param("a", "float"), Param("b", "float")), "float"), lambda a, b: a + b
            ),
            Feature(FeatureSpec("boom"), boom),
            Feature(FeatureSpec("refuse"), refuse),
            Feature(FeatureSpec("driver"), driver),
            Feature(FeatureSpec("unjsonable"), unjsonable),
            Feature(FeatureSpec("sleep", (Param("seconds", "float", 0, 5),), "float"), sleep),
        ]


@pytest.fixture
def probe() -> Probe:
    return Probe()


@pytest.fixture
def server(broker: BrokerProcess, probe: Probe) -> Iterator[ComponentServer]:
    srv = ComponentServer(BrokerSettings.from_url(broker.url), ROBOT, "Motor", "l298n", probe.features())
    srv.start(5.0)
    yield srv
    srv.stop()


@pytest.fixture
def client(broker: BrokerProcess, server: ComponentServer) -> Iterator[BusClient]:
    bus = BusClient(BrokerSettings.from_url(broker.url), ROBOT, role="test")
    bus.start(5.0)
    yield bus
    bus.close()


def test_call_returns_values(client: BusClient, probe: Probe) -> None:
    assert client.call("Motor", "dutycycle", 60) is None
    assert probe.calls == [("dutycycle", (60,))]
    assert client.call("Motor", "value") == 42
    assert client.call("Motor", "echo", "héllo ✓") == "héllo ✓"
    assert client.call("Motor", "add", 1.5, 2) == 3.5


@pytest.mark.parametrize(
    ("feature", "args", "code"),
    [
        ("dutycycle", (150,), "out_of_range"),
        ("dutycycle", (-1,), "out_of_range"),
        ("dutycycle", ("fast",), "bad_args"),
        ("dutycycle", (), "bad_args"),
        ("dutycycle", (1, 2), "bad_args"),
        ("enabled", ("yes",), "bad_args"),
        ("fly", (), "unknown_feature"),
        ("refuse", (), "out_of_range"),
        ("driver", (), "driver_error"),
        ("boom", (), "internal"),
        ("unjsonable", (), "internal"),
    ],
)
def test_bad_calls_get_error_replies_and_service_keeps_serving(
    client: BusClient, probe: Probe, feature: str, args: tuple[Any, ...], code: str
) -> None:
    with pytest.raises(RemoteError) as info:
        client.call("Motor", feature, *args)
    assert info.value.code == code
    assert (info.value.component, info.value.feature) == ("Motor", feature)
    assert probe.calls == []  # invalid input never reaches the handler
    assert client.call("Motor", "dutycycle", 10) is None  # the next good call still works


def test_internal_errors_do_not_leak_tracebacks(client: BusClient) -> None:
    with pytest.raises(RemoteError) as info:
        client.call("Motor", "boom")
    assert "secret internal detail" not in info.value.message
    assert "Traceback" not in info.value.message
    assert "ZeroDivisionError" not in info.value.message


def test_call_to_missing_component_times_out(client: BusClient) -> None:
    started = time.monotonic()
    with pytest.raises(CallTimeout) as info:
        client.call("Nobody", "value", timeout=0.3)
    assert 0.25 < time.monotonic() - started < 2.0
    assert isinstance(info.value, TimeoutError)


def test_many_calls_in_flight_from_threads(client: BusClient) -> None:
    def work(i: int) -> float:
        return float(client.call("Motor", "add", i, 0.5, timeout=10.0))

    with ThreadPoolExecutor(max_workers=8) as pool:
        results = list(pool.map(work, range(200)))
    assert results == [i + 0.5 for i in range(200)]


def test_async_calls_run_concurrently(client: BusClient) -> None:
    async def main() -> list[Any]:
        return await asyncio.gather(*(client.acall("Motor", "add", i, 1, timeout=10.0) for i in range(50)))

    assert asyncio.run(main()) == [i + 1.0 for i in range(50)]

    async def failing() -> None:
        await client.acall("Motor", "dutycycle", 500)

    with pytest.raises(RemoteError, match="out_of_range"):
        asyncio.run(failing())

    async def timing_out() -> None:
        await client.acall("Nobody", "value", timeout=0.2)

    with pytest.raises(CallTimeout):
        asyncio.run(timing_out())


def test_status_is_retained_online(broker: BrokerProcess, server: ComponentServer,
                                   raw_client: Callable[..., RawClient]) -> None:
    watcher = raw_client(broker)
    watcher.subscribe(TOPICS.status("Motor"))
    status = json.loads(watcher.get(5.0, TOPICS.status("Motor")).payload)
    assert status["state"] == "online"
    assert status["impl"] == "l298n"
    assert "dutycycle" in status["features"]


def test_stop_publishes_offline(broker: BrokerProcess, probe: Probe,
                                raw_client: Callable[..., RawClient]) -> None:
    srv = ComponentServer(BrokerSettings.from_url(broker.url), ROBOT, "Gone", "l298n", probe.features())
    srv.start(5.0)
    srv.stop()
    srv.stop()  # twice is fine
    watcher = raw_client(broker)
    watcher.subscribe(TOPICS.status("Gone"))
    assert json.loads(watcher.get(5.0, TOPICS.status("Gone")).payload)["state"] == "offline"


def test_publish_state_is_retained(broker: BrokerProcess, server: ComponentServer,
                                   raw_client: Callable[..., RawClient]) -> None:
    server.publish_state({"dutycycle": 60, "enabled": True})
    time.sleep(0.2)  # let the retained message reach the broker before a new subscriber comes
    watcher = raw_client(broker)
    watcher.subscribe(TOPICS.state("Motor"))
    assert json.loads(watcher.get(5.0, TOPICS.state("Motor")).payload) == {"dutycycle": 60, "enabled": True}


def test_an_unchanged_state_is_not_published_again(broker: BrokerProcess, server: ComponentServer,
                                                  raw_client: Callable[..., RawClient]) -> None:
    """A state equal to the last one published says nothing new: only changes go out."""
    watcher = raw_client(broker)
    watcher.subscribe(TOPICS.state("Motor"))
    for duty in (60, 60, 60, 70, 70, 60):
        server.publish_state({"dutycycle": duty})
    seen = []
    with contextlib.suppress(TimeoutError):
        while True:
            seen.append(json.loads(watcher.get(1.0, TOPICS.state("Motor")).payload)["dutycycle"])
    assert seen == [60, 70, 60]


def test_raw_paho_bare_payload_is_fire_and_forget(broker: BrokerProcess, server: ComponentServer,
                                                  probe: Probe, raw_client: Callable[..., RawClient]) -> None:
    raw = raw_client(broker)
    raw.publish(TOPICS.call("Motor", "dutycycle"), b"60")
    assert probe.called.wait(5.0)
    probe.called.clear()
    raw.publish(TOPICS.call("Motor", "enabled"), b"[true]")
    assert probe.called.wait(5.0)
    assert probe.calls == [("dutycycle", (60,)), ("enabled", (True,))]


def test_raw_paho_envelope_gets_a_reply(broker: BrokerProcess, server: ComponentServer,
                                        probe: Probe, raw_client: Callable[..., RawClient]) -> None:
    raw = raw_client(broker)
    raw.subscribe("raw/replies")
    request = {"id": "r1", "reply_to": "raw/replies", "args": []}
    raw.publish(TOPICS.call("Motor", "value"), json.dumps(request))
    assert json.loads(raw.get(5.0, "raw/replies").payload) == {"id": "r1", "ok": True, "value": 42}
    raw.publish(TOPICS.call("Motor", "dutycycle"),
                json.dumps({"id": "r2", "reply_to": "raw/replies", "args": [101]}))
    reply = json.loads(raw.get(5.0, "raw/replies").payload)
    assert reply["id"] == "r2" and reply["ok"] is False and reply["error"]["code"] == "out_of_range"
    assert "value" not in reply


@pytest.mark.parametrize(
    ("payload", "code"),
    [
        (b'{"id": "x", "reply_to": "raw/replies", "args": [1], "bogus": 1}', "bad_request"),
        (b'{"id": "x", "reply_to": "raw/replies", "args": ["sixty"]}', "bad_args"),
        (b'{"id": "x", "reply_to": "raw/replies", "args": [1, 2, 3]}', "bad_args"),
        (b'{"id": "x", "reply_to": "raw/replies", "args": [1000]}', "out_of_range"),
    ],
)
def test_raw_paho_bad_envelopes(broker: BrokerProcess, server: ComponentServer, probe: Probe,
                                raw_client: Callable[..., RawClient], payload: bytes, code: str) -> None:
    raw = raw_client(broker)
    raw.subscribe("raw/replies")
    raw.publish(TOPICS.call("Motor", "dutycycle"), payload)
    reply = json.loads(raw.get(5.0, "raw/replies").payload)
    assert reply == {"id": "x", "ok": False, "error": {"code": code, "message": reply["error"]["message"]}}
    assert probe.calls == []


def test_unknown_feature_from_raw_paho(broker: BrokerProcess, server: ComponentServer,
                                       raw_client: Callable[..., RawClient]) -> None:
    raw = raw_client(broker)
    raw.subscribe("raw/replies")
    raw.publish(TOPICS.call("Motor", "warp"), json.dumps({"id": 5, "reply_to": "raw/replies"}))
    reply = json.loads(raw.get(5.0, "raw/replies").payload)
    assert reply["id"] == 5 and reply["error"]["code"] == "unknown_feature"
    assert "dutycycle" in reply["error"]["message"]


def test_malformed_json_is_survived(client: BusClient, broker: BrokerProcess, probe: Probe,
                                    raw_client: Callable[..., RawClient]) -> None:
    raw = raw_client(broker)
    for junk in (b"{not json", b"\xff\xfe\x00", b'{"id": "a", "reply_to": ', b"[1, 2"):
        raw.publish(TOPICS.call("Motor", "dutycycle"), junk)
    assert client.call("Motor", "dutycycle", 30) is None
    assert probe.calls == [("dutycycle", (30,))]


def test_one_megabyte_payloads(client: BusClient, broker: BrokerProcess, probe: Probe,
                               raw_client: Callable[..., RawClient]) -> None:
    big = "x" * (1024 * 1024)
    with pytest.raises(RemoteError) as info:
        client.call("Motor", "echo", big, timeout=10.0)
    assert info.value.code == "payload_too_large"
    raw = raw_client(broker)
    raw.subscribe("raw/replies")
    envelope = json.dumps({"id": "big", "reply_to": "raw/replies", "args": [big]})
    raw.publish(TOPICS.call("Motor", "echo"), envelope)
    reply = json.loads(raw.get(10.0, "raw/replies").payload)
    assert reply["id"] == "big" and reply["error"]["code"] == "payload_too_large"
    raw.publish(TOPICS.call("Motor", "dutycycle"), b"[" + b"1," * (512 * 1024) + b"1]")  # bare, no reply
    assert client.call("Motor", "echo", "small") == "small"
    assert probe.calls == []


def test_fire_and_forget_send(client: BusClient, probe: Probe) -> None:
    client.send("Motor", "dutycycle", 77)
    assert probe.called.wait(5.0)
    assert probe.calls == [("dutycycle", (77,))]


def test_client_subscribe_and_publish_passthrough(client: BusClient) -> None:
    got: list[Message] = []
    event = threading.Event()

    def on_signal(message: Message) -> None:
        got.append(message)
        event.set()

    client.subscribe(TOPICS.signals, on_signal)
    deadline = time.monotonic() + 5.0
    while not event.is_set() and time.monotonic() < deadline:
        client.publish(TOPICS.signal("obstacle"), {"cm": 12}, qos=1)
        event.wait(0.2)
    assert got and got[0].topic == TOPICS.signal("obstacle") and got[0].json() == {"cm": 12}


def test_closed_client_refuses_calls(broker: BrokerProcess, server: ComponentServer) -> None:
    bus = BusClient(BrokerSettings.from_url(broker.url), ROBOT)
    with pytest.raises(NotConnected):
        bus.call("Motor", "value")  # never started
    bus.start(5.0)
    assert bus.call("Motor", "value") == 42
    bus.close()
    bus.close()
    with pytest.raises(NotConnected):
        bus.call("Motor", "value")


def test_handlers_run_off_the_network_thread(broker: BrokerProcess) -> None:
    threads: list[str] = []
    srv = ComponentServer(
        BrokerSettings.from_url(broker.url), ROBOT, "Threads", "x",
        [Feature(FeatureSpec("where", (), "str"), lambda: threads.append(threading.current_thread().name))],
    )
    with srv, BusClient(BrokerSettings.from_url(broker.url), ROBOT) as bus:
        bus.call("Threads", "where")
    assert threads and threads[0].startswith("bus-dispatch")
    assert wait_until(lambda: not srv.connected, 2.0)


def _unix_sockets() -> set[str]:
    """The inodes of this process's open Unix sockets (Linux)."""
    links = set()
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):  # the descriptor listdir itself used is gone
            links.add(os.readlink(f"/proc/self/fd/{fd}"))
    with open("/proc/net/unix") as table:
        unix = {line.split()[6] for line in list(table)[1:]}
    return {link[8:-1] for link in links if link.startswith("socket:[")} & unix


def test_a_burst_is_handled_in_order_and_close_leaves_no_socket_open(broker: BrokerProcess,
                                                                     probe: Probe) -> None:
    # the dispatcher's mailbox wakes it with a byte on a Unix socket pair, closed with the connection
    before = _unix_sockets()
    srv = ComponentServer(BrokerSettings.from_url(broker.url), ROBOT, "Motor", "l298n", probe.features())
    srv.start(5.0)
    bus = BusClient(BrokerSettings.from_url(broker.url), ROBOT, role="burst")
    bus.start(5.0)
    assert len(_unix_sockets() - before) == 4  # two pairs
    percents = [*range(101), *range(99, -1, -1)]  # up and down again
    for percent in percents:
        bus.send("Motor", "dutycycle", percent)
    assert wait_until(lambda: len(probe.calls) == len(percents), 5.0), len(probe.calls)
    assert [args[0] for _, args in probe.calls] == percents
    bus.close()
    srv.stop()
    assert wait_until(lambda: not _unix_sockets() - before, 2.0), _unix_sockets() - before


def test_start_returns_once_the_subscriptions_are_confirmed(
    broker: BrokerProcess, probe: Probe, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(broker)
    raw.subscribe("raw/early")
    for attempt in range(5):
        srv = ComponentServer(BrokerSettings.from_url(broker.url), ROBOT, f"Early{attempt}", "l298n",
                              probe.features())
        srv.start(5.0)
        try:
            # published the moment start() returns: the broker must already route it to the server
            raw.publish(TOPICS.call(f"Early{attempt}", "value"),
                        json.dumps({"id": attempt, "reply_to": "raw/early"}))
            assert json.loads(raw.get(5.0, "raw/early").payload) == {"id": attempt, "ok": True, "value": 42}
        finally:
            srv.stop()
    assert srv.connection.wait_subscribed(0.1)


def test_cancelled_async_calls_are_forgotten(client: BusClient) -> None:
    async def main() -> None:
        task = asyncio.ensure_future(client.acall("Nobody", "value", timeout=30.0))
        await asyncio.sleep(0.05)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task

    asyncio.run(main())
    assert client._pending == {}
    assert client.call("Motor", "value") == 42


def test_request_then_calls_back_with_the_reply_or_the_lost_connection(
    broker: BrokerProcess, server: ComponentServer
) -> None:
    # the ROS 2 bridge's way: no Future, the function runs on the network thread
    got: queue.Queue[tuple[str, Any, Any]] = queue.Queue()
    bus = BusClient(BrokerSettings.from_url(broker.url), ROBOT, role="test")
    bus.start(5.0)
    try:
        noted = bus.new_request_id()
        assert bus.request_then("Motor", "add", 1, 2, timeout=5.0, request_id=noted,
                                then=lambda *outcome: got.put(outcome)) == noted
        assert got.get(timeout=5) == (noted, {"id": noted, "ok": True, "value": 3}, None)
        assert bus.new_request_id() != noted
        other = bus.request_then("Motor", "refuse", then=lambda *outcome: got.put(outcome))
        request_id, reply, error = got.get(timeout=5)
        assert (request_id, reply["ok"], error) == (other, False, None)
        assert reply["error"]["code"] == "out_of_range"
        assert reply_value_error(reply) == "out_of_range"
        slow = bus.request_then("Motor", "sleep", 2.0, timeout=5.0, then=lambda *outcome: got.put(outcome))
    finally:
        bus.close()  # the call in flight is told the connection is gone
    request_id, reply, error = got.get(timeout=5)
    assert (request_id, reply, type(error)) == (slow, None, NotConnected)
    assert bus._pending == {}


def reply_value_error(reply: dict[str, Any]) -> str:
    try:
        reply_value(reply, "Motor", "refuse")
    except RemoteError as exc:
        return exc.code
    raise AssertionError("an error reply unwraps as RemoteError")
