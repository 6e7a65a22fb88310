"""The recorder's cheaper paths write what rosbags' did: the CDR of trace events and calls made in
one `struct` pass (umlbot/record/cdr.py) against rosbags' serialiser of the `Builder`'s message,
MCAP message records in one pack against rosbags' storage, calls paired without the monitor's
tables, and a bus connection reading its socket in blocks (`read_ahead`) against every message
published, whole and in order."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess, wait_until
from hypothesis import given, settings
from hypothesis import strategies as st
from record_support import read_with_mcap

from umlbot.base import rosmsg
from umlbot.record import cdr
from umlbot.record.bag import McapBag
from umlbot.record.messages import CALL, TRACE, Builder, to_ns
from umlbot.record.recorder import Recorder, open_file_recorder
from umlbot.services.bus import BrokerSettings, BusConnection, Message

STORE = rosmsg.typestore("record")
BUILD = Builder(STORE)

_text = st.text(max_size=40)
_number = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-2**70, 2**70), st.booleans(),
                    st.just(1_795_000_000.123456))
_wire = st.one_of(st.none(), _text, _number, st.lists(st.integers(), max_size=3),
                  st.dictionaries(st.text(max_size=5), st.integers(), max_size=2))


@settings(max_examples=300, deadline=None)
@given(event=st.dictionaries(
    st.sampled_from(["lane", "node", "kind", "start", "end", "duration_ms", "value", "level", "error",
                     "detail", "seq"]),
    st.one_of(_wire, _number, st.integers(-5, 2**64 + 5)), max_size=11))
def test_a_trace_event_is_the_cdr_rosbags_makes(event: dict[str, Any]) -> None:
    try:
        message = BUILD.trace(event)
    except OverflowError:  # a time of 1e300 s: skipped by both (the recorder logs it)
        with pytest.raises(OverflowError):
            cdr.trace_event(event)
        return
    data, stamp_ns = cdr.trace_event(event)
    assert data == bytes(STORE.serialize_cdr(message, TRACE))
    assert stamp_ns == to_ns(message.end)


@settings(max_examples=300, deadline=None)
@given(at=_number.filter(lambda v: not isinstance(v, bool)), component=_text, feature=_text,
       call_id=st.one_of(st.none(), _text), args=st.one_of(st.none(), st.lists(_wire, max_size=3)),
       ok=st.one_of(st.none(), st.booleans()), value=_wire, error=st.one_of(st.none(), _text),
       latency_ms=st.one_of(st.none(), st.floats(allow_nan=False, allow_infinity=False)))
def test_a_call_is_the_cdr_rosbags_makes(at: float, component: str, feature: str, call_id: str | None,
                                          args: list[Any] | None, ok: bool | None, value: Any,
                                          error: str | None, latency_ms: float | None) -> None:
    try:
        message = BUILD.call(at, component, feature, call_id, args, ok, value, error, latency_ms)
    except OverflowError:
        with pytest.raises(OverflowError):
            cdr.feature_call(at, component, feature, call_id, args, ok, value, error, latency_ms)
        return
    data, stamp_ns = cdr.feature_call(at, component, feature, call_id, args, ok, value, error, latency_ms)
    assert data == bytes(STORE.serialize_cdr(message, CALL))
    assert stamp_ns == to_ns(at)


def test_message_records_are_the_bytes_rosbags_storage_writes(tmp_path: Path) -> None:
    """The same messages through `McapBag.write_cdr` and through rosbags' `McapWriter.write`: the
    same file (chunks closed by size too: 3 MB of messages)."""
    def write(folder: Path, own: bool) -> bytes:
        folder.mkdir()
        bag = McapBag(folder / "same.mcap", custom_data={"umlbot.clock": "wall"})
        for i in range(12_000):
            topic, msgtype = ("/a/trace", TRACE) if i % 3 else ("/a/calls", CALL)
            data = bytes([i % 251]) * (i % 500)
            stamp = 1_795_000_000_000_000_000 + (i * 7919) % 100_000  # not in order
            if own:
                bag.write_cdr(topic, msgtype, data, stamp)
            else:  # what write_cdr did before: rosbags' storage, and the writer's counts
                connection = bag.channel(topic, msgtype)
                bag._writer.storage.write(connection, stamp, data)
                bag._writer.counts[connection.id] += 1
                bag._writer.min_timestamp = min(bag._writer.min_timestamp, stamp)
                bag._writer.max_timestamp = max(bag._writer.max_timestamp, stamp)
        bag.close()
        return (folder / "same.mcap").read_bytes()

    ours, theirs = write(tmp_path / "ours", True), write(tmp_path / "theirs", False)
    assert len(ours) > 3 * 2**20
    assert ours == theirs


class TraceViewer:
    """A sink that shows trace events (as the live server does): the recorder makes their message
    objects and serialises them with rosbags for it."""

    def __init__(self, bag: McapBag) -> None:
        self.bag = bag
        self.shown = 0

    def write_cdr(self, topic: str, msgtype: str, data: bytes | memoryview, stamp_ns: int) -> None:
        self.bag.write_cdr(topic, msgtype, data, stamp_ns)

    def on_trace(self, message: Any) -> None:
        self.shown += 1

    def tick(self) -> None:
        self.bag.tick()

    def close(self) -> None:
        self.bag.close()


def _feed_a_run(recorder: Recorder) -> None:
    def feed(topic: str, payload: Any, at: float) -> None:
        data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
        recorder._queue.append(("mqtt", topic, data, at, at))

    t0 = 1_795_000_000.0
    feed("umlbot/bot/orchestrator/status", {"state": "running", "model": "m", "call_timeout_s": 2}, t0)
    for i in range(300):
        at = t0 + 1 + i * 0.01
        feed("umlbot/bot/Motor/call/dutycycle", {"id": f"c{i}", "reply_to": "umlbot/bot/_reply/r",
                                                 "args": [i, "x"], "timeout_s": 5.0}, at)
        reply: dict[str, Any] = {"id": f"c{i}", "ok": True, "value": [i, None]} if i % 7 else \
            {"id": f"c{i}", "ok": False, "error": {"code": "busy", "message": f"no: {i}"}}
        feed("umlbot/bot/_reply/r", reply, at + 0.0012)
        feed("umlbot/bot/orchestrator/trace", [
            {"lane": "Main", "node": f"n{i}", "kind": "action", "start": at, "end": at + 0.002,
             "duration_ms": 2.0, "value": {"v": i} if i % 2 else None, "level": "info",
             "detail": f"Motor.dutycycle({i}) ü", "seq": 2 * i + 1},
            {"lane": "Main", "node": "d", "kind": "decision", "start": at, "end": at, "seq": 2 * i + 2,
             "level": "error" if i % 11 == 0 else "info", "error": "x" if i % 11 == 0 else None}], at)
    feed("umlbot/bot/Motor/call/dutycycle", {"id": "lost", "reply_to": "umlbot/bot/_reply/r", "args": []},
         t0 + 9)  # never answered: expires at the end
    feed("umlbot/bot/Motor/call/dutycycle", [1, 2], t0 + 9.5)  # fire-and-forget
    feed("umlbot/bot/orchestrator/status", {"state": "stopped"}, t0 + 10)


def test_a_run_records_the_same_messages_by_both_paths(tmp_path: Path) -> None:
    """Trace events straight to CDR (no sink shows them) or through rosbags (a sink shows them):
    the same messages at the same times; every call paired, the unanswered one recorded too."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    fast = open_file_recorder(tmp_path / "a" / "run.mcap", "bot", "wall", lambda: 1_795_000_020.0)
    viewer = TraceViewer(McapBag(tmp_path / "b" / "run.mcap"))
    slow = Recorder("bot", [viewer], lambda: 1_795_000_020.0)
    for recorder in (fast, slow):
        recorder._with_trace = True
        _feed_a_run(recorder)
        recorder._calls.call_timeout_s = 0.5
        assert wait_until(lambda r=recorder: not r._queue, timeout=10)  # type: ignore[misc]
        time.sleep(0.5)  # a tick expires the unanswered call
        assert recorder.close().dropped == 0
    assert viewer.shown == 600
    read_fast = read_with_mcap(tmp_path / "a" / "run.mcap")
    read_slow = read_with_mcap(tmp_path / "b" / "run.mcap")
    assert read_fast[0] == read_slow[0] and read_fast[1] == read_slow[1]
    assert read_fast[1]["/umlbot/bot/orchestrator/trace"] == 600
    assert read_fast[1]["/umlbot/bot/calls"] == 302  # 300 answered, one expired, one fire-and-forget
    for (topic_a, a, stamp_a), (topic_b, b, stamp_b) in zip(read_fast[2], read_slow[2], strict=True):
        assert (topic_a, stamp_a) == (topic_b, stamp_b)
        if topic_a != "/umlbot/bot/calls" or a.id != "lost":  # its stamp is when it expired
            assert repr(a) == repr(b)
    calls = [m for t, m, _ in read_fast[2] if t == "/umlbot/bot/calls"]
    assert calls[1].latency_ms == pytest.approx(1.2) and calls[1].value_json == "[1,null]"
    assert (calls[7].ok, calls[7].error_code, calls[7].error_message) == (False, "busy", "no: 7")
    lost = next(m for m in calls if m.id == "lost")
    assert not lost.answered and lost.latency_ms == -1.0
    traces = [m for t, m, _ in read_fast[2] if t == "/umlbot/bot/orchestrator/trace"]
    assert traces[2].detail == "Motor.dutycycle(1) ü" and json.loads(traces[2].value_json) == {"v": 1}
    assert traces[0].stamp.sec == 1_795_000_001 and math.isclose(traces[0].end, 1_795_000_001.002)


