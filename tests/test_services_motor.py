"""The motor service over real brokers: features via the bus and via raw bare payloads, error
replies, retained state, and every safety stop (service stop, SIGTERM/SIGINT of the process,
orchestrator last will, broker loss, watchdog), and the sim driver driving a simulated world."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess, RawClient
from services_support import ROBOT, StateWatch, client, deployment, raw_state, running, sim_world, wait_for

from umlbot.base.errors import RemoteError
from umlbot.services.bus import Topics
from umlbot.services.motor.mock import MockMotorChannel
from umlbot.services.pins import pigpio as pigpio_connection
from umlbot.testing.pigpio import FakePi

pytestmark = pytest.mark.network
TOPICS = Topics(ROBOT)


def mock(host: Any, name: str = "LeftActuator") -> MockMotorChannel:
    driver: MockMotorChannel = host.drivers[name]
    return driver


def test_every_feature_via_the_bus_and_state_follows(broker: BrokerProcess) -> None:
    with running("motor", deployment(), broker.url) as host, client(broker.url) as bus:
        watch = StateWatch(bus, "LeftActuator")
        watch.wait("LeftActuator", lambda s: s["enabled"] is False)
        assert bus.call("LeftActuator", "dutycycle", 60) is None
        assert bus.call("LeftActuator", "direction", False) is None
        assert bus.call("LeftActuator", "enabled", True) is None
        left = mock(host)
        assert (left.enabled, left.clockwise, left.duty_cycle_percent) == (True, False, 60)
        state = watch.wait("LeftActuator", lambda s: s["enabled"])
        assert state == {"enabled": True, "clockwise": False, "dutycycle": 60, "running": True,
                         "stop_reason": None}
        assert mock(host, "RightActuator").commands == [("stop", ())], "the other channel untouched"
    assert not left.running and left.closed, "stopping the service stops and closes the motor"


def test_status_is_online_with_features_then_offline(
    broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(broker)
    with running("motor", deployment(), broker.url):
        raw.subscribe(TOPICS.status("LeftActuator"))
        status = json.loads(raw.get(topic=TOPICS.status("LeftActuator")).payload)
        assert status["state"] == "online" and status["impl"] == "l298n"
        assert status["features"] == ["direction", "dutycycle", "enabled"]
    msg = raw.get(topic=TOPICS.status("LeftActuator"))
    assert json.loads(msg.payload)["state"] == "offline"


def test_raw_bare_payloads_drive_the_motor(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(mosquitto_broker)
    with running("motor", deployment(), mosquitto_broker.url) as host:
        raw.publish(TOPICS.call("RightActuator", "dutycycle"), "60")
        raw.publish(TOPICS.call("RightActuator", "direction"), "[true]")
        raw.publish(TOPICS.call("RightActuator", "enabled"), "true")
        right = mock(host, "RightActuator")
        assert right.wait_until(lambda: right.running, 5.0)
        assert right.duty_cycle_percent == 60 and right.clockwise
        raw.subscribe(TOPICS.state("RightActuator"))
        state = raw_state(raw, "RightActuator", lambda s: s["running"])
        assert state["dutycycle"] == 60 and state["clockwise"] is True


@pytest.mark.parametrize(
    ("feature", "args", "code"),
    [
        ("dutycycle", ["fast"], "bad_args"),
        ("dutycycle", [101], "out_of_range"),
        ("dutycycle", [-1], "out_of_range"),
        ("dutycycle", [50.5], "bad_args"),
        ("enabled", ["yes"], "bad_args"),
        ("enabled", [True, False], "bad_args"),
        ("direction", [], "bad_args"),
        ("angle", [90], "unknown_feature"),
    ],
)
def test_bad_calls_get_error_replies(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient],
    feature: str, args: list[Any], code: str,
) -> None:
    raw = raw_client(mosquitto_broker)
    raw.subscribe("test/reply")
    with running("motor", deployment(), mosquitto_broker.url) as host:
        body = json.dumps({"id": "r1", "reply_to": "test/reply", "args": args})
        raw.publish(TOPICS.call("LeftActuator", feature), body)
        reply = json.loads(raw.get(topic="test/reply").payload)
        assert reply["id"] == "r1" and reply["ok"] is False
        assert reply["error"]["code"] == code, reply
        assert mock(host).commands == [("stop", ())], "nothing reached the driver"


def test_malformed_payloads_never_wedge_the_service(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(mosquitto_broker)
    raw.subscribe("test/reply")
    with running("motor", deployment(), mosquitto_broker.url) as host:
        for junk in (b"{not json", b"\xff\xfe", b'{"id": 1, "reply_to": "test/reply", "args": 5, "x": 1}'):
            raw.publish(TOPICS.call("LeftActuator", "dutycycle"), junk)
        reply = json.loads(raw.get(topic="test/reply").payload)
        assert reply["ok"] is False and reply["error"]["code"] == "bad_request"
        raw.publish(TOPICS.call("LeftActuator", "dutycycle"),
                    json.dumps({"id": "ok", "reply_to": "test/reply", "args": [33]}))
        assert json.loads(raw.get(topic="test/reply").payload) == {"id": "ok", "ok": True, "value": None}
        assert mock(host).duty_cycle_percent == 33


def test_driver_fault_is_a_driver_error_reply_and_service_survives(mosquitto_broker: BrokerProcess) -> None:
    dep = deployment(LeftActuator={"mock_faults": {"set_duty_cycle": "H-bridge overheated"}})
    with running("motor", dep, mosquitto_broker.url) as host, client(mosquitto_broker.url) as bus:
        with pytest.raises(RemoteError) as caught:
            bus.call("LeftActuator", "dutycycle", 50)
        assert caught.value.code == "driver_error" and "overheated" in caught.value.message
        assert bus.call("LeftActuator", "enabled", True) is None
        assert mock(host).enabled


def test_pigpio_driver_on_the_fake_over_the_bus(mosquitto_broker: BrokerProcess) -> None:
    fake = FakePi()
    pigpio_connection.install_fake(fake)
    try:
        with running("motor", deployment(), mosquitto_broker.url, driver="pigpio"), \
                client(mosquitto_broker.url) as bus:
            bus.call("LeftActuator", "dutycycle", 75)
            bus.call("LeftActuator", "enabled", True)
            assert fake.pin(22).duty_fraction == pytest.approx(0.75)
            bus.call("LeftActuator", "direction", False)
            assert fake.pin(23).duty_fraction == pytest.approx(0.75) and fake.pin(22).duty_fraction == 0
        assert all(fake.pin(p).duty_fraction == 0 for p in (22, 23, 24, 25))
    finally:
        pigpio_connection.install_fake(None)


# --- safety ------------------------------------------------------------------------------------


def test_watchdog_stops_a_motor_without_commands(mosquitto_broker: BrokerProcess) -> None:
    dep = deployment(LeftActuator={"watchdog_s": 0.8}, RightActuator={"watchdog_s": 0})
    with running("motor", dep, mosquitto_broker.url) as host, client(mosquitto_broker.url) as bus:
        watch = StateWatch(bus, "LeftActuator")
        for name in ("LeftActuator", "RightActuator"):
            bus.call(name, "dutycycle", 40)
            bus.call(name, "enabled", True)
        left, right = mock(host), mock(host, "RightActuator")
        for _ in range(8):  # commands keep it alive for longer than the watchdog period
            assert left.wait_until(lambda: not left.running, 0.15) is False
            bus.call("LeftActuator", "dutycycle", 40)
        assert left.wait_until(lambda: not left.running, 3.0)
        state = watch.wait("LeftActuator", lambda s: s["stop_reason"] == "watchdog")
        assert state["enabled"] is False and state["running"] is False
        assert left.duty_cycle_percent == 0, "the driver's duty is zeroed"
        assert right.running, "watchdog_s: 0 turns the watchdog off"
        bus.call("LeftActuator", "enabled", True)  # a model that set dutycycle once resumes
        assert left.running and left.duty_cycle_percent == 40
        assert watch.wait("LeftActuator", lambda s: s["running"])["stop_reason"] is None


class Heartbeat:
    """Publishes an orchestrator's heartbeat naming `reply_to` every `period_s`, until stopped."""

    def __init__(self, bus: Any, reply_to: str, period_s: float = 0.1) -> None:
        self.stopped_at: float | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(bus, reply_to, period_s), daemon=True)
        self._thread.start()

    def _run(self, bus: Any, reply_to: str, period_s: float) -> None:
        seq = 0
        while not self._stop.is_set():
            beat = {"reply_to": reply_to, "seq": seq, "period_s": period_s}
            bus.publish(TOPICS.orchestrator_heartbeat, json.dumps(beat), qos=0)
            seq += 1
            self._stop.wait(period_s)

    def stop(self) -> float:
        self._stop.set()
        self._thread.join(5)
        self.stopped_at = time.monotonic()
        return self.stopped_at


