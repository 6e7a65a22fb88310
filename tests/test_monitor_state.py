"""MonitorState: requests paired with replies, availability changes, lanes and percentiles."""

from __future__ import annotations

import io
import json
import logging
import math
import re
from pathlib import Path

import pytest
from rich.console import Console

from umlbot.base.errors import ConfigError
from umlbot.monitor import MonitorEvent, MonitorState, Stats, read_trace, render, replay
from umlbot.services.bus import TraceEvent


def j(value: object) -> bytes:
    return json.dumps(value).encode()


def trace(lane: str, node: str, kind: str, start: float, ms: float, **extra: object) -> TraceEvent:
    return TraceEvent(lane=lane, node=node, kind=kind, start=start, end=start + ms / 1000,
                      duration_ms=ms, **extra)


def test_a_request_is_paired_with_its_reply_by_reply_topic_and_id() -> None:
    state = MonitorState()
    reply_to = "umlbot/car/_reply/orch-1"
    assert state.observe("umlbot/car/DistanceRead/call/value",
                         j({"id": "7", "reply_to": reply_to, "args": []}), at=100.0) == []
    assert state.pending_calls == 1
    # same id on another caller's reply topic: not ours
    assert state.observe("umlbot/car/_reply/other", j({"id": "7", "ok": True, "value": 1}), 100.01) == []
    [event] = state.observe(reply_to, j({"id": "7", "ok": True, "value": 42}), at=100.0125)
    assert event.type == "call" and event.component == "DistanceRead" and event.feature == "value"
    assert event.ok is True and event.value == 42
    assert event.latency_ms == pytest.approx(12.5)
    assert state.pending_calls == 0
    assert state.features[("car", "DistanceRead", "value")].count == 1


def test_error_replies_and_unanswered_calls_are_failures() -> None:
    state = MonitorState(call_timeout_s=1.0)
    motor = "umlbot/car/LeftActuator/call"
    state.observe(f"{motor}/dutycycle", j({"id": 1, "reply_to": "r/x", "args": [500]}), 0.0)
    [failed] = state.observe("r/x", j({"id": 1, "ok": False,
                                       "error": {"code": "out_of_range", "message": "0..100"}}), 0.002)
    assert failed.ok is False and failed.error == "out_of_range: 0..100" and failed.args == [500]
    state.observe(f"{motor}/enabled", j({"id": 2, "reply_to": "r/x", "args": [True]}), 1.0)
    assert state.expire(1.5) == []
    [late] = state.expire(2.5)
    assert late.ok is False and late.error is not None and "no reply" in late.error
    assert state.features[("car", "LeftActuator", "dutycycle")].errors == 1


def test_fire_and_forget_and_bad_requests() -> None:
    state = MonitorState()
    [bare] = state.observe("umlbot/car/LeftActuator/call/dutycycle", b"60", 5.0)
    assert bare.args == [60] and bare.ok is None and bare.detail == "fire-and-forget"
    [listed] = state.observe("umlbot/car/RaspberryPI/call/writePin", b"[22, 1]", 5.0)
    assert listed.args == [22, 1]
    [bad] = state.observe("umlbot/car/LeftActuator/call/dutycycle", b"{not json", 5.0)
    assert bad.ok is False and bad.error is not None and bad.error.startswith("bad_json")


def test_availability_events_only_on_change() -> None:
    state = MonitorState()
    online = j({"state": "online", "impl": "l298n", "features": ["enabled"]})
    [first] = state.observe("umlbot/car/LeftActuator/status", online, 1.0)
    assert (first.type, first.component, first.state, first.impl) == ("availability", "LeftActuator",
                                                                     "online", "l298n")
    assert state.observe("umlbot/car/LeftActuator/status", online, 2.0) == []
    [gone] = state.observe("umlbot/car/LeftActuator/status", j({"state": "offline"}), 3.0)
    assert gone.state == "offline"
    assert state.availability[("car", "LeftActuator")].state == "offline"


