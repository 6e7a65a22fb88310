"""The fake pigpio.pi behaves like pigpio where the drivers rely on it, and the connection module
hands it out (installed in-process, or selected by UMLBOT_FAKE_PIGPIO in a child process)."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from umlbot.base.errors import DriverError
from umlbot.services.pins import pigpio as pigpio_connection
from umlbot.testing.pigpio import EITHER_EDGE, FALLING_EDGE, OUTPUT, RISING_EDGE, FakePi, error


@pytest.fixture
def no_installed_fake(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    monkeypatch.delenv(pigpio_connection.FAKE_ENV, raising=False)
    pigpio_connection.install_fake(None)
    yield
    pigpio_connection.install_fake(None)


def test_records_every_call() -> None:
    pi = FakePi()
    pi.set_mode(4, OUTPUT)
    pi.write(4, 1)
    assert pi.read(4) == 1
    assert pi.calls == [("set_mode", (4, 1)), ("write", (4, 1)), ("read", (4,))]


def test_pwm_semantics() -> None:
    pi = FakePi()
    assert pi.set_PWM_frequency(22, 900) in (800, 1000)
    assert pi.set_PWM_frequency(22, 1000) == 1000
    assert pi.set_PWM_range(22, 1000) == 200  # real range at 1 kHz with 5 µs samples
    pi.set_PWM_dutycycle(22, 250)
    assert pi.get_PWM_dutycycle(22) == 250
    assert pi.pin(22).duty_fraction == 0.25
    pi.set_PWM_range(22, 100)
    assert pi.get_PWM_dutycycle(22) == 25, "pigpio rescales a running duty cycle"
    pi.write(22, 0)
    assert pi.pin(22).pwm_dutycycle == 0, "write ends PWM"
    with pytest.raises(error):
        pi.get_PWM_dutycycle(22)
    with pytest.raises(error):
        pi.set_PWM_dutycycle(22, 101)
    with pytest.raises(error):
        pi.set_PWM_range(22, 10)


def test_servo_semantics() -> None:
    pi = FakePi()
    pi.set_servo_pulsewidth(18, 1500)
    assert pi.get_servo_pulsewidth(18) == 1500
    with pytest.raises(error):
        pi.set_servo_pulsewidth(18, 400)
    pi.set_servo_pulsewidth(18, 0)
    with pytest.raises(error):
        pi.get_servo_pulsewidth(18)


def test_bad_gpio_and_trigger_arguments() -> None:
    pi = FakePi()
    with pytest.raises(error):
        pi.write(54, 1)
    with pytest.raises(error):
        pi.write(4, 2)
    pi.set_mode(8, OUTPUT)
    with pytest.raises(error):
        pi.gpio_trigger(8, 101)
    with pytest.raises(error, match="not an output"):
        pi.gpio_trigger(9, 10)


def test_callbacks_by_edge_with_tally_and_cancel() -> None:
    pi = FakePi(start_tick=100)
    seen: list[tuple[int, int, int]] = []
    threads: set[str] = set()

    def record(gpio: int, level: int, tick: int) -> None:
        seen.append((gpio, level, tick))
        threads.add(threading.current_thread().name)

    either = pi.callback(17, EITHER_EDGE, record)
    rising = pi.callback(17, RISING_EDGE)
    falling = pi.callback(17, FALLING_EDGE)
    pi.set_input(17, 1)
    pi.set_input(17, 1)  # no change, no edge
    pi.set_input(17, 0)
    assert pi.wait_idle()
    assert seen == [(17, 1, 101), (17, 0, 102)]
    assert (rising.tally(), falling.tally()) == (1, 1)
    assert threads == {"fake-pigpio-cb"}, "callbacks run on their own thread, as in pigpio"
    either.cancel()
    either.cancel()
    pi.set_input(17, 1)
    assert pi.wait_idle()
    assert len(seen) == 2
    pi.stop()


def test_hcsr04_echo_width_and_no_echo() -> None:
    pi = FakePi()
    pi.set_mode(8, OUTPUT)
    sonar = pi.attach_hcsr04(8, 7, distance_cm=10)
    edges: list[tuple[int, int]] = []
    pi.callback(7, EITHER_EDGE, lambda g, level, tick: edges.append((level, tick)))
    pi.gpio_trigger(8, 10, 1)
    assert pi.wait_idle()
    (l1, t1), (l2, t2) = edges
    assert (l1, l2) == (1, 0) and t2 - t1 == 580
    edges.clear()
    sonar.distance_cm = None
    pi.gpio_trigger(8, 10, 1)
    assert pi.wait_idle()
    assert edges[1][1] - edges[0][1] == 38_000, "nothing in range: a 38 ms pulse"
    edges.clear()
    sonar.no_echo = "silent"
    pi.gpio_trigger(8, 10, 1)
    assert pi.wait_idle()
    assert edges == []
    pi.stop()


def test_disconnected_pi_raises() -> None:
    pi = FakePi(connected=False)
    with pytest.raises(error, match="not connected"):
        pi.write(4, 1)


def test_state_file_follows_outputs(tmp_path: Path) -> None:
    path = tmp_path / "pins.json"
    pi = FakePi(state_file=path)
    pi.set_PWM_range(22, 1000)
    pi.set_PWM_dutycycle(22, 600)
    state = json.loads(path.read_text())
    assert state["pins"]["22"]["duty_fraction"] == 0.6
    pi.write(22, 0)
    pi.stop()
    pi.stop()
    state = json.loads(path.read_text())
    assert state["pins"]["22"]["duty_fraction"] == 0 and state["stopped"] is True


def test_installed_fake_is_handed_out(no_installed_fake: None) -> None:
    fake = FakePi()
    pigpio_connection.install_fake(fake)
    assert pigpio_connection.acquire() is fake
    pigpio_connection.release(fake)
    assert not fake.stopped, "the installed fake outlives its users"


def test_env_selects_a_fake_with_state_file(
    no_installed_fake: None, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv(pigpio_connection.FAKE_ENV, "1")
    monkeypatch.setenv(pigpio_connection.FAKE_STATE_ENV, str(tmp_path / "s.json"))
    pi = pigpio_connection.acquire()
    assert isinstance(pi, FakePi)
    assert pigpio_connection.acquire() is pi
    pi.write(4, 1)
    assert json.loads((tmp_path / "s.json").read_text())["pins"]["4"]["level"] == 1


def test_without_pigpio_or_daemon_the_error_says_what_to_do(no_installed_fake: None) -> None:
    with pytest.raises(DriverError, match=r"pigpio|pigpiod"):
        pigpio_connection.acquire("127.0.0.1", 1)


def test_disconnected_fake_is_a_driver_error(no_installed_fake: None) -> None:
    pigpio_connection.install_fake(FakePi(connected=False))
    with pytest.raises(DriverError, match="cannot reach the pigpio daemon"):
        pigpio_connection.acquire()


def test_env_fake_is_stopped_by_its_last_user(
    no_installed_fake: None, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv(pigpio_connection.FAKE_ENV, "1")
    monkeypatch.setenv(pigpio_connection.FAKE_STATE_ENV, str(tmp_path / "s.json"))
    first = pigpio_connection.acquire()
    second = pigpio_connection.acquire()
    assert first is second
    pigpio_connection.release(first)
    assert not first.stopped
    pigpio_connection.release(second)
    assert first.stopped
    assert json.loads((tmp_path / "s.json").read_text())["stopped"] is True


# --- daemon-side scripts -------------------------------------------------------------------------


def _until(predicate: Callable[[], bool], timeout: float = 2.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return False


def test_a_script_counts_its_parameter_down_and_writes_low_as_pigpiod_runs_it() -> None:
    from umlbot.testing.pigpio import PI_SCRIPT_HALTED, PI_SCRIPT_RUNNING

    pi = FakePi()
    pi.set_PWM_dutycycle(22, 200)
    script = pi.store_script(b"tag 0 mils 20 dcr p0 jp 0 w p1 0 halt w p1 1")
    assert _until(lambda: pi.script_status(script)[0] == PI_SCRIPT_HALTED), "ready once its thread runs"
    pi.run_script(script, [5, 22])
    assert _until(lambda: pi.script_status(script)[0] == PI_SCRIPT_RUNNING)
    for _ in range(5):  # renewed: it keeps counting from 5
        pi.update_script(script, [5, 22])
        assert pi.pin(22).pwm_dutycycle == 200
        assert not _until(lambda: pi.pin(22).pwm_dutycycle == 0, 0.05)
    pi.stop()  # the client goes; pigpiod runs the script on
    assert _until(lambda: pi.pin(22).pwm_dutycycle == 0, 1.0), "it wrote the pin low (ending PWM)"
    daemon_side = pi.scripts[script]  # the client is gone: look into the daemon
    assert daemon_side.run_state == PI_SCRIPT_HALTED and daemon_side.params[0] == -1, "halted, p0 < 0"
    assert pi.pin(22).level == 0, "the command after HALT never ran"


def test_bad_scripts_and_ids_are_refused_with_pigpios_messages() -> None:
    pi = FakePi()
    with pytest.raises(error, match="illegal script command"):
        pi.store_script("tag 0 fly p0")
    with pytest.raises(error, match="unresolved tag"):
        pi.store_script("jmp 7")
    with pytest.raises(error, match="unknown script id"):
        pi.script_status(31)
    script = pi.store_script("mils 1")
    pi.delete_script(script)
    with pytest.raises(error, match="unknown script id"):
        pi.run_script(script)
