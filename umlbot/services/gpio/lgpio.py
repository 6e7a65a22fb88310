"""Plain GPIO reads and writes through lgpio (the Raspberry Pi 5 and any recent Pi OS).

The pin rules are `umlbot.services.gpio.driver.HardwareGpio`'s; lgpio claims a pin as an input or an
output (claiming an output sets its level at once).
"""

from __future__ import annotations

from typing import Any

from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.gpio.driver import GpioSettings, HardwareGpio
from umlbot.services.pins.lgpio import LgpioHandle

log = get_logger("umlbot.gpio.lgpio")

PULL = {"off": 128, "up": 32, "down": 64}  # lgpio.SET_PULL_NONE, SET_PULL_UP, SET_PULL_DOWN


class LgpioGpio(HardwareGpio):
    """The system component's pins; satisfies `GpioPins`."""

    def __init__(self, component: str, settings: GpioSettings, lg: Any = None) -> None:
        self._handle = LgpioHandle(component, settings.chip, lg)
        super().__init__(component, settings, self._handle)
        log.info("gpio ready", component=component, pins=sorted(self.allowed_pins), chip=settings.chip)

    def _input(self, pin: int) -> None:
        self._handle.call("gpio_claim_input", pin, PULL[self.settings.pull])

    def _level(self, pin: int) -> int:
        return int(self._handle.call("gpio_read", pin))

    def _output(self, pin: int, value: int, first: bool) -> None:
        # claiming an output sets its level at once
        self._handle.call("gpio_claim_output" if first else "gpio_write", pin, value)


def _create(component: str, settings: GpioSettings) -> LgpioGpio:
    return LgpioGpio(component, settings)


FACTORY = DriverFactory(GpioSettings, _create)
