"""Plain GPIO reads and writes on the Raspberry Pi through the pigpio daemon.

The pin rules are `umlbot.services.gpio.driver.HardwareGpio`'s; pigpio sets a pin's mode, then reads or
writes it.
"""

from __future__ import annotations

from typing import Any

from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.gpio.driver import GpioSettings, HardwareGpio
from umlbot.services.pins.pigpio import PigpioHandle

log = get_logger("umlbot.gpio.pigpio")

INPUT = 0  # pigpio.INPUT
OUTPUT = 1  # pigpio.OUTPUT
PULL = {"off": 0, "down": 1, "up": 2}  # pigpio.PUD_OFF, PUD_DOWN, PUD_UP


class PigpioGpio(HardwareGpio):
    """The system component's pins; satisfies `GpioPins`."""

    def __init__(self, component: str, settings: GpioSettings, pi: Any = None) -> None:
        self._handle = PigpioHandle(component, settings.host, settings.port, pi)
        super().__init__(component, settings, self._handle)
        log.info("gpio ready", component=component, pins=sorted(self.allowed_pins))

    def _input(self, pin: int) -> None:
        self._handle.call("set_mode", pin, INPUT)
        self._handle.call("set_pull_up_down", pin, PULL[self.settings.pull])

    def _level(self, pin: int) -> int:
        return int(self._handle.call("read", pin))

    def _output(self, pin: int, value: int, first: bool) -> None:
        if first:
            self._handle.call("set_mode", pin, OUTPUT)
        self._handle.call("write", pin, value)


def _create(component: str, settings: GpioSettings) -> PigpioGpio:
    return PigpioGpio(component, settings)


FACTORY = DriverFactory(GpioSettings, _create)
