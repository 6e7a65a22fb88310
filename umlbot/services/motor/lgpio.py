"""L298N motor channel through lgpio (/dev/gpiochipN; the Raspberry Pi 5 and any recent Pi OS).

The truth table and wiring rules are `L298NBridge`'s (`umlbot/services/motor/driver.py`): with an enable
pin the duty cycle is PWM on EN and the inputs set the direction; without one the PWM goes to the
input of the direction while the other input is low, and stopped means both inputs low. lgpio's
software PWM (`tx_pwm`) takes the frequency in Hz and the duty cycle in percent, so the commanded
percent is passed on exactly. Every pin is claimed as an output at level 0 before any PWM starts,
and PWM on a pin is switched off before the pin is written a plain level (lgpio's `gpio_write`
does not end a running PWM).

The deadman: PWM goes out in finite bursts of `watchdog_s` / 2 (`tx_pwm`'s cycle count), and each
renewal queues the next burst once nothing is queued behind the running one; lgpio's TX thread
writes the line low when the last burst is done. So the motor stops by itself within
`watchdog_s` when the service's own threads stop renewing (a hung service, a deadlock). lgpio's
TX thread runs inside the service's process, though: a SIGSTOP freezes it with the line's level
of that moment, so a frozen process is systemd's to catch (`WatchdogSec=`, then `ExecStopPost=`
writes the pins low; docs/services.md). A new duty cycle replaces the running burst at once (PWM
off, then the new burst), not after the queued ones. `watchdog_s: 0`: endless PWM, no deadman.
"""

from __future__ import annotations

import math
from typing import Any

from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.motor.driver import L298NBridge, L298NSettings
from umlbot.services.pins.lgpio import LgpioHandle

log = get_logger("umlbot.motor.lgpio")

TX_PWM = 0  # lgpio.TX_PWM
#: entries of an lgpio PWM queue, the running one included (LG_TX_BUF)
TX_BUF = 10


class LgpioL298NChannel(L298NBridge):
    """One L298N channel on lgpio; satisfies `MotorChannel` (the truth table: `L298NBridge`)."""

    _pins: LgpioHandle

    def __init__(self, component: str, settings: L298NSettings, lg: Any = None) -> None:
        super().__init__(component, settings)
        self.pwm_frequency_hz = settings.pwm_frequency_hz
        #: cycles per burst (0: endless PWM, no deadman)
        self.burst_cycles = (max(1, math.floor(self.pwm_frequency_hz * settings.watchdog_s / 2))
                             if settings.watchdog_s > 0 else 0)
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

    def _level(self, pin: int, level: int) -> None:
        if pin in self._pwm_on:
            self._pins.call("tx_pwm", pin, 0, 0)
            self._pwm_on.discard(pin)
        self._pins.call("gpio_write", pin, level)

    def _pwm(self, pin: int) -> None:
        if pin in self._pwm_on:  # the new duty at once, not after the bursts queued
            self._pins.call("tx_pwm", pin, 0, 0)
        self._pins.call("tx_pwm", pin, self.pwm_frequency_hz, self._percent, 0, self.burst_cycles)
        self._pwm_on.add(pin)

    def _renew(self) -> bool:
        if not self.burst_cycles:
            return True
        for pin in list(self._pwm_on):
            if not self._pins.call("tx_busy", pin, TX_PWM):
                self._pwm_on.discard(pin)  # the last burst ended: the TX thread wrote the line low
                return False
            if self._pins.call("tx_room", pin, TX_PWM) >= TX_BUF - 1:  # only the running burst
                self._pins.call("tx_pwm", pin, self.pwm_frequency_hz, self._percent, 0, self.burst_cycles)
        return True


def _create(component: str, settings: L298NSettings) -> LgpioL298NChannel:
    return LgpioL298NChannel(component, settings)


FACTORY = DriverFactory(L298NSettings, _create)