def test_a_request_that_says_its_time_out_is_reported_after_it() -> None:
    """The caller's own time-out (`timeout_s`, the orchestrator's fail-safe stop calls: 1 s) wins
    over the one the orchestrator's status announces (its run's 2 s) and `--call-timeout`."""
    for state in (MonitorState(), MonitorState(call_timeout_s=0.5)):
        state.observe("umlbot/car/orchestrator/status", j({"state": "stopping", "call_timeout_s": 2.0}), 99.0)
        stop = {"id": "s1", "reply_to": "umlbot/car/_reply/o", "args": [False], "timeout_s": 1.0}
        state.observe("umlbot/car/LeftActuator/call/enabled", j(stop), 100.0)
        state.observe("umlbot/car/Sensor/call/angle",
                      j({"id": "s2", "reply_to": "umlbot/car/_reply/o", "args": [90]}), 100.0)
        early = state.expire(100.9)
        assert "enabled" not in {e.feature for e in early}  # not before its own 1 s
        by_feature = {e.feature: e.error for e in early + state.expire(101.1) + state.expire(102.1)}
        assert by_feature == {"enabled": "no reply within 1 s",
                              "angle": "no reply within 2 s" if state.call_timeout_s is None
                              else "no reply within 0.5 s"}
    [bad] = MonitorState().observe("umlbot/car/Sensor/call/angle",
                                   j({"id": "s3", "reply_to": "r/t", "args": [90], "timeout_s": "soon"}), 1.0)
    assert bad.ok is False and bad.error == "bad_request: not a valid request envelope"


def test_the_driver_a_status_says_is_an_event_and_a_column() -> None:
    """A status that names its driver (`auto` resolved by the service) says it in the availability
    event and the table; a status without one (another client's service) is still a status."""
    state = MonitorState()
    topic = "umlbot/car/LeftActuator/status"
    [first] = state.observe(topic, j({"state": "online", "impl": "l298n", "driver": "mock"}), 1.0)
    assert (first.state, first.driver) == ("online", "mock")
    assert '"driver":"mock"' in first.line()
    assert state.observe(topic, j({"state": "online", "impl": "l298n", "driver": "mock"}), 2.0) == []
    [other] = state.observe(topic, j({"state": "online", "impl": "l298n", "driver": "pigpio"}), 3.0)
    assert other.driver == "pigpio"  # the same state, another driver: said
    out = io.StringIO()
    Console(file=out, width=160).print(render(state, now=4.0))
    assert "driver" in out.getvalue()
    assert "pigpio" in next(line for line in out.getvalue().splitlines() if "LeftActuator" in line)
    [gone] = state.observe(topic, j({"state": "offline"}), 5.0)
    assert gone.driver is None and "driver" not in gone.line()
    [plain] = state.observe("umlbot/car/Sensor/status", j({"state": "online", "impl": "servo"}), 6.0)
    assert plain.driver is None and state.availability[("car", "Sensor")].state == "online"


def test_the_time_in_a_state_counts_from_the_since_the_status_gives() -> None:
    """A service online since 1000 s is shown online for 500 s at 1500 s, though the monitor saw
    its (retained) status only at 1490 s; a status without a usable `since` counts from when it
    was seen."""
    state = MonitorState()
    topic = "umlbot/car/Sensor/status"
    state.observe(topic, j({"state": "online", "impl": "servo", "since": 1000.0}), 1490.0)
    assert state.availability[("car", "Sensor")].since == 1000.0
    state.observe(topic, j({"state": "online", "impl": "servo", "since": 1200.0}), 1495.0)  # restarted
    assert state.availability[("car", "Sensor")].since == 1200.0
    state.observe(topic, j({"state": "offline"}), 1497.0)  # the last will says no since
    assert state.availability[("car", "Sensor")].since == 1497.0
    for bad in ("yesterday", -5, True, None, [1]):
        state.observe(topic, j({"state": "online", "since": bad}), 1498.0)
        assert state.availability[("car", "Sensor")].since in (1497.0, 1498.0)
        state.observe(topic, j({"state": "offline"}), 1497.0)
    state.observe(topic, j({"state": "online", "impl": "servo", "since": 1000.0}), 1499.0)
    out = io.StringIO()
    Console(file=out, width=160).print(render(state, now=1500.0))
    row = next(line for line in out.getvalue().splitlines() if "Sensor" in line)
    assert "online" in row and "500.0s" not in row and re.search(r"\b8m\b", row), row


