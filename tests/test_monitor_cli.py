"""`umlbot monitor --json` over real brokers, and `--replay` of a recorded trace."""

from __future__ import annotations

import json
import os
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess, RawClient, free_port
from robot_run import CAR_COMPONENTS, Proc, compile_car, processes, start_services, umlbot_argv

ROBOT = "car"


def monitor(workdir: Path, broker: BrokerProcess, *extra: str) -> Proc:
    return Proc("monitor", umlbot_argv("monitor", "--json", "--robot", ROBOT, "--duration", "90", *extra),
                workdir, broker.url)


def wait_subscribed(raw: RawClient, mon: Proc) -> None:
    """A retained status proves the monitor's subscription is in place (it gets it on subscribe)."""
    raw.publish(f"umlbot/{ROBOT}/Probe/status", '{"state":"online","impl":"probe"}', retain=True)
    mon.wait_line(lambda e: e["type"] == "availability" and e["component"] == "Probe")


def test_json_shows_calls_trace_and_availability(
    broker: BrokerProcess, raw_client: Any, tmp_path: Path
) -> None:
    raw = raw_client(broker)
    with processes() as made:
        mon = monitor(tmp_path, broker)
        made.append(mon)
        wait_subscribed(raw, mon)
        base = f"umlbot/{ROBOT}"
        raw.publish(f"{base}/LeftActuator/status", '{"state":"online","impl":"l298n"}', retain=True)
        raw.publish(f"{base}/LeftActuator/call/dutycycle",
                    json.dumps({"id": "c1", "reply_to": f"{base}/_reply/tester", "args": [60]}))
        time.sleep(0.05)
        raw.publish(f"{base}/_reply/tester", '{"id":"c1","ok":true,"value":null}')
        raw.publish(f"{base}/LeftActuator/call/enabled", "true")  # fire-and-forget
        trace = {"lane": "LeftActuator", "node": "go", "kind": "action", "start": 1.0, "end": 1.01,
                 "duration_ms": 10.0, "level": "info", "detail": "LeftActuator.enabled(true)"}
        raw.publish(f"{base}/orchestrator/trace", json.dumps(trace))
        raw.publish(f"{base}/LeftActuator/status", '{"state":"offline"}', retain=True)

        online = mon.wait_line(lambda e: e["type"] == "availability" and e["component"] == "LeftActuator")
        assert online["state"] == "online" and online["impl"] == "l298n"
        call = mon.wait_line(lambda e: e["type"] == "call" and e.get("id") == "c1")
        assert (call["component"], call["feature"], call["args"], call["ok"]) == ("LeftActuator", "dutycycle",
                                                                                 [60], True)
        assert call["latency_ms"] >= 40.0  # the reply came at least 50 ms after the request
        forgotten = mon.wait_line(lambda e: e["type"] == "call" and e["feature"] == "enabled")
        assert forgotten["args"] == [True] and "latency_ms" not in forgotten
        traced = mon.wait_line(lambda e: e["type"] == "trace")
        assert (traced["lane"], traced["node"], traced["duration_ms"]) == ("LeftActuator", "go", 10.0)
        offline = mon.wait_line(lambda e: e["type"] == "availability" and e["component"] == "LeftActuator")
        assert offline["state"] == "offline"
        assert mon.stop() == 0
        for topic in (f"{base}/Probe/status", f"{base}/LeftActuator/status"):
            raw.publish(topic, b"", retain=True)


