"""Contract suite for distance sensor drivers: mock, pigpio on the fake pigpio.pi with a simulated
HC-SR04 (echo edges with ticks, 32-bit wrap-around, no echo), lgpio on the fake lgpio (echo alerts
with nanosecond timestamps), and sim pinging a simulated world
(a wall at the distance asked for). The sim sensor reads whole centimetres and cannot see a wall
closer than its bumper, so sub-centimetre and 2 cm readings are checked on mock and pigpio only."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

from umlbot.base.errors import DriverError
from umlbot.base.registry import create_driver
from umlbot.services.simworld import Side, StereoImages, attach_local_world
from umlbot.services.sonar import DistanceSensor, HCSR04Settings
from umlbot.services.sonar.lgpio import LgpioHCSR04
from umlbot.services.sonar.mock import MockDistanceSensor, MockSonarSettings
from umlbot.services.sonar.pigpio import PigpioHCSR04, tick_diff
from umlbot.services.sonar.sim import SimDistanceSensor
from umlbot.sim import Track
from umlbot.sim.world import CarSpec, World
from umlbot.testing.lgpio import FakeLgpio
from umlbot.testing.pigpio import TICK_WRAP, FakePi, tickDiff

CAR = CarSpec()


@dataclass
class Rig:
    driver: DistanceSensor
    set_distance: Callable[[float | None], None]


def wall_world(cm: float | None, *walls: list[tuple[float, float]]) -> World:
    """The car at the origin facing +x, a long wall `cm` ahead of its sonar (None: no wall in
    front, only one behind the car), plus any further `walls`."""
    x = -1.0 if cm is None else CAR.sonar_forward_m + cm / 100
    track = Track.model_validate({
        "name": "wall", "start": {"x": 0.0, "y": 0.0, "heading_deg": 0.0},
        "goal": {"x_min": -0.6, "x_max": -0.5, "y_min": -0.05, "y_max": 0.05},
        "walls": [[(x, -5.0), (x, 5.0)], *walls],
    })
    return World(track)


class MovingWall:
    """A `WorldHandle` whose world is rebuilt with the wall at each new distance, so one sim
    sensor sees the distance change, as when the car drives towards a wall."""

    def __init__(self) -> None:
        self.world = wall_world(100)

    def set_distance(self, cm: float | None) -> None:
        self.world = wall_world(cm)

    def set_motor(self, side: Side, *, enabled: bool | None = None, forward: bool | None = None,
                  duty_percent: float | None = None) -> None:
        self.world.set_motor(side, enabled=enabled, forward=forward, duty_percent=duty_percent)

    def renew_motor(self, side: Side, lease_s: float) -> bool:
        return self.world.renew_motor(side, lease_s)

    def set_servo(self, degrees: float) -> None:
        self.world.set_servo(degrees)

    def servo_angle_deg(self) -> float:
        return self.world.servo_angle_deg()

    def read_sonar_cm(self) -> int | None:
        return self.world.read_sonar_cm()

    def time_s(self) -> float:
        return self.world.time_s()

    def render_stereo(self, width_px: int, height_px: int) -> StereoImages:
        return self.world.render_stereo(width_px, height_px)


def _make_rig(name: str) -> Iterator[Rig]:
    if name == "sim":
        wall = MovingWall()
        sim = SimDistanceSensor("DistanceRead", wall)
        yield Rig(sim, wall.set_distance)
        sim.close()
        return
    if name == "mock":
        mock = MockDistanceSensor("DistanceRead")
        yield Rig(mock, mock.set_distance)
        mock.close()
        return
    if name == "lgpio-fake":
        lg = FakeLgpio()
        lg_sonar = lg.attach_hcsr04(trigger=8, echo=7, distance_cm=100)
        lg_driver = LgpioHCSR04("DistanceRead", HCSR04Settings(trigger=8, echo=7), lg=lg)

        def set_lg_distance(cm: float | None) -> None:
            lg_sonar.distance_cm = cm

        yield Rig(lg_driver, set_lg_distance)
        lg_driver.close()
        lg.shutdown()
        return
    fake = FakePi()
    sonar = fake.attach_hcsr04(trigger=8, echo=7, distance_cm=100)
    driver = PigpioHCSR04("DistanceRead", HCSR04Settings(trigger=8, echo=7), pi=fake)

    def set_distance(cm: float | None) -> None:
        sonar.distance_cm = cm

    yield Rig(driver, set_distance)
    driver.close()


@pytest.fixture(params=["mock", "pigpio-fake", "lgpio-fake", "sim"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    yield from _make_rig(request.param)


@pytest.fixture(params=["mock", "pigpio-fake", "lgpio-fake"])
def fine_rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    """The backends that read fractions of a centimetre and down to 2 cm."""
    yield from _make_rig(request.param)


@pytest.mark.parametrize("cm", [3.0, 57.0, 399.0])
def test_reads_the_distance(rig: Rig, cm: float) -> None:
    rig.set_distance(cm)
    assert rig.driver.read_distance_cm() == pytest.approx(cm, abs=0.05)


@pytest.mark.parametrize("cm", [2.0, 15.5])
def test_reads_fractions_and_the_minimum(fine_rig: Rig, cm: float) -> None:
    fine_rig.set_distance(cm)
    assert fine_rig.driver.read_distance_cm() == pytest.approx(cm, abs=0.05)


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


# --- sim specifics -----------------------------------------------------------------------------


@pytest.fixture
def attached() -> Iterator[Callable[[World], World]]:
    """Attach a world as this process's, so `create_driver(..., "sim", ...)` reads it."""

    def attach(world: World) -> World:
        attach_local_world(world)
        return world

    yield attach
    attach_local_world(None)