def test_orchestrator_status_signal_state_and_exit() -> None:
    state = MonitorState()
    [status] = state.observe("umlbot/car/orchestrator/status", j({"state": "running", "model": "m"}), 1.0)
    assert status.type == "orchestrator" and status.state == "running"
    [signal] = state.observe("umlbot/car/signal/obstacle", j({"cm": 12}), 1.0)
    assert signal.type == "signal" and signal.feature == "obstacle" and signal.payload == {"cm": 12}
    [st] = state.observe("umlbot/car/LeftActuator/state", j({"enabled": True}), 1.0)
    assert st.type == "state" and st.payload == {"enabled": True}
    [ex] = state.observe("umlbot/car/orchestrator/exit", b"{}", 1.0)
    assert ex.type == "exit"
    assert state.observe("elsewhere/topic", b"1", 1.0) == []


def test_trace_events_drive_lanes_and_action_percentiles() -> None:
    state = MonitorState()
    for i in range(100):
        event = state.observe("umlbot/car/orchestrator/trace", trace(
            "LeftActuator", "a1", "action", 10.0 + i, float(i + 1),
            detail="LeftActuator.dutycycle(60)").model_dump_json().encode(), 0.0)
        assert event[0].type == "trace"
    state.observe_trace(trace("LeftActuator", "d1", "decision", 200.0, 0.01), "car")
    lane = state.lanes[("car", "LeftActuator")]
    assert (lane.node, lane.kind) == ("d1", "decision")
    stats = state.actions[("car", "LeftActuator", "a1")]
    assert stats.count == 100 and stats.label == "LeftActuator.dutycycle(60)"
    assert stats.p50 == pytest.approx(50.0, rel=0.01) and stats.p99 == pytest.approx(99.0, rel=0.01)
    assert ("car", "LeftActuator", "d1") not in state.actions  # decisions are not timed


def test_percentiles_within_one_percent_of_the_nearest_rank() -> None:
    empty = Stats("a")
    assert math.isnan(empty.p50) and math.isnan(empty.p99)
    one = Stats("b")
    one.add(3.0)
    assert one.p50 == pytest.approx(3.0, rel=0.01) and one.p99 == pytest.approx(3.0, rel=0.01)
    many = Stats("c")
    for i in range(1, 1001):
        many.add(float(i))
    many.add(math.nan)  # not a duration: counted, not sampled
    many.add(None, failed=True)
    assert (many.count, many.errors) == (1002, 1)
    assert many.p50 == pytest.approx(500.0, rel=0.01) and many.p99 == pytest.approx(990.0, rel=0.01)


def test_replay_reads_a_trace_file_at_the_recorded_pace(tmp_path: Path) -> None:
    path = tmp_path / "trace.jsonl"
    events = [trace("Sensor", f"n{i}", "action", 100.0 + i * 0.5, 1.0) for i in range(4)]
    path.write_text("".join(e.model_dump_json() + "\n" for e in events) + "\n", encoding="utf-8")
    state = MonitorState()
    seen: list[MonitorEvent] = []
    slept: list[float] = []
    assert replay(path, state, "car", seen.append, speed=2.0, sleep=slept.append) == 4
    assert [e.node for e in seen] == ["n0", "n1", "n2", "n3"]
    assert slept == pytest.approx([0.25, 0.25, 0.25])
    assert state.lanes[("car", "Sensor")].node == "n3"
    console = Console(record=True, width=160, file=io.StringIO())
    console.print(render(state, now=200.0))
    screen = console.export_text()
    assert "Lanes" in screen and "Sensor" in screen and "n3" in screen


def test_a_bad_trace_line_names_file_and_line(tmp_path: Path) -> None:
    path = tmp_path / "trace.jsonl"
    path.write_text(trace("L", "n", "action", 1.0, 1.0).model_dump_json() + "\n{\"lane\": 1}\n")
    with pytest.raises(ConfigError, match=r"trace.jsonl:2: not a trace event"):
        list(read_trace(path))
    with pytest.raises(ConfigError, match="cannot read trace file"):
        list(read_trace(tmp_path / "missing.jsonl"))


def test_datastores_count_only_when_set_from_a_call() -> None:
    state = MonitorState()
    from_call = trace("Measure", "c", "datastore", 1.0, 5.0, detail="center = DistanceRead.value()")
    state.observe_trace(from_call, "car")
    state.observe_trace(trace("Main", "k", "datastore", 1.0, 0.0, detail="speed_percent = 70"), "car")
    assert ("car", "Measure", "c") in state.actions
    assert ("car", "Main", "k") not in state.actions


