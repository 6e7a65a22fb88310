"""`umlbot run --record` and `umlbot record` (from outside, over MQTT) of one run on a real
Mosquitto, and recordings that cannot be made: one clear line before anything runs."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from conftest import BrokerProcess
from orchestrator_support import MODELS, rig, wait_for
from record_support import ROOT, jsonl_nodes, read_with_mcap

from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import dump_compiled

pytestmark = pytest.mark.network

def umlbot(*args: str) -> list[str]:
    return [sys.executable, "-c", "from umlbot.cli import main; main()", *args]


def _trace_nodes(path: Path, topic: str) -> list[tuple[int, str, str]]:
    _, _, messages, _ = read_with_mcap(path)
    return sorted((m.seq, m.lane, m.node) for t, m, _ in messages if t == topic)


@pytest.mark.timeout(90)
def test_run_records_and_record_records_the_same_run_from_outside(
        mosquitto_broker: BrokerProcess, tmp_path: Path) -> None:
    url = mosquitto_broker.url
    compiled = tmp_path / "exit_loop.json"
    compiled.write_bytes(dump_compiled(compile_model(MODELS / "exit_loop.yaml")))
    outside, inside, trace = tmp_path / "outside.mcap", tmp_path / "run.mcap", tmp_path / "trace.jsonl"
    record_log, run_log = tmp_path / "record.log", tmp_path / "run.log"
    recorder = subprocess.Popen(umlbot("record", "--broker", url, "--robot", "test", "-o", str(outside)),
                                stdout=subprocess.DEVNULL, stderr=record_log.open("wb"))
    try:
        assert wait_for(lambda: "recording umlbot/test/#" in record_log.read_text(), 30.0), \
            record_log.read_text()
        with rig(url, "exit_loop.yaml") as r:
            run = subprocess.Popen(umlbot("run", str(compiled), "--broker", url, "--robot", "test",
                                          "--trace", str(trace), "--record", str(inside)),
                                   stdout=subprocess.DEVNULL, stderr=run_log.open("wb"))
            try:
                left = r.driver("LeftActuator")
                assert wait_for(lambda: left.running, 20.0), run_log.read_text()
                # some loops of the lane (msleep(20) each), then the end
                assert wait_for(lambda: trace.exists() and len(trace.read_text().splitlines()) > 30, 20.0)
                run.send_signal(signal.SIGTERM)
                assert run.wait(15) == 0, run_log.read_text()
            finally:
                if run.poll() is None:
                    run.kill()
                    run.wait(5)
        time.sleep(0.3)  # the last QoS 0 trace batch crosses the broker
        recorder.send_signal(signal.SIGINT)
        assert recorder.wait(15) == 0, record_log.read_text()
    finally:
        if recorder.poll() is None:
            recorder.kill()
            recorder.wait(5)
    assert "Traceback" not in record_log.read_text() + run_log.read_text()
    expected = jsonl_nodes(trace)
    assert expected[-1][2] == "end"
    topic = "/umlbot/test/orchestrator/trace"
    assert _trace_nodes(inside, topic) == expected  # the orchestrator's own trace
    assert _trace_nodes(outside, topic) == expected  # the trace topic over MQTT: nothing lost
    for path in (inside, outside):
        _, counts, messages, metadata = read_with_mcap(path)
        info = yaml.safe_load(metadata["rosbag2"]["serialized_metadata"])
        assert info["custom_data"]["umlbot.clock"] == "wall"
        calls = [m for t, m, _ in messages if t == "/umlbot/test/calls"]
        duty = [c for c in calls if c.component == "LeftActuator" and c.feature == "dutycycle"]
        assert duty and duty[0].answered and json.loads(duty[0].args_json) == [50]
        assert 0 <= duty[0].latency_ms < 2000
        states = [m.state for t, m, _ in messages if t == "/umlbot/test/orchestrator/status"]
        assert "running" in states
        assert counts["/umlbot/test/LeftActuator/state"] >= 1
        # wall time: the stamps are today's unix time, not sim seconds from 0
        assert all(abs(log_ns / 1e9 - time.time()) < 600 for _, _, log_ns in messages)
    assert "stopped" in [m.state for t, m, _ in read_with_mcap(outside)[2]
                         if t == "/umlbot/test/orchestrator/status"]


def test_run_record_without_the_trace_is_refused(tmp_path: Path) -> None:
    compiled = tmp_path / "exit_loop.json"
    compiled.write_bytes(dump_compiled(compile_model(MODELS / "exit_loop.yaml")))
    done = subprocess.run(umlbot("run", str(compiled), "--no-trace", "--record", str(tmp_path / "r.mcap")),
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 2
    assert "--record records the trace from MQTT: leave out --no-trace" in done.stderr
    assert not (tmp_path / "r.mcap").exists()


@pytest.mark.parametrize("command", ["sim", "run", "record"])
def test_an_unwritable_recording_is_one_line_before_anything_runs(command: str, tmp_path: Path) -> None:
    a_file = tmp_path / "a_file"
    a_file.write_text("x")
    out = str(a_file / "run.mcap")
    compiled = tmp_path / "exit_loop.json"
    compiled.write_bytes(dump_compiled(compile_model(MODELS / "exit_loop.yaml")))
    args = {"sim": ["sim", str(ROOT / "models" / "robot_car"), "--port", "0", "--record", out],
            "run": ["run", str(compiled), "--broker", "mqtt://127.0.0.1:1", "--record", out],
            "record": ["record", "--robot", "car", "--broker", "mqtt://127.0.0.1:1", "-o", out]}[command]
    began = time.monotonic()
    done = subprocess.run(umlbot(*args), capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 1
    assert done.stderr.strip() == f"error: cannot write the recording {out}: a part of its folder is a file"
    assert time.monotonic() - began < 30  # refused at once: no broker was waited for
