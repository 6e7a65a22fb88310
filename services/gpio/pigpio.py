"""Plain GPIO reads and writes on the Raspberry Pi through the pigpio daemon.

A pin becomes an input (with the configured pull resistor) the first time it is read and an
output the first time it is written; reading an output returns its level. Pins the deployment
does not allow, and pins owned by other components, are refused with `PinNotAllowed`.
"""

from __future__ import annotations

import threading
from typing import Any

from services.gpio.driver import GpioSettings, PinNotAllowed
from services.pigpio_connection import PigpioHandle
from services.registry import DriverFactory
from umlbot.errors import DriverError
from umlbot.logs import get_logger

log = get_logger("umlbot.gpio.pigpio")

INPUT = 0  # pigpio.INPUT
OUTPUT = 1  # pigpio.OUTPUT
PULL = {"off": 0, "down": 1, "up": 2}  # pigpio.PUD_OFF, PUD_DOWN, PUD_UP


class PigpioGpio:
    """The system component's pins; satisfies `GpioPins`."""

    def __init__(self, component: str, settings: GpioSettings, pi: Any = None) -> None:
        self.component = component
        self.settings = settings
        self.allowed_pins = settings.allowed()
        self._modes: dict[int, int] = {}
        self._lock = threading.Lock()
        self._closed = False
        self._pins = PigpioHandle(component, settings.host, settings.port, pi)
        log.info("gpio ready", component=component, pins=sorted(self.allowed_pins))

    def _check(self, pin: int) -> None:
        reason = self.settings.refusal(pin)
        if reason is not None:
            raise PinNotAllowed(pin, reason)
        if self._closed:
            raise DriverError(f"{self.component}: gpio is closed")

    def read(self, pin: int) -> int:
        with self._lock:
            self._check(pin)
            if pin not in self._modes:
                self._pins.call("set_mode", pin, INPUT)
                self._pins.call("set_pull_up_down", pin, PULL[self.settings.pull])
                self._modes[pin] = INPUT
            return 1 if self._pins.call("read", pin) else 0

    def write(self, pin: int, value: int) -> None:
        if value not in (0, 1):
            raise ValueError(f"a pin value is 0 or 1, got {value}")
        with self._lock:
            self._check(pin)
            if self._modes.get(pin) != OUTPUT:
                self._pins.call("set_mode", pin, OUTPUT)
                self._modes[pin] = OUTPUT
            self._pins.call("write", pin, value)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._pins.close()


def _create(component: str, settings: GpioSettings) -> PigpioGpio:
    return PigpioGpio(component, settings)


FACTORY = DriverFactory(GpioSettings, _create)
