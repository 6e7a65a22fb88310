"""The lgpio backend: the fake `lgpio` behaves like the real module (handles, claims, errors with
lgpio's messages, alerts), the connection shares one handle per chip, `driver: auto` picks lgpio
on a Pi 5 and pigpio where pigpiod answers, and an lgpio service runs over a real broker, in-process
and as a process that leaves its lines at zero when signalled."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import tomllib
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import BrokerProcess
from services_support import client, deployment, running, wait_for

from umlbot.base import registry
from umlbot.base.autodetect import Machine, choose, forget
from umlbot.base.errors import DriverError, UnknownDriver
from umlbot.services.motor.lgpio import LgpioL298NChannel
from umlbot.services.motor.pigpio import PigpioL298NChannel
from umlbot.services.pins import lgpio as lgpio_connection
from umlbot.testing.lgpio import FakeLgpio, error


@pytest.fixture(autouse=True)
def _no_installed_fake() -> Iterator[None]:
    lgpio_connection.install_fake(None)
    forget()
    yield
    lgpio_connection.install_fake(None)
    forget()


# --- the fake is the lgpio module's API ----------------------------------------------------------


def test_handles_carry_the_chip_and_unknown_handles_fail() -> None:
    lg = FakeLgpio({0: 54, 4: 54})
    handle = lg.gpiochip_open(4)
    assert handle >> 16 == 4
    assert lg.gpio_claim_output(handle, 17) == 0
    lg.gpiochip_close(handle)
    with pytest.raises(error) as caught:
        lg.gpio_write(handle, 17, 1)
    assert caught.value.value == "unknown handle" and str(caught.value) == "'unknown handle'"
    with pytest.raises(error, match="can not open gpiochip"):
        lg.gpiochip_open(1)


def test_claims_belong_to_one_handle() -> None:
    lg = FakeLgpio()
    first, second = lg.gpiochip_open(0), lg.gpiochip_open(0)
    lg.gpio_claim_output(first, 22, 1)
    with pytest.raises(error, match="GPIO busy"):
        lg.gpio_claim_input(second, 22)
    with pytest.raises(error, match="GPIO not allocated"):
        lg.gpio_read(second, 22)
    assert lg.gpio_read(first, 22) == 1, "an output reads back its level"
    lg.gpio_claim_input(first, 22, lg.SET_PULL_DOWN)  # the owner may claim again, as input
    assert lg.gpio_read(first, 22) == 0
    with pytest.raises(error, match="GPIO not set as an output"):
        lg.gpio_write(first, 22, 1)
    lg.gpio_free(first, 22)
    assert lg.gpio_claim_output(second, 22) == 0, "a freed line can be claimed by another handle"
    with pytest.raises(error, match="bad GPIO number"):
        lg.gpio_claim_output(first, 54)


def test_pwm_and_servo_ranges_are_lgpios() -> None:
    lg = FakeLgpio()
    h = lg.gpiochip_open(0)
    with pytest.raises(error, match="GPIO not allocated"):
        lg.tx_pwm(h, 12, 1000, 50)
    lg.gpio_claim_output(h, 12)
    with pytest.raises(error, match="bad PWM frequency"):
        lg.tx_pwm(h, 12, 20000, 50)
    with pytest.raises(error, match="bad PWM dutycycle"):
        lg.tx_pwm(h, 12, 1000, 101)
    lg.tx_pwm(h, 12, 1000, 25)
    lg.gpio_write(h, 12, 1)
    assert lg.line(12).duty_fraction == 0.25, "gpio_write does not end PWM"
    with pytest.raises(error, match="bad servo pulsewidth"):
        lg.tx_servo(h, 12, 400)
    with pytest.raises(error, match="bad servo frequency"):
        lg.tx_servo(h, 12, 1500, 30)
    lg.tx_servo(h, 12, 1500)
    assert (lg.line(12).servo_pulse_us, lg.line(12).pwm_frequency) == (1500, 0)
    lg.gpiochip_close(h)
    assert lg.line(12).claim == "free" and lg.line(12).servo_pulse_us == 0, "closing frees and stops"


def test_alerts_reach_callbacks_with_nanosecond_timestamps() -> None:
    lg = FakeLgpio()
    h = lg.gpiochip_open(0)
    seen: list[tuple[int, int, int, int]] = []
    got = threading.Event()

    def on_edge(chip: int, gpio: int, level: int, tick: int) -> None:
        seen.append((chip, gpio, level, tick))
        got.set()

    lg.gpio_claim_input(h, 5)
    cb = lg.callback(h, 5, lg.BOTH_EDGES, on_edge)
    lg.set_input(5, 1)
    assert lg.wait_idle() and not seen, "an input claim gives no alerts"
    lg.gpio_claim_alert(h, 5, lg.FALLING_EDGE)
    lg.set_input(5, 0)
    lg.set_input(5, 1)
    assert got.wait(2.0) and lg.wait_idle()
    assert [(c, g, lvl) for c, g, lvl, _ in seen] == [(0, 5, 0)], "only the claimed edges"
    assert seen[0][3] > 1_000_000_000 and cb.tally() == 1
    cb.cancel()
    lg.shutdown()


def test_the_connection_shares_one_handle_per_chip() -> None:
    fake = FakeLgpio()
    lgpio_connection.install_fake(fake)
    a = lgpio_connection.LgpioHandle("A", 0)
    b = lgpio_connection.LgpioHandle("B", 0)
    assert a.handle == b.handle and len(fake.open_handles) == 1
    a.call("gpio_claim_output", 4, 0)
    a.close()
    a.close()
    assert fake.line(4).claim == "free" and len(fake.open_handles) == 1, "B still uses the chip"
    b.close()
    assert not fake.open_handles


def test_missing_lgpio_package_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """Into the Python that runs the service: the robot's venv does not see Debian's python3-lgpio,
    so that is named as what does not help rather than offered as a way."""
    monkeypatch.setitem(sys.modules, "lgpio", None)  # import fails, as where it is not installed
    with pytest.raises(DriverError) as caught:
        registry.create_driver("motor", "lgpio", "M", {"in1": 22, "in2": 23})
    message = str(caught.value)
    assert message.startswith(f"the lgpio Python package is not installed for {sys.executable}: ")
    assert f"`{sys.executable} -m pip install 'lgpio>=0.2.2'` (umlbot's `pi` extra" in message
    assert "`sudo apt install swig python3-dev liblgpio-dev` first" in message
    assert "apt install python3-lgpio" not in message
    assert "python3-lgpio serves the system's Python only, not a virtual environment" in message
    assert message.endswith("Or use --driver mock / sim")
    extra = tomllib.loads((Path(__file__).parent.parent / "pyproject.toml").read_text())
    assert "lgpio>=0.2.2" in extra["project"]["optional-dependencies"]["pi"], "the message names its pin"


def test_lgpio_that_cannot_make_its_pipe_says_where(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    # The real module opens '.lgd-nfy<n>' in the working directory on import.
    (tmp_path / "lgpio.py").write_text("open('/nonexistent/.lgd-nfy0', 'rb')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "lgpio", raising=False)
    with pytest.raises(DriverError, match=r"notification pipe \(\.lgd-nfy\*\) in the working directory"):
        registry.create_driver("servo", "lgpio", "S", {"gpio": 18})


# --- driver: auto ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("machine", "expected"), [
    (Machine(model="Raspberry Pi 5 Model B Rev 1.0", gpiochips=("/dev/gpiochip0",)), "lgpio"),
    (Machine(model="Raspberry Pi 5 Model B Rev 1.0", pigpiod="localhost:8888"), "lgpio"),
    (Machine(model="Raspberry Pi 4 Model B Rev 1.4", pigpiod="localhost:8888",
             gpiochips=("/dev/gpiochip0",)), "pigpio"),
    (Machine(model="Raspberry Pi 4 Model B Rev 1.4", gpiochips=("/dev/gpiochip0",)), "lgpio"),
    (Machine(pigpiod="pi.local:8888"), "pigpio"),
    (Machine(model="Raspberry Pi 5", fake="pigpio"), "pigpio"),
])
def test_auto_picks_the_backend_the_machine_has(machine: Machine, expected: str) -> None:
    chosen, reason = choose(machine)
    assert chosen == expected and reason


def test_auto_without_any_backend_says_what_it_looked_for() -> None:
    with pytest.raises(DriverError, match=r"no pigpio daemon at .*no /dev/gpiochip.*--driver mock or sim"):
        choose(Machine(model="QEMU"))


def test_auto_builds_the_chosen_driver(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("UMLBOT_FAKE_LGPIO", "1")
    channel = registry.create_driver("motor", "auto", "M", {"in1": 22, "in2": 23, "mock_latency_s": 1})
    assert isinstance(channel, LgpioL298NChannel)
    channel.close()
    forget()
    monkeypatch.delenv("UMLBOT_FAKE_LGPIO")
    monkeypatch.setenv("UMLBOT_FAKE_PIGPIO", "1")
    channel = registry.create_driver("motor", "auto", "M", {"in1": 22, "in2": 23})
    assert isinstance(channel, PigpioL298NChannel)
    channel.close()
    assert "auto" in registry.known_drivers("motor")


def test_auto_names_its_choice_when_a_kind_lacks_that_driver(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("UMLBOT_FAKE_PIGPIO", "1")
    monkeypatch.delenv("UMLBOT_FAKE_LGPIO", raising=False)
    with pytest.raises(UnknownDriver, match=r"driver auto chose 'pigpio' here, but there is no buzzer "
                                            r"driver 'pigpio'; known drivers: auto, lgpio, mock, sim"):
        registry.get_factory("buzzer", "auto")  # the example plugin has no pigpio driver


# --- services on lgpio ----------------------------------------------------------------------------


def test_lgpio_motor_service_over_the_bus(mosquitto_broker: BrokerProcess) -> None:
    fake = FakeLgpio()
    lgpio_connection.install_fake(fake)
    with running("motor", deployment(), mosquitto_broker.url, driver="lgpio"), \
            client(mosquitto_broker.url) as bus:
        assert len(fake.open_handles) == 1, "both channels share the chip handle"
        bus.call("LeftActuator", "dutycycle", 75)
        bus.call("LeftActuator", "enabled", True)
        assert fake.line(22).duty_fraction == pytest.approx(0.75)
        bus.call("LeftActuator", "direction", False)
        assert fake.line(23).duty_fraction == pytest.approx(0.75) and fake.line(22).duty_fraction == 0
    assert all(fake.line(p).duty_fraction == 0 and fake.line(p).claim == "free" for p in (22, 23, 24, 25))
    assert not fake.open_handles


def test_auto_service_process_says_it_chose_lgpio_and_stops_the_lines(
    mosquitto_broker: BrokerProcess, tmp_path: Path
) -> None:
    deploy = tmp_path / "deploy.yaml"
    deploy.write_text(json.dumps(json.loads(deployment("auto").model_dump_json())))
    state_file = tmp_path / "lines.json"
    env = {**os.environ, "UMLBOT_FAKE_LGPIO": "1", "UMLBOT_FAKE_LGPIO_STATE": str(state_file),
           "UMLBOT_LOG_LEVEL": "INFO", "UMLBOT_FAKE_PIGPIO": ""}
    proc = subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-json", "service", "motor",
         "--deploy", str(deploy), "--broker", mosquitto_broker.url],
        env=env, stderr=subprocess.PIPE,
    )
    try:
        with client(mosquitto_broker.url) as bus:
            def online() -> bool:
                try:
                    bus.call("RightActuator", "enabled", False, timeout=0.5)
                    return True
                except Exception:
                    return False

            assert wait_for(online, 15.0), "service came online"
            bus.call("RightActuator", "dutycycle", 30, timeout=5.0)
            bus.call("RightActuator", "enabled", True, timeout=5.0)
        lines = json.loads(state_file.read_text())["lines"]
        assert lines["0:24"]["duty_fraction"] == pytest.approx(0.3)
        proc.send_signal(signal.SIGTERM)
        _, stderr = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
    assert proc.returncode == 0
    state = json.loads(state_file.read_text())
    assert state["open_handles"] == 0
    assert all(line["duty_fraction"] == 0 for line in state["lines"].values()), state
    events = [json.loads(line) for line in stderr.decode().splitlines() if line.startswith("{")]
    chosen = [e for e in events if e.get("event") == "driver_auto"]
    assert chosen and chosen[0]["chose"] == "lgpio" and "UMLBOT_FAKE_LGPIO" in chosen[0]["because"]


def test_pwm_bursts_end_low_queue_behind_each_other_and_the_queue_is_bounded() -> None:
    import time

    lg = FakeLgpio()
    h = lg.gpiochip_open(0)
    lg.gpio_claim_output(h, 12)
    assert lg.tx_pwm(h, 12, 100, 100, 0, 10) == 9, "0.1 s at 100 %: nine entries left"
    assert lg.tx_pwm(h, 12, 100, 30, 0, 10) == 8, "queued behind the running burst"
    assert lg.line(12).pwm_duty_percent == 100 and lg.tx_room(h, 12, lg.TX_PWM) == 8
    time.sleep(0.15)
    assert lg.line(12).pwm_duty_percent == 30, "the queued burst followed"
    time.sleep(0.15)
    line = lg.line(12)
    assert (line.pwm_frequency, line.level, lg.tx_busy(h, 12, lg.TX_PWM)) == (0, 0, 0), "ended low"
    lg.tx_pwm(h, 12, 100, 50)  # endless
    lg.tx_pwm(h, 12, 100, 60, 0, 50)
    assert lg.line(12).pwm_duty_percent == 60, "an endless entry gives way to the next at once"
    for room in range(8, -1, -1):  # LG_TX_BUF: ten entries, the running one included
        assert lg.tx_pwm(h, 12, 100, 70, 0, 50) == room
    with pytest.raises(error, match="TX queue full"):
        lg.tx_pwm(h, 12, 100, 70, 0, 50)
    lg.tx_pwm(h, 12, 0, 0)
    assert lg.tx_room(h, 12, lg.TX_PWM) == 10 and lg.line(12).pwm_queue == []
    lg.shutdown()
