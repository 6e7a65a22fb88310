"""A mock servo: records the angles it was sent; no hardware."""

from __future__ import annotations

from pydantic import Field

from umlbot.base.registry import DriverFactory
from umlbot.services.mock_support import MockDriver, MockSettings


class MockServoSettings(MockSettings):
    """Mock servo settings."""

    max_angle_deg: float = Field(default=180.0, gt=0, le=360)
    initial_angle_deg: float | None = Field(default=None, ge=0)


class MockServo(MockDriver):
    """Satisfies `Servo`. State: `angle_deg` (None before the first command), `pulsing`."""

    def __init__(self, component: str, settings: MockServoSettings | None = None) -> None:
        settings = settings or MockServoSettings()
        super().__init__(component, settings)
        self.max_angle_deg = settings.max_angle_deg
        self.angle_deg: float | None = settings.initial_angle_deg
        self.pulsing = settings.initial_angle_deg is not None

    def set_angle(self, degrees: float) -> None:
        if not 0 <= degrees <= self.max_angle_deg:
            raise ValueError(f"angle must be 0..{self.max_angle_deg:g}°, got {degrees:g}")
        self._enter("set_angle", degrees)
        with self._cond:
            self.angle_deg = float(degrees)
            self.pulsing = True
            self._changed()

    def stop(self) -> None:
        with self._cond:
            self._record("stop")
            self.pulsing = False
            self._changed()

    def close(self) -> None:
        with self._cond:
            if self.closed:
                return
            self.stop()
            self._record("close")
            self.closed = True
            self._changed()


FACTORY = DriverFactory(MockServoSettings, MockServo)
