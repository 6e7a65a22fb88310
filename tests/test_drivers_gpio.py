"""Contract suite for GPIO drivers: mock, pigpio on the fake pigpio.pi, and lgpio on the fake lgpio."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

from umlbot.base.errors import DriverError
from umlbot.base.registry import create_driver
from umlbot.services.gpio import GpioPins, GpioSettings, PinNotAllowed
from umlbot.services.gpio.lgpio import LgpioGpio
from umlbot.services.gpio.mock import MockGpio, MockGpioSettings
from umlbot.services.gpio.pigpio import PigpioGpio
from umlbot.testing.lgpio import FakeLgpio
from umlbot.testing.pigpio import FakePi

ALLOWED = [4, 17, 27]
RESERVED = {22: "LeftActuator"}


@dataclass
class Rig:
    driver: GpioPins
    set_input: Callable[[int, int], None]
    output: Callable[[int], int]


@pytest.fixture(params=["mock", "pigpio-fake", "lgpio-fake"])
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    if request.param == "mock":
        mock = MockGpio("RaspberryPI", MockGpioSettings(pins=ALLOWED, reserved_pins=RESERVED))
        yield Rig(mock, mock.set_level, lambda pin: mock.levels.get(pin, 0))
        mock.close()
        return
    if request.param == "lgpio-fake":
        lg = FakeLgpio()
        lg_driver = LgpioGpio("RaspberryPI", GpioSettings(pins=ALLOWED, reserved_pins=RESERVED), lg=lg)
        yield Rig(lg_driver, lambda pin, level: lg.set_input(pin, level), lambda pin: lg.line(pin).level)
        lg_driver.close()
        lg.shutdown()
        return
    fake = FakePi()
    driver = PigpioGpio("RaspberryPI", GpioSettings(pins=ALLOWED, reserved_pins=RESERVED), pi=fake)
    yield Rig(driver, fake.set_input, lambda pin: fake.pin(pin).level)
    driver.close()


def test_reads_inputs(rig: Rig) -> None:
    rig.set_input(17, 1)
    assert rig.driver.read(17) == 1
    rig.set_input(17, 0)
    assert rig.driver.read(17) == 0


def test_writes_outputs_and_reads_them_back(rig: Rig) -> None:
    rig.driver.write(4, 1)
    assert rig.output(4) == 1
    assert rig.driver.read(4) == 1
    rig.driver.write(4, 0)
    assert rig.output(4) == 0


def test_pin_not_listed_is_refused(rig: Rig) -> None:
    with pytest.raises(PinNotAllowed, match="not in the deployment's pins"):
        rig.driver.read(5)
    with pytest.raises(PinNotAllowed):
        rig.driver.write(5, 1)


def test_pin_owned_by_a_component_is_refused(rig: Rig) -> None:
    with pytest.raises(PinNotAllowed, match="belongs to component LeftActuator"):
        rig.driver.write(22, 1)
    assert rig.output(22) == 0


def test_bad_value_is_refused(rig: Rig) -> None:
    with pytest.raises(ValueError):
        rig.driver.write(4, 2)


def test_allowed_pins_and_close(rig: Rig) -> None:
    assert rig.driver.allowed_pins == frozenset(ALLOWED)
    rig.driver.close()
    rig.driver.close()


def test_default_pins_are_all_but_reserved() -> None:
    settings = GpioSettings(reserved_pins={22: "L", 23: "L"})
    assert settings.allowed() == frozenset(range(28)) - {22, 23}
    with pytest.raises(ValueError):
        GpioSettings(pins=[28])


def test_pigpio_sets_modes_and_pull() -> None:
    fake = FakePi()
    driver = PigpioGpio("P", GpioSettings(pins=[4, 17], pull="up"), pi=fake)
    assert driver.read(17) == 1  # pulled up
    assert fake.calls_named("set_pull_up_down") == [(17, 2)]
    driver.write(4, 1)
    assert fake.calls_named("set_mode") == [(17, 0), (4, 1)]
    fake.connected = False
    with pytest.raises(DriverError):
        driver.write(4, 0)


def test_mock_initial_levels_from_settings() -> None:
    mock = create_driver("gpio", "mock", "P", {"pins": [4], "mock_levels": {4: 1}})
    assert mock.read(4) == 1
    assert mock.commands == [("read", (4,))]


def test_lgpio_claims_inputs_with_pull_and_outputs_with_their_level() -> None:
    lg = FakeLgpio()
    driver = LgpioGpio("P", GpioSettings(pins=[4, 17], pull="up"), lg=lg)
    assert driver.read(17) == 1  # pulled up
    driver.write(4, 1)
    driver.write(4, 0)
    (handle,) = lg.open_handles
    assert lg.calls_named("gpio_claim_input") == [(handle, 17, lg.SET_PULL_UP)]
    assert lg.calls_named("gpio_claim_output") == [(handle, 4, 1, 0)], "claimed once, at the level"
    assert lg.calls_named("gpio_write") == [(handle, 4, 0)]
    driver.close()
    assert lg.line(4).claim == lg.line(17).claim == "free" and not lg.open_handles
    with pytest.raises(DriverError, match="gpio is closed"):
        driver.read(17)
