"""What every servo driver must provide, and the settings of a hobby servo."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict, Field, model_validator


@runtime_checkable
class Servo(Protocol):
    """A positional servo; angles are degrees in 0..`max_angle_deg`."""

    max_angle_deg: float

    def set_angle(self, degrees: float) -> None:
        """Turn to `degrees`; raises `ValueError` outside 0..max_angle_deg, `DriverError` on failure."""

    def stop(self) -> None:
        """Stop sending pulses (the servo goes limp); idempotent."""

    def close(self) -> None:
        """Stop pulses and release the pin/connection; idempotent."""


class ServoSettings(BaseModel):
    """Deployment settings of one servo: its signal pin and pulse calibration (microseconds)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    gpio: int = Field(ge=0, le=27, description="GPIO of the signal wire")
    min_pulse_us: int = Field(default=500, ge=500, le=2500, description="pulse at 0°")
    max_pulse_us: int = Field(default=2500, ge=500, le=2500, description="pulse at max_angle_deg")
    max_angle_deg: float = Field(default=180.0, gt=0, le=360, description="mechanical range")
    initial_angle_deg: float | None = Field(default=None, ge=0, description="angle set at start-up")
    host: str | None = Field(default=None, description="pigpiod host (default env PIGPIO_ADDR or localhost)")
    port: int | None = Field(default=None, description="pigpiod port (default env PIGPIO_PORT or 8888)")
    chip: int = Field(default=0, ge=0, description="lgpio: the gpiochip of the header pins (/dev/gpiochipN)")

    @model_validator(mode="after")
    def _calibration(self) -> ServoSettings:
        if self.min_pulse_us == self.max_pulse_us:
            raise ValueError("min_pulse_us and max_pulse_us must differ")
        if self.initial_angle_deg is not None and self.initial_angle_deg > self.max_angle_deg:
            raise ValueError(f"initial_angle_deg must be <= max_angle_deg ({self.max_angle_deg:g})")
        return self

    @property
    def pins(self) -> tuple[int, ...]:
        """Every GPIO this servo owns."""
        return (self.gpio,)

    def pulse_us(self, degrees: float) -> int:
        """The pulse width for an angle (linear calibration; min > max reverses the servo)."""
        span = self.max_pulse_us - self.min_pulse_us
        return round(self.min_pulse_us + span * degrees / self.max_angle_deg)
