"""Contract suite for distance sensor drivers: mock, and pigpio on the fake pigpio.pi with a
simulated HC-SR04 (echo edges with ticks, 32-bit wrap-around, no echo)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

from services.fake_pigpio import TICK_WRAP, FakePi, tickDiff
from services.registry import create_driver
from services.sonar.driver import DistanceSensor, HCSR04Settings
from services.sonar.mock import MockDistanceSensor, MockSonarSettings
from services.sonar.pigpio import PigpioHCSR04, tick_diff


@dataclass
class Rig:
    driver: DistanceSensor
    set_distance: Callable[[float | None], None]


@pytest.fixture(params=["mock", "pigpio-fake"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    if request.param == "mock":
        mock = MockDistanceSensor("DistanceRead")
        yield Rig(mock, mock.set_distance)
        mock.close()
        return
    fake = FakePi()
    sonar = fake.attach_hcsr04(trigger=8, echo=7, distance_cm=100)
    driver = PigpioHCSR04("DistanceRead", HCSR04Settings(trigger=8, echo=7), pi=fake)

    def set_distance(cm: float | None) -> None:
        sonar.distance_cm = cm

    yield Rig(driver, set_distance)
    driver.close()


@pytest.mark.parametrize("cm", [2.0, 15.5, 57.0, 399.0])
def test_reads_the_distance(rig: Rig, cm: float) -> None:
    rig.set_distance(cm)
    assert rig.driver.read_distance_cm() == pytest.approx(cm, abs=0.05)


def test_no_echo_is_none(rig: Rig) -> None:
    rig.set_distance(None)
    assert rig.driver.read_distance_cm() is None
    rig.set_distance(30)
    assert rig.driver.read_distance_cm() == pytest.approx(30, abs=0.05), "recovers after no echo"


def test_max_range_is_declared(rig: Rig) -> None:
    assert rig.driver.max_range_cm == 400


def test_close_twice_is_safe(rig: Rig) -> None:
    rig.driver.close()
    rig.driver.close()
    assert isinstance(rig.driver, DistanceSensor)


# --- pigpio specifics --------------------------------------------------------------------------


def test_tick_diff_wraps_like_pigpio() -> None:
    assert tick_diff(10, 30) == 20
    assert tick_diff(TICK_WRAP - 100, 50) == 150
    assert tickDiff(TICK_WRAP - 100, 50) == 150


def test_pigpio_echo_across_tick_wrap() -> None:
    fake = FakePi()
    fake.attach_hcsr04(8, 7, distance_cm=42.0)
    driver = PigpioHCSR04("S", HCSR04Settings(trigger=8, echo=7), pi=fake)
    fake.set_tick(TICK_WRAP - 1000)  # rise before the wrap, fall (42 * 58 µs later) after it
    assert driver.read_distance_cm() == pytest.approx(42.0, abs=0.05)
    assert fake.get_current_tick() < 10_000, "the tick did wrap during the echo"
    driver.close()


def test_pigpio_uses_a_10us_trigger_and_edge_callbacks() -> None:
    fake = FakePi()
    fake.attach_hcsr04(8, 7, distance_cm=20)
    driver = PigpioHCSR04("S", HCSR04Settings(trigger=8, echo=7), pi=fake)
    driver.read_distance_cm()
    assert fake.calls_named("gpio_trigger") == [(8, 10, 1)]
    assert fake.calls_named("callback") == [(7, 2)]  # EITHER_EDGE on echo
    driver.close()
    assert fake.calls_named("callback") == [(7, 2)] and not fake._callbacks


def test_pigpio_silent_sensor_times_out_to_none() -> None:
    fake = FakePi()
    fake.attach_hcsr04(8, 7, distance_cm=None, no_echo="silent")
    driver = PigpioHCSR04("S", HCSR04Settings(trigger=8, echo=7, echo_timeout_s=0.04), pi=fake)
    started = time.monotonic()
    assert driver.read_distance_cm() is None
    assert 0.03 <= time.monotonic() - started < 1.0
    driver.close()


def test_pigpio_enforces_60ms_between_pings() -> None:
    fake = FakePi()
    fake.attach_hcsr04(8, 7, distance_cm=50)
    driver = PigpioHCSR04("S", HCSR04Settings(trigger=8, echo=7), pi=fake)
    started = time.monotonic()
    for _ in range(4):
        driver.read_distance_cm()
    assert time.monotonic() - started >= 3 * 0.06 - 0.005
    driver.close()


def test_pigpio_median_of_samples_ignores_no_echo() -> None:
    fake = FakePi()
    sonar = fake.attach_hcsr04(8, 7, distance_cm=50)
    driver = PigpioHCSR04("S", HCSR04Settings(trigger=8, echo=7, samples=3, min_interval_s=0.06), pi=fake)
    readings = iter([10.0, None, 30.0])
    original = fake.gpio_trigger

    def trigger(gpio: int, pulse_len: int = 10, level: int = 1) -> int:
        sonar.distance_cm = next(readings)
        return original(gpio, pulse_len, level)

    fake.gpio_trigger = trigger  # type: ignore[method-assign,assignment]
    assert driver.read_distance_cm() == pytest.approx(20.0, abs=0.05)
    assert sonar.pings == 3
    driver.close()


def test_pigpio_far_echo_is_clamped_to_max_range() -> None:
    fake = FakePi()
    fake.attach_hcsr04(8, 7, distance_cm=450)
    driver = PigpioHCSR04("S", HCSR04Settings(trigger=8, echo=7, max_range_cm=400), pi=fake)
    assert driver.read_distance_cm() == 400
    driver.close()


def test_settings_refuse_same_pin_and_short_interval() -> None:
    with pytest.raises(ValueError, match="different pins"):
        HCSR04Settings(trigger=7, echo=7)
    with pytest.raises(ValueError):
        HCSR04Settings(trigger=8, echo=7, min_interval_s=0.01)


# --- mock specifics ----------------------------------------------------------------------------


def test_mock_script_then_last_value() -> None:
    mock = create_driver("sonar", "mock", "S", {"trigger": 8, "echo": 7, "mock_distances": [100, 15, None]})
    assert [mock.read_distance_cm() for _ in range(5)] == [100, 15, None, None, None]


def test_mock_script_cycles() -> None:
    mock = MockDistanceSensor("S", MockSonarSettings(mock_distances=[1, 2], mock_repeat="cycle"))
    assert [mock.read_distance_cm() for _ in range(5)] == [1, 2, 1, 2, 1]
    mock.queue_distances([7])
    assert mock.reads == 5


def test_mock_unknown_mock_setting_is_a_config_error() -> None:
    from umlbot.errors import ConfigError

    with pytest.raises(ConfigError, match="mock_distnces"):
        create_driver("sonar", "mock", "S", {"mock_distnces": [1]})