def test_the_orchestrators_heartbeat_keeps_the_motors_it_commanded_running(
    mosquitto_broker: BrokerProcess,
) -> None:
    # a model sets the motors once and then only reads the sonar: it must drive on while its
    # orchestrator lives, and stop within watchdog_s once the orchestrator hangs
    url = mosquitto_broker.url
    watchdog_s = 1.5
    dep = deployment(LeftActuator={"watchdog_s": watchdog_s}, RightActuator={"watchdog_s": watchdog_s})
    with running("motor", dep, url) as host, client(url) as orchestrator, client(url) as direct:
        watch = StateWatch(direct, "LeftActuator", "RightActuator")
        beat = Heartbeat(direct, orchestrator.reply_topic)
        for bad in (b"garbage", b'{"reply_to": 5}', b"{}"):  # not heartbeats: ignored, no crash
            direct.publish(TOPICS.orchestrator_heartbeat, bad, qos=0)
        orchestrator.call("LeftActuator", "dutycycle", 40)
        orchestrator.call("LeftActuator", "enabled", True)
        direct.call("RightActuator", "dutycycle", 40)  # a direct caller, while the heartbeat comes
        direct.call("RightActuator", "enabled", True)
        commanded = time.monotonic()
        left, right = mock(host), mock(host, "RightActuator")
        assert right.wait_until(lambda: not right.running, watchdog_s + 2.0), "a direct caller: the watchdog"
        assert watch.wait("RightActuator", lambda s: not s["running"])["stop_reason"] == "watchdog"
        time.sleep(max(0.0, commanded + 2 * watchdog_s - time.monotonic()))
        assert left.running and left.stops == 1, "the lease holds (1 stop: the service's start-up stop)"
        silent = beat.stop()  # the orchestrator hangs (SIGSTOP): no heartbeat, no call
        assert left.wait_until(lambda: not left.running, watchdog_s + 2.0)
        assert time.monotonic() - silent <= watchdog_s + 0.3, "stopped within watchdog_s (+ a safety round)"
        state = watch.wait("LeftActuator", lambda s: not s["running"])
        assert state["stop_reason"] == "orchestrator unresponsive"
        orchestrator.call("LeftActuator", "enabled", False)  # the run's final stop calls ...
        direct.publish(TOPICS.orchestrator_status, json.dumps({"state": "stopped"}), qos=1)
        time.sleep(0.3)
        assert watch.latest["LeftActuator"]["stop_reason"] == "orchestrator unresponsive", \
            "... leave the reason why the car stood still"
        orchestrator.call("LeftActuator", "enabled", True)  # running again: it is history
        assert watch.wait("LeftActuator", lambda s: s["running"])["stop_reason"] is None


