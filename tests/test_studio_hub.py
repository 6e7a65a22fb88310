"""What the studio holds for its pages, over real sockets: large retained messages from a real
broker are cut before they reach a page, a page that stops reading is dropped with a close code
and the reason once its queue is full (the others keep going), a page that neither reads nor
answers pings is closed, and a closed page keeps nothing. Asserted on the hub's own accounting
(characters queued per page, pages dropped), not on the process's memory."""

from __future__ import annotations

import asyncio
import base64
import gc
import json
import os
import socket
import struct
import time
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

import aiohttp
from conftest import BrokerProcess, wait_until
from studio_support import events_of

from umlbot.services.bus import BrokerSettings
from umlbot.studio.data import StudioData
from umlbot.studio.hub import CLOSE_TOO_SLOW, MAX_VALUE_CHARS, Hub, Page
from umlbot.studio.server import StudioServer, StudioThread
from umlbot.studio.sources import RobotFollower

ROBOT = "car"
T = TypeVar("T")


@contextmanager
def served(hub: Hub, page_limit: int, heartbeat_s: float = 20.0, broker: BrokerProcess | None = None,
           data: StudioData | None = None) -> Iterator[StudioThread]:
    """A studio serving `hub` (and `data`, else no model) on a free port, following `broker` when
    given."""
    data = data or StudioData(mode="live", robot=ROBOT, source="test", model=None, diagnostics=[])
    server = StudioServer(data, hub=hub, port=0, page_limit=page_limit, heartbeat_s=heartbeat_s)
    follower = RobotFollower(BrokerSettings.from_url(broker.url), ROBOT, hub) if broker else None
    thread = StudioThread(server)
    thread.start()
    try:
        if follower is not None:
            follower.start()
        yield thread
    finally:
        if follower is not None:
            follower.close()
        thread.stop()


def on_loop(thread: StudioThread, fn: Callable[[], T]) -> T:
    """`fn()` on the studio's event loop (where the hub's pages live)."""

    async def call() -> T:
        return fn()

    return asyncio.run_coroutine_threadsafe(call(), thread._loop).result(5.0)


def never_reading(url: str) -> socket.socket:
    """A WebSocket client on a raw socket with a tiny receive buffer that never reads after the
    handshake (the server's sends fill its buffers and then wait)."""
    host, port = url.removeprefix("http://").rstrip("/").rsplit(":", 1)
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect((host, int(port)))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET /ws HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
    head = b""
    while b"\r\n\r\n" not in head:
        head += sock.recv(1)
    assert head.startswith(b"HTTP/1.1 101"), head
    return sock


def read_until_close(sock: socket.socket, timeout: float) -> tuple[int, str] | None:
    """Read the server's frames until its close frame: (code, reason); None when the connection
    ended without one."""
    sock.settimeout(timeout)
    buffer = b""

    def take(n: int) -> bytes:
        nonlocal buffer
        while len(buffer) < n:
            chunk = sock.recv(1 << 20)
            if not chunk:
                raise ConnectionResetError("end of stream")
            buffer += chunk
        out, buffer = buffer[:n], buffer[n:]
        return out

    try:
        while True:
            first, second = take(2)
            length = second & 0x7F
            if length == 126:
                (length,) = struct.unpack("!H", take(2))
            elif length == 127:
                (length,) = struct.unpack("!Q", take(8))
            payload = take(length)
            if first & 0x0F == 0x8:  # close
                (code,) = struct.unpack("!H", payload[:2])
                return code, payload[2:].decode()
    except (ConnectionResetError, TimeoutError, OSError):
        return None


def trace_event(i: int, detail_chars: int = 400) -> dict[str, Any]:
    return {"type": "trace", "time": 1000.0 + i, "robot": ROBOT, "lane": "RaspberryPI", "node": f"n{i % 50}",
            "kind": "action", "duration_ms": 1.0, "level": "info", "detail": "x" * detail_chars, "seq": i + 1}


def push_until_dropped(hub: Hub, thread: StudioThread, detail_chars: int = 400) -> int:
    """Push trace events until the hub drops a page (at most 300 000); how many were pushed."""
    pushed = 0
    while on_loop(thread, lambda: hub.dropped_pages) == 0:
        for _ in range(300):
            hub.push(trace_event(pushed, detail_chars))
            pushed += 1
        time.sleep(0.02)
        assert pushed < 300_000, "no page was dropped"
    return pushed


