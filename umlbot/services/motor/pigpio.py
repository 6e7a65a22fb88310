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

The deadman lives in pigpiod, outside the service's process: a daemon-side script
(`DEADMAN_SCRIPT`) runs while the motor drives and counts its parameter p0 down every 100 ms;
the driver sets p0 again (`update_script`) at every renewal, at least every `watchdog_s` / 4.
When p0 runs out (no renewal for `watchdog_s`: the service is frozen, killed or hung) the script
writes the channel's pins low and halts, and the next renewal reports it. p1..p3 are the pins and
p9 `DEADMAN_MARK`, by which a starting driver finds and deletes the script of a killed
predecessor on the same pins (pigpiod keeps scripts until they are deleted). `watchdog_s: 0`: no
deadman.
"""

from __future__ import annotations

import math
import time
from typing import Any

from umlbot.base.errors import DriverError
from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.motor.driver import L298NBridge, L298NSettings
from umlbot.services.pins.pigpio import PigpioHandle

log = get_logger("umlbot.motor.pigpio")

PWM_RANGE = 1000
OUTPUT = 1  # pigpio.OUTPUT
PI_SCRIPT_INITING = 0  # pigpio's script states
PI_SCRIPT_RUNNING = 2
PI_MAX_SCRIPTS = 32

#: the deadman's step: p0 counts down once per step
DEADMAN_TICK_MS = 100
#: count p0 down every step while it stays >= 0; then write the pins p1..p3 low and halt
DEADMAN_SCRIPT = f"tag 0 mils {DEADMAN_TICK_MS} dcr p0 jp 0 w p1 0 w p2 0 w p3 0"
#: p9 of every umlbot deadman script ("umlb")
DEADMAN_MARK = 0x756D6C62
#: seconds a stored script may take to start its thread in pigpiod
SCRIPT_READY_S = 2.0


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
            self._delete_stale_deadmen()
            self._script: int | None = None
            self._armed = False
            self._renewed_at = 0.0
            if settings.watchdog_s > 0:
                self._script = self._store_deadman()
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

    # the deadman script ----------------------------------------------------------------------

    def _params(self) -> list[int]:
        """The script's parameters: p0 the steps left, p1..p3 the pins, p9 the mark."""
        s = self.settings
        steps = max(1, math.floor(s.watchdog_s * 1000 / DEADMAN_TICK_MS))
        pins = [s.in1, s.in2, s.enable if s.enable is not None else s.in1]
        return [steps - 1, *pins, 0, 0, 0, 0, 0, DEADMAN_MARK]

    def _store_deadman(self) -> int:
        script = int(self._pins.call("store_script", DEADMAN_SCRIPT.encode()))
        deadline = time.monotonic() + SCRIPT_READY_S
        while self._pins.call("script_status", script)[0] == PI_SCRIPT_INITING:
            if time.monotonic() > deadline:
                raise DriverError(f"{self.component}: pigpiod did not start the deadman script")
            time.sleep(0.005)
        self._pins.call("update_script", script, self._params())  # marked: a successor finds it
        return script

    def _delete_stale_deadmen(self) -> None:
        """Delete the deadman scripts a killed driver of these pins left in pigpiod."""
        mine = set(self.settings.pins)
        for script in range(PI_MAX_SCRIPTS):
            try:
                status, params = self._pins.pi.script_status(script)
            except Exception:  # an unused id: pigpio raises (or returns a negative status)
                status, params = -1, ()
            if status >= 0 and len(params) == 10 and params[9] == DEADMAN_MARK and mine & set(params[1:4]):
                self._pins.call("delete_script", script)
                log.info("stale deadman script deleted", component=self.component, script=script)

    def _deadman(self, driving: bool) -> None:
        if self._script is None or driving == self._armed:
            return
        if driving:
            self._pins.call("run_script", self._script, self._params())
            self._renewed_at = time.monotonic()
        else:
            self._pins.call("stop_script", self._script)
        self._armed = driving

    def _renew(self) -> bool:
        if self._script is None or not self._armed:
            return True
        now = time.monotonic()
        if now - self._renewed_at < self.settings.watchdog_s / 4:
            return True
        if self._pins.call("script_status", self._script)[0] != PI_SCRIPT_RUNNING:
            self._armed = False  # it wrote the pins low and halted
            return False
        self._pins.call("update_script", self._script, self._params())
        self._renewed_at = now
        return True

    def _release(self) -> None:
        if self._script is not None:
            self._pins.call("delete_script", self._script)
            self._script = None


def _create(component: str, settings: L298NSettings) -> PigpioL298NChannel:
    return PigpioL298NChannel(component, settings)


FACTORY = DriverFactory(L298NSettings, _create)