def test_a_deadman_that_fired_while_the_service_was_frozen_is_the_stop_reason(
    mosquitto_broker: BrokerProcess,
) -> None:
    url = mosquitto_broker.url
    with running("motor", deployment(), url) as host, client(url) as bus:
        watch = StateWatch(bus, "LeftActuator")
        bus.call("LeftActuator", "dutycycle", 70)
        bus.call("LeftActuator", "enabled", True)
        left = mock(host)
        assert left.wait_until(lambda: left.renewals >= 2, 2.0), "renewed every safety round"
        left.fire_deadman()
        state = watch.wait("LeftActuator", lambda s: not s["enabled"], 2.0)
        assert state["stop_reason"] == "deadman" and state["dutycycle"] == 70


def _stopped(driver: MockMotorChannel) -> Callable[[], bool]:
    return lambda: not driver.running


def _fake_orchestrator(port: int, tmp_path: Path) -> subprocess.Popen[bytes]:
    """A plain paho client with the orchestrator's last will; SIGKILL makes the broker send it."""
    script = tmp_path / "orchestrator.py"
    script.write_text(textwrap.dedent(f"""
        import json, sys, time
        import paho.mqtt.client as mqtt
        from paho.mqtt.enums import CallbackAPIVersion
        topic = "{TOPICS.orchestrator_status}"
        c = mqtt.Client(CallbackAPIVersion.VERSION2, client_id="fake-orchestrator")
        c.will_set(topic, json.dumps({{"state": "offline"}}), qos=1, retain=True)
        c.connect("127.0.0.1", {port}, keepalive=5)
        c.loop_start()
        c.publish(topic, json.dumps({{"state": "running"}}), qos=1, retain=True).wait_for_publish(5)
        print("ready", flush=True)
        time.sleep(60)
    """))
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE)
    assert proc.stdout is not None and proc.stdout.readline().strip() == b"ready"
    return proc


