"""Mock GPIO pins: inputs a test can set, outputs it can read; the same pin rules as pigpio."""

from __future__ import annotations

from pydantic import ConfigDict, Field

from umlbot.base.registry import DriverFactory
from umlbot.services.gpio.driver import GpioSettings, PinNotAllowed
from umlbot.services.mock_support import MockDriver, MockSettings


class MockGpioSettings(GpioSettings, MockSettings):
    """The system component's settings plus `mock_levels` (pin -> initial input level)."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    mock_levels: dict[int, int] = Field(default_factory=dict)


class MockGpio(MockDriver):
    """Satisfies `GpioPins`. `levels` holds every pin's level; `set_level` drives an input."""

    def __init__(self, component: str, settings: MockGpioSettings | None = None) -> None:
        settings = settings or MockGpioSettings()
        super().__init__(component, settings)
        self.settings = settings
        self.allowed_pins = settings.allowed()
        self.levels: dict[int, int] = {pin: 1 if level else 0 for pin, level in settings.mock_levels.items()}
        self.outputs: set[int] = set()

    def set_level(self, pin: int, level: int) -> None:
        """What an outside signal (a button, a sensor) puts on `pin`."""
        with self._cond:
            self.levels[pin] = 1 if level else 0
            self._changed()

    def _check(self, pin: int) -> None:
        reason = self.settings.refusal(pin)
        if reason is not None:
            raise PinNotAllowed(pin, reason)

    def read(self, pin: int) -> int:
        self._check(pin)
        self._enter("read", pin)
        with self._cond:
            return self.levels.get(pin, 0)

    def write(self, pin: int, value: int) -> None:
        if value not in (0, 1):
            raise ValueError(f"a pin value is 0 or 1, got {value}")
        self._check(pin)
        self._enter("write", pin, value)
        with self._cond:
            self.levels[pin] = value
            self.outputs.add(pin)
            self._changed()

    def close(self) -> None:
        with self._cond:
            self._record("close")
            self.closed = True
            self._changed()


FACTORY = DriverFactory(MockGpioSettings, MockGpio)
