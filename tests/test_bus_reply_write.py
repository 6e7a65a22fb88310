"""A packet published from another thread is written at once, also while the network thread is
inside a paho callback (the dispatcher's reply to the request that callback handed over); only
the network thread itself leaves its packets to its loop while in a callback."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator

import pytest
from conftest import BrokerProcess

from umlbot.services.bus import BrokerSettings, BusConnection, Message

pytestmark = pytest.mark.network


@pytest.fixture
def connection(mosquitto_broker: BrokerProcess) -> Iterator[BusConnection]:
    conn = BusConnection(BrokerSettings.from_url(mosquitto_broker.url), "reply-write-test")
    yield conn
    conn.close()


def test_a_reply_is_written_while_the_network_thread_is_in_a_callback(connection: BusConnection) -> None:
    inside = threading.Event()  # the network thread is in the `hold` callback
    published = threading.Event()  # the dispatcher's publish returned
    seen: dict[str, object] = {}
    replies: queue.Queue[Message] = queue.Queue()

    def go(message: Message) -> None:  # on the dispatcher thread
        assert inside.wait(5.0)
        connection.publish("rw/reply", b"answer", qos=0)
        seen["left_queued"] = connection._client.want_write()  # still waiting for the loop?
        seen["thread"] = threading.current_thread().name
        published.set()

    def hold(message: Message) -> None:  # on the network thread: stays in the callback
        inside.set()
        seen["held_until_published"] = published.wait(5.0)

    def own_write(message: Message) -> None:  # on the network thread: a publish from a callback
        connection.publish("rw/reply", b"from the callback", qos=0)
        seen["own_left_queued"] = connection._client.want_write()

    connection.subscribe("rw/go", go, qos=0)
    connection.subscribe_inline("rw/hold", hold, qos=0)
    connection.subscribe_inline("rw/own", own_write, qos=0)
    connection.subscribe("rw/reply", replies.put, qos=0)
    connection.start(5.0)
    connection.publish("rw/go", b"", qos=0)
    connection.publish("rw/hold", b"", qos=0)
    assert replies.get(timeout=5.0).payload == b"answer"
    assert seen["held_until_published"] is True  # the reply left while the callback still ran
    assert seen["left_queued"] is False  # written by the dispatcher thread itself
    assert seen["thread"] != threading.current_thread().name
    connection.publish("rw/own", b"", qos=0)
    assert replies.get(timeout=5.0).payload == b"from the callback"
    assert seen["own_left_queued"] is True  # the network thread's own: written by its loop after
