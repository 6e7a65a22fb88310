"""What every GPIO driver must provide, and the settings of the system component."""

from __future__ import annotations

import threading
from typing import Literal, Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict, Field, field_validator

from umlbot.base.errors import DriverError

#: BCM GPIO numbers a Raspberry Pi exposes on its header.
ALL_PINS: tuple[int, ...] = tuple(range(28))


@runtime_checkable
class GpioPins(Protocol):
    """Plain digital pins. The driver refuses pins outside `allowed_pins` with `PinNotAllowed`."""

    allowed_pins: frozenset[int]

    def read(self, pin: int) -> int:
        """The level of `pin`, 0 or 1 (an output pin reads back what was written)."""

    def write(self, pin: int, value: int) -> None:
        """Drive `pin` to 0 or 1 (the pin becomes an output)."""

    def close(self) -> None:
        """Release the pins/connection; idempotent. Output pins are left as they are."""


class GpioSettings(BaseModel):
    """Deployment settings of the system component.

    `pins` lists the GPIOs the model may use; when it is not given, every BCM pin 0..27 that no other
    component of the deployment owns is allowed. A pin owned by another component (a motor input,
    the sonar's trigger...) is always refused.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    pins: list[int] | None = Field(default=None, description="allowed BCM pins")
    pull: Literal["off", "up", "down"] = Field(default="off", description="pull resistor of read pins")
    reserved_pins: dict[int, str] = Field(
        default_factory=dict, description="pin -> owning component; filled in by the service host"
    )
    host: str | None = Field(default=None, description="pigpiod host (default env PIGPIO_ADDR or localhost)")
    port: int | None = Field(default=None, description="pigpiod port (default env PIGPIO_PORT or 8888)")
    chip: int = Field(default=0, ge=0, description="lgpio: the gpiochip of the header pins (/dev/gpiochipN)")

    @field_validator("pins")
    @classmethod
    def _valid_pins(cls, pins: list[int] | None) -> list[int] | None:
        if pins is not None:
            bad = [p for p in pins if p not in ALL_PINS]
            if bad:
                raise ValueError(f"pins must be BCM numbers 0..27, got {bad}")
        return pins

    def allowed(self) -> frozenset[int]:
        """The pins the model may read and write."""
        wanted = set(ALL_PINS if self.pins is None else self.pins)
        return frozenset(wanted - set(self.reserved_pins))

    def refusal(self, pin: int) -> str | None:
        """Why `pin` may not be used, or None when it may."""
        if pin in self.reserved_pins:
            return f"GPIO {pin} belongs to component {self.reserved_pins[pin]}"
        if pin not in self.allowed():
            return f"GPIO {pin} is not in the deployment's pins {sorted(self.allowed())}"
        return None


class PinNotAllowed(DriverError, ValueError):
    """A pin the deployment does not allow the model to use (not listed, or owned by a component)."""

    def __init__(self, pin: int, reason: str) -> None:
        super().__init__(reason)
        self.pin = pin


class ClosablePins(Protocol):
    """A backend's pin connection as `HardwareGpio` needs it."""

    def close(self) -> None: ...


class HardwareGpio:
    """What the GPIO drivers of real backends share: the pin rules, one lock, the modes the
    backend gave each pin, closing once. A backend implements `_input`, `_level` and `_output`.

    A pin is made an input (with the configured pull resistor) the first time it is read and an
    output the first time it is written; reading an output returns the level last written. Pins
    the deployment does not allow, and pins owned by other components, are refused with
    `PinNotAllowed` before the backend is asked.
    """

    def __init__(self, component: str, settings: GpioSettings, pins: ClosablePins) -> None:
        self.component = component
        self.settings = settings
        self.allowed_pins = settings.allowed()
        self._outputs: dict[int, bool] = {}  # pin -> made an output (False: an input)
        self._lock = threading.Lock()
        self._closed = False
        self._pins = pins

    def _input(self, pin: int) -> None:
        """Make `pin` an input with the settings' pull resistor."""
        raise NotImplementedError

    def _level(self, pin: int) -> int:
        """The level the backend reads on `pin` (truthy: high)."""
        raise NotImplementedError

    def _output(self, pin: int, value: int, first: bool) -> None:
        """Drive `pin` to `value`; `first`: the pin is not an output yet."""
        raise NotImplementedError

    def _check(self, pin: int) -> None:
        reason = self.settings.refusal(pin)
        if reason is not None:
            raise PinNotAllowed(pin, reason)
        if self._closed:
            raise DriverError(f"{self.component}: gpio is closed")

    def read(self, pin: int) -> int:
        with self._lock:
            self._check(pin)
            if pin not in self._outputs:
                self._input(pin)
                self._outputs[pin] = False
            return 1 if self._level(pin) else 0

    def write(self, pin: int, value: int) -> None:
        if value not in (0, 1):
            raise ValueError(f"a pin value is 0 or 1, got {value}")
        with self._lock:
            self._check(pin)
            self._output(pin, value, first=not self._outputs.get(pin))
            self._outputs[pin] = True

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._pins.close()
