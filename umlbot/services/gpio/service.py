"""The gpio service's features for the system component: `readPin(gpio)`, `writePin(gpio, value)`.

A pin the deployment does not allow (or one owned by another component) → `out_of_range`.
State: `{"pins": {"<gpio>": level, ...}}`, the last level read or written per pin.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from umlbot.base.library import Implementation
from umlbot.services.bus import FeatureError
from umlbot.services.component_service import ComponentService
from umlbot.services.gpio.driver import GpioPins, PinNotAllowed


class GpioService(ComponentService):
    """The system component on the bus."""

    kind = "gpio"
    handlers = {"readPin": "read_pin", "writePin": "write_pin"}

    @property
    def pins(self) -> GpioPins:
        pins: GpioPins = self.driver
        return pins

    def __init__(self, component: str, impl: Implementation, driver: GpioPins,
                 settings: Mapping[str, Any] | None = None) -> None:
        super().__init__(component, impl, driver, settings)
        self.levels: dict[int, int] = {}

    def read_pin(self, gpio: int) -> int:
        try:
            level = self.pins.read(gpio)
        except PinNotAllowed as exc:
            raise FeatureError("out_of_range", str(exc)) from exc
        self._remember(gpio, level)
        return level

    def write_pin(self, gpio: int, value: int) -> None:
        try:
            self.pins.write(gpio, value)
        except PinNotAllowed as exc:
            raise FeatureError("out_of_range", str(exc)) from exc
        self._remember(gpio, value)

    def _remember(self, gpio: int, level: int) -> None:
        with self.lock:
            changed = self.levels.get(gpio) != level
            self.levels[gpio] = level
        if changed:
            self.changed()

    def state(self) -> dict[str, Any]:
        with self.lock:
            return {"pins": {str(pin): level for pin, level in sorted(self.levels.items())}}