def test_orchestrator_last_will_stops_the_motors(broker: BrokerProcess, tmp_path: Path) -> None:
    orchestrator = _fake_orchestrator(broker.port, tmp_path)
    try:
        with running("motor", deployment(), broker.url) as host, client(broker.url) as bus:
            watch = StateWatch(bus, "LeftActuator", "RightActuator")
            for name in ("LeftActuator", "RightActuator"):
                bus.call(name, "dutycycle", 80)
                bus.call(name, "enabled", True)
            assert mock(host).running and mock(host, "RightActuator").running
            orchestrator.kill()  # no DISCONNECT: the broker publishes the will
            for name in ("LeftActuator", "RightActuator"):
                driver = mock(host, name)
                assert driver.wait_until(_stopped(driver), 10.0), name
                watch.wait(name, lambda s: s["stop_reason"] == "orchestrator offline")
    finally:
        orchestrator.kill()
        orchestrator.wait(5)


@pytest.mark.parametrize("state", ["stopped", "failed"])
def test_orchestrator_stopped_or_failed_stops_the_motors(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient], state: str
) -> None:
    raw = raw_client(mosquitto_broker)
    with running("motor", deployment(), mosquitto_broker.url) as host, client(mosquitto_broker.url) as bus:
        bus.call("LeftActuator", "dutycycle", 80)
        bus.call("LeftActuator", "enabled", True)
        raw.publish(TOPICS.orchestrator_status, json.dumps({"state": "running"}))
        assert mock(host).wait_until(lambda: not mock(host).running, 0.3) is False, "running is fine"
        raw.publish(TOPICS.orchestrator_status, json.dumps({"state": state}))
        assert mock(host).wait_until(lambda: not mock(host).running, 5.0)


def test_an_unreadable_orchestrator_status_stops_the_motors_with_one_warning(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    import structlog

    raw = raw_client(mosquitto_broker)
    with running("motor", deployment(), mosquitto_broker.url) as host, client(mosquitto_broker.url) as bus:
        with structlog.testing.capture_logs() as logs:
            for payload in (b"garbage", b'{"state": 5}', b'{"state": "dancing"}'):
                bus.call("LeftActuator", "dutycycle", 80)
                bus.call("LeftActuator", "enabled", True)
                assert mock(host).running
                raw.publish(TOPICS.orchestrator_status, payload)
                assert mock(host).wait_until(lambda: not mock(host).running, 5.0), payload
            raw.publish(TOPICS.orchestrator_status, b"", retain=True)  # clearing it is no status
            bus.call("LeftActuator", "enabled", True)
            assert mock(host).wait_until(lambda: not mock(host).running, 0.3) is False
        warnings = [e for e in logs if e["event"] == "orchestrator_status_unreadable"]
        assert len(warnings) == 1, warnings  # rate-limited: one line, not one per message
        assert warnings[0]["payload"] == "garbage" and warnings[0]["log_level"] == "warning"


def test_broker_loss_stops_the_motors(broker: BrokerProcess) -> None:
    with running("motor", deployment(), broker.url) as host:
        with client(broker.url) as bus:
            bus.call("LeftActuator", "dutycycle", 50)
            bus.call("LeftActuator", "enabled", True)
        left = mock(host)
        assert left.running
        broker.kill()
        assert left.wait_until(lambda: not left.running, 10.0)
        broker.start()  # the service reconnects and serves again
        assert wait_for(lambda: all(s.connected for s in host.servers.values()), 20.0)
        with client(broker.url) as bus:
            bus.call("LeftActuator", "dutycycle", 10, timeout=5.0)
            assert left.duty_cycle_percent == 10


# --- the process: signals leave the (fake) pins at zero duty -----------------------------------


@pytest.fixture
def motor_process(
    mosquitto_broker: BrokerProcess, tmp_path: Path
) -> Iterator[tuple[subprocess.Popen[bytes], Path]]:
    deploy = tmp_path / "deploy.yaml"
    deploy.write_text(json.dumps(json.loads(deployment("pigpio").model_dump_json())))
    state_file = tmp_path / "pins.json"
    env = {**os.environ, "UMLBOT_FAKE_PIGPIO": "1", "UMLBOT_FAKE_PIGPIO_STATE": str(state_file),
           "UMLBOT_LOG_LEVEL": "WARNING"}
    proc = subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "service", "motor",
         "--deploy", str(deploy), "--broker", mosquitto_broker.url],
        env=env, stderr=subprocess.PIPE,
    )
    yield proc, state_file
    if proc.poll() is None:
        proc.kill()
    proc.wait(5)