def test_a_trace_message_may_be_one_event_or_an_array_of_them() -> None:
    state = MonitorState()
    one = trace("Main", "a", "action", 1.0, 2.0, seq=1).model_dump()
    batch = [trace("Main", f"b{i}", "action", 2.0 + i, 2.0, seq=2 + i).model_dump() for i in range(3)]
    [single] = state.observe("umlbot/car/orchestrator/trace", j(one), 5.0)
    events = state.observe("umlbot/car/orchestrator/trace", j(batch), 5.0)
    assert single.node == "a" and [e.node for e in events] == ["b0", "b1", "b2"]
    assert state.actions[("car", "Main", "b2")].count == 1
    # a bad item in a batch is skipped and counted; its neighbours still count
    mixed = [batch[0], {"lane": 1}, 5, batch[1]]
    assert [e.node for e in state.observe("umlbot/car/orchestrator/trace", j(mixed), 6.0)] == ["b0", "b1"]
    assert state.malformed == 2 and state.messages == 3


def test_replay_accepts_lines_with_arrays_and_old_lines_without_seq(tmp_path: Path) -> None:
    path = tmp_path / "trace.jsonl"
    old = trace("L", "n0", "action", 1.0, 1.0)  # recorded before seq existed
    batch = [trace("L", f"n{i}", "action", 1.0 + i, 1.0, seq=i) for i in (1, 2)]
    path.write_text(old.model_dump_json(exclude_none=True) + "\n"
                    + json.dumps([e.model_dump() for e in batch]) + "\n", encoding="utf-8")
    events = list(read_trace(path))
    assert [(e.node, e.seq) for e in events] == [("n0", None), ("n1", 1), ("n2", 2)]


@pytest.mark.parametrize("line, message", [
    ("[" * 5000, "trace.jsonl:2: not a trace event"),
    ('{"lane": "L"', "trace.jsonl:2: not a trace event"),
    ("\udcff", "trace.jsonl:2:1: cannot read trace file: not UTF-8 text: byte 0xff: invalid start byte"),
    ('{"lane": "\u00e9\udce9"}', "trace.jsonl:2:12: cannot read trace file: not UTF-8 text: byte 0xe9"),
])
def test_a_malformed_replay_line_is_a_config_error(tmp_path: Path, line: str, message: str) -> None:
    path = tmp_path / "trace.jsonl"
    path.write_bytes(trace("L", "n", "action", 1.0, 1.0).model_dump_json().encode() + b"\n"
                     + line.encode("utf-8", errors="surrogateescape") + b"\n")
    with pytest.raises(ConfigError, match=re.escape(message)):
        list(read_trace(path))


def test_wire_values_are_shown_as_text_never_as_rich_markup() -> None:
    state = MonitorState()
    reply_to = "umlbot/car/_reply/orch-1"
    request = {"id": "1", "reply_to": reply_to, "args": [True]}
    state.observe("umlbot/car/LeftActuator/call/enabled", j(request), 1.0)
    state.observe(reply_to, j({"id": "1", "ok": True, "value": "[bold]done[/bold]"}), 1.005)
    state.observe("umlbot/car/LeftActuator/status", j({"state": "online", "impl": "[red]l298n"}), 1.0)
    state.observe_trace(trace("[b]Main", "[i]n", "action", 1.0, 1.0, detail="Sensor.angle([90])"), "car")
    console = Console(record=True, width=200, file=io.StringIO())
    console.print(render(state, now=2.0))
    screen = console.export_text()
    row = next(line for line in screen.splitlines() if "LeftActuator.enabled" in line)
    assert "[true]" in row and "[bold]done[/bold]" in row
    for text in ("[red]l298n", "[b]Main", "[i]n", "Sensor.angle([90])"):
        assert text in screen


MALFORMED: list[tuple[str, bytes]] = [
    (topic, payload)
    for topic in ("umlbot/car/M/status", "umlbot/car/M/state", "umlbot/car/signal/go",
                  "umlbot/car/orchestrator/status", "umlbot/car/orchestrator/trace",
                  "umlbot/car/orchestrator/exit", "umlbot/car/_reply/x")
    for payload in (b"[" * 5000, b"\xff\xfe{", b'{"lane": NaN}', b'{"state": [1], "impl": 7, "reason": {}}',
                    b"[" * 150 + b"1" + b"]" * 150)
] + [("umlbot/car/M/call/enabled", b"[" * 5000), ("umlbot/car/M/call/enabled", b'{"id": [], "reply_to": 5}')]


