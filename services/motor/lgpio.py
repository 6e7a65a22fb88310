"""L298N motor channel through lgpio (/dev/gpiochipN; the Raspberry Pi 5 and any recent Pi OS).

Same truth table and wiring rules as the pigpio driver (`services/motor/pigpio.py`): with an enable
pin the duty cycle is PWM on EN and the inputs set the direction; without one the PWM goes to the
input of the direction while the other input is low, and stopped means both inputs low. lgpio's
software PWM (`tx_pwm`) takes the frequency in Hz and the duty cycle in percent, so the commanded
percent is passed on exactly. Every pin is claimed as an output at level 0 before any PWM starts,
and PWM on a pin is switched off before the pin is written a plain level (lgpio's `gpio_write`
does not end a running PWM).
"""

from __future__ import annotations

import threading
from typing import Any

from services.lgpio_connection import LgpioHandle
from services.motor.driver import L298NSettings
from services.registry import DriverFactory
from umlbot.logs import get_logger

log = get_logger("umlbot.motor.lgpio")


class LgpioL298NChannel:
    """One L298N channel; satisfies `MotorChannel`. Starts stopped; `close()` leaves it stopped."""

    def __init__(self, component: str, settings: L298NSettings, lg: Any = None) -> None:
        self.component = component
        self.settings = settings
        self.pwm_frequency_hz = settings.pwm_frequency_hz
        self._lock = threading.Lock()
        self._enabled = False
        self._clockwise = True
        self._percent = 0.0
        self._closed = False
        self._pwm_on: set[int] = set()
        self._pins = LgpioHandle(component, settings.chip, lg)
        try:
            for pin in settings.pins:
                self._pins.call("gpio_claim_output", pin, 0)
        except Exception:
            self._pins.close()
            raise
        log.info("motor channel ready", component=component, pins=settings.pins, chip=settings.chip,
                 pwm_frequency_hz=self.pwm_frequency_hz)

    # MotorChannel ---------------------------------------------------------------------------

    def set_enabled(self, enabled: bool) -> None:
        with self._lock:
            self._enabled = enabled
            self._apply()

    def set_direction(self, clockwise: bool) -> None:
        with self._lock:
            if clockwise != self._clockwise and self._driving():
                self._halt()  # never drive both inputs of a bridge arm at once while switching
            self._clockwise = clockwise
            self._apply()

    def set_duty_cycle(self, percent: float) -> None:
        if not 0 <= percent <= 100:
            raise ValueError(f"duty cycle must be 0..100 %, got {percent}")
        with self._lock:
            self._percent = float(percent)
            self._apply()

    def stop(self) -> None:
        with self._lock:
            self._enabled = False
            self._percent = 0.0
            if not self._pins.closed:
                self._apply()

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._enabled = False
            self._percent = 0.0
            try:
                self._apply()
            finally:
                self._pins.close()

    # pins -----------------------------------------------------------------------------------

    def _driving(self) -> bool:
        return self._enabled and self._percent > 0

    def _level(self, pin: int, level: int) -> None:
        if pin in self._pwm_on:
            self._pins.call("tx_pwm", pin, 0, 0)
            self._pwm_on.discard(pin)
        self._pins.call("gpio_write", pin, level)

    def _pwm(self, pin: int) -> None:
        self._pins.call("tx_pwm", pin, self.pwm_frequency_hz, self._percent)
        self._pwm_on.add(pin)

    def _forward_pin(self) -> tuple[int, int]:
        """(driving input, other input) for the current direction."""
        s = self.settings
        forward = self._clockwise != s.invert
        return (s.in1, s.in2) if forward else (s.in2, s.in1)

    def _halt(self) -> None:
        s = self.settings
        if s.enable is not None:
            self._level(s.enable, 0)
        self._level(s.in1, 0)
        self._level(s.in2, 0)

    def _apply(self) -> None:
        s = self.settings
        drive, other = self._forward_pin()
        if not self._driving():
            if s.enable is not None and s.brake:
                self._level(s.in1, 0)
                self._level(s.in2, 0)
                self._level(s.enable, 1)  # EN high, IN1 = IN2: fast stop
            else:
                self._halt()  # EN low: coast; without EN both inputs low (the L298N's stop)
            return
        self._level(other, 0)
        if s.enable is not None:
            self._level(drive, 1)
            self._pwm(s.enable)
        else:
            self._pwm(drive)


def _create(component: str, settings: L298NSettings) -> LgpioL298NChannel:
    return LgpioL298NChannel(component, settings)


FACTORY = DriverFactory(L298NSettings, _create)
