"""HC-SR04 range finder on the Raspberry Pi through the pigpio daemon.

A ping is a 10 µs high pulse on TRIG (`gpio_trigger`); the module answers with a high pulse on
ECHO whose length is the sound's round trip: cm = µs / 58. Both echo edges are timed by pigpio
(edge callbacks carry the daemon's microsecond tick) and the pulse length is `tickDiff(rise,
fall)`, which is right across the 32-bit tick wrap-around (every ~72 minutes). Pings are at least
`min_interval_s` (≥ 60 ms, the datasheet's measurement cycle) apart so an old echo is never taken
for a new one. When no falling edge comes within `echo_timeout_s`, or the pulse is as long as a
module's "nothing in range" pulse (≥ 30 ms, ~5 m), the reading is None. With `samples` > 1 the
result is the median of the pings that got an echo (None when none did).
"""

from __future__ import annotations

from typing import Any

from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.pins.pigpio import PigpioHandle
from umlbot.services.sonar.driver import HCSR04Pings, HCSR04Settings

log = get_logger("umlbot.sonar.pigpio")

INPUT = 0  # pigpio.INPUT
OUTPUT = 1  # pigpio.OUTPUT
PUD_DOWN = 1  # pigpio.PUD_DOWN
EITHER_EDGE = 2  # pigpio.EITHER_EDGE
TRIGGER_PULSE_US = 10
TICK_WRAP = 1 << 32


def tick_diff(t1: int, t2: int) -> int:
    """Microseconds from tick t1 to t2 across the 32-bit wrap (pigpio.tickDiff)."""
    diff = t2 - t1
    return diff + TICK_WRAP if diff < 0 else diff


class PigpioHCSR04(HCSR04Pings):
    """One HC-SR04 on pigpio; satisfies `DistanceSensor` (how it is read: `HCSR04Pings`)."""

    _pins: PigpioHandle

    def __init__(self, component: str, settings: HCSR04Settings, pi: Any = None) -> None:
        super().__init__(component, settings)
        self._pins = PigpioHandle(component, settings.host, settings.port, pi)
        try:
            self._pins.call("set_mode", settings.trigger, OUTPUT)
            self._pins.call("write", settings.trigger, 0)
            self._pins.call("set_mode", settings.echo, INPUT)
            self._pins.call("set_pull_up_down", settings.echo, PUD_DOWN)
            self._callback = self._pins.call("callback", settings.echo, EITHER_EDGE, self._on_edge)
        except Exception:
            self._pins.close()
            raise
        log.info("sonar ready", component=component, trigger=settings.trigger, echo=settings.echo)

    def _on_edge(self, gpio: int, level: int, tick: int) -> None:
        self._edge(level, tick)  # on pigpio's callback thread

    def _pulse_us(self, rise: int, fall: int) -> float:
        return tick_diff(rise, fall)

    def _trigger(self) -> None:
        self._pins.call("gpio_trigger", self.settings.trigger, TRIGGER_PULSE_US, 1)


def _create(component: str, settings: HCSR04Settings) -> PigpioHCSR04:
    return PigpioHCSR04(component, settings)


FACTORY = DriverFactory(HCSR04Settings, _create)