def test_json_shows_a_real_short_run_and_the_trace_replays(
    broker: BrokerProcess, raw_client: Any, tmp_path: Path
) -> None:
    compiled = compile_car(tmp_path)
    trace_file = tmp_path / "trace.jsonl"
    raw = raw_client(broker)
    with processes() as made:
        mon = monitor(tmp_path, broker)
        made.append(mon)
        wait_subscribed(raw, mon)
        services = start_services(made, tmp_path, lambda kind: broker.url, robot=ROBOT)
        online: set[str] = set()
        while online != CAR_COMPONENTS:
            event = mon.wait_line(lambda e: e["type"] == "availability" and e["state"] == "online", 30)
            online.add(event["component"])
        run = Proc("run", umlbot_argv("run", str(compiled), "--robot", ROBOT, "--trace", str(trace_file)),
                   tmp_path, broker.url)
        made.append(run)
        mon.wait_line(lambda e: e["type"] == "orchestrator" and e["state"] == "running", 30)
        call = mon.wait_line(lambda e: e["type"] == "call" and e["component"] == "DistanceRead", 30)
        assert call["ok"] is True and isinstance(call["value"], int) and call["latency_ms"] > 0
        mon.wait_line(lambda e: e["type"] == "trace" and e["kind"] == "action", 30)
        raw.publish(f"umlbot/{ROBOT}/orchestrator/exit", "{}")
        assert run.popen.wait(30) == 0, run.log_text()[-2000:]
        for service in services:  # a graceful stop publishes "offline"
            assert service.stop() == 0, service.log_text()[-2000:]
        offline: set[str] = set()
        while offline != CAR_COMPONENTS:
            event = mon.wait_line(lambda e: e["type"] == "availability" and e["state"] == "offline", 30)
            offline.add(event["component"])
        events = mon.events()
        raw.publish(f"umlbot/{ROBOT}/Probe/status", b"", retain=True)

    calls = [e for e in events if e["type"] == "call" and e.get("latency_ms") is not None]
    assert {(e["component"], e["feature"]) for e in calls} >= {
        ("LeftActuator", "dutycycle"), ("RightActuator", "dutycycle"), ("Sensor", "angle"),
        ("DistanceRead", "value"), ("LeftActuator", "enabled"),
    }
    assert all(e["ok"] for e in calls)
    live_traces = [e for e in events if e["type"] == "trace"]
    assert {e["lane"] for e in live_traces} >= {"RaspberryPI"}
    recorded = [json.loads(line) for line in trace_file.read_text().splitlines() if line]
    assert len(recorded) >= len(live_traces) > 0

    replayed = subprocess.run(umlbot_argv("monitor", "--replay", str(trace_file), "--json", "--robot", ROBOT),
                              capture_output=True, text=True, timeout=60, check=False)
    assert replayed.returncode == 0, replayed.stderr
    lines = [json.loads(line) for line in replayed.stdout.splitlines()]
    assert [(e["lane"], e["node"], e["kind"]) for e in lines] == [
        (r["lane"], r["node"], r["kind"]) for r in recorded
    ]
    assert all(e["type"] == "trace" and e["robot"] == ROBOT for e in lines)


def _trace_file(path: Path, count: int) -> Path:
    with path.open("w", encoding="utf-8") as out:
        for i in range(count):
            out.write(json.dumps({"lane": "Sensor", "node": f"n{i % 3}", "kind": "action", "start": 100.0 + i,
                                  "end": 100.0 + i + 0.002, "duration_ms": 2.0 + i, "level": "info",
                                  "detail": f"Sensor.angle({i})"}) + "\n")
    return path


