"""What every buzzer driver must provide, and the settings of a passive buzzer."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict, Field

DEFAULT_TONE_HZ = 440


@runtime_checkable
class Buzzer(Protocol):
    """A buzzer. Every method may raise `DriverError`; `close()` twice is safe."""

    def play(self, hz: int) -> None:
        """Sound at `hz` (20..10000) until `silence()`."""

    def silence(self) -> None:
        """Stop sounding; never raises for a silent buzzer."""

    def close(self) -> None:
        """Silence and release the pin; idempotent."""


class BuzzerSettings(BaseModel):
    """Deployment settings of a passive buzzer (BCM pin)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    gpio: int = Field(ge=0, le=27, description="GPIO of the buzzer's signal pin")
    chip: int = Field(default=0, ge=0, description="lgpio: the gpiochip of the header pins")