def test_malformed_wire_input_is_counted_never_raised(caplog: pytest.LogCaptureFixture,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    caplog.set_level(logging.DEBUG)
    state = MonitorState()
    for topic, payload in MALFORMED:
        for event in state.observe(topic, payload, 1.0):
            event.line()  # every event can still be printed
    console = Console(record=True, width=160, file=io.StringIO())
    console.print(render(state, now=2.0))
    assert state.malformed >= 10
    assert f"{state.malformed} malformed skipped" in console.export_text()
    # the log goes through stdlib logging once configured (caplog), else structlog prints it
    printed = capsys.readouterr()
    logged = printed.out + printed.err + "\n".join(str(r.msg) for r in caplog.records)
    assert logged.count("malformed message skipped") == 1
    assert "Traceback" not in logged and not any(r.exc_info for r in caplog.records)


def test_an_unanswered_call_uses_the_orchestrators_time_out_and_keeps_its_request_time() -> None:
    # the orchestrator fails a call after its call_timeout_s (2 s): the monitor must say the same
    # time-out, not its own 5 s, and list the call where it was made, not when it gave up on it
    state = MonitorState()
    state.observe("umlbot/car/orchestrator/status", j({"state": "running", "call_timeout_s": 2.0}), 99.0)
    state.observe("umlbot/other/orchestrator/status", j({"state": "running"}), 99.0)
    state.observe("umlbot/car/DistanceRead/call/value", j({"id": 1, "reply_to": "r/o", "args": []}), 100.0)
    state.observe("umlbot/other/DistanceRead/call/value", j({"id": 2, "reply_to": "r/o", "args": []}), 100.0)
    state.observe("umlbot/car/Sensor/call/angle", j({"id": 3, "reply_to": "r/o", "args": [45]}), 101.0)
    [answered] = state.observe("r/o", j({"id": 3, "ok": True, "value": None}), 101.01)
    assert answered.time == 101.01
    assert state.expire(101.9) == []
    [late] = state.expire(102.5)  # the car's call after 2 s; the other robot's waits for 5 s
    assert (late.robot, late.feature, late.ok, late.error) == ("car", "value", False, "no reply within 2 s")
    assert late.time == 100.0 and late.latency_ms is None
    assert [e.feature for e in state.recent_calls] == ["value", "angle"]  # in the order they were made
    assert state.expire(104.9) == []
    [other] = state.expire(105.5)
    assert other.robot == "other" and other.error == "no reply within 5 s"
    given = MonitorState(call_timeout_s=0.5, fallback_call_timeout_s=9.0)  # --call-timeout wins
    given.observe("umlbot/car/orchestrator/status", j({"state": "running", "call_timeout_s": 2.0}), 99.0)
    given.observe("umlbot/car/DistanceRead/call/value", j({"id": 1, "reply_to": "r/o"}), 100.0)
    [quick] = given.expire(100.6)
    assert quick.error == "no reply within 0.5 s"
    assert MonitorState(fallback_call_timeout_s=3.0).call_timeout("car") == 3.0


def test_a_cut_off_last_line_ends_the_trace_with_a_note(tmp_path: Path) -> None:
    path = tmp_path / "trace.jsonl"
    whole = "".join(trace("L", f"n{i}", "action", 1.0 + i, 1.0).model_dump_json() + "\n" for i in range(2))
    cut = trace("L", "n2", "action", 3.0, 1.0).model_dump_json()[:25]
    path.write_text(whole + cut, encoding="utf-8")
    notes: list[str] = []
    assert [e.node for e in read_trace(path, notes)] == ["n0", "n1"]
    assert notes == ["trace.jsonl:3: the last line is cut off (the run was killed or is still writing the "
                     "trace): replayed the lines before it"]
    # a cut in the middle of a UTF-8 character is cut off too
    path.write_bytes((whole + '{"lane": "\u00e9').encode()[:-1])
    assert [e.node for e in read_trace(path, notes)] == ["n0", "n1"] and len(notes) == 2
    # the same text with its newline is a bad line, not a cut-off one: still an error
    path.write_text(whole + cut + "\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"trace.jsonl:3: not a trace event"):
        list(read_trace(path))
    # a bad line in the middle stays an error even when the last line is cut off
    path.write_text(whole + '{"lane": 1}\n' + cut, encoding="utf-8")
    with pytest.raises(ConfigError, match=r"trace.jsonl:3: not a trace event"):
        list(read_trace(path))