def test_a_read_ahead_connection_gets_every_message_whole_and_in_order(
        mosquitto_broker: BrokerProcess) -> None:
    settings_ = BrokerSettings.from_url(mosquitto_broker.url)
    got: list[Message] = []
    reader = BusConnection(settings_, "read-ahead", read_ahead=True)
    reader.subscribe_inline("ahead/#", got.append)
    reader.start(10)
    reader.wait_subscribed(10)
    writer = BusConnection(settings_, "writer")
    writer.start(10)
    sizes = [0, 1, 127, 128, 16_383, 16_384, 70_000, 200_000] + [i % 300 for i in range(3000)]
    try:
        for i, size in enumerate(sizes):  # many small ones gather in one read, big ones span reads
            writer.publish(f"ahead/{i}", bytes([i % 256]) * size, qos=i % 2)
        assert wait_until(lambda: len(got) >= len(sizes), timeout=30)
    finally:
        writer.close()
        reader.close()
    assert len(got) == len(sizes)
    by_topic = {m.topic: m.payload for m in got}
    assert all(by_topic[f"ahead/{i}"] == bytes([i % 256]) * size for i, size in enumerate(sizes))
    for qos in (0, 1):  # in order (the broker may let a QoS 0 message pass a QoS 1 one)
        order = [int(m.topic.split("/")[1]) for m in got if int(m.topic.split("/")[1]) % 2 == qos]
        assert order == sorted(order)
