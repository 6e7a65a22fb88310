"""A passive buzzer through lgpio: a 50 % square wave at the tone's frequency (`tx_pwm`)."""

from __future__ import annotations

import threading
from typing import Any

from umlbot.base.registry import DriverFactory
from umlbot.services.pins.lgpio import LgpioHandle
from umlbot_buzzer.driver import BuzzerSettings


class LgpioBuzzer:
    """Satisfies `Buzzer`; starts silent, `close()` leaves it silent."""

    def __init__(self, component: str, settings: BuzzerSettings, lg: Any = None) -> None:
        self.component = component
        self.settings = settings
        self._lock = threading.Lock()
        self._pins = LgpioHandle(component, settings.chip, lg)
        try:
            self._pins.call("gpio_claim_output", settings.gpio, 0)
        except Exception:
            self._pins.close()
            raise

    def play(self, hz: int) -> None:
        with self._lock:
            self._pins.call("tx_pwm", self.settings.gpio, hz, 50)

    def silence(self) -> None:
        with self._lock:
            if not self._pins.closed:
                self._pins.call("tx_pwm", self.settings.gpio, 0, 0)

    def close(self) -> None:
        try:
            self.silence()
        finally:
            self._pins.close()


def _create(component: str, settings: BuzzerSettings) -> LgpioBuzzer:
    return LgpioBuzzer(component, settings)


FACTORY = DriverFactory(BuzzerSettings, _create)
