"""Contract suite for servo drivers: mock, pigpio on the fake pigpio.pi, lgpio on the fake lgpio,
and sim turning the sonar of a simulated world. Pulses are a pin-level notion: whether a servo
sends them is checked on mock, pigpio and lgpio; for sim the observable is the world's servo angle
once its turning time has passed."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest
from services_support import ROOM  # 2 m x 3 m room, car in the middle facing +y

from umlbot.base.errors import ConfigError, DriverError
from umlbot.base.registry import create_driver
from umlbot.services.servo import Servo, ServoSettings
from umlbot.services.servo.lgpio import LgpioServo
from umlbot.services.servo.mock import MockServo
from umlbot.services.servo.pigpio import PigpioServo
from umlbot.services.simworld import attach_local_world
from umlbot.sim import CarSpec, World, parse_track
from umlbot.testing.lgpio import FakeLgpio
from umlbot.testing.pigpio import FakePi

#: Sim seconds the servo needs for its whole range.
FULL_TURN_S = CarSpec().servo_max_deg / CarSpec().servo_deg_per_s


@dataclass
class Rig:
    driver: Servo
    angle: Callable[[], float | None]  # None = no pulses


@pytest.fixture
def world() -> Iterator[World]:
    """A room attached as this process's world, so `create_driver(..., "sim", ...)` turns its servo."""
    room = World(parse_track(ROOM))
    attach_local_world(room)
    yield room
    attach_local_world(None)


def _settled_angle(world: World) -> float:
    """The world's servo angle after the turning time of a full sweep."""
    world.advance_to(world.snapshot().time_s + FULL_TURN_S)
    return world.servo_angle_deg()


def _make_rig(name: str, request: pytest.FixtureRequest) -> Iterator[Rig]:
    if name == "sim":
        world: World = request.getfixturevalue("world")
        sim = create_driver("servo", "sim", "Sensor", {"gpio": 18})
        yield Rig(sim, lambda: _settled_angle(world))
        sim.close()
        return
    if name == "mock":
        mock = MockServo("Sensor")
        yield Rig(mock, lambda: mock.angle_deg if mock.pulsing else None)
        mock.close()
        return
    if name == "lgpio-fake":
        lg = FakeLgpio()
        lg_driver = LgpioServo("Sensor", ServoSettings(gpio=18), lg=lg)

        def lg_angle() -> float | None:
            line = lg.line(18)
            assert line.servo_frequency in (0, 50)
            return None if line.servo_pulse_us == 0 else (line.servo_pulse_us - 500) * 180 / 2000

        yield Rig(lg_driver, lg_angle)
        lg_driver.close()
        return
    fake = FakePi()
    settings = ServoSettings(gpio=18)
    driver = PigpioServo("Sensor", settings, pi=fake)

    def angle() -> float | None:
        width = fake.pin(18).servo_pulsewidth
        return None if width == 0 else (width - 500) * 180 / 2000

    yield Rig(driver, angle)
    driver.close()


@pytest.fixture(params=["mock", "pigpio-fake", "lgpio-fake", "sim"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    yield from _make_rig(request.param, request)


@pytest.fixture(params=["mock", "pigpio-fake", "lgpio-fake"])
def pulse_rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    """The backends whose servo is driven by pulses that can be switched off."""
    yield from _make_rig(request.param, request)


def test_starts_without_pulses(pulse_rig: Rig) -> None:
    assert pulse_rig.angle() is None


@pytest.mark.parametrize("degrees", [0, 45, 90, 180])
def test_turns_to_angle(rig: Rig, degrees: float) -> None:
    rig.driver.set_angle(degrees)
    assert rig.angle() == pytest.approx(degrees, abs=0.1)


@pytest.mark.parametrize("degrees", [-1, 180.5, 360])
def test_out_of_range_is_refused(rig: Rig, degrees: float) -> None:
    before = rig.angle()
    with pytest.raises(ValueError, match="angle"):
        rig.driver.set_angle(degrees)
    assert rig.angle() == before, "the servo is not moved"


@pytest.mark.parametrize("degrees", [-1, 180.5, 360])
def test_out_of_range_sends_no_pulses(pulse_rig: Rig, degrees: float) -> None:
    with pytest.raises(ValueError, match="angle"):
        pulse_rig.driver.set_angle(degrees)
    assert pulse_rig.angle() is None


def test_declares_its_range_and_is_a_servo(rig: Rig) -> None:
    assert rig.driver.max_angle_deg == 180
    assert isinstance(rig.driver, Servo)


def test_stop_and_close_switch_pulses_off(pulse_rig: Rig) -> None:
    pulse_rig.driver.set_angle(90)
    pulse_rig.driver.stop()
    assert pulse_rig.angle() is None
    pulse_rig.driver.set_angle(30)
    pulse_rig.driver.close()
    pulse_rig.driver.close()
    assert pulse_rig.angle() is None


# --- sim specifics -----------------------------------------------------------------------------


def test_sim_starts_looking_ahead_and_turns_at_the_servo_speed(world: World) -> None:
    car = CarSpec()
    servo = create_driver("servo", "sim", "Sensor", {"gpio": 18})
    assert world.servo_angle_deg() == 90
    servo.set_angle(180)
    half_way_s = 45 / car.servo_deg_per_s
    world.advance_to(half_way_s)
    assert world.servo_angle_deg() == pytest.approx(135), "half way after half the turning time"
    world.advance_to(2 * half_way_s)
    assert world.servo_angle_deg() == pytest.approx(180)
    servo.close()


def test_sim_stop_holds_the_angle_and_close_refuses_commands(world: World) -> None:
    servo = create_driver("servo", "sim", "Sensor", {"gpio": 18})
    servo.set_angle(30)
    servo.stop()
    assert _settled_angle(world) == pytest.approx(30), "no pulses to stop: the mount stays where it is"
    servo.close()
    servo.close()
    with pytest.raises(DriverError, match="Sensor: driver is closed"):
        servo.set_angle(60)
    assert _settled_angle(world) == pytest.approx(30)


def test_sim_initial_angle_and_narrower_range(world: World) -> None:
    servo = create_driver("servo", "sim", "Sensor", {"gpio": 18, "max_angle_deg": 120,
                                                     "initial_angle_deg": 0})
    assert _settled_angle(world) == 0
    with pytest.raises(ValueError, match=r"0\.\.120"):
        servo.set_angle(150)
    with pytest.raises(ConfigError, match="initial_angle_deg must be <= max_angle_deg"):
        create_driver("servo", "sim", "Sensor", {"gpio": 18, "max_angle_deg": 90, "initial_angle_deg": 120})


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


def test_lgpio_uses_tx_servo_at_50_hz() -> None:
    lg = FakeLgpio()
    servo = LgpioServo("S", ServoSettings(gpio=18, initial_angle_deg=90), lg=lg)
    (handle,) = lg.open_handles
    assert lg.calls_named("tx_servo") == [(handle, 18, 1500, 50, 0, 0)]
    servo.set_angle(180)
    assert lg.line(18).servo_pulse_us == 2500
    servo.close()
    assert lg.calls_named("tx_servo")[-1] == (handle, 18, 0, 50, 0, 0)
    assert lg.line(18).claim == "free" and not lg.open_handles
