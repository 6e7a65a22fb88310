"""Hobby servo on the Raspberry Pi through the pigpio daemon (`set_servo_pulsewidth`).

The angle maps linearly onto the pulse width: 0° → `min_pulse_us`, `max_angle_deg` →
`max_pulse_us` (defaults 500..2500 µs, pigpio's own limits). pigpio repeats the pulse every 20 ms
(50 Hz) on any GPIO. Stopping sends pulse width 0: no more pulses, the servo goes limp.
"""

from __future__ import annotations

import threading
from typing import Any

from umlbot.base.errors import DriverError
from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.pins.pigpio import PigpioHandle
from umlbot.services.servo.driver import ServoSettings

log = get_logger("umlbot.servo.pigpio")

OUTPUT = 1  # pigpio.OUTPUT


class PigpioServo:
    """One servo; satisfies `Servo`."""

    def __init__(self, component: str, settings: ServoSettings, pi: Any = None) -> None:
        self.component = component
        self.settings = settings
        self.max_angle_deg = settings.max_angle_deg
        self._lock = threading.Lock()
        self._closed = False
        self._pins = PigpioHandle(component, settings.host, settings.port, pi)
        try:
            self._pins.call("set_mode", settings.gpio, OUTPUT)
            self._pins.call("set_servo_pulsewidth", settings.gpio, 0)
            if settings.initial_angle_deg is not None:
                self._pins.call("set_servo_pulsewidth", settings.gpio,
                                settings.pulse_us(settings.initial_angle_deg))
        except Exception:
            self._pins.close()
            raise
        log.info("servo ready", component=component, gpio=settings.gpio)

    def set_angle(self, degrees: float) -> None:
        if not 0 <= degrees <= self.max_angle_deg:
            raise ValueError(f"angle must be 0..{self.max_angle_deg:g}°, got {degrees:g}")
        with self._lock:
            if self._closed:
                raise DriverError(f"{self.component}: servo is closed")
            self._pins.call("set_servo_pulsewidth", self.settings.gpio, self.settings.pulse_us(degrees))

    def stop(self) -> None:
        with self._lock:
            if not self._closed:
                self._pins.call("set_servo_pulsewidth", self.settings.gpio, 0)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._pins.call("set_servo_pulsewidth", self.settings.gpio, 0)
            finally:
                self._pins.close()


def _create(component: str, settings: ServoSettings) -> PigpioServo:
    return PigpioServo(component, settings)


FACTORY = DriverFactory(ServoSettings, _create)
