"""The recorder on its own (no broker): what each MQTT payload of SPEC §3 becomes, wire input that
is not what it should be, the queue bound, and a sink that fails."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import pytest
from record_support import read_with_mcap

from umlbot.record import Recorder, open_file_recorder
from umlbot.services.bus import Message

T0 = 1_795_000_000.0


def feed(recorder: Recorder, topic: str, payload: Any) -> None:
    data = payload if isinstance(payload, bytes) else json.dumps(payload).encode()
    recorder.on_message(Message(topic, data))


def test_each_payload_becomes_its_message(tmp_path: Path) -> None:
    clock = iter(T0 + i for i in range(1000))
    path = tmp_path / "r.mcap"
    recorder = open_file_recorder(path, "bot", "wall", lambda: next(clock))
    feed(recorder, "umlbot/bot/Lamp/status", {"state": "online", "impl": "led", "features": ["enabled"],
                                              "driver": "mock"})
    feed(recorder, "umlbot/bot/Lamp/state", {"enabled": True})
    feed(recorder, "umlbot/bot/orchestrator/status", {"state": "running", "model": "m", "call_timeout_s": 2})
    feed(recorder, "umlbot/bot/signal/obstacle", {"cm": 12})
    feed(recorder, "umlbot/bot/signal/ping", b"")  # a signal without payload is no message
    call, reply = "umlbot/bot/Lamp/call/enabled", "umlbot/bot/_reply/x"
    feed(recorder, call, {"id": "c1", "reply_to": reply, "args": [True]})
    feed(recorder, "umlbot/bot/_reply/x", {"id": "c1", "ok": True, "value": None})
    feed(recorder, call, {"id": "c2", "reply_to": reply, "args": [7]})
    feed(recorder, "umlbot/bot/_reply/x", {"id": "c2", "ok": False,
                                          "error": {"code": "bad_args", "message": "not a bool"}})
    feed(recorder, "umlbot/bot/Lamp/call/enabled", False)  # fire-and-forget, a bare value
    # wire input that is not what it should be: recorded as far as it goes, never raised on
    feed(recorder, "umlbot/bot/Lamp/state", b"\xff\xfe not utf-8")
    feed(recorder, "umlbot/bot/orchestrator/status", b"[1, 2")
    feed(recorder, "umlbot/bot/Lamp/call/enabled", b"{not json")
    feed(recorder, "umlbot/bot/orchestrator/trace", [{"lane": "L", "node": "n"}])  # not listened to
    stats = recorder.close()
    assert stats.dropped == 0 and stats.failed is None
    types, counts, messages, _ = read_with_mcap(path)
    assert types["/umlbot/bot/Lamp/status"] == "umlbot_msgs/msg/ComponentStatus"
    assert counts["/umlbot/bot/Lamp/state"] == 2 and counts["/umlbot/bot/signals"] == 1
    assert counts["/umlbot/bot/orchestrator/status"] == 2
    assert "/umlbot/bot/orchestrator/trace" not in counts
    by_topic: dict[str, list[Any]] = {}
    for topic, message, _ in messages:
        by_topic.setdefault(topic, []).append(message)
    status = by_topic["/umlbot/bot/Lamp/status"][0]
    assert (status.state, status.impl, status.driver, list(status.features)) == ("online", "led", "mock",
                                                                                  ["enabled"])
    assert json.loads(by_topic["/umlbot/bot/signals"][0].payload_json) == {"cm": 12}
    assert by_topic["/umlbot/bot/signals"][0].name == "obstacle"
    assert by_topic["/umlbot/bot/orchestrator/status"][0].call_timeout_s == 2.0
    calls = by_topic["/umlbot/bot/calls"]
    ok = next(c for c in calls if c.id == "c1")
    assert ok.answered and ok.ok and json.loads(ok.args_json) == [True]
    assert 0 <= ok.latency_ms < 5000  # wall time between the request's and the reply's arrival
    # on the wall clock a call is stamped when it was requested: the reply's time less the latency
    assert abs(ok.stamp.sec + ok.stamp.nanosec / 1e9 - time.time()) < 60
    failed = next(c for c in calls if c.id == "c2")
    assert failed.answered and not failed.ok
    assert (failed.error_code, failed.error_message) == ("bad_args", "not a bool")
    bare = next(c for c in calls if json.loads(c.args_json) == [False])
    assert not bare.answered and bare.latency_ms == -1.0
    assert any(c.error_code == "bad_json" for c in calls)  # the request that is not JSON


class Failing:
    """A sink whose every write fails."""

    failed = "always"

    def write_cdr(self, topic: str, msgtype: str, data: bytes | memoryview, stamp_ns: int) -> None:
        raise OSError(5, "Input/output error")

    def tick(self) -> None:
        raise OSError(5, "Input/output error")

    def close(self) -> None:
        raise OSError(5, "Input/output error")


def test_a_failing_sink_and_a_full_queue_never_reach_the_caller() -> None:
    recorder = Recorder("bot", [Failing()], max_queue=10)
    for seq in range(1, 5001):  # far more than the queue holds, as fast as a loop goes
        recorder.on_trace({"lane": "L", "node": f"n{seq}", "kind": "action", "start": T0, "end": T0,
                           "duration_ms": 0.1, "seq": seq})
    stats = recorder.close()
    assert stats.dropped > 0 and stats.messages + stats.dropped == 5000
    assert stats.failed == "always"


@pytest.mark.parametrize("name", ["car-1", "1car", "car.x"])
def test_names_that_are_no_ros_names_are_made_ones(name: str) -> None:
    from umlbot.record.messages import Topics

    topic = Topics(name).trace
    assert all(part and (part[0].isalpha() or part[0] == "_") for part in topic.split("/")[1:])
    assert set(topic) <= set("/_abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789")


class FullAfter:
    """A file whose writes fail with ENOSPC once `limit` bytes are written (a disk that fills up
    in the middle of a chunk; the kernel's own refusal is tested in test_record_mcap.py)."""

    def __init__(self, path: Path, limit: int) -> None:
        from umlbot.record.bag import WholeFile

        self.inner = WholeFile(path)
        self.limit = limit

    def write(self, data: bytes | bytearray | memoryview) -> int:
        if self.inner.tell() + len(data) > self.limit:
            raise OSError(28, "No space left on device")
        return self.inner.write(data)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


@pytest.mark.parametrize("flush_every_s", [0.0, 3600.0], ids=["small-chunks", "full-chunks-only"])
def test_a_disk_that_fills_up_mid_chunk_leaves_a_readable_file(tmp_path: Path, flush_every_s: float) -> None:
    from umlbot.record import McapBag

    path = tmp_path / "full.mcap"
    limit = 1_500_000  # past the first full (1 MiB) chunk of rosbags, inside the second
    bag = McapBag(path, file=FullAfter(path, limit), flush_every_s=flush_every_s)  # type: ignore[arg-type]
    recorder = Recorder("bot", [bag])
    for seq in range(1, 30_001):
        recorder.on_trace({"lane": "L", "node": f"n{seq}", "kind": "action", "start": T0 + seq,
                           "end": T0 + seq, "duration_ms": 0.1, "detail": "x" * 60, "seq": seq})
    stats = recorder.close(timeout=120)
    assert stats.failed is not None and "No space left on device" in stats.failed
    assert path.stat().st_size <= limit
    messages = read_with_mcap(path)[2]
    seqs = [m.seq for _, m, _ in messages]
    assert seqs == list(range(1, len(seqs) + 1))  # whole chunks, in order, nothing half-written
    assert 1000 < len(seqs) < 30_000
