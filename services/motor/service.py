"""The motor service's features for one L298N channel, with its safety stops.

Features (library): `enabled(bool)`, `direction(bool)` (true = clockwise), `dutycycle(0..100)`.
State: `{"enabled", "clockwise", "dutycycle", "running", "stop_reason"}` where `stop_reason` names
the last safety stop (`watchdog`, `orchestrator offline`, `broker connection lost`, `service
stopping`) and is null after a command. A safety stop disables the motor and puts its pins at
zero duty; `dutycycle` stays the commanded value, applied again by the next `enabled(true)`.

Watchdog: while enabled, a command (any feature) must arrive at least every `watchdog_s` seconds
of wall time (deployment setting, default 2.0; 0 turns it off); otherwise the motor stops. A
driver with its own clock (`now_s()`: the simulator's) times it in that clock's seconds.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from services.component_service import ComponentService
from services.motor.driver import MotorChannel
from umlbot.errors import ConfigError
from umlbot.library import Implementation

DEFAULT_WATCHDOG_S = 2.0


class MotorServiceSettings(BaseModel):
    """The settings the motor service itself reads (whatever the driver)."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    watchdog_s: float = Field(default=DEFAULT_WATCHDOG_S, ge=0)


class MotorService(ComponentService):
    """One motor channel on the bus."""

    kind = "motor"
    handlers = {"enabled": "enabled", "direction": "direction", "dutycycle": "dutycycle"}

    def __init__(self, component: str, impl: Implementation, driver: MotorChannel,
                 settings: Mapping[str, Any] | None = None) -> None:
        super().__init__(component, impl, driver, settings)
        try:
            self.watchdog_s = MotorServiceSettings.model_validate(self.settings).watchdog_s
        except ValidationError as exc:
            raise ConfigError(f"{component}: invalid watchdog_s: {exc.errors()[0]['msg']}") from exc
        self.channel: MotorChannel = driver
        self.is_enabled = False
        self.clockwise = True
        self.duty_percent = 0
        self.stop_reason: str | None = None
        self.safety_stops = 0
        self._duty_zeroed = True
        # a driver with its own time (the simulator's) times the watchdog in it: at --speed 10 a
        # model's 3 s sleep with the motors on is 0.3 s of wall time, and stops them all the same
        own_clock = getattr(driver, "now_s", None)
        self._own_clock: Callable[[], float] | None = own_clock if callable(own_clock) else None
        self.last_command = self._now()
        self.channel.stop()

    def _now(self) -> float:
        return time.monotonic() if self._own_clock is None else float(self._own_clock())

    def _command(self) -> None:
        self.last_command = self._now()
        self.stop_reason = None

    def enabled(self, on: bool) -> None:
        with self.lock:
            if on and self._duty_zeroed:
                if self.duty_percent > 0:
                    self.channel.set_duty_cycle(self.duty_percent)  # a safety stop zeroed the pins
                self._duty_zeroed = False
            self.channel.set_enabled(on)
            self.is_enabled = on
            self._command()
        self.changed()

    def direction(self, clockwise: bool) -> None:
        with self.lock:
            self.channel.set_direction(clockwise)
            self.clockwise = clockwise
            self._command()
        self.changed()

    def dutycycle(self, percent: int) -> None:
        with self.lock:
            self.channel.set_duty_cycle(percent)
            self.duty_percent = percent
            self._duty_zeroed = False
            self._command()
        self.changed()

    def state(self) -> dict[str, Any]:
        with self.lock:
            return {
                "enabled": self.is_enabled,
                "clockwise": self.clockwise,
                "dutycycle": self.duty_percent,
                "running": self.is_enabled and self.duty_percent > 0,
                "stop_reason": self.stop_reason,
            }

    def safe_stop(self, reason: str) -> None:
        """Stop the motor: the driver disables it and zeroes the pins' duty cycle.

        The commanded duty cycle is remembered: the next `enabled(true)` drives at it again (a
        model may set `dutycycle` once and then only switch `enabled`).
        """
        with self.lock:
            was_active = self.is_enabled
            self.channel.stop()
            self.is_enabled = False
            self._duty_zeroed = True
            if was_active:
                self.stop_reason = reason
                self.safety_stops += 1
        if was_active:
            self.log.warning("motor_stopped", reason=reason)
            self.changed()

    def tick(self, now: float) -> None:
        if self._own_clock is not None:
            now = self._now()
        with self.lock:
            expired = (
                self.watchdog_s > 0 and self.is_enabled and now - self.last_command > self.watchdog_s
            )
        if expired:
            self.safe_stop("watchdog")
