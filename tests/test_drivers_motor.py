"""Contract suite for motor channel drivers: mock, pigpio and lgpio (with and without an enable
pin) on the fake pigpio.pi and the fake lgpio, and sim on a small simulated world. The observable
is the signed drive in percent (+ clockwise, - anticlockwise): for sim, the command the world holds
for the channel's side."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest
from conftest import wait_until
from services_support import ROOM  # 2 m x 3 m room, car in the middle facing +y

from umlbot.base.errors import DriverError
from umlbot.base.registry import create_driver
from umlbot.services.motor import L298NSettings, MotorChannel
from umlbot.services.motor.lgpio import LgpioL298NChannel
from umlbot.services.motor.mock import MockMotorChannel, MockMotorSettings
from umlbot.services.motor.pigpio import PWM_RANGE, PigpioL298NChannel
from umlbot.services.motor.sim import SimMotorChannel
from umlbot.services.simworld import attach_local_world
from umlbot.sim import CarSpec, World, parse_track
from umlbot.testing.lgpio import FakeLgpio
from umlbot.testing.pigpio import FakePi


@dataclass
class Rig:
    driver: MotorChannel
    drive: Callable[[], float]  # signed percent the motor receives


def _pigpio_rig(fake: FakePi, enable: int | None, watchdog_s: float = 2.0) -> Rig:
    settings = L298NSettings(in1=22, in2=23, enable=enable, watchdog_s=watchdog_s)
    driver = PigpioL298NChannel("LeftActuator", settings, pi=fake)

    def drive() -> float:
        in1, in2 = fake.pin(22), fake.pin(23)
        if enable is None:
            return 100 * (in1.duty_fraction - in2.duty_fraction)
        return 100 * fake.pin(enable).duty_fraction * (in1.level - in2.level)

    return Rig(driver, drive)


def _lgpio_rig(fake: FakeLgpio, enable: int | None, watchdog_s: float = 2.0) -> Rig:
    settings = L298NSettings(in1=22, in2=23, enable=enable, watchdog_s=watchdog_s)
    driver = LgpioL298NChannel("LeftActuator", settings, lg=fake)

    def drive() -> float:
        in1, in2 = fake.line(22), fake.line(23)
        if enable is None:
            return 100 * (in1.duty_fraction - in2.duty_fraction)
        return 100 * fake.line(enable).duty_fraction * (in1.level - in2.level)

    return Rig(driver, drive)


def _sim_drive(world: World) -> float:
    left = world.motor("left")
    return (1 if left.forward else -1) * left.duty_percent * left.enabled


@pytest.fixture
def world() -> Iterator[World]:
    """A room attached as this process's world, so `create_driver(..., "sim", ...)` drives it."""
    room = World(parse_track(ROOM))
    attach_local_world(room)
    yield room
    attach_local_world(None)