def test_large_retained_messages_are_cut_and_pages_that_do_not_read_are_dropped_and_forgotten(
        mosquitto_broker: BrokerProcess, raw_client: Any) -> None:
    raw = raw_client(mosquitto_broker)
    big = json.dumps({"blob": "x" * (10 * 1024 * 1024)})  # six 10 MB retained states
    for i in range(6):
        raw.publish(f"umlbot/{ROBOT}/Comp{i}/state", big, retain=True)
    limit = 1024 * 1024
    hub = Hub()
    try:
        with served(hub, page_limit=limit, broker=mosquitto_broker) as thread:
            assert wait_until(lambda: len(hub.retained) == 6, 20.0), "the retained states arrive"
            # a page that reads gets every state, each cut to a note of its size
            frames = _read_frames(thread.url, lambda f: len(events_of(f, "state")) >= 6)
            states = events_of(frames, "state")
            assert {e["component"] for e in states} == {f"Comp{i}" for i in range(6)}
            size = len(json.dumps(json.loads(big), separators=(",", ":")))
            note = (f"(cut by the studio: {size:,} characters of JSON, more than the {MAX_VALUE_CHARS:,} "
                    "it shows)")
            assert all(e["payload"] == note for e in states), states[0]["payload"][:200]
            assert sum(len(json.dumps(f)) for f in frames) < 10 * MAX_VALUE_CHARS
            assert all(len(json.dumps(e)) < MAX_VALUE_CHARS for e in hub.retained.values())

            # eight pages that never read, and one that does
            stuck = [never_reading(thread.url) for _ in range(8)]
            assert wait_until(lambda: on_loop(thread, lambda: len(hub.pages)) == 8, 10.0)
            pages: list[weakref.ref[Page]] = on_loop(thread, lambda: [weakref.ref(p) for p in hub.pages])
            got: list[dict[str, Any]] = []
            reader = _Reader(thread.url, got)
            assert wait_until(lambda: on_loop(thread, lambda: len(hub.pages)) == 9, 10.0)
            for burst in range(60):  # ~15 MB of trace events for each page, in 60 bursts
                for i in range(500):
                    hub.push(trace_event(burst * 500 + i))
                time.sleep(0.05)
            assert wait_until(lambda: on_loop(thread, lambda: hub.dropped_pages) == 8, 10.0)
            # no page ever held more than its limit; the reading page was not dropped and got it all
            assert 0 < hub.peak_queued <= limit, hub.peak_queued
            assert on_loop(thread, lambda: len(hub.pages)) == 1
            assert wait_until(lambda: len(events_of(got, "trace")) == 30_000, 20.0), len(got)
            assert [e["seq"] for e in events_of(got, "trace")] == list(range(1, 30_001))
            # the dropped pages' connections are aborted: their clients see the end
            for sock in stuck:
                read_until_close(sock, 10.0)
                assert ended(sock)
                sock.close()
            reader.close()
            assert wait_until(lambda: on_loop(thread, lambda: (len(hub.pages), hub.queued())) == (0, 0), 10.0)
            gc.collect()
            assert [ref() for ref in pages] == [None] * 8, "a closed page keeps nothing"
    finally:
        for i in range(6):
            raw.publish(f"umlbot/{ROBOT}/Comp{i}/state", b"", retain=True)


def ended(sock: socket.socket) -> bool:
    """The server closed or reset the connection (a read gives the end of the stream)."""
    sock.settimeout(5.0)
    try:
        while sock.recv(1 << 20):
            pass
    except ConnectionResetError:
        pass
    except TimeoutError:
        return False
    return True


def test_a_dropped_page_gets_the_close_code_and_the_reason() -> None:
    hub = Hub()
    limit = 256 * 1024
    with served(hub, page_limit=limit) as thread:
        sock = never_reading(thread.url)
        assert wait_until(lambda: on_loop(thread, lambda: len(hub.pages)) == 1, 10.0)
        push_until_dropped(hub, thread)
        closed = read_until_close(sock, 5.0)  # it reads again at once: the close frame is there
        assert ended(sock)
        sock.close()
    reason = f"the page fell behind: more than {limit:,} characters of frames waiting"
    assert closed == (CLOSE_TOO_SLOW, reason)


def test_a_page_that_neither_reads_nor_answers_pings_is_closed_and_forgotten() -> None:
    hub = Hub()
    with served(hub, page_limit=1 << 20, heartbeat_s=0.5) as thread:
        sock = never_reading(thread.url)
        assert wait_until(lambda: on_loop(thread, lambda: len(hub.pages)) == 1, 10.0)
        ref = on_loop(thread, lambda: weakref.ref(next(iter(hub.pages))))
        assert wait_until(lambda: on_loop(thread, lambda: len(hub.pages)) == 0, 10.0)
        sock.close()
        gc.collect()
        assert ref() is None


class _Reader:
    """A page that reads every frame (an aiohttp client on its own thread)."""

    def __init__(self, url: str, frames: list[dict[str, Any]]) -> None:
        import threading

        self.frames = frames
        self._stop = threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run(url)), daemon=True)
        self._thread.start()

    async def _run(self, url: str) -> None:
        async with aiohttp.ClientSession() as client, client.ws_connect(url.rstrip("/") + "/ws") as ws:
            while not self._stop.is_set():
                try:
                    message = await ws.receive(timeout=0.2)
                except TimeoutError:
                    continue
                if message.type != aiohttp.WSMsgType.TEXT:
                    return
                self.frames.append(json.loads(message.data))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(10.0)


def _read_frames(url: str, until: Callable[[list[dict[str, Any]]], bool]) -> list[dict[str, Any]]:
    from studio_support import read_frames

    return read_frames(url, until, timeout=30.0)
