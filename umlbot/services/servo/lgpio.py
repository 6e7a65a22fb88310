"""Hobby servo through lgpio (`tx_servo`; the Raspberry Pi 5 and any recent Pi OS).

The angle maps linearly onto the pulse width as for pigpio: 0° → `min_pulse_us`, `max_angle_deg`
→ `max_pulse_us` (500..2500 µs, lgpio's limits too), 50 pulses a second. Stopping sends pulse
width 0: no more pulses, the servo goes limp. lgpio times the pulses in software, so expect a
little more jitter than pigpio's DMA-timed pulses.
"""

from __future__ import annotations

import threading
from typing import Any

from umlbot.base.errors import DriverError
from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.pins.lgpio import LgpioHandle
from umlbot.services.servo.driver import ServoSettings

log = get_logger("umlbot.servo.lgpio")

SERVO_FREQUENCY_HZ = 50


class LgpioServo:
    """One servo; satisfies `Servo`."""

    def __init__(self, component: str, settings: ServoSettings, lg: Any = None) -> None:
        self.component = component
        self.settings = settings
        self.max_angle_deg = settings.max_angle_deg
        self._lock = threading.Lock()
        self._closed = False
        self._pins = LgpioHandle(component, settings.chip, lg)
        try:
            self._pins.call("gpio_claim_output", settings.gpio, 0)
            if settings.initial_angle_deg is not None:
                self._pulse(settings.pulse_us(settings.initial_angle_deg))
        except Exception:
            self._pins.close()
            raise
        log.info("servo ready", component=component, gpio=settings.gpio, chip=settings.chip)

    def _pulse(self, width_us: int) -> None:
        self._pins.call("tx_servo", self.settings.gpio, width_us, SERVO_FREQUENCY_HZ)

    def set_angle(self, degrees: float) -> None:
        if not 0 <= degrees <= self.max_angle_deg:
            raise ValueError(f"angle must be 0..{self.max_angle_deg:g}°, got {degrees:g}")
        with self._lock:
            if self._closed:
                raise DriverError(f"{self.component}: servo is closed")
            self._pulse(self.settings.pulse_us(degrees))

    def stop(self) -> None:
        with self._lock:
            if not self._closed:
                self._pulse(0)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._pulse(0)
            finally:
                self._pins.close()


def _create(component: str, settings: ServoSettings) -> LgpioServo:
    return LgpioServo(component, settings)


FACTORY = DriverFactory(ServoSettings, _create)
