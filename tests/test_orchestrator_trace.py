"""TraceRecorder: events numbered by `seq`, shipped as JSON arrays at most once per window.

The recorder only calls a publish function; the real-broker path is in
test_orchestrator_semantics.py (test_trace_on_mqtt_and_in_a_file).
"""

from __future__ import annotations

import asyncio
import itertools
import json
import re
from pathlib import Path
from typing import Any

import pytest

from umlbot.services.bus import TraceEvent
from umlbot.services.orchestrator import TraceRecord, TraceRecorder, event_dict
from umlbot.services.orchestrator import trace as trace_module
from umlbot.services.orchestrator.trace import DEFAULT_BATCH, encode_record


def rec(i: int, value: Any = None) -> TraceRecord:
    return ("Main", f"n{i}", "datastore", f"x = {i}", 100.0 + i, 100.0 + i + 0.001, value, None, None)


def strict(payload: bytes) -> Any:
    """Parse as a browser would: NaN and Infinity are not JSON."""
    def refuse(name: str) -> Any:
        raise ValueError(f"{name} is not JSON")
    return json.loads(payload, parse_constant=refuse)


class Sink:
    def __init__(self) -> None:
        self.messages: list[tuple[float, list[dict[str, Any]]]] = []

    def __call__(self, payload: bytes) -> None:
        batch = strict(payload)
        assert isinstance(batch, list)
        for item in batch:
            TraceEvent.model_validate(item)
        self.messages.append((asyncio.get_running_loop().time(), batch))

    @property
    def seqs(self) -> list[int]:
        return [event["seq"] for _, batch in self.messages for event in batch]


def test_events_leave_as_one_array_per_window_numbered_in_order(tmp_path: Path) -> None:
    sink = Sink()
    listened: list[dict[str, Any]] = []
    trace_file = tmp_path / "trace.jsonl"

    async def run() -> TraceRecorder:
        recorder = TraceRecorder(sink, trace_file, listened.append, window_s=0.02, burst=1)
        began = asyncio.get_running_loop().time()
        for i in range(1, 51):  # one event a millisecond for 50 ms
            recorder.record(rec(i))
            await asyncio.sleep(0.001)
        # the first event found the recorder quiet: it left at the loop's next turn, alone
        assert [e["seq"] for e in sink.messages[0][1]] == [1]
        elapsed.append(asyncio.get_running_loop().time() - began)
        recorder.close()
        return recorder

    elapsed: list[float] = []
    recorder = asyncio.run(run())
    assert sink.seqs == list(range(1, 51))
    assert [e["node"] for _, batch in sink.messages for e in batch] == [f"n{i}" for i in range(1, 51)]
    # >= 50 ms of events in 20 ms windows: one message per window (and close()'s), not one per event
    assert 2 <= len(sink.messages) <= elapsed[0] / 0.02 + 2
    assert len(sink.messages) < 25
    times = [at for at, _ in sink.messages[:-1]]  # the last one is close()'s flush
    assert all(later - earlier >= 0.019 for earlier, later in itertools.pairwise(times))
    assert (recorder.recorded, recorder.shipped, recorder.dropped) == (50, 50, 0)
    lines = trace_file.read_text(encoding="utf-8").splitlines()
    assert [json.loads(line)["seq"] for line in lines] == list(range(1, 51))  # one event a line
    assert [e["seq"] for e in listened] == list(range(1, 51))


def test_a_lone_event_leaves_at_once_and_the_next_ones_wait_for_the_window() -> None:
    sink = Sink()

    async def run() -> None:
        loop = asyncio.get_running_loop()
        recorder = TraceRecorder(sink, window_s=0.05, burst=1)
        began = loop.time()
        recorder.record(rec(1))
        recorder.record(rec(2))  # the same turn of the loop: the same message
        await asyncio.sleep(0)
        assert [[e["seq"] for e in batch] for _, batch in sink.messages] == [[1, 2]]
        recorder.record(rec(3))  # within the window: waits for its end
        await asyncio.sleep(0.01)
        assert len(sink.messages) == 1
        await asyncio.sleep(0.06)  # the window (50 ms) has ended
        assert len(sink.messages) == 2 and sink.messages[1][0] - began >= 0.049
        assert [e["seq"] for e in sink.messages[1][1]] == [3]
        recorder.close()

    asyncio.run(run())


