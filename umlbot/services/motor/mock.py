"""A mock motor channel: records commands and exposes its state; no hardware."""

from __future__ import annotations

from pydantic import Field

from umlbot.base.registry import DriverFactory
from umlbot.services.mock_support import MockDriver, MockSettings


class MockMotorSettings(MockSettings):
    """Mock motor settings (`watchdog_s` is read by the motor service, as for every driver)."""

    watchdog_s: float = Field(default=2.0, ge=0)


class MockMotorChannel(MockDriver):
    """Satisfies `MotorChannel`. State: `enabled`, `clockwise`, `duty_cycle_percent`, `running`.

    It has no deadman of its own: `renew()` counts the renewals (`renewals`) and answers True,
    unless a test called `fire_deadman()`, which stops the motor as a hardware deadman would.
    """

    def __init__(self, component: str, settings: MockMotorSettings | None = None) -> None:
        super().__init__(component, settings or MockMotorSettings())
        self.enabled = False
        self.clockwise = True
        self.duty_cycle_percent = 0.0
        self.stops = 0
        self.renewals = 0
        self._deadman_fired = False

    @property
    def running(self) -> bool:
        """True while the motor would turn (enabled with a duty cycle above 0)."""
        return self.enabled and self.duty_cycle_percent > 0

    def set_enabled(self, enabled: bool) -> None:
        self._enter("set_enabled", enabled)
        with self._cond:
            self.enabled = enabled
            self._changed()

    def set_direction(self, clockwise: bool) -> None:
        self._enter("set_direction", clockwise)
        with self._cond:
            self.clockwise = clockwise
            self._changed()

    def set_duty_cycle(self, percent: float) -> None:
        if not 0 <= percent <= 100:
            raise ValueError(f"duty cycle must be 0..100 %, got {percent}")
        self._enter("set_duty_cycle", percent)
        with self._cond:
            self.duty_cycle_percent = float(percent)
            self._changed()

    def stop(self) -> None:
        # A safety stop never fails and never waits: no latency, no faults.
        with self._cond:
            self._record("stop")
            self.enabled = False
            self.duty_cycle_percent = 0.0
            self.stops += 1
            self._changed()

    def renew(self) -> bool:
        with self._cond:
            self.renewals += 1
            fired, self._deadman_fired = self._deadman_fired, False
            return not fired

    def fire_deadman(self) -> None:
        """Stop the motor behind the service's back, as a hardware deadman does; the next
        `renew()` says so."""
        with self._cond:
            self.enabled = False
            self.duty_cycle_percent = 0.0
            self._deadman_fired = True
            self._changed()

    def close(self) -> None:
        with self._cond:
            if self.closed:
                return
            self.stop()
            self._record("close")
            self.closed = True
            self._changed()


FACTORY = DriverFactory(MockMotorSettings, MockMotorChannel)
