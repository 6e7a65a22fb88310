"""The motor service's features for one L298N channel, with its safety stops.

Features (library): `enabled(bool)`, `direction(bool)` (true = clockwise), `dutycycle(0..100)`.
State: `{"enabled", "clockwise", "dutycycle", "running", "stop_reason"}` where `stop_reason` names
the last safety stop (`watchdog`, `orchestrator unresponsive`, `deadman`, `orchestrator offline`,
`broker connection lost`, `service stopping` …) and stays until a command makes the motor run
again (so that a run's end does not wipe out why the car stood still). A safety stop disables
the motor and puts its pins at zero duty; `dutycycle` stays the commanded value, applied again by
the next `enabled(true)`.

What keeps an enabled motor running (`watchdog_s`, deployment setting, default 2.0; 0 turns both
checks off):

- the lease of the running orchestrator: when the last command came from it (its reply topic is
  the one its heartbeat names, `umlbot.services.bus.server.caller`), its heartbeat keeps the motor
  running; when no heartbeat came for `watchdog_s` seconds of wall time (a hung or frozen
  orchestrator) the motor stops (`orchestrator unresponsive`);
- otherwise (a direct caller: `umlbot call`, any MQTT client) the command watchdog: a command
  (any feature) at least every `watchdog_s` seconds, else it stops (`watchdog`). A driver with
  its own clock (`now_s()`: the simulator's) times this watchdog in that clock's seconds.

Every tick the service also renews the driver's deadman (`MotorChannel.renew`): the hardware path
stops the motor by itself when this process stops renewing it (frozen, killed); a deadman that
fired while the service could not act is reported as the stop reason `deadman`.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from umlbot.base.errors import ConfigError
from umlbot.base.library import Implementation
from umlbot.services.bus import caller
from umlbot.services.component_service import ComponentService
from umlbot.services.motor.driver import MotorChannel

DEFAULT_WATCHDOG_S = 2.0
#: the heartbeats of this many orchestrators (reply topics) are remembered at most
MAX_LEASE_HOLDERS = 8


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
        #: the reply topic of the last command (None: fire-and-forget), see `caller()`
        self.commanded_by: str | None = None
        #: reply topic of an orchestrator -> `time.monotonic()` of its last heartbeat
        self._heartbeats: dict[str, float] = {}
        self._duty_zeroed = True
        # a driver with its own time (the simulator's) times the watchdog in it: at --speed 10 a
        # model's 3 s sleep with the motors on is 0.3 s of wall time, and stops them all the same
        own_clock = getattr(driver, "now_s", None)
        self._own_clock: Callable[[], float] | None = own_clock if callable(own_clock) else None
        # a plugin's driver written before `renew` existed has no deadman: the service still runs
        # its watchdogs, and says once that nothing outside it stops the motor
        renew = getattr(driver, "renew", None)
        self._renew: Callable[[], bool] = renew if callable(renew) else (lambda: True)
        if not callable(renew):
            self.log.warning("motor_driver_without_deadman", driver=type(driver).__name__,
                             why="a frozen or killed service cannot stop this motor (MotorChannel.renew)")
        self.last_command = self._now()
        self.channel.stop()

    def _now(self) -> float:
        return time.monotonic() if self._own_clock is None else float(self._own_clock())

    def _command(self) -> None:
        self.last_command = self._now()
        self.commanded_by = caller()
        if self.is_enabled and self.duty_percent > 0:
            self.stop_reason = None  # running again: the last safety stop is history

    def orchestrator_heartbeat(self, reply_to: str) -> None:
        now = time.monotonic()
        with self.lock:
            self._heartbeats.pop(reply_to, None)
            self._heartbeats[reply_to] = now
            while len(self._heartbeats) > MAX_LEASE_HOLDERS:  # the oldest goes (dicts keep order)
                del self._heartbeats[next(iter(self._heartbeats))]

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
        """The safety round (`now`: the host's `time.monotonic()`): renew the deadman, then the
        lease or the command watchdog."""
        with self.lock:
            if not self.is_enabled:
                return
            alive = self._renew()
        if not alive:  # the hardware stopped it while this process could not act (frozen)
            self.safe_stop("deadman")
            return
        reason = self._expired(now)
        if reason is not None:
            self.safe_stop(reason)

    def _expired(self, wall_now: float) -> str | None:
        """Why the enabled motor must stop now, or None: the lease, else the command watchdog."""
        if self.watchdog_s <= 0:
            return None
        command_now = self._now() if self._own_clock is not None else wall_now
        with self.lock:
            if not self.is_enabled:
                return None
            beat = self._heartbeats.get(self.commanded_by) if self.commanded_by else None
            if beat is not None and wall_now - beat <= self.watchdog_s:
                return None  # the running orchestrator's lease
            if command_now - self.last_command <= self.watchdog_s:
                return None
            return "watchdog" if beat is None else "orchestrator unresponsive"
