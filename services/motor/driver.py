"""What every motor channel driver must provide, and the settings of an L298N channel.

A channel is one side of the robot (one H-bridge output). Units outside a driver are percent and
booleans; PWM ranges, frequencies and pin levels stay inside the driver.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict, Field, model_validator

BcmPin = int


@runtime_checkable
class MotorChannel(Protocol):
    """One DC-motor channel. Every method may raise `DriverError`; `close()` twice is safe.

    Must provide: `set_enabled`, `set_direction`, `set_duty_cycle`, `stop`, `close`.
    """

    def set_enabled(self, enabled: bool) -> None:
        """Drive (True) or stop the motor (False: coast, or brake where the settings say so)."""

    def set_direction(self, clockwise: bool) -> None:
        """Turning direction; True = clockwise (forward)."""

    def set_duty_cycle(self, percent: float) -> None:
        """Drive strength in percent, 0..100; takes effect immediately when enabled."""

    def stop(self) -> None:
        """Safe state: disabled and duty 0. Never raises for an already stopped channel."""

    def close(self) -> None:
        """Stop the motor and release the pins/connection; idempotent."""


class L298NSettings(BaseModel):
    """Deployment settings of one L298N channel (BCM pin numbers).

    Without `enable` the ENA/ENB jumper is fitted: PWM goes to the input pin of the direction and
    "stopped" means both inputs low (the L298N's fast stop). With `enable`, PWM goes to the enable
    pin and `enabled(false)` lets the motor coast (EN low), or brakes (EN high, IN1 = IN2 = low)
    when `brake` is true.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    in1: BcmPin = Field(ge=0, le=27, description="GPIO of IN1 (high = clockwise)")
    in2: BcmPin = Field(ge=0, le=27, description="GPIO of IN2 (high = anticlockwise)")
    enable: BcmPin | None = Field(default=None, ge=0, le=27, description="GPIO of ENA/ENB")
    pwm_frequency_hz: int = Field(default=1000, ge=10, le=8000, description="software PWM frequency")
    brake: bool = Field(default=False, description="stopping brakes instead of coasting")
    watchdog_s: float = Field(default=2.0, ge=0, description="stop after this long without a command")
    invert: bool = Field(default=False, description="swap clockwise/anticlockwise (motor wired reversed)")
    host: str | None = Field(default=None, description="pigpiod host (default env PIGPIO_ADDR or localhost)")
    port: int | None = Field(default=None, description="pigpiod port (default env PIGPIO_PORT or 8888)")
    chip: int = Field(default=0, ge=0, description="lgpio: the gpiochip of the header pins (/dev/gpiochipN)")

    @model_validator(mode="after")
    def _distinct_pins(self) -> L298NSettings:
        pins = [p for p in (self.in1, self.in2, self.enable) if p is not None]
        if len(set(pins)) != len(pins):
            raise ValueError(f"in1, in2 and enable must be different pins, got {pins}")
        return self

    @property
    def pins(self) -> tuple[BcmPin, ...]:
        """Every GPIO this channel owns."""
        return tuple(p for p in (self.in1, self.in2, self.enable) if p is not None)
