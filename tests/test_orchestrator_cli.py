"""`umlbot run` as a process: SIGTERM makes `Application.exit` true and the run ends cleanly,
start-up problems are one clear line and a non-zero exit, SIGKILL leaves the last will.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import BrokerProcess, RawClient
from orchestrator_support import MODELS, rig, wait_for

from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import dump_compiled
from umlbot.services.bus import OrchestratorStatus, TraceEvent

pytestmark = pytest.mark.network


def compiled_file(tmp_path: Path, model: str) -> Path:
    path = tmp_path / f"{Path(model).stem}.json"
    path.write_bytes(dump_compiled(compile_model(MODELS / model)))
    return path


def umlbot_run(*args: str, log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "INFO", "run", *args],
        stdout=subprocess.DEVNULL, stderr=log.open("wb"),
    )


def test_sigterm_sets_application_exit_and_ends_cleanly(
    broker: BrokerProcess, raw_client: Callable[..., RawClient], tmp_path: Path
) -> None:
    raw = raw_client(broker)
    raw.subscribe("umlbot/test/orchestrator/status")
    compiled = compiled_file(tmp_path, "exit_loop.yaml")
    trace = tmp_path / "trace.jsonl"
    log = tmp_path / "run.log"
    with rig(broker.url, "exit_loop.yaml") as r:
        proc = umlbot_run(str(compiled), "--broker", broker.url, "--robot", "test", "--trace", str(trace),
                          log=log)
        try:
            left = r.driver("LeftActuator")
            assert wait_for(lambda: left.running, 15.0), log.read_text()
            began = time.monotonic()
            proc.send_signal(signal.SIGTERM)
            assert proc.wait(10) == 0, log.read_text()
            assert time.monotonic() - began < 2.0  # the lane saw Application.exit, no grace needed
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(5)
        assert not left.running
        events = [TraceEvent.model_validate(json.loads(line)) for line in trace.read_text().splitlines()]
        assert [e.node for e in events][-2:] == ["halt", "end"]
        states = []
        while True:
            try:
                states.append(OrchestratorStatus.model_validate_json(
                    raw.get(timeout=0.5, topic="umlbot/test/orchestrator/status").payload))
            except TimeoutError:
                break
        assert [s.state for s in states][-2:] == ["stopping", "stopped"]
        assert states[-1].reason == "SIGTERM received"


def test_components_not_online_is_one_clear_error(amqtt_broker: BrokerProcess, tmp_path: Path) -> None:
    compiled = compiled_file(tmp_path, "sensor_decision.yaml")
    result = subprocess.run(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "ERROR", "run",
         str(compiled), "--broker", amqtt_broker.url, "--robot", "test", "--startup-timeout", "0.5"],
        capture_output=True, timeout=30,
    )
    assert result.returncode == 1
    last = result.stderr.decode().strip().splitlines()[-1]
    assert last.startswith("error: ")
    assert "DistanceRead (sonar service" in last and "LeftActuator (motor service" in last


def test_unreachable_broker_and_bad_file(tmp_path: Path) -> None:
    compiled = compiled_file(tmp_path, "fork.yaml")
    from conftest import free_port

    result = subprocess.run(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "ERROR", "run",
         str(compiled), "--broker", f"mqtt://127.0.0.1:{free_port()}"],
        capture_output=True, timeout=30,
    )
    assert result.returncode == 1
    assert "cannot connect to the MQTT broker" in result.stderr.decode()
    bad = tmp_path / "bad.json"
    bad.write_text('{"format_version": 99}')
    result = subprocess.run(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "run", str(bad)],
        capture_output=True, timeout=30,
    )
    assert result.returncode == 1
    assert "newer than this umlbot reads" in result.stderr.decode()


def test_sigkill_leaves_the_last_will_and_the_motors_stop(
    amqtt_broker: BrokerProcess, raw_client: Callable[..., RawClient], tmp_path: Path
) -> None:
    raw = raw_client(amqtt_broker)
    compiled = compiled_file(tmp_path, "exit_loop.yaml")
    log = tmp_path / "run.log"
    with rig(amqtt_broker.url, "exit_loop.yaml") as r:
        proc = umlbot_run(str(compiled), "--broker", amqtt_broker.url, "--robot", "test", "--no-trace",
                          log=log)
        try:
            left = r.driver("LeftActuator")
            assert wait_for(lambda: left.running, 15.0), log.read_text()
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(5)
        finally:
            if proc.poll() is None:
                proc.kill()
        # the services see the orchestrator's last will and stop the motor
        assert wait_for(lambda: not left.running, 5.0)
        raw.subscribe("umlbot/test/orchestrator/status")
        status = OrchestratorStatus.model_validate_json(
            raw.get(timeout=5.0, topic="umlbot/test/orchestrator/status").payload)
        assert status.state == "offline"
