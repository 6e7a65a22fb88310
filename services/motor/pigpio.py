"""L298N motor channel on the Raspberry Pi through the pigpio daemon.

Truth table of one L298N channel (EN = enable, IN1/IN2 = inputs):

    EN  IN1 IN2  motor
    1   1   0    clockwise (forward)
    1   0   1    anticlockwise
    1   x   x    with IN1 = IN2: fast stop (brake)
    0   x   x    free running stop (coast)

With an enable pin, the duty cycle is PWM on EN and the inputs set the direction. Without one (the
ENA/ENB jumper fitted, as on the reference robot) the duty cycle is PWM on the input of the
direction while the other input is low, and stopped means both inputs low. Software PWM at
`pwm_frequency_hz` (pigpio picks the nearest frequency it offers) with a range of 1000 steps; a
pin is written 0 before PWM starts on it.
"""

from __future__ import annotations

import threading
from typing import Any

from services.motor.driver import L298NSettings
from services.pigpio_connection import PigpioHandle
from services.registry import DriverFactory
from umlbot.logs import get_logger

log = get_logger("umlbot.motor.pigpio")

PWM_RANGE = 1000
OUTPUT = 1  # pigpio.OUTPUT


class PigpioL298NChannel:
    """One L298N channel; satisfies `MotorChannel`. Starts stopped; `close()` leaves it stopped."""

    def __init__(self, component: str, settings: L298NSettings, pi: Any = None) -> None:
        self.component = component
        self.settings = settings
        self._lock = threading.Lock()
        self._enabled = False
        self._clockwise = True
        self._percent = 0.0
        self._closed = False
        self._pins = PigpioHandle(component, settings.host, settings.port, pi)
        try:
            for pin in settings.pins:
                self._pins.call("set_mode", pin, OUTPUT)
                self._pins.call("write", pin, 0)
            self.pwm_frequency_hz = 0
            for pin in self._pwm_pins():
                self.pwm_frequency_hz = self._pins.call("set_PWM_frequency", pin, settings.pwm_frequency_hz)
                self._pins.call("set_PWM_range", pin, PWM_RANGE)
        except Exception:
            self._pins.close()
            raise
        log.info("motor channel ready", component=component, pins=settings.pins,
                 pwm_frequency_hz=self.pwm_frequency_hz)

    def _pwm_pins(self) -> tuple[int, ...]:
        s = self.settings
        return (s.enable,) if s.enable is not None else (s.in1, s.in2)

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

    def _duty_units(self) -> int:
        return round(self._percent * PWM_RANGE / 100)

    def _forward_pin(self) -> tuple[int, int]:
        """(driving input, other input) for the current direction."""
        s = self.settings
        forward = self._clockwise != s.invert
        return (s.in1, s.in2) if forward else (s.in2, s.in1)

    def _halt(self) -> None:
        s = self.settings
        if s.enable is not None:
            self._pins.call("write", s.enable, 0)
        self._pins.call("write", s.in1, 0)
        self._pins.call("write", s.in2, 0)

    def _apply(self) -> None:
        s = self.settings
        drive, other = self._forward_pin()
        if not self._driving():
            if s.enable is not None and s.brake:
                self._pins.call("write", s.in1, 0)
                self._pins.call("write", s.in2, 0)
                self._pins.call("write", s.enable, 1)  # EN high, IN1 = IN2: fast stop
            else:
                self._halt()  # EN low: coast; without EN both inputs low (the L298N's stop)
            return
        if s.enable is not None:
            self._pins.call("write", other, 0)
            self._pins.call("write", drive, 1)
            self._pins.call("set_PWM_dutycycle", s.enable, self._duty_units())
        else:
            self._pins.call("write", other, 0)
            self._pins.call("set_PWM_dutycycle", drive, self._duty_units())


def _create(component: str, settings: L298NSettings) -> PigpioL298NChannel:
    return PigpioL298NChannel(component, settings)


FACTORY = DriverFactory(L298NSettings, _create)
