"""The execution semantics, one small model per node kind and rule, over both real brokers.

Every model runs against mock services (in-process `ServiceHost`s) through a real broker; the
assertions read the trace events and the commands the mock drivers recorded.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import BrokerProcess, RawClient
from orchestrator_support import rig, wait_for

from umlbot.base.errors import OrchestratorError
from umlbot.services.bus import OrchestratorStatus, TraceEvent
from umlbot.services.orchestrator import run_orchestrator

pytestmark = pytest.mark.network


def test_fork_runs_both_calls_at_once_and_join_continues_once(broker: BrokerProcess) -> None:
    with rig(broker.url, "fork.yaml") as r:
        code, orch = r.run()
        assert code == 0, orch.failure
        actions = {e["node"]: e for e in r.trace(kind="action")}
        assert set(actions) == {"left", "right"}
        # both 100 ms calls were in flight at once: each began before the other ended (an
        # overlap, not a wall-time bound: a loaded machine stretches both alike)
        left, right = actions["left"], actions["right"]
        assert left["start"] < right["end"] and right["start"] < left["end"], actions
        assert all(e["duration_ms"] >= 95 for e in actions.values())
        assert r.nodes().count("joined") == 1
        assert r.nodes().count("after") == 1
        assert r.driver("LeftActuator").commands_named("set_duty_cycle") == [(10,)]
        assert r.driver("RightActuator").commands_named("set_duty_cycle") == [(20,)]
        assert orch.engine.stores["RaspberryPI"] == {"began": 1, "done": True}


def test_replies_feed_datastores_guards_and_arguments(broker: BrokerProcess) -> None:
    with rig(broker.url, "sensor_decision.yaml") as r:
        code, orch = r.run()
        assert code == 0, orch.failure
        assert r.driver("DistanceRead").reads == 3
        # 50 cm: clear -> 60 %; 10 cm: blocked -> 60 - 50 + 2 = 12 %; 30 cm: clear -> 60 %
        assert r.driver("LeftActuator").commands_named("set_duty_cycle") == [(60,), (12,), (60,)]
        reads = [e["value"] for e in r.trace(kind="datastore") if e["node"] == "read"]
        assert reads == [50, 10, 30]
        choices = [e["value"] for e in r.trace(kind="decision") if e["node"] == "clear"]
        assert choices == ["go", "slow", "go"]
        assert orch.engine.stores["RaspberryPI"]["readings"] == 3
        naps = [e for e in r.trace(kind="action") if e["node"] == "nap"]
        assert len(naps) == 3 and all(e["duration_ms"] >= 0.9 for e in naps)


def test_virtual_lane_called_from_two_lanes_at_once(broker: BrokerProcess) -> None:
    with rig(broker.url, "reentrant.yaml") as r:
        began = time.monotonic()
        code, orch = r.run()
        assert code == 0, orch.failure
        waits = [e for e in r.trace(lane="Pulse") if e["node"] == "wait"]
        assert len(waits) == 2
        # the two calls' sleeps overlap: they really ran at the same time
        assert max(e["start"] for e in waits) < min(e["end"] for e in waits)
        assert r.driver("LeftActuator").commands_named("set_direction") == [(True,), (True,)]
        assert orch.engine.stores["Pulse"]["last_caller_done"] is True
        callers = [e for e in r.trace(kind="action") if e["node"] == "call"]
        assert {e["lane"] for e in callers} == {"LeftActuator", "RightActuator"}
        assert all(150 <= e["duration_ms"] < 290 for e in callers), callers
        assert time.monotonic() - began < 5.0


def test_decision_with_no_match_and_no_else_stops_that_flow(broker: BrokerProcess) -> None:
    with rig(broker.url, "no_match.yaml") as r:
        code, orch = r.run()
        assert code == 0, orch.failure
        warnings = [e for e in r.events if e["level"] == "warning"]
        assert len(warnings) == 1
        assert warnings[0]["node"] == "check" and "no guard holds" in warnings[0]["detail"]
        assert "drive" not in r.nodes()
        assert r.driver("LeftActuator").commands_named("set_enabled") == [(False,), (False,)]


def test_signal_from_a_raw_mqtt_client_wakes_the_accept_event(
    broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(broker)
    raw.subscribe("umlbot/test/signal/done")
    with rig(broker.url, "signals.yaml") as r:
        running = r.start()
        orch = running.orchestrator
        assert wait_for(lambda: orch.signals.waiting("go") == 1, 5.0), "the accept node never waited"
        raw.publish("umlbot/test/signal/go", "55")
        assert running.wait() == 0, orch.failure
        assert r.driver("LeftActuator").commands_named("set_duty_cycle") == [(55,)]
        accepted = [e for e in r.trace(kind="accept")]
        assert accepted[0]["value"] == 55
        done = raw.get(topic="umlbot/test/signal/done")
        assert json.loads(done.payload) == 110


def test_held_signal_and_text_payload(broker: BrokerProcess, raw_client: Callable[..., RawClient]) -> None:
    # a signal that arrives before anyone waits is held (newest wins); a non-JSON payload is text
    raw = raw_client(broker)
    raw.subscribe("umlbot/test/signal/done")
    with rig(broker.url, "held_signals.yaml") as r:
        running = r.start()
        orch = running.orchestrator
        assert wait_for(lambda: orch.signals.waiting("go") == 1, 5.0)
        raw.publish("umlbot/test/signal/note", "1")
        raw.publish("umlbot/test/signal/note", "hello there")
        assert wait_for(lambda: orch.signals.held("note"), 5.0)
        raw.publish("umlbot/test/signal/go", "")
        assert running.wait() == 0, orch.failure
        assert orch.engine.stores["RaspberryPI"]["note"] == "hello there"
        assert json.loads(raw.get(topic="umlbot/test/signal/done").payload) == "hello there"


def test_malformed_payloads_of_an_accepted_signal_arrive_as_text_and_break_nothing(
    broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    import structlog

    raw = raw_client(broker)
    raw.subscribe("umlbot/test/signal/done")
    deep = b"[" * 5000  # more than the JSON decoder's nesting: RecursionError inside it
    with rig(broker.url, "held_signals.yaml") as r, structlog.testing.capture_logs() as logs:
        running = r.start()
        orch = running.orchestrator
        assert wait_for(lambda: orch.signals.waiting("go") == 1, 5.0)
        for junk in (b"\xff\xfe", b"NaN", b'{"a": 1e999}', b"x" * 1_000_000, b'{"k": ' * 3000, deep):
            raw.publish("umlbot/test/signal/note", junk)
        raw.publish("umlbot/test/signal/go", b"[[[")  # a payload the accept does not store
        assert running.wait() == 0, orch.failure
        note = orch.engine.stores["RaspberryPI"]["note"]
    assert note == deep.decode()  # the newest held, as its text
    assert json.loads(raw.get(topic="umlbot/test/signal/done").payload) == deep.decode()
    assert not [e for e in logs if e.get("exc_info") or e.get("log_level") in ("error", "critical")]


def test_signal_names_no_accept_node_takes_are_ignored_with_one_log_line(
    broker: BrokerProcess, raw_client: Callable[..., RawClient], caplog: pytest.LogCaptureFixture,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # any client may publish under the robot's signal prefix: names the model does not accept are
    # not held (memory stays bounded) and are logged once, not once per message
    caplog.set_level(logging.DEBUG)
    raw = raw_client(broker)
    foreign = 300
    with rig(broker.url, "held_signals.yaml") as r:
        running = r.start()
        orch = running.orchestrator
        assert wait_for(lambda: orch.signals.waiting("go") == 1, 5.0)
        for i in range(foreign):
            raw.publish(f"umlbot/test/signal/intruder{i}", str(i))
        raw.publish("umlbot/test/signal/note", "kept")
        assert wait_for(lambda: orch.signals.ignored == foreign and orch.signals.held("note"), 10.0), \
            orch.signals.ignored
        assert not any(orch.signals.held(f"intruder{i}") for i in range(foreign))
        raw.publish("umlbot/test/signal/go", "")
        assert running.wait() == 0, orch.failure
        assert orch.engine.stores["RaspberryPI"]["note"] == "kept"
    printed = capsys.readouterr()
    logged = printed.out + printed.err + "\n".join(str(r.msg) for r in caplog.records)
    assert logged.count("ignoring signals that no accept node of the model waits for") == 1, logged[-2000:]
    assert "intruder0" in logged and "intruder1'" not in logged and '"intruder1"' not in logged


def test_exit_request_over_mqtt_sets_application_exit(
    broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(broker)
    raw.subscribe("umlbot/test/orchestrator/status")
    with rig(broker.url, "exit_loop.yaml") as r:
        running = r.start()
        orch = running.orchestrator
        assert wait_for(lambda: "nap" in r.nodes(), 5.0)
        began = time.monotonic()
        raw.publish("umlbot/test/orchestrator/exit", json.dumps({"reason": "end of test"}))
        assert running.wait() == 0, orch.failure
        assert time.monotonic() - began < orch.grace_s  # the lane ended by itself
        assert orch.exit_reason == "exit requested over MQTT: end of test"
        nodes = r.nodes()
        assert nodes[-2:] == ["halt", "end"]
        left = r.driver("LeftActuator")
        assert left.commands_named("set_enabled")[-2:] == [(False,), (False,)]  # the lane's, then ours
        assert not left.running
        states = []
        while True:
            try:
                message = raw.get(timeout=1.0, topic="umlbot/test/orchestrator/status")
            except TimeoutError:
                break
            states.append(OrchestratorStatus.model_validate_json(message.payload).state)
        assert states[-3:] == ["running", "stopping", "stopped"]


def test_only_a_json_object_on_the_exit_topic_requests_the_exit(
    broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    """Clearing a retained exit message (`mosquitto_pub -r -n`) or stray bytes do not end a run."""
    raw = raw_client(broker)
    with rig(broker.url, "exit_loop.yaml") as r:
        running = r.start()
        orch = running.orchestrator
        assert wait_for(lambda: "nap" in r.nodes(), 5.0)
        raw.publish("umlbot/test/orchestrator/exit", b"", retain=True)  # the retained-clear
        for junk in (b"", b"\xff\xfe", b"[1]", b"[" * 5000, b'"stop"', b"null", b'{"reason": 5}'):
            raw.publish("umlbot/test/orchestrator/exit", junk)
        # the first request that counts names its reason: so none of the junk before it counted
        raw.publish("umlbot/test/orchestrator/exit", json.dumps({"reason": "the real one"}))
        assert running.wait() == 0, orch.failure
        assert orch.exit_reason == "exit requested over MQTT: the real one"


def test_an_exit_reason_is_cut_and_a_reason_that_is_no_string_is_named(
    broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    import structlog

    from umlbot.services.orchestrator.orchestrator import MAX_REASON_CHARS

    raw = raw_client(broker)
    raw.subscribe("umlbot/test/orchestrator/status")
    with rig(broker.url, "exit_loop.yaml") as r, structlog.testing.capture_logs() as logs:
        running = r.start()
        orch = running.orchestrator
        assert wait_for(lambda: "nap" in r.nodes(), 5.0)
        raw.publish("umlbot/test/orchestrator/exit", b'{"reason": 5}')
        raw.publish("umlbot/test/orchestrator/exit", json.dumps({"reason": "a" * 3_000_000}))
        assert running.wait() == 0, orch.failure
    assert orch.exit_reason is not None
    assert orch.exit_reason.startswith("exit requested over MQTT: aaa")
    assert orch.exit_reason.endswith("… (3000000 characters)")
    assert len(orch.exit_reason) < MAX_REASON_CHARS + 100
    reasons = []
    while True:
        try:
            message = raw.get(timeout=1.0, topic="umlbot/test/orchestrator/status")
        except TimeoutError:
            break
        reasons.append(OrchestratorStatus.model_validate_json(message.payload).reason or "")
    assert reasons and max(len(reason) for reason in reasons) < MAX_REASON_CHARS + 100
    events = [e["event"] for e in logs]
    assert "ignoring an exit request whose reason is not a string" in events
    assert "ignoring an exit request that is not a JSON object" not in events
    assert max(len(str(e)) for e in logs) < 2000  # the 3 MB reason is in no log line


def test_grace_period_then_lanes_cancelled_and_motor_stopped(broker: BrokerProcess) -> None:
    with rig(broker.url, "stubborn.yaml") as r:
        running = r.start(grace_s=0.3)
        orch = running.orchestrator
        left = r.driver("LeftActuator")
        assert wait_for(lambda: left.running, 5.0)
        began = time.monotonic()
        orch.request_exit("test")
        assert running.wait() == 0
        assert 0.25 < time.monotonic() - began < 3.0
        assert not left.running
        assert "nap" not in r.nodes()  # cancelled, never completed


def test_trace_on_mqtt_and_in_a_file(
    broker: BrokerProcess, raw_client: Callable[..., RawClient], tmp_path: Path
) -> None:
    raw = raw_client(broker)
    raw.subscribe("umlbot/test/orchestrator/trace")
    raw.subscribe("umlbot/test/orchestrator/status")
    trace_file = tmp_path / "trace.jsonl"
    with rig(broker.url, "fork.yaml") as r:
        code, _ = r.run(trace_file=trace_file)
        assert code == 0
    lines = [json.loads(line) for line in trace_file.read_text(encoding="utf-8").splitlines()]
    from_file = [TraceEvent.model_validate(line) for line in lines]  # one event a line
    assert [e.node for e in from_file] == r.nodes()
    assert len(from_file) == 8  # start, before, fork, left, right, join, after, end
    assert [e.seq for e in from_file] == list(range(1, 9))
    received: list[TraceEvent] = []
    messages = 0
    while True:  # batches: JSON arrays of events in recording order, all before the final status
        message = raw.get(topic="umlbot/test/orchestrator/+")
        if message.topic.endswith("/status"):
            if OrchestratorStatus.model_validate_json(message.payload).state == "stopped":
                break
            continue
        batch = json.loads(message.payload)
        assert isinstance(batch, list) and batch
        received += [TraceEvent.model_validate(item) for item in batch]
        messages += 1
    assert received == from_file
    # the 100 ms action splits the run into two 20 ms windows at least, never one message per event
    assert 2 <= messages < len(from_file)
    left = next(e for e in from_file if e.node == "left")
    assert (left.lane, left.kind, left.detail) == ("RaspberryPI", "action", "LeftActuator.dutycycle(10)")
    assert left.end >= left.start and left.duration_ms >= 95


def test_no_trace_publishes_nothing(broker: BrokerProcess, raw_client: Callable[..., RawClient]) -> None:
    raw = raw_client(broker)
    raw.subscribe("umlbot/test/orchestrator/trace")
    with rig(broker.url, "no_match.yaml") as r:
        code, orch = r.run(trace=False, trace_listener=None)
        assert code == 0
        assert orch.recorder is None and orch.engine.trace is None
    with pytest.raises(TimeoutError):
        raw.get(timeout=0.5, topic="umlbot/test/orchestrator/trace")


def test_start_up_names_the_components_that_are_not_online(broker: BrokerProcess) -> None:
    with rig(broker.url, "sensor_decision.yaml", services=["motor"]) as r:
        began = time.monotonic()
        with pytest.raises(OrchestratorError) as caught:
            r.run(startup_timeout_s=0.5)
        assert time.monotonic() - began < 5.0
        assert "DistanceRead (sonar service" in str(caught.value)
        assert "LeftActuator" not in str(caught.value)
        # the online actuators are stopped on this exit path too
        assert r.driver("LeftActuator").commands_named("set_enabled") == [(False,)]


def test_run_orchestrator_helper_runs_to_the_end(broker: BrokerProcess) -> None:
    with rig(broker.url, "fork.yaml") as r:
        seen: list[dict[str, object]] = []
        code = run_orchestrator(r.model, r.settings, robot="test", handle_signals=False,
                                trace_listener=seen.append)
        assert code == 0
        assert [e["node"] for e in seen][-1] == "end"
        assert r.driver("LeftActuator").commands_named("set_duty_cycle") == [(10,)]
