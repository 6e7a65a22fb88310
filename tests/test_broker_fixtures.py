"""The broker fixtures themselves: real brokers that answer, restart on the same port and die."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from conftest import BrokerProcess, RawClient, port_accepts

pytestmark = pytest.mark.network


def test_broker_routes_messages(broker: BrokerProcess, raw_client: Callable[..., RawClient]) -> None:
    assert broker.url == f"mqtt://127.0.0.1:{broker.port}"
    sub = raw_client(broker)
    sub.subscribe("fixture/test")
    raw_client(broker).publish("fixture/test", b"hello")
    assert sub.get(5.0, "fixture/test").payload == b"hello"


def test_broker_restarts_on_the_same_port(
    broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    port = broker.port
    broker.stop()
    assert not port_accepts(port)
    broker.start()
    assert broker.port == port and port_accepts(port)
    sub = raw_client(broker)
    sub.subscribe("fixture/again")
    sub.publish("fixture/again", b"1")
    assert sub.get(5.0).payload == b"1"


def test_broker_kill_closes_the_port(broker: BrokerProcess) -> None:
    broker.kill()
    assert not broker.running
    assert not port_accepts(broker.port)
