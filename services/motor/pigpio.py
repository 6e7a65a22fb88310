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

from typing import Any

from services.motor.driver import L298NBridge, L298NSettings
from services.pigpio_connection import PigpioHandle
from services.registry import DriverFactory
from umlbot.logs import get_logger

log = get_logger("umlbot.motor.pigpio")

PWM_RANGE = 1000
OUTPUT = 1  # pigpio.OUTPUT


class PigpioL298NChannel(L298NBridge):
    """One L298N channel on pigpio; satisfies `MotorChannel` (the truth table: `L298NBridge`)."""

    _pins: PigpioHandle

    def __init__(self, component: str, settings: L298NSettings, pi: Any = None) -> None:
        super().__init__(component, settings)
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

    def _level(self, pin: int, level: int) -> None:
        self._pins.call("write", pin, level)  # pigpio's write ends PWM on the pin

    def _pwm(self, pin: int) -> None:
        self._pins.call("set_PWM_dutycycle", pin, round(self._percent * PWM_RANGE / 100))


def _create(component: str, settings: L298NSettings) -> PigpioL298NChannel:
    return PigpioL298NChannel(component, settings)


FACTORY = DriverFactory(L298NSettings, _create)
