"""What every distance sensor driver must provide, and the settings of an HC-SR04."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict, Field, model_validator


@runtime_checkable
class DistanceSensor(Protocol):
    """A range finder. `max_range_cm` is what the service reports when there is no echo."""

    max_range_cm: float

    def read_distance_cm(self) -> float | None:
        """One measurement in centimetres, or None when no echo came back (nothing in range).

        May block for the ping interval; raises `DriverError` when the hardware fails.
        """

    def close(self) -> None:
        """Release the pins/connection; idempotent."""


class HCSR04Settings(BaseModel):
    """Deployment settings of one HC-SR04 (BCM pin numbers, centimetres, seconds)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    trigger: int = Field(ge=0, le=27, description="GPIO of TRIG")
    echo: int = Field(ge=0, le=27, description="GPIO of ECHO (through a 5 V -> 3.3 V divider)")
    samples: int = Field(default=1, ge=1, le=15, description="median of this many pings")
    max_range_cm: float = Field(default=400.0, gt=0, le=1000, description="reported when no echo")
    min_interval_s: float = Field(default=0.06, ge=0.06, description="pause between pings (>= 60 ms)")
    echo_timeout_s: float = Field(default=0.04, gt=0, le=1, description="no echo within this -> None")
    host: str | None = Field(default=None, description="pigpiod host (default env PIGPIO_ADDR or localhost)")
    port: int | None = Field(default=None, description="pigpiod port (default env PIGPIO_PORT or 8888)")
    chip: int = Field(default=0, ge=0, description="lgpio: the gpiochip of the header pins (/dev/gpiochipN)")

    @model_validator(mode="after")
    def _distinct_pins(self) -> HCSR04Settings:
        if self.trigger == self.echo:
            raise ValueError(f"trigger and echo must be different pins, got {self.trigger}")
        return self

    @property
    def pins(self) -> tuple[int, ...]:
        """Every GPIO this sensor owns."""
        return (self.trigger, self.echo)
