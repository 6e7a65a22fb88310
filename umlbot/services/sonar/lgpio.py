"""HC-SR04 range finder through lgpio (the Raspberry Pi 5 and any recent Pi OS).

A ping drives TRIG high for at least 10 µs; the module answers with a high pulse on ECHO whose
length is the sound's round trip: cm = µs / 58. ECHO is claimed for alerts on both edges, and the
kernel timestamps each edge (nanoseconds) when it happens, so the pulse length does not depend on
how fast Python runs: µs = (fall - rise) / 1000. The rest is as for pigpio: pings at least
`min_interval_s` apart, None when no falling edge comes within `echo_timeout_s` or the pulse is a
module's "nothing in range" pulse (≥ 30 ms), the median of `samples` pings that got an echo.
"""

from __future__ import annotations

import time
from typing import Any

from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.pins.lgpio import LgpioHandle
from umlbot.services.sonar.driver import HCSR04Pings, HCSR04Settings

log = get_logger("umlbot.sonar.lgpio")

SET_PULL_DOWN = 64  # lgpio.SET_PULL_DOWN
BOTH_EDGES = 3  # lgpio.BOTH_EDGES
TRIGGER_PULSE_S = 10e-6


class LgpioHCSR04(HCSR04Pings):
    """One HC-SR04 on lgpio; satisfies `DistanceSensor` (how it is read: `HCSR04Pings`)."""

    _pins: LgpioHandle

    def __init__(self, component: str, settings: HCSR04Settings, lg: Any = None) -> None:
        super().__init__(component, settings)
        self._pins = LgpioHandle(component, settings.chip, lg)
        try:
            self._pins.call("gpio_claim_output", settings.trigger, 0)
            self._pins.call("gpio_claim_alert", settings.echo, BOTH_EDGES, SET_PULL_DOWN)
            self._callback = self._pins.call("callback", settings.echo, BOTH_EDGES, self._on_edge)
        except Exception:
            self._pins.close()
            raise
        log.info("sonar ready", component=component, trigger=settings.trigger, echo=settings.echo,
                 chip=settings.chip)

    def _on_edge(self, chip: int, gpio: int, level: int, timestamp_ns: int) -> None:
        self._edge(level, timestamp_ns)  # on lgpio's notification thread

    def _pulse_us(self, rise: int, fall: int) -> float:
        return (fall - rise) / 1000

    def _trigger(self) -> None:
        self._pins.call("gpio_write", self.settings.trigger, 1)
        time.sleep(TRIGGER_PULSE_S)  # sleeps at least this long: the module needs >= 10 µs
        self._pins.call("gpio_write", self.settings.trigger, 0)


def _create(component: str, settings: HCSR04Settings) -> LgpioHCSR04:
    return LgpioHCSR04(component, settings)


FACTORY = DriverFactory(HCSR04Settings, _create)