@pytest.fixture(params=["mock", "pigpio-fake", "pigpio-fake-enable", "lgpio-fake", "lgpio-fake-enable",
                        "sim"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    if request.param == "mock":
        mock = MockMotorChannel("LeftActuator")
        yield Rig(mock, lambda: (1 if mock.clockwise else -1) * mock.duty_cycle_percent * mock.enabled)
        mock.close()
        return
    if request.param == "sim":
        world: World = request.getfixturevalue("world")
        channel = create_driver("motor", "sim", "LeftActuator", {"in1": 22, "in2": 23})
        yield Rig(channel, lambda: _sim_drive(world))
        channel.close()
        return
    enable = 24 if request.param.endswith("enable") else None
    lgpio = request.param.startswith("lgpio")
    rig = _lgpio_rig(FakeLgpio(), enable) if lgpio else _pigpio_rig(FakePi(), enable)
    yield rig
    rig.driver.close()


def test_starts_stopped(rig: Rig) -> None:
    assert rig.drive() == 0


def test_drives_with_duty_cycle_when_enabled(rig: Rig) -> None:
    rig.driver.set_duty_cycle(60)
    assert rig.drive() == 0, "not enabled yet"
    rig.driver.set_enabled(True)
    assert rig.drive() == pytest.approx(60)
    rig.driver.set_duty_cycle(25.5)
    assert rig.drive() == pytest.approx(25.5)


def test_direction_reverses(rig: Rig) -> None:
    rig.driver.set_duty_cycle(40)
    rig.driver.set_enabled(True)
    rig.driver.set_direction(False)
    assert rig.drive() == pytest.approx(-40)
    rig.driver.set_direction(True)
    assert rig.drive() == pytest.approx(40)


def test_disable_stops(rig: Rig) -> None:
    rig.driver.set_duty_cycle(80)
    rig.driver.set_enabled(True)
    rig.driver.set_enabled(False)
    assert rig.drive() == 0


def test_stop_is_disabled_and_zero_duty(rig: Rig) -> None:
    rig.driver.set_duty_cycle(80)
    rig.driver.set_enabled(True)
    rig.driver.stop()
    assert rig.drive() == 0
    rig.driver.set_enabled(True)
    assert rig.drive() == 0, "stop() also sets the duty cycle to 0"


def test_duty_cycle_out_of_range_is_refused(rig: Rig) -> None:
    with pytest.raises(ValueError):
        rig.driver.set_duty_cycle(101)
    with pytest.raises(ValueError):
        rig.driver.set_duty_cycle(-1)


def test_close_twice_is_safe_and_leaves_motor_stopped(rig: Rig) -> None:
    rig.driver.set_duty_cycle(100)
    rig.driver.set_enabled(True)
    rig.driver.close()
    rig.driver.close()
    assert rig.drive() == 0


def test_is_a_motor_channel(rig: Rig) -> None:
    assert isinstance(rig.driver, MotorChannel)


# --- sim specifics -----------------------------------------------------------------------------


def test_sim_side_speed_follows_the_command_and_the_car_turns(world: World) -> None:
    car = CarSpec()
    left = create_driver("motor", "sim", "LeftActuator", {"in1": 22, "in2": 23})
    assert isinstance(left, SimMotorChannel) and left.side == "left"
    left.set_duty_cycle(60)
    left.set_enabled(True)
    world.advance_to(0.5)  # many motor time constants
    assert world.motor("left").speed_mps == pytest.approx(car.top_speed_mps * 0.6, rel=1e-3)
    assert world.motor("right").speed_mps == 0, "the other side is untouched"
    assert world.snapshot().pose.heading < world.track.start.pose.heading, "left side only: turns right"
    left.set_direction(False)
    world.advance_to(1.0)
    assert world.motor("left").speed_mps == pytest.approx(-car.top_speed_mps * 0.6, rel=1e-3)
    left.close()
    world.advance_to(1.5)
    assert world.motor("left").speed_mps == pytest.approx(0, abs=1e-6), "closing stops the side"


def test_sim_duty_below_the_dead_band_does_not_move_the_car(world: World) -> None:
    right = create_driver("motor", "sim", "RightActuator", {"in1": 24, "in2": 25})
    right.set_duty_cycle(CarSpec().dead_band_percent - 1)
    right.set_enabled(True)
    world.advance_to(0.5)
    assert world.motor("right").enabled and world.motor("right").speed_mps == 0
    assert world.snapshot().distance_m == 0
    right.close()


def test_sim_closed_channel_refuses_commands(world: World) -> None:
    channel = create_driver("motor", "sim", "LeftActuator", {"in1": 22, "in2": 23})
    channel.close()
    with pytest.raises(DriverError, match="LeftActuator: driver is closed"):
        channel.set_enabled(True)
    assert not world.motor("left").enabled


# --- pigpio specifics --------------------------------------------------------------------------


def test_pigpio_writes_zero_before_pwm_and_uses_documented_range() -> None:
    fake = FakePi()
    channel = PigpioL298NChannel("M", L298NSettings(in1=22, in2=23, pwm_frequency_hz=1000), pi=fake)
    writes = [args for name, args in fake.calls if name == "write"]
    assert (22, 0) in writes and (23, 0) in writes
    assert fake.calls_named("set_PWM_range") == [(22, PWM_RANGE), (23, PWM_RANGE)]
    assert fake.pin(22).pwm_frequency == 1000
    channel.set_duty_cycle(50)
    channel.set_enabled(True)
    first_pwm = next(i for i, (n, a) in enumerate(fake.calls) if n == "set_PWM_dutycycle" and a[0] == 22)
    first_write = next(i for i, (n, a) in enumerate(fake.calls) if n == "write" and a == (22, 0))
    assert first_write < first_pwm
    assert fake.pin(22).pwm_dutycycle == PWM_RANGE // 2
    channel.close()


def test_pigpio_frequency_is_the_nearest_pigpio_offers() -> None:
    fake = FakePi()
    channel = PigpioL298NChannel("M", L298NSettings(in1=5, in2=6, pwm_frequency_hz=900), pi=fake)
    assert channel.pwm_frequency_hz in (800, 1000)
    channel.close()


def test_pigpio_never_drives_both_inputs() -> None:
    fake = FakePi()
    channel = PigpioL298NChannel("M", L298NSettings(in1=22, in2=23), pi=fake)
    channel.set_duty_cycle(70)
    channel.set_enabled(True)
    for clockwise in (False, True, False):
        channel.set_direction(clockwise)
        assert min(fake.pin(22).duty_fraction, fake.pin(23).duty_fraction) == 0
    channel.close()


def test_pigpio_enable_pin_coasts_or_brakes() -> None:
    fake = FakePi()
    coast = PigpioL298NChannel("M", L298NSettings(in1=22, in2=23, enable=24), pi=fake)
    coast.set_duty_cycle(50)
    coast.set_enabled(True)
    coast.set_enabled(False)
    assert fake.pin(24).level == 0 and fake.pin(24).pwm_dutycycle == 0  # EN low: free running
    coast.close()
    fake2 = FakePi()
    brake = PigpioL298NChannel("M", L298NSettings(in1=22, in2=23, enable=24, brake=True), pi=fake2)
    brake.set_duty_cycle(50)
    brake.set_enabled(True)
    brake.set_enabled(False)
    assert fake2.pin(24).level == 1 and fake2.pin(22).level == fake2.pin(23).level == 0  # fast stop
    brake.close()


def test_pigpio_invert_swaps_direction() -> None:
    fake = FakePi()
    channel = PigpioL298NChannel("M", L298NSettings(in1=22, in2=23, invert=True), pi=fake)
    channel.set_duty_cycle(30)
    channel.set_enabled(True)
    assert fake.pin(23).duty_fraction == pytest.approx(0.3) and fake.pin(22).duty_fraction == 0
    channel.close()


def test_pigpio_lost_daemon_is_a_driver_error() -> None:
    fake = FakePi()
    channel = PigpioL298NChannel("M", L298NSettings(in1=22, in2=23), pi=fake)
    fake.connected = False
    with pytest.raises(DriverError, match="M: pigpio"):
        channel.set_duty_cycle(10)


def test_settings_refuse_shared_pins() -> None:
    with pytest.raises(ValueError, match="different pins"):
        L298NSettings(in1=22, in2=22)


def test_mock_records_commands_and_injects_faults() -> None:
    mock = create_driver("motor", "mock", "M", {"in1": 22, "mock_faults": {"set_direction": "jammed"}})
    assert isinstance(mock, MockMotorChannel)
    mock.set_duty_cycle(10)
    with pytest.raises(DriverError, match="jammed"):
        mock.set_direction(False)
    mock.fail_next("set_enabled", "once")
    with pytest.raises(DriverError, match="once"):
        mock.set_enabled(True)
    mock.set_enabled(True)
    assert mock.commands == [
        ("set_duty_cycle", (10,)),
        ("set_direction", (False,)),
        ("set_enabled", (True,)),
        ("set_enabled", (True,)),
    ]
    assert mock.running


def test_mock_latency_is_applied() -> None:
    import time

    mock = MockMotorChannel("M", MockMotorSettings(mock_latency_s=0.05))
    started = time.monotonic()
    mock.set_enabled(True)
    assert time.monotonic() - started >= 0.05


# --- lgpio specifics ---------------------------------------------------------------------------


def test_lgpio_claims_outputs_low_before_pwm_and_passes_the_percent() -> None:
    fake = FakeLgpio()
    channel = LgpioL298NChannel("M", L298NSettings(in1=22, in2=23, pwm_frequency_hz=1000), lg=fake)
    (handle,) = fake.open_handles  # chip 0: the handle is its own key
    assert fake.calls_named("gpio_claim_output") == [(handle, 22, 0, 0), (handle, 23, 0, 0)]
    channel.set_duty_cycle(37.5)
    channel.set_enabled(True)
    assert fake.line(22).pwm_frequency == 1000 and fake.line(22).pwm_duty_percent == 37.5
    channel.set_direction(False)
    assert fake.line(22).pwm_frequency == 0, "PWM is switched off before the pin is written low"
    assert fake.line(22).level == 0 and fake.line(23).pwm_duty_percent == 37.5
    channel.close()
    assert fake.line(22).claim == fake.line(23).claim == "free", "close frees the lines"
    assert not fake.open_handles, "and closes the chip"


def test_lgpio_never_drives_both_inputs() -> None:
    fake = FakeLgpio()
    channel = LgpioL298NChannel("M", L298NSettings(in1=22, in2=23), lg=fake)
    channel.set_duty_cycle(70)
    channel.set_enabled(True)
    for clockwise in (False, True, False):
        channel.set_direction(clockwise)
        assert min(fake.line(22).duty_fraction, fake.line(23).duty_fraction) == 0
    channel.close()


def test_lgpio_enable_pin_brakes() -> None:
    fake = FakeLgpio()
    brake = LgpioL298NChannel("M", L298NSettings(in1=22, in2=23, enable=24, brake=True), lg=fake)
    brake.set_duty_cycle(50)
    brake.set_enabled(True)
    brake.set_enabled(False)
    assert fake.line(24).pwm_frequency == 0 and fake.line(24).level == 1
    assert fake.line(22).level == fake.line(23).level == 0  # fast stop
    brake.close()


def test_lgpio_busy_line_is_a_driver_error_naming_the_component() -> None:
    fake = FakeLgpio()
    first = LgpioL298NChannel("Left", L298NSettings(in1=22, in2=23), lg=fake)
    with pytest.raises(DriverError, match=r"Right: lgpio gpio_claim_output.*'GPIO busy'"):
        LgpioL298NChannel("Right", L298NSettings(in1=23, in2=24), lg=fake)
    assert len(fake.open_handles) == 1, "the failed channel closed its handle"
    first.close()


def test_lgpio_missing_chip_says_how_to_fix_it() -> None:
    fix = r"cannot open /dev/gpiochip4 .*can not open gpiochip.*usermod -aG gpio"
    with pytest.raises(DriverError, match=fix):
        LgpioL298NChannel("M", L298NSettings(in1=22, in2=23, chip=4), lg=FakeLgpio())


# --- the deadman outside the service's process (pigpio script, lgpio bursts, the sim world) -----

DEADMAN_S = 0.4  # watchdog_s of the deadman rigs
#: the fakes' threads and the sim's world loop end a deadman this much late at most
DEADMAN_SLACK_S = 0.15


@pytest.fixture(params=["pigpio-fake", "pigpio-fake-enable", "lgpio-fake", "lgpio-fake-enable", "sim"])
def deadman_rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    """A driver with `watchdog_s: 0.4` whose deadman runs where the hardware's would: pigpiod's
    script thread (the fake's), lgpio's TX thread (the fake's), the world (wall-clock time)."""
    settings = {"in1": 22, "in2": 23, "watchdog_s": DEADMAN_S}
    if request.param == "sim":
        from umlbot.base.clock import Clock

        world: World = request.getfixturevalue("world")
        world.clock = Clock(1.0)
        channel = create_driver("motor", "sim", "LeftActuator", settings)

        def drive() -> float:
            world.advance_to(world.time_s())
            return _sim_drive(world)

        yield Rig(channel, drive)
        channel.close()
        return
    enable = 24 if request.param.endswith("enable") else None
    if request.param.startswith("lgpio"):
        lg = FakeLgpio()
        rig = _lgpio_rig(lg, enable, DEADMAN_S)
        yield rig
        rig.driver.close()
        lg.shutdown()
        return
    rig = _pigpio_rig(FakePi(), enable, DEADMAN_S)
    yield rig
    rig.driver.close()


def _stops_after(rig: Rig, limit_s: float, started: float | None = None) -> float | None:
    """Seconds from `started` (default: now) until the motor stopped by itself (None: still
    running `limit_s` after it)."""
    started = time.monotonic() if started is None else started
    while time.monotonic() - started < limit_s:
        if rig.drive() == 0:
            return time.monotonic() - started
        time.sleep(0.01)
    return None


def test_deadman_stops_a_motor_nobody_renews_within_watchdog_s(deadman_rig: Rig) -> None:
    deadman_rig.driver.set_duty_cycle(60)
    enabled = time.monotonic()
    deadman_rig.driver.set_enabled(True)
    armed = time.monotonic()
    assert deadman_rig.drive() == 60
    stopped = _stops_after(deadman_rig, DEADMAN_S + 1.0, enabled)
    assert stopped is not None, "a service that renews nothing (frozen) leaves the motor running"
    # lgpio's one unrenewed burst lasts half of it; pigpio's count down ends between 3/4 and all
    assert DEADMAN_S / 2 - (armed - enabled) <= stopped <= DEADMAN_S + DEADMAN_SLACK_S, stopped
    assert deadman_rig.driver.renew() is False, "the next renewal says that the deadman fired"
    assert deadman_rig.driver.renew() is True, "once"
    deadman_rig.driver.stop()  # what the motor service does then
    deadman_rig.driver.set_duty_cycle(60)  # commanded again: it drives again, deadman armed
    deadman_rig.driver.set_enabled(True)
    assert deadman_rig.drive() == 60
    assert _stops_after(deadman_rig, DEADMAN_S + 1.0) is not None


def test_renewals_keep_the_motor_running_and_their_end_stops_it(deadman_rig: Rig) -> None:
    deadman_rig.driver.set_duty_cycle(40)
    deadman_rig.driver.set_direction(False)
    deadman_rig.driver.set_enabled(True)
    until = time.monotonic() + 3 * DEADMAN_S
    while time.monotonic() < until:
        renewed = time.monotonic()
        assert deadman_rig.driver.renew() is True
        assert deadman_rig.drive() == -40
        time.sleep(0.05)  # the motor service's safety round
    stopped = _stops_after(deadman_rig, DEADMAN_S + 1.0, renewed)
    assert stopped is not None and stopped <= DEADMAN_S + DEADMAN_SLACK_S, stopped


def test_without_a_watchdog_there_is_no_deadman() -> None:
    pi, lg = FakePi(), FakeLgpio()
    settings = L298NSettings(in1=22, in2=23, watchdog_s=0)
    pigpio = PigpioL298NChannel("M", settings, pi=pi)
    lgpio = LgpioL298NChannel("M", settings, lg=lg)
    for channel in (pigpio, lgpio):
        channel.set_duty_cycle(50)
        channel.set_enabled(True)
    time.sleep(0.3)
    assert pi.pin(22).duty_fraction == 0.5 and lg.line(22).duty_fraction == 0.5
    assert not pi.calls_named("store_script") and lg.calls_named("tx_pwm")[-1][-1] == 0, "endless PWM"
    pigpio.close()
    lgpio.close()
    lg.shutdown()


def test_pigpio_deadman_is_a_daemon_script_deleted_on_close_and_after_a_kill() -> None:
    from umlbot.services.motor.pigpio import DEADMAN_MARK

    pi = FakePi()
    first = PigpioL298NChannel("Left", L298NSettings(in1=22, in2=23, watchdog_s=2.0), pi=pi)
    other = PigpioL298NChannel("Right", L298NSettings(in1=24, in2=25, watchdog_s=2.0), pi=pi)
    assert len(pi.scripts) == 2
    (script,) = [i for i, s in pi.scripts.items() if 22 in s.params]
    params = pi.script_status(script)[1]
    assert params[:4] == (19, 22, 23, 22) and params[9] == DEADMAN_MARK, "2 s in 100 ms steps, pins, mark"
    first.set_duty_cycle(30)
    first.set_enabled(True)
    assert wait_until(lambda: pi.script_status(script)[0] == 2), "it runs while the motor drives"
    first.set_enabled(False)
    assert wait_until(lambda: pi.script_status(script)[0] == 1), "and halts when it stops"
    first.set_enabled(True)
    # the service is killed: nobody closes `first`; its script stays in pigpiod. A new driver of
    # the same pins deletes it (and leaves the other channel's alone)
    stored = set(pi.scripts)
    second = PigpioL298NChannel("Left", L298NSettings(in1=22, in2=23, watchdog_s=2.0), pi=pi)
    assert script in pi.calls_named("delete_script")[0], "the killed driver's script was deleted"
    assert len(pi.scripts) == 2 and set(pi.scripts) - stored <= {script}, "the new one stored"
    assert any(25 in s.params for s in pi.scripts.values()), "the other channel's script is kept"
    second.close()
    other.close()
    assert not pi.scripts, "close deletes the script"


def test_lgpio_pwm_goes_out_in_bursts_and_a_new_duty_replaces_them_at_once() -> None:
    lg = FakeLgpio()
    channel = LgpioL298NChannel("M", L298NSettings(in1=22, in2=23, pwm_frequency_hz=100, watchdog_s=2.0),
                                lg=lg)
    channel.set_duty_cycle(50)
    channel.set_enabled(True)
    assert lg.calls_named("tx_pwm")[-1][2:] == (100, 50.0, 0, 100), "1 s bursts: watchdog_s / 2"
    assert channel.renew() is True
    assert lg.line(22).pwm_queue == [(100.0, 50.0, 100)], "the next burst is queued"
    assert channel.renew() is True
    assert len(lg.line(22).pwm_queue) == 1, "one burst queued at most"
    channel.set_duty_cycle(80)
    assert lg.line(22).pwm_duty_percent == 80 and lg.line(22).pwm_queue == [], "at once"
    channel.close()
    lg.shutdown()