def _pin_duties(state_file: Path) -> dict[str, float]:
    try:
        pins = json.loads(state_file.read_text())["pins"]
    except (OSError, ValueError, KeyError):
        return {}
    return {gpio: pin["duty_fraction"] for gpio, pin in pins.items()}


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_signal_leaves_pins_at_zero_duty(
    motor_process: tuple[subprocess.Popen[bytes], Path], mosquitto_broker: BrokerProcess, signum: int
) -> None:
    proc, state_file = motor_process
    with client(mosquitto_broker.url) as bus:
        assert wait_for(lambda: _status(bus, "RightActuator"), 15.0), "service came online"
        bus.call("LeftActuator", "dutycycle", 60, timeout=5.0)
        bus.call("LeftActuator", "enabled", True, timeout=5.0)
        bus.call("RightActuator", "dutycycle", 30, timeout=5.0)
        bus.call("RightActuator", "direction", False, timeout=5.0)
        bus.call("RightActuator", "enabled", True, timeout=5.0)
    duties = _pin_duties(state_file)
    assert duties["22"] == pytest.approx(0.6) and duties["25"] == pytest.approx(0.3)
    proc.send_signal(signum)
    assert proc.wait(10) == 0 or proc.returncode in (0, 130)
    duties = _pin_duties(state_file)
    assert duties and all(d == 0 for d in duties.values()), duties
    assert json.loads(state_file.read_text())["stopped"] is True


def _status(bus: Any, component: str) -> bool:
    try:
        bus.call(component, "enabled", False, timeout=0.5)
        return True
    except Exception:
        return False


def test_sim_driver_calls_over_the_bus_drive_the_world(mosquitto_broker: BrokerProcess) -> None:
    url = mosquitto_broker.url
    with sim_world() as world, running("motor", deployment("sim"), url), client(url) as bus:
        assert bus.call("LeftActuator", "dutycycle", 60) is None
        assert bus.call("LeftActuator", "direction", False) is None
        assert bus.call("LeftActuator", "enabled", True) is None
        left = world.motor("left")
        assert (left.enabled, left.forward, left.duty_percent) == (True, False, 60)
        assert not world.motor("right").enabled, "the other side untouched"
        world.advance_to(0.5)
        assert world.snapshot().distance_m > 0, "the car moves"
    left = world.motor("left")
    assert (left.enabled, left.duty_percent) == (False, 0), "stopping the service stops the side"


def test_a_plugin_driver_without_a_deadman_still_gets_the_watchdog() -> None:
    """A motor driver of a plugin written before `MotorChannel.renew`: the service warns once that
    nothing outside it can stop the motor, and its safety round (the watchdog) still works."""
    import structlog

    from umlbot.base.catalog import resolve_implementation
    from umlbot.services.motor.service import MotorService

    class OldDriver:
        def __init__(self) -> None:
            self.enabled = False

        def set_enabled(self, enabled: bool) -> None:
            self.enabled = enabled

        def set_direction(self, clockwise: bool) -> None: ...

        def set_duty_cycle(self, percent: float) -> None: ...

        def stop(self) -> None:
            self.enabled = False

        def close(self) -> None:
            self.stop()

    impl = resolve_implementation("l298n")
    assert impl is not None
    driver = OldDriver()
    with structlog.testing.capture_logs() as logs:
        service = MotorService("LeftActuator", impl, driver, {"watchdog_s": 0.5})  # type: ignore[arg-type]
    assert [e["event"] for e in logs if e["log_level"] == "warning"] == ["motor_driver_without_deadman"]
    service.dutycycle(50)
    service.enabled(True)
    service.tick(time.monotonic())
    assert driver.enabled, "renewed (nothing to renew) and within the watchdog"
    service.tick(time.monotonic() + 1.0)
    assert service.stop_reason == "watchdog"
    assert not driver.enabled
