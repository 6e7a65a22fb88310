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
from umlbot.services.orchestrator.trace import encode_record


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
        recorder = TraceRecorder(sink, trace_file, listened.append, window_s=0.02)
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
        recorder = TraceRecorder(sink, window_s=0.05)
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
