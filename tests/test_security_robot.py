"""The robot car on a secured broker: every process logs in as its own user, the ACL holds.

On Mosquitto (shipped umlbot.conf and umlbot.acl) and on the embedded broker (shipped
amqtt/acl.yaml): the four mock services and the orchestrator run the car to a clean exit, the
monitor user watches it, a user without rights cannot move a motor, and no password appears in
any process's log (all of them at DEBUG).
"""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from robot_run import CAR_COMPONENTS, Proc, compile_car, processes, start_services, umlbot_argv
from secured_brokers import (
    ROBOT,
    AuthFiles,
    SecuredBroker,
    connect_client,
    make_auth_files,
    start_secured,
    stop_broker,
    url_of,
)


@pytest.fixture(scope="module")
def auth(tmp_path_factory: pytest.TempPathFactory) -> AuthFiles:
    return make_auth_files(tmp_path_factory.mktemp("auth"), tmp_path_factory.mktemp("certs"))


@pytest.fixture(params=["mosquitto", "amqtt"])
def secured(request: pytest.FixtureRequest, tmp_path: Path, auth: AuthFiles) -> Iterator[SecuredBroker]:
    broker = start_secured(request.param, tmp_path, auth)
    try:
        yield broker
    finally:
        stop_broker(broker)


def call(secured: SecuredBroker, role: str, target: str, *args: str) -> subprocess.CompletedProcess[str]:
    """`umlbot call` as `role`, the credentials in UMLBOT_BROKER (never on the command line)."""
    env = {**os.environ, "UMLBOT_BROKER": url_of(secured, role), "UMLBOT_LOG_LEVEL": "DEBUG"}
    return subprocess.run(umlbot_argv("call", target, *args, "--robot", ROBOT, "--timeout", "2"),
                          capture_output=True, text=True, timeout=60, check=False, env=env)


def motor_state(secured: SecuredBroker) -> dict[str, Any]:
    """LeftActuator's retained state, read as the monitor user."""
    watcher = connect_client(secured.port, "umlbot-monitor", secured.passwords["monitor"])
    try:
        assert watcher.accepted
        assert watcher.subscribe(f"umlbot/{ROBOT}/LeftActuator/state")
        [message] = watcher.received(f"umlbot/{ROBOT}/LeftActuator/state", 2.0)[-1:]
        state: dict[str, Any] = json.loads(message.payload)
        return state
    finally:
        watcher.client.disconnect()
        watcher.client.loop_stop()


def test_the_car_runs_with_one_user_per_process(secured: SecuredBroker, tmp_path: Path) -> None:
    compiled = compile_car(tmp_path)
    with processes() as made:
        mon = Proc("monitor", umlbot_argv("monitor", "--json", "--robot", ROBOT, "--duration", "120"),
                   tmp_path, url_of(secured, "monitor"))
        made.append(mon)
        services = start_services(made, tmp_path, lambda kind: url_of(secured, kind), robot=ROBOT)
        online: set[str] = set()
        while online != CAR_COMPONENTS:
            event = mon.wait_line(lambda e: e["type"] == "availability" and e["state"] == "online", 30)
            online.add(event["component"])

        # A user without rights cannot move a motor; the operator can.
        for role in ("monitor", "sonar"):
            refused = call(secured, role, "LeftActuator.dutycycle", "100")
            assert refused.returncode != 0
            intruder = connect_client(secured.port, f"umlbot-{role}", secured.passwords[role])
            intruder.publish(f"umlbot/{ROBOT}/LeftActuator/call/dutycycle", "100")
            intruder.publish(f"umlbot/{ROBOT}/LeftActuator/call/enabled", "true")
            intruder.client.disconnect()
            intruder.client.loop_stop()
        allowed = call(secured, "operator", "LeftActuator.dutycycle", "35")
        assert allowed.returncode == 0, allowed.stderr
        state = motor_state(secured)
        assert state["dutycycle"] == 35 and state["enabled"] is False, state

        run = Proc("run", umlbot_argv("run", str(compiled), "--robot", ROBOT), tmp_path,
                   url_of(secured, "orchestrator"))
        made.append(run)
        mon.wait_line(lambda e: e["type"] == "orchestrator" and e["state"] == "running", 30)
        distance = mon.wait_line(lambda e: e["type"] == "call" and e["component"] == "DistanceRead", 30)
        assert distance["ok"] is True
        mon.wait_line(lambda e: e["type"] == "trace" and e["kind"] == "action", 30)
        stop = call(secured, "operator", "LeftActuator.enabled", "false")  # operator traffic mid-run
        assert stop.returncode == 0, stop.stderr
        exit_request = connect_client(secured.port, "umlbot-operator", secured.passwords["operator"])
        exit_request.publish(f"umlbot/{ROBOT}/orchestrator/exit", "{}")
        exit_request.client.disconnect()
        exit_request.client.loop_stop()
        assert run.popen.wait(30) == 0, run.log_text()[-3000:]
        for service in services:
            assert service.stop() == 0, service.log_text()[-2000:]
        assert mon.stop() == 0
        logs = {proc.name: proc.log_text() + "\n".join(proc.seen) for proc in made}

    events = mon.events()
    calls = [e for e in events if e["type"] == "call" and e.get("latency_ms") is not None]
    assert {(e["component"], e["feature"]) for e in calls} >= {("LeftActuator", "dutycycle"),
                                                               ("DistanceRead", "value")}
    assert all(e["ok"] for e in calls if e["component"] != "LeftActuator" or e["feature"] != "dutycycle"
               or e["args"] != [100])
    assert not any(e["type"] == "call" and e["args"] == [100] for e in events)  # the intruders' calls
    for name, text in logs.items():
        assert "mqtt_connected" in text, f"{name} logged nothing useful"
        for password in secured.passwords.values():
            assert password not in text, f"a password leaked into the {name} log"


def test_a_service_with_the_wrong_user_cannot_serve(secured: SecuredBroker, tmp_path: Path) -> None:
    """The sonar's user cannot run the motor service: its components' topics are not its own."""
    with processes() as made:
        mon = Proc("monitor", umlbot_argv("monitor", "--json", "--robot", ROBOT, "--duration", "60"),
                   tmp_path, url_of(secured, "monitor"))
        made.append(mon)
        (tmp_path / "car.txt").write_text("LeftActuator=l298n\n", encoding="utf-8")
        wrong = Proc("motor", umlbot_argv("service", "motor", "--deploy", str(tmp_path / "car.txt"),
                                          "--driver", "mock", "--robot", ROBOT, "--connect-timeout", "3"),
                     tmp_path, url_of(secured, "sonar"))
        made.append(wrong)
        with contextlib.suppress(subprocess.TimeoutExpired):
            wrong.popen.wait(8)
        mon.drain(1.0)
        # Whatever the service did, the broker never let an "online" status through.
        assert not any(e["type"] == "availability" and e["component"] == "LeftActuator"
                       and e["state"] == "online" for e in mon.events())
        refused = call(secured, "operator", "LeftActuator.enabled", "false")
        assert refused.returncode != 0  # nobody serves LeftActuator
