"""The sim motor driver: an L298N channel that drives one side of the simulated car.

It accepts the same deployment settings as the pigpio driver (pins are ignored) plus `sim_side`
(`left` or `right`); without it the side is taken from the component name (`LeftActuator` →
left). `invert` swaps the direction, as it does on the real robot. Its deadman is the world's
(`World.renew_motor`, armed when the channel is made): the world stops the side when
`watchdog_s` of sim time pass without a renewal or a command, as the robot's hardware path does.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from umlbot.base.errors import ConfigError, DriverError, SimError
from umlbot.base.registry import DriverFactory
from umlbot.services.simworld import WorldHandle, connect_world


class SimMotorSettings(BaseModel):
    """Settings of a simulated motor channel; the real channel's pin settings are accepted and ignored."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    sim_side: Literal["left", "right"] | None = Field(default=None, description="side of the car")
    invert: bool = Field(default=False, description="swap clockwise/anticlockwise")
    watchdog_s: float = Field(default=2.0, ge=0, description="stop after this long without a command")


def side_of(component: str, settings: SimMotorSettings) -> Literal["left", "right"]:
    """The side a channel drives: `sim_side`, else `left`/`right` in the component's name."""
    if settings.sim_side is not None:
        return settings.sim_side
    name = component.lower()
    if ("left" in name) == ("right" in name):
        raise ConfigError(
            f"{component}: cannot tell which side of the simulated car it drives; "
            "add the setting sim_side: left (or right)"
        )
    return "left" if "left" in name else "right"


class SimMotorChannel:
    """A `MotorChannel` whose commands set one side of the simulated car."""

    def __init__(self, component: str, side: Literal["left", "right"], world: WorldHandle,
                 invert: bool = False, watchdog_s: float = 2.0) -> None:
        self.component = component
        self.side: Literal["left", "right"] = side
        self._world = world
        self._invert = invert
        self._watchdog_s = watchdog_s
        self._closed = False
        self.renew()  # the deadman is armed from the start, as the hardware's is

    def _set(self, **kwargs: bool | float) -> None:
        if self._closed:
            raise DriverError(f"{self.component}: driver is closed")
        try:
            self._world.set_motor(self.side, **kwargs)  # type: ignore[arg-type]
        except SimError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc

    def set_enabled(self, enabled: bool) -> None:
        self._set(enabled=bool(enabled))

    def set_direction(self, clockwise: bool) -> None:
        self._set(forward=bool(clockwise) != self._invert)

    def set_duty_cycle(self, percent: float) -> None:
        if not 0 <= percent <= 100:
            raise ValueError(f"duty cycle must be 0..100 %, got {percent}")
        self._set(duty_percent=float(percent))

    def now_s(self) -> float:
        """Sim time: the motor service times its watchdog with it (`watchdog_s` is sim seconds)."""
        try:
            return self._world.time_s()
        except SimError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc

    def stop(self) -> None:
        if not self._closed:
            self._set(enabled=False, duty_percent=0.0)

    def renew(self) -> bool:
        if self._closed:
            return True
        try:
            return self._world.renew_motor(self.side, self._watchdog_s)
        except SimError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc

    def close(self) -> None:
        if self._closed:
            return
        try:
            self.stop()
        finally:
            self._closed = True


def create(component: str, settings: SimMotorSettings) -> SimMotorChannel:
    """Build the sim channel of `component` against the world of this process."""
    try:
        world = connect_world()
    except SimError as exc:
        raise DriverError(f"{component}: {exc}") from exc
    return SimMotorChannel(component, side_of(component, settings), world, settings.invert,
                           settings.watchdog_s)


FACTORY = DriverFactory(SimMotorSettings, create)
