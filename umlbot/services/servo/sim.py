"""The sim servo driver: the servo that turns the simulated car's sonar.

Same deployment settings as the real servo (pin and pulses ignored). The world turns the sonar at
the servo's finite speed (0.1 s per 60°); 90° looks ahead, 180° left, 0° right.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator

from umlbot.base.errors import DriverError, SimError
from umlbot.base.registry import DriverFactory
from umlbot.services.simworld import WorldHandle, connect_world


class SimServoSettings(BaseModel):
    """Settings of a simulated servo; the real servo's pin and pulse settings are accepted and ignored."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    max_angle_deg: float = Field(default=180.0, gt=0, le=180, description="mechanical range")
    initial_angle_deg: float | None = Field(default=None, ge=0, le=180, description="angle at start-up")

    @model_validator(mode="after")
    def _initial_within_range(self) -> SimServoSettings:
        if self.initial_angle_deg is not None and self.initial_angle_deg > self.max_angle_deg:
            raise ValueError(f"initial_angle_deg must be <= max_angle_deg ({self.max_angle_deg:g})")
        return self


class SimServo:
    """A `Servo` turning the simulated sonar mount."""

    def __init__(self, component: str, world: WorldHandle, max_angle_deg: float = 180.0) -> None:
        self.component = component
        self.max_angle_deg = max_angle_deg
        self._world = world
        self._closed = False

    def set_angle(self, degrees: float) -> None:
        if not 0 <= degrees <= self.max_angle_deg:
            raise ValueError(f"angle must be 0..{self.max_angle_deg:g}°, got {degrees}")
        if self._closed:
            raise DriverError(f"{self.component}: driver is closed")
        try:
            self._world.set_servo(float(degrees))
        except SimError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc

    def stop(self) -> None:
        """A limp servo stays where it is; nothing to do in the world."""

    def close(self) -> None:
        self._closed = True


def create(component: str, settings: SimServoSettings) -> SimServo:
    """Build the sim servo of `component` against the world of this process."""
    try:
        world = connect_world()
    except SimError as exc:
        raise DriverError(f"{component}: {exc}") from exc
    servo = SimServo(component, world, settings.max_angle_deg)
    if settings.initial_angle_deg is not None:
        servo.set_angle(settings.initial_angle_deg)
    return servo


FACTORY = DriverFactory(SimServoSettings, create)
