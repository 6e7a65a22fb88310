"""Plain GPIO reads and writes through lgpio (the Raspberry Pi 5 and any recent Pi OS).

A pin is claimed as an input (with the configured pull resistor) the first time it is read and as
an output the first time it is written; reading an output returns the level last written. Pins
the deployment does not allow, and pins owned by other components, are refused with
`PinNotAllowed` before lgpio is asked.
"""

from __future__ import annotations

import threading
from typing import Any

from services.gpio.driver import GpioSettings, PinNotAllowed
from services.lgpio_connection import LgpioHandle
from services.registry import DriverFactory
from umlbot.errors import DriverError
from umlbot.logs import get_logger

log = get_logger("umlbot.gpio.lgpio")

PULL = {"off": 128, "up": 32, "down": 64}  # lgpio.SET_PULL_NONE, SET_PULL_UP, SET_PULL_DOWN


class LgpioGpio:
    """The system component's pins; satisfies `GpioPins`."""

    def __init__(self, component: str, settings: GpioSettings, lg: Any = None) -> None:
        self.component = component
        self.settings = settings
        self.allowed_pins = settings.allowed()
        self._outputs: dict[int, bool] = {}  # pin -> claimed as output (False: as input)
        self._lock = threading.Lock()
        self._closed = False
        self._pins = LgpioHandle(component, settings.chip, lg)
        log.info("gpio ready", component=component, pins=sorted(self.allowed_pins), chip=settings.chip)

    def _check(self, pin: int) -> None:
        reason = self.settings.refusal(pin)
        if reason is not None:
            raise PinNotAllowed(pin, reason)
        if self._closed:
            raise DriverError(f"{self.component}: gpio is closed")

    def read(self, pin: int) -> int:
        with self._lock:
            self._check(pin)
            if pin not in self._outputs:
                self._pins.call("gpio_claim_input", pin, PULL[self.settings.pull])
                self._outputs[pin] = False
            return 1 if self._pins.call("gpio_read", pin) else 0

    def write(self, pin: int, value: int) -> None:
        if value not in (0, 1):
            raise ValueError(f"a pin value is 0 or 1, got {value}")
        with self._lock:
            self._check(pin)
            if self._outputs.get(pin):
                self._pins.call("gpio_write", pin, value)
            else:
                self._pins.call("gpio_claim_output", pin, value)  # claims and sets the level at once
                self._outputs[pin] = True

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._pins.close()


def _create(component: str, settings: GpioSettings) -> LgpioGpio:
    return LgpioGpio(component, settings)


FACTORY = DriverFactory(GpioSettings, _create)