def test_a_full_batch_leaves_without_waiting_for_the_window() -> None:
    sink = Sink()

    async def run() -> None:
        recorder = TraceRecorder(sink, batch=10, window_s=10.0)
        for i in range(1, 26):
            recorder.record(rec(i))
        await asyncio.sleep(0)
        await asyncio.sleep(0)
        assert [len(batch) for _, batch in sink.messages] == [10, 10]  # 5 wait for the window
        recorder.close()

    asyncio.run(run())
    assert [len(batch) for _, batch in sink.messages] == [10, 10, 5]
    assert sink.seqs == list(range(1, 26))


def test_dropped_events_leave_a_gap_in_seq() -> None:
    sink = Sink()

    async def run() -> TraceRecorder:
        recorder = TraceRecorder(sink, max_pending=5, batch=100)
        for i in range(1, 9):  # never yields: the oldest three are dropped
            recorder.record(rec(i))
        recorder.close()
        return recorder

    recorder = asyncio.run(run())
    assert sink.seqs == [4, 5, 6, 7, 8]
    assert recorder.dropped == 3 and recorder.recorded == 8


@pytest.mark.parametrize("value", [float("nan"), float("inf"), object()])
@pytest.mark.parametrize("with_file", [False, True])
def test_a_value_that_is_not_strict_json_goes_as_text(value: Any, with_file: bool, tmp_path: Path) -> None:
    sink = Sink()
    trace_file = tmp_path / "t.jsonl" if with_file else None

    async def run() -> None:
        recorder = TraceRecorder(sink, trace_file)
        recorder.record(rec(1, value))
        recorder.record(rec(2, [1, 2]))
        recorder.close()

    asyncio.run(run())
    [(_, batch)] = sink.messages
    assert batch[0]["value"] == repr(value) and batch[1]["value"] == [1, 2]
    if trace_file is not None:
        assert [strict(line.encode())["value"] for line in trace_file.read_text().splitlines()] == [
            repr(value), [1, 2]]


@pytest.mark.parametrize("record", [
    ("Main", "n1", "action", "Motor.dutycycle(50)", 1.5, 1.5012345, 7, None, None),
    ("Lane \"q\"", "ü\n", "decision", "x < 1 → \\", 1795413440.2197144, 1795413440.9, None, None, "slow"),
    ("Main", "n3", "action", "Motor.enabled(true)", 2.0, 3.0, {"a": [True, None, 1e300]}, "timed out", None),
    ("Main", "n4", "datastore", "x = nan", 2.0, 2.0, float("nan"), None, None),
    ("Main", "n5", "datastore", "x", 2.0, 2.0, "text \u2028 \x00", None, None),
])
def test_the_event_text_is_the_event_dict_as_strict_json(record: TraceRecord) -> None:
    expected = event_dict(record, 42)
    if record[6] is not None and record[6] != record[6]:  # NaN goes as its repr
        expected["value"] = repr(record[6])
    text = encode_record(record, 42)
    assert strict(text.encode()) == expected
    TraceEvent.model_validate_json(text)


def test_a_failing_publish_does_not_stop_the_file(tmp_path: Path) -> None:
    def broken(payload: bytes) -> None:
        raise RuntimeError("gone")

    async def run() -> None:
        recorder = TraceRecorder(broken, tmp_path / "t.jsonl")
        recorder.record(rec(1))
        recorder.close()

    asyncio.run(run())
    assert json.loads((tmp_path / "t.jsonl").read_text(encoding="utf-8"))["seq"] == 1


def test_the_trace_section_of_mqtt_md_matches_the_wire_format() -> None:
    text = (Path(__file__).parents[1] / "docs" / "mqtt.md").read_text(encoding="utf-8")
    section = text.split("\n## The trace\n", 1)[1].split("\n## ", 1)[0]
    example = json.loads(section.split("```json\n", 1)[1].split("```", 1)[0])
    assert isinstance(example, list) and len(example) >= 2
    for item in example:
        assert set(item) <= set(TraceEvent.model_fields)
        TraceEvent.model_validate(item)
    assert [e["seq"] for e in example] == sorted(e["seq"] for e in example)
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    documented = [name for row in rows for name in re.findall(r"`(\w+)`", row.split("|")[1])]
    assert documented == list(TraceEvent.model_fields)


def test_a_trace_file_in_a_missing_folder_is_written_there(tmp_path: Path) -> None:
    trace_file = tmp_path / "runs" / "today" / "t.jsonl"

    async def run() -> None:
        recorder = TraceRecorder(Sink(), trace_file)
        recorder.record(rec(1, 5))
        recorder.close()

    asyncio.run(run())
    assert [strict(line.encode())["value"] for line in trace_file.read_text().splitlines()] == [5]