def test_sim_reads_whole_centimetres_and_no_closer_than_the_bumper() -> None:
    wall = MovingWall()
    sensor = SimDistanceSensor("S", wall)
    for cm, expected in [(15.4, 15), (15.6, 16), (2.4, 2)]:
        wall.set_distance(cm)
        assert sensor.read_distance_cm() == expected
    bumper_cm = (CAR.length_m / 2 - CAR.sonar_forward_m) * 100
    with pytest.raises(ValueError, match="overlaps a wall"):
        wall.set_distance(bumper_cm)


def _post(bearing_deg: float, metres: float) -> list[tuple[float, float]]:
    """A 4 cm post `metres` from the sonar at a bearing from straight ahead (left > 0)."""
    x = CAR.sonar_forward_m + metres * math.cos(math.radians(bearing_deg))
    y = metres * math.sin(math.radians(bearing_deg))
    return [(x, y - 0.02), (x, y + 0.02)]


def test_sim_sees_a_post_within_the_beam_and_not_beside_it(attached: Callable[[World], World]) -> None:
    half_beam = CAR.sonar_beam_deg / 2
    attached(wall_world(None, _post(half_beam - 2.5, 1.0)))
    sensor = create_driver("sonar", "sim", "DistanceRead", {"trigger": 8, "echo": 7})
    assert sensor.read_distance_cm() == 100, "a post inside the 15° beam echoes"
    world = attached(wall_world(None, _post(half_beam + 5, 1.0)))
    beside = create_driver("sonar", "sim", "DistanceRead", {"trigger": 8, "echo": 7})
    assert beside.read_distance_cm() is None, "outside the beam: no echo"
    servo = create_driver("servo", "sim", "Sensor", {"gpio": 18})
    servo.set_angle(90 + half_beam + 5)  # turn the sonar towards the post
    world.advance_to(1.0)
    assert beside.read_distance_cm() == 100


def test_sim_far_echo_is_clamped_to_max_range(attached: Callable[[World], World]) -> None:
    attached(wall_world(350))
    sensor = create_driver("sonar", "sim", "DistanceRead", {"trigger": 8, "echo": 7, "max_range_cm": 300})
    assert sensor.max_range_cm == 300
    assert sensor.read_distance_cm() == 300


class ScriptedPings(MovingWall):
    """A world handle whose pings return the given readings in order."""

    def __init__(self, readings: list[int | None]) -> None:
        super().__init__()
        self.readings = iter(readings)

    def read_sonar_cm(self) -> int | None:
        return next(self.readings)


@pytest.mark.parametrize(("readings", "expected"), [
    ([10, None, 30], 20.0),
    ([None, None, 30], 30.0),  # like the real driver: the median of the pings that got an echo
    ([None, None, None], None),
])
def test_sim_median_of_samples_ignores_no_echo(readings: list[int | None], expected: float | None) -> None:
    sensor = SimDistanceSensor("S", ScriptedPings(readings), samples=3)
    assert sensor.read_distance_cm() == expected


def test_sim_closed_sensor_refuses_to_read(attached: Callable[[World], World]) -> None:
    attached(wall_world(50))
    sensor = create_driver("sonar", "sim", "DistanceRead", {"trigger": 8, "echo": 7})
    sensor.close()
    with pytest.raises(DriverError, match="DistanceRead: driver is closed"):
        sensor.read_distance_cm()


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


# --- lgpio specifics --------------------------------------------------------------------------


def test_lgpio_pings_by_writing_trigger_and_times_echo_alerts() -> None:
    lg = FakeLgpio()
    lg.attach_hcsr04(8, 7, distance_cm=20)
    driver = LgpioHCSR04("S", HCSR04Settings(trigger=8, echo=7), lg=lg)
    assert driver.read_distance_cm() == pytest.approx(20, abs=0.05)
    (handle,) = lg.open_handles
    assert lg.calls_named("gpio_claim_alert") == [(handle, 7, lg.BOTH_EDGES, lg.SET_PULL_DOWN)]
    assert lg.calls_named("gpio_write") == [(handle, 8, 1), (handle, 8, 0)]
    driver.close()
    assert not lg._callbacks and not lg.open_handles, "close cancels the callback and the handle"
    lg.shutdown()


def test_lgpio_silent_sensor_times_out_to_none() -> None:
    lg = FakeLgpio()
    lg.attach_hcsr04(8, 7, distance_cm=None, no_echo="silent")
    driver = LgpioHCSR04("S", HCSR04Settings(trigger=8, echo=7, echo_timeout_s=0.04), lg=lg)
    started = time.monotonic()
    assert driver.read_distance_cm() is None
    assert 0.03 <= time.monotonic() - started < 1.0
    driver.close()
    lg.shutdown()


def test_lgpio_far_echo_is_clamped_to_max_range() -> None:
    lg = FakeLgpio()
    lg.attach_hcsr04(8, 7, distance_cm=450)
    driver = LgpioHCSR04("S", HCSR04Settings(trigger=8, echo=7, max_range_cm=400), lg=lg)
    assert driver.read_distance_cm() == 400
    driver.close()
    lg.shutdown()


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
    from umlbot.base.errors import ConfigError

    with pytest.raises(ConfigError, match="mock_distnces"):
        create_driver("sonar", "mock", "S", {"mock_distnces": [1]})
