"""Contract suite for servo drivers: mock, and pigpio on the fake pigpio.pi."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

from services.fake_pigpio import FakePi
from services.servo.driver import Servo, ServoSettings
from services.servo.mock import MockServo
from services.servo.pigpio import PigpioServo


@dataclass
class Rig:
    driver: Servo
    angle: Callable[[], float | None]  # None = no pulses


@pytest.fixture(params=["mock", "pigpio-fake"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    if request.param == "mock":
        mock = MockServo("Sensor")
        yield Rig(mock, lambda: mock.angle_deg if mock.pulsing else None)
        mock.close()
        return
    fake = FakePi()
    settings = ServoSettings(gpio=18)
    driver = PigpioServo("Sensor", settings, pi=fake)

    def angle() -> float | None:
        width = fake.pin(18).servo_pulsewidth
        return None if width == 0 else (width - 500) * 180 / 2000

    yield Rig(driver, angle)
    driver.close()


def test_starts_without_pulses(rig: Rig) -> None:
    assert rig.angle() is None


@pytest.mark.parametrize("degrees", [0, 45, 90, 180])
def test_turns_to_angle(rig: Rig, degrees: float) -> None:
    rig.driver.set_angle(degrees)
    assert rig.angle() == pytest.approx(degrees, abs=0.1)


@pytest.mark.parametrize("degrees", [-1, 180.5, 360])
def test_out_of_range_is_refused(rig: Rig, degrees: float) -> None:
    with pytest.raises(ValueError, match="angle"):
        rig.driver.set_angle(degrees)
    assert rig.angle() is None


def test_stop_and_close_switch_pulses_off(rig: Rig) -> None:
    rig.driver.set_angle(90)
    rig.driver.stop()
    assert rig.angle() is None
    rig.driver.set_angle(30)
    rig.driver.close()
    rig.driver.close()
    assert rig.angle() is None


def test_pulse_calibration() -> None:
    s = ServoSettings(gpio=18, min_pulse_us=600, max_pulse_us=2400)
    assert (s.pulse_us(0), s.pulse_us(90), s.pulse_us(180)) == (600, 1500, 2400)
    reversed_servo = ServoSettings(gpio=18, min_pulse_us=2500, max_pulse_us=500)
    assert reversed_servo.pulse_us(0) == 2500
    with pytest.raises(ValueError):
        ServoSettings(gpio=18, min_pulse_us=400)


def test_pigpio_uses_set_servo_pulsewidth() -> None:
    fake = FakePi()
    servo = PigpioServo("S", ServoSettings(gpio=18, initial_angle_deg=90), pi=fake)
    assert fake.calls_named("set_servo_pulsewidth")[-1] == (18, 1500)
    servo.set_angle(180)
    assert fake.calls_named("set_servo_pulsewidth")[-1] == (18, 2500)
    servo.close()
    assert fake.calls_named("set_servo_pulsewidth")[-1] == (18, 0)