class FrozenClock:
    """A `time` stand-in whose monotonic clock only moves when told (the loop's own runs on)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def monotonic(self) -> float:
        return self.now


def test_after_a_quiet_spell_the_first_clusters_of_a_burst_leave_at_once(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The mechanism, on a frozen clock: the first message and the next `burst - 1` are scheduled
    for the loop's next turn, not for the end of a window; the one after waits one interval."""
    clock = FrozenClock()
    monkeypatch.setattr(trace_module, "time", clock)
    sink = Sink()

    async def run() -> None:
        recorder = TraceRecorder(sink, window_s=0.02, burst=4)
        interval = recorder.pacer.interval_s
        assert interval == pytest.approx(1 / 47)  # 50 in any second, the burst included
        for cluster in range(4):  # four clusters 3 ms apart, as a lane's nodes between replies
            recorder.record(rec(2 * cluster + 1))
            recorder.record(rec(2 * cluster + 2))
            await asyncio.sleep(0)  # the loop's next turn: the cluster has left, as one message
            assert len(sink.messages) == cluster + 1
            clock.now += 0.003
        recorder.record(rec(9))  # the fifth within the bound's room: waits, at most an interval
        await asyncio.sleep(0)
        await asyncio.sleep(0)
        assert len(sink.messages) == 4
        clock.now += interval
        await asyncio.sleep(interval + 0.01)  # the loop's timer runs on the real clock
        assert len(sink.messages) == 5
        clock.now += 1.0  # quiet: the next leaves at once again
        recorder.record(rec(10))
        await asyncio.sleep(0)
        assert len(sink.messages) == 6
        recorder.close()

    asyncio.run(run())
    assert [[e["seq"] for e in batch] for _, batch in sink.messages] == [
        [1, 2], [3, 4], [5, 6], [7, 8], [9], [10]]


@pytest.mark.parametrize("burst", [1, 4])
@pytest.mark.parametrize("nodes_per_turn, pause_s", [(10, 0.001), (128, 0.0)])
def test_a_tight_loop_sends_at_most_50_messages_in_any_second(burst: int, nodes_per_turn: int,
                                                               pause_s: float) -> None:
    """A fast lane for 1.5 s: 10 nodes then a 1 ms reply (10 000 nodes/s: a message a millisecond
    without a bound), or one that never waits (a loop turn every 128 nodes, as the engine yields).
    The burst does not raise the bound of plain 20 ms windows: at most 50 messages in any second,
    besides full batches (500 events), which leave at once with or without it. Counted at the
    times the recorder sent them (its pacer's clock; the sink's may lag under load)."""
    sink = Sink()
    sent_at: list[float] = []
    turns = 0

    async def run() -> TraceRecorder:
        nonlocal turns
        loop = asyncio.get_running_loop()
        recorder = TraceRecorder(sink, window_s=0.02, burst=burst)
        pacer_sent = recorder.pacer.sent

        def sent(now: float) -> None:
            sent_at.append(now)
            pacer_sent(now)

        recorder.pacer.sent = sent  # type: ignore[method-assign]
        end = loop.time() + 1.5
        i = 0
        while loop.time() < end:
            for _ in range(nodes_per_turn):
                i += 1
                recorder.record(rec(i))
            turns += 1
            await asyncio.sleep(pause_s)
        sent_at.append(float("inf"))  # close()'s own message is not counted
        recorder.close()
        return recorder

    recorder = asyncio.run(run())
    assert len(sent_at) >= len(sink.messages)
    times = [at for at, (_, batch) in zip(sent_at, sink.messages, strict=False)
             if len(batch) < DEFAULT_BATCH and at < float("inf")]
    most = 0
    for first, at in enumerate(times):  # any half-open second
        most = max(most, sum(1 for later in times[first:] if later - at < 1.0))
    assert most <= 50
    if nodes_per_turn == 10:  # no full batch: the bound is the whole rate; turns were coalesced
        assert all(len(batch) < DEFAULT_BATCH for _, batch in sink.messages)
        assert len(sink.messages) < turns / 2
    else:  # the lane outran the bound: full batches left besides
        assert any(len(batch) == DEFAULT_BATCH for _, batch in sink.messages)
    assert recorder.dropped == 0 and sink.seqs == list(range(1, recorder.recorded + 1))
