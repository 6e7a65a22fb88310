"""Bad input and faults, the same for both engines: `umlbot run COMPILED` and the generated program.

Each test runs once with the interpreter (`umlbot run` as a child process) and once with the
generated C++ program (built once per session, tests/codegen_support.py), on a real Mosquitto with
mock services, and asserts the same exit code, the same one-line error and the same safe end.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from codegen_support import TEST_MODELS, built_programs, wait_for
from conftest import BrokerProcess, RawClient
from orchestrator_support import rig

from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import write_compiled

# the first test builds every program (tests/codegen_support.py): ~1-2 min on a loaded machine, once
pytestmark = [pytest.mark.network, pytest.mark.timeout(600)]

ENGINES = ["python", "cpp"]


def _argv(engine: str, model: str, tmp_path: Path) -> list[str]:
    """The command line of `engine` running TEST_MODELS[model] (no options yet)."""
    if engine == "cpp":
        return [str(built_programs()[model])]
    compiled = tmp_path / f"{model}.json"
    if not compiled.exists():
        write_compiled(compile_model(TEST_MODELS[model]), compiled)
    return [sys.executable, "-c", "from umlbot.cli import main; main()", "run", str(compiled)]


def _start(engine: str, model: str, tmp_path: Path, *options: str) -> subprocess.Popen[str]:
    argv = [*_argv(engine, model, tmp_path), "--robot", "test", "--log-level", "WARNING",
            "--trace", str(tmp_path / f"{engine}.jsonl"), *options]
    env = {**os.environ, "UMLBOT_BROKER": "", "UMLBOT_LOG_LEVEL": "WARNING"}
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _finish(proc: subprocess.Popen[str], timeout: float = 20.0) -> tuple[int, str]:
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
        raise AssertionError(f"did not finish within {timeout} s:\n{err[-2000:]}") from None
    return proc.returncode, err


def _nodes(tmp_path: Path, engine: str) -> list[str]:
    path = tmp_path / f"{engine}.jsonl"
    if not path.exists():
        return []
    return [json.loads(line)["node"] for line in path.read_text(encoding="utf-8").splitlines() if line]


def _error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(lines) == 1, err[-2000:]
    return lines[0]


@pytest.fixture(scope="session", autouse=True)
def _programs() -> None:
    built_programs()


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize(("url", "message"), [
    ("foo://127.0.0.1:1883", "error: bad broker URL foo://127.0.0.1:1883: the scheme must be mqtt:// or mqtts://"),
    ("mqtt://:1883", "error: bad broker URL mqtt://:1883: no host"),
    ("mqtt://user:secret@127.0.0.1:1", "error: cannot connect to the MQTT broker at mqtt://user:***@127.0.0.1:1"),
])
def test_a_broken_broker_url_is_one_error_line_and_exit_1(engine: str, url: str, message: str,
                                                           tmp_path: Path) -> None:
    code, err = _finish(_start(engine, "fork", tmp_path, "--broker", url))
    assert code == 1
    assert _error_line(err).startswith(message)
    assert "secret" not in err  # the password never shows


@pytest.mark.parametrize("engine", ENGINES)
def test_a_bad_option_is_exit_2(engine: str, tmp_path: Path) -> None:
    code, err = _finish(_start(engine, "fork", tmp_path, "--call-timeout", "soon"))
    assert code == 2, err
    assert "--call-timeout" in err


@pytest.mark.parametrize("engine", ENGINES)
def test_components_not_online_name_them_and_exit_1(engine: str, mosquitto_broker: BrokerProcess,
                                                    tmp_path: Path) -> None:
    with rig(mosquitto_broker.url, TEST_MODELS["sensor_decision"], services=["motor"]) as r:
        proc = _start(engine, "sensor_decision", tmp_path, "--broker", mosquitto_broker.url,
                      "--startup-timeout", "0.5")
        code, err = _finish(proc)
        assert code == 1
        line = _error_line(err)
        assert line.startswith("error: component(s) not online after 0.5 s: DistanceRead"), line
        assert "LeftActuator" not in line
        # the online actuators are stopped on this exit path too
        assert r.driver("LeftActuator").commands_named("set_enabled") == [(False,)]


@pytest.mark.parametrize("engine", ENGINES)
def test_sigterm_stops_the_motors_and_ends_cleanly(
    engine: str, mosquitto_broker: BrokerProcess,
    raw_client: Callable[..., RawClient], tmp_path: Path,
) -> None:
    raw = raw_client(mosquitto_broker)
    raw.subscribe("umlbot/test/orchestrator/status")
    with rig(mosquitto_broker.url, TEST_MODELS["stubborn"]) as r:
        proc = _start(engine, "stubborn", tmp_path, "--broker", mosquitto_broker.url, "--grace", "0.3")
        left = r.driver("LeftActuator")
        assert wait_for(lambda: left.running, 10.0), "the motor never ran"
        proc.send_signal(signal.SIGTERM)
        code, err = _finish(proc)
        assert code == 0, err
        assert not left.running
        assert left.commands_named("set_enabled")[-1] == (False,)
        assert "nap" not in _nodes(tmp_path, engine)  # cancelled, never completed
    states = []
    while True:
        try:
            states.append(json.loads(raw.get(timeout=1.0, topic="umlbot/test/orchestrator/status").payload))
        except TimeoutError:
            break
    assert [s["state"] for s in states][-3:] == ["running", "stopping", "stopped"]
    assert states[-1]["reason"] == "SIGTERM received"


@pytest.mark.parametrize("engine", ENGINES)
def test_a_killed_service_fails_the_run_safely(engine: str, mosquitto_broker: BrokerProcess,
                                               tmp_path: Path) -> None:
    with rig(mosquitto_broker.url, TEST_MODELS["fault_loop"]) as r:
        proc = _start(engine, "fault_loop", tmp_path, "--broker", mosquitto_broker.url)
        assert wait_for(lambda: _nodes(tmp_path, engine).count("read") >= 3, 10.0)
        r.host_of("DistanceRead").stop()
        code, err = _finish(proc)
        assert code == 1
        line = _error_line(err)
        assert line.startswith("error: fail-safe stop: "), line
        assert "DistanceRead" in line
        left = r.driver("LeftActuator")
        assert not left.running
        assert left.commands_named("set_enabled")[-1] == (False,)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("how", ["kill", "stop"])
def test_a_lost_broker_fails_the_run_and_stops_the_motors_when_it_is_back(
    engine: str, how: str, mosquitto_broker: BrokerProcess, tmp_path: Path
) -> None:
    # "stop": the broker shut down cleanly (SIGTERM) instead of killed (a broker that says goodbye
    # with an MQTT 5 DISCONNECT first: test_after_the_brokers_own_disconnect_the_program_connects_again)
    with rig(mosquitto_broker.url, TEST_MODELS["fault_loop"]) as r:
        proc = _start(engine, "fault_loop", tmp_path, "--broker", mosquitto_broker.url)
        assert wait_for(lambda: _nodes(tmp_path, engine).count("read") >= 3, 10.0)
        if how == "kill":
            mosquitto_broker.kill()
        else:
            mosquitto_broker.stop()
        mosquitto_broker.start()
        code, err = _finish(proc, 30.0)
        assert code == 1
        assert _error_line(err) == "error: fail-safe stop: connection to the MQTT broker lost"
        left = r.driver("LeftActuator")
        assert wait_for(lambda: not left.running, 5.0)


def test_an_error_reply_fails_both_engines_with_the_same_line(mosquitto_broker: BrokerProcess,
                                                              tmp_path: Path) -> None:
    lines = {}
    for engine in ENGINES:
        with rig(mosquitto_broker.url, TEST_MODELS["values"]):
            code, err = _finish(_start(engine, "values", tmp_path, "--broker", mosquitto_broker.url))
        assert code == 1, err
        lines[engine] = _error_line(err)
    assert lines["python"] == lines["cpp"]
    assert lines["cpp"].startswith(
        "error: fail-safe stop: lane RaspberryPI, node overdrive (LeftActuator.dutycycle(Count.depth * 60)): "
        "LeftActuator.dutycycle: "), lines


@pytest.mark.parametrize("engine", ENGINES)
def test_the_heartbeat_keeps_the_motor_running_and_a_frozen_orchestrator_stops_it(
    engine: str, mosquitto_broker: BrokerProcess, tmp_path: Path,
) -> None:
    # the motor's watchdog is 0.6 s; the model enables it once and then sleeps a minute: only the
    # orchestrator's heartbeat (its lease, docs/services.md) keeps it running
    lease = {"LeftActuator": {"watchdog_s": 0.6}}
    with rig(mosquitto_broker.url, TEST_MODELS["stubborn"], settings=lease) as r:
        proc = _start(engine, "stubborn", tmp_path, "--broker", mosquitto_broker.url, "--grace", "0.3")
        left = r.driver("LeftActuator")
        try:
            assert wait_for(lambda: left.running, 10.0), "the motor never ran"
            assert not wait_for(lambda: not left.running, 2.0), "the motor stopped while the heartbeat came"
            proc.send_signal(signal.SIGSTOP)  # frozen: no heartbeat, no goodbye
            assert wait_for(lambda: not left.running, 3.0), "a frozen orchestrator's motor ran on"
            service = r.host_of("LeftActuator").services["LeftActuator"]
            assert getattr(service, "stop_reason", None) == "orchestrator unresponsive"
        finally:
            proc.send_signal(signal.SIGCONT)
            proc.send_signal(signal.SIGTERM)
        code, err = _finish(proc)
        assert code == 0, err


@pytest.mark.parametrize("engine", ENGINES)
def test_retained_exit_requests_and_signals_published_during_the_run_are_ignored(
    engine: str, mosquitto_broker: BrokerProcess,
    raw_client: Callable[..., RawClient], tmp_path: Path,
) -> None:
    # a retained request is stale by nature (docs/fleet.md): one published while the program runs
    # (or passed on by a fleet bridge on every reconnect) must not look live. Over MQTT 3.1.1 the
    # broker clears RETAIN on what it forwards to a subscriber; over MQTT 5 with Retain As
    # Published it keeps it, so the program sees it is retained and ignores it, as `umlbot run` does.
    raw = raw_client(mosquitto_broker)
    raw.subscribe("umlbot/test/orchestrator/status")
    with rig(mosquitto_broker.url, TEST_MODELS["signals"]) as r:
        proc = _start(engine, "signals", tmp_path, "--broker", mosquitto_broker.url)
        try:
            while json.loads(raw.get(timeout=10.0, topic="umlbot/test/orchestrator/status").payload)[
                    "state"] != "running":
                pass
            left = r.driver("LeftActuator")
            raw.publish("umlbot/test/signal/go", "77", retain=True)
            assert not wait_for(lambda: left.commands_named("set_duty_cycle") != [], 1.0), \
                "a retained signal was accepted"
            raw.publish("umlbot/test/orchestrator/exit", json.dumps({"reason": "stale"}), retain=True)
            assert not wait_for(lambda: proc.poll() is not None, 1.5), "a retained exit request ended the run"
            raw.publish("umlbot/test/signal/go", "33")  # a live signal: the model goes on and ends
            code, err = _finish(proc)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        assert code == 0, err
        assert left.commands_named("set_duty_cycle") == [(33,)]
        assert "stale" not in err
    states = []
    while True:
        try:
            states.append(json.loads(raw.get(timeout=1.0, topic="umlbot/test/orchestrator/status").payload))
        except TimeoutError:
            break
    assert states[-1]["state"] == "stopped"
    assert states[-1]["reason"] is None or "stale" not in states[-1]["reason"]


@pytest.mark.parametrize("engine", ENGINES)
def test_on_a_broker_that_speaks_only_3_1_1_auto_falls_back_and_5_is_refused(
    engine: str, amqtt_broker: BrokerProcess, tmp_path: Path,
) -> None:
    # `?protocol=` as `umlbot run` reads it: auto (the default) tries MQTT 5 and falls back to
    # 3.1.1 on a broker that refuses 5 (the embedded amqtt broker); 5 insists, and cannot start
    with rig(amqtt_broker.url, TEST_MODELS["fork"]) as r:
        code, err = _finish(_start(engine, "fork", tmp_path, "--broker", amqtt_broker.url))
        assert code == 0, err
        assert r.driver("LeftActuator").commands_named("set_duty_cycle") == [(10,)]
        code, err = _finish(_start(engine, "fork", tmp_path, "--broker", amqtt_broker.url + "?protocol=5",
                                   "--startup-timeout", "1"), 60.0)
        assert code == 1, err
        assert _error_line(err).startswith(
            f"error: cannot connect to the MQTT broker at {amqtt_broker.url}"), err


@pytest.mark.parametrize("engine", ENGINES)
def test_a_bad_protocol_in_the_broker_url_is_one_error_line_and_exit_1(engine: str, tmp_path: Path) -> None:
    code, err = _finish(_start(engine, "fork", tmp_path, "--broker", "mqtt://127.0.0.1:1?protocol=4.2"))
    assert code == 1, err
    assert _error_line(err) == ("error: bad broker URL mqtt://127.0.0.1:1?protocol=4.2: "
                                "protocol must be auto, 3.1.1 or 5")


class _KickingBroker:
    """A minimal MQTT 5 broker that accepts every CONNECT, then ends the connection after `after_s`
    with a DISCONNECT of its own ("Server shutting down", as a broker restarting says goodbye)."""

    def __init__(self, after_s: float = 0.3) -> None:
        self.after_s = after_s
        self.connects: list[tuple[int, str]] = []  # (protocol level, client id) of each CONNECT
        self._server = socket.create_server(("127.0.0.1", 0))
        self._server.settimeout(0.1)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self._server.getsockname()[1]}"

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        self._server.close()

    def _serve(self) -> None:
        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except TimeoutError:
                continue
            threading.Thread(target=self._session, args=(conn,), daemon=True).start()

    @staticmethod
    def _read_packet(conn: socket.socket) -> tuple[int, bytes]:
        head = conn.recv(1)
        if not head:
            raise ConnectionError("closed")
        length, shift = 0, 0
        while True:
            byte = conn.recv(1)[0]
            length |= (byte & 0x7F) << shift
            shift += 7
            if not byte & 0x80:
                break
        body = b""
        while len(body) < length:
            chunk = conn.recv(length - len(body))
            if not chunk:
                raise ConnectionError("closed")
            body += chunk
        return head[0] >> 4, body

    def _session(self, conn: socket.socket) -> None:
        with conn:
            try:
                conn.settimeout(2.0)
                kind, body = self._read_packet(conn)
                assert kind == 1  # CONNECT
                level = body[6]
                at = 10
                if level == 5:  # skip the CONNECT properties (a one-byte length here)
                    at += 1 + body[at]
                size = int.from_bytes(body[at:at + 2], "big")
                self.connects.append((level, body[at + 2:at + 2 + size].decode()))
                conn.sendall(bytes([0x20, 3, 0, 0, 0]) if level == 5 else bytes([0x20, 2, 0, 0]))
                time.sleep(self.after_s)
                conn.sendall(bytes([0xE0, 2, 0x8B, 0]) if level == 5 else b"")
            except (OSError, ConnectionError, AssertionError, IndexError):
                pass


@pytest.mark.parametrize("engine", ENGINES)
def test_after_the_brokers_own_disconnect_the_program_connects_again(engine: str, tmp_path: Path) -> None:
    # MQTT 5 lets a broker end a connection with a DISCONNECT of its own (a restart, a session
    # taken over); libmosquitto's network thread then ends instead of reconnecting: the program
    # must start it again, as it reconnects after a lost connection
    broker = _KickingBroker()
    try:
        proc = _start(engine, "fork", tmp_path, "--broker", broker.url, "--startup-timeout", "3")
        code, err = _finish(proc, 30.0)
    finally:
        broker.close()
    assert code == 1, err
    assert _error_line(err).startswith("error: "), err
    ids = [client for level, client in broker.connects if client.startswith("umlbot-orchestrator-test-")]
    assert all(level == 5 for level, _ in broker.connects), broker.connects
    assert len(ids) >= 3 and len(set(ids)) == 1, broker.connects  # the same client, again and again