def test_replay_view_draws_the_tables(tmp_path: Path) -> None:
    path = _trace_file(tmp_path / "t.jsonl", 9)
    result = subprocess.run(umlbot_argv("monitor", "--replay", str(path), "--speed", "0"),
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 0, result.stderr
    for text in ("replay, 9 events", "Lanes", "Actions", "Sensor.angle(8)", "p99 ms"):
        assert text in result.stdout


def test_replay_keeps_the_recorded_pace(tmp_path: Path) -> None:
    path = _trace_file(tmp_path / "t.jsonl", 3)  # node ends 1 s apart: 2 s of gaps
    started = time.monotonic()
    result = subprocess.run(umlbot_argv("monitor", "--replay", str(path), "--json", "--speed", "4"),
                            capture_output=True, text=True, timeout=60, check=False)
    elapsed = time.monotonic() - started
    assert result.returncode == 0, result.stderr
    assert len(result.stdout.splitlines()) == 3
    assert elapsed >= 0.5  # 2 s of recorded gaps at 4x


def test_bad_replay_file_is_one_line_error(tmp_path: Path) -> None:
    path = tmp_path / "bad.jsonl"
    path.write_text("not json\n", encoding="utf-8")
    result = subprocess.run(umlbot_argv("monitor", "--replay", str(path), "--json"),
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 1
    assert "bad.jsonl:1: not a trace event" in result.stderr
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize("as_json", [False, True])
def test_a_bad_line_anywhere_or_an_empty_trace_is_an_error_before_any_view(tmp_path: Path,
                                                                          as_json: bool) -> None:
    good = _trace_file(tmp_path / "good.jsonl", 2).read_text()
    (tmp_path / "late.jsonl").write_text(good + "garbage\n")
    (tmp_path / "empty.jsonl").write_text("\n")
    expected = {"late.jsonl": "late.jsonl:3: not a trace event", "empty.jsonl": "no trace events",
                "nope.jsonl": "cannot read trace file"}
    for name, message in expected.items():
        result = subprocess.run(umlbot_argv("monitor", "--replay", str(tmp_path / name), "--speed", "0",
                                            *(["--json"] if as_json else [])),
                                capture_output=True, text=True, timeout=60, check=False)
        assert result.returncode == 1, (name, result.stdout, result.stderr)
        assert message in result.stderr and "Traceback" not in result.stderr
        assert result.stdout == "", (name, result.stdout)  # no view drawn, no event printed


def test_replayed_events_name_the_robot_only_when_given(tmp_path: Path) -> None:
    path = _trace_file(tmp_path / "t.jsonl", 2)
    for robot_arg, robot in (([], None), (["--robot", "car"], "car")):
        result = subprocess.run(umlbot_argv("monitor", "--replay", str(path), "--json", *robot_arg),
                                capture_output=True, text=True, timeout=60, check=False)
        assert result.returncode == 0, result.stderr
        events = [json.loads(line) for line in result.stdout.splitlines()]
        assert len(events) == 2 and all(e["type"] == "trace" for e in events)
        assert [e.get("robot") for e in events] == [robot, robot]


def test_monitor_without_broker_fails_cleanly(tmp_path: Path) -> None:
    nowhere = f"mqtt://127.0.0.1:{free_port()}"
    result = subprocess.run(
        umlbot_argv("monitor", "--json", "--broker", nowhere, "--connect-timeout", "1"),
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert result.returncode == 1
    assert "cannot connect" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize("robot_arg", [[], ["--robot", ROBOT]])
def test_live_view_renders(mosquitto_broker: BrokerProcess, raw_client: Any, tmp_path: Path,
                           robot_arg: list[str]) -> None:
    raw = raw_client(mosquitto_broker)
    raw.publish(f"umlbot/{ROBOT}/Sensor/status", '{"state":"online","impl":"servo"}', retain=True)
    view = subprocess.Popen(
        umlbot_argv("monitor", "--broker", mosquitto_broker.url, "--duration", "2", *robot_arg),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env={**os.environ, "COLUMNS": "200"},
    )
    deadline = time.monotonic() + 30
    while view.poll() is None and time.monotonic() < deadline:  # until the view has seen some
        raw.publish(f"umlbot/{ROBOT}/LeftActuator/call/enabled", "true")  # fire-and-forget
        time.sleep(0.2)
    stdout, stderr = view.communicate(timeout=30)
    assert view.returncode == 0, stderr
    assert "Components" in stdout and "Sensor" in stdout and "online" in stdout
    # rich must not read the arguments [true] as markup
    assert any("LeftActuator.enabled" in line and "[true]" in line for line in stdout.splitlines())


def test_live_view_counts_the_time_online_from_the_status_since(mosquitto_broker: BrokerProcess,
                                                              raw_client: Any) -> None:
    """A component online for ten minutes before the monitor starts is shown as 10m, not 0.0s."""
    raw = raw_client(mosquitto_broker)
    since = time.time() - 600
    raw.publish(f"umlbot/{ROBOT}/Sensor/status",
                json.dumps({"state": "online", "impl": "servo", "since": since}), retain=True)
    result = subprocess.run(
        umlbot_argv("monitor", "--broker", mosquitto_broker.url, "--robot", ROBOT, "--duration", "1.5"),
        capture_output=True, text=True, timeout=60, env={**os.environ, "COLUMNS": "200"}, check=False)
    assert result.returncode == 0, result.stderr
    rows = [line for line in result.stdout.splitlines() if "Sensor" in line and "online" in line]
    assert rows, result.stdout
    assert "10m" in rows[-1] and "s " not in rows[-1].split("servo", 1)[1], rows[-1]


def test_malformed_messages_are_counted_never_a_traceback(
    broker: BrokerProcess, raw_client: Any, tmp_path: Path
) -> None:
    raw = raw_client(broker)
    base = f"umlbot/{ROBOT}"
    with processes() as made:
        mon = monitor(tmp_path, broker)
        made.append(mon)
        wait_subscribed(raw, mon)
        bad_payloads = [b"[" * 5000, b"\xff\xfe{", b'{"lane": NaN, "state": NaN}',
                        b'{"state": [1], "impl": 7, "reason": {}, "ok": "yes"}', b"[1, {}, null]"]
        for topic in ("M/status", "M/state", "signal/go", "orchestrator/status", "orchestrator/trace",
                      "orchestrator/exit", "_reply/x", "M/call/enabled"):
            for payload in bad_payloads:
                raw.publish(f"{base}/{topic}", payload)
        good = [{"lane": "Main", "node": f"n{i}", "kind": "action", "start": 1.0, "end": 1.01,
                 "duration_ms": 10.0, "level": "info", "detail": "M.enabled(true)", "seq": i}
                for i in (1, 2, 3)]
        raw.publish(f"{base}/orchestrator/trace", json.dumps(good[:2]))  # the batched form
        raw.publish(f"{base}/orchestrator/trace", json.dumps(good[2]))  # the single-event form
        # none of the malformed trace payloads made an event; the good ones after them all did
        seen = [mon.wait_line(lambda e: e["type"] == "trace") for _ in range(3)]
        assert [(e["node"], e["seq"]) for e in seen] == [("n1", 1), ("n2", 2), ("n3", 3)]
        assert mon.stop() == 0
        raw.publish(f"{base}/Probe/status", b"", retain=True)
        raw.publish(f"{base}/M/status", b"", retain=True)
    log = mon.log_text()
    assert "Traceback" not in log and "bus_handler_failed" not in log
    assert log.count("malformed message skipped") == 1, log[-3000:]
