"""The sonar service's feature for one range finder: `value()` → centimetres (int).

No echo (nothing in range): the driver returns None, `value()` replies the sensor's
`max_range_cm` (default 400, like gpiozero's DistanceSensor returning its max_distance) and the
retained state says `{"distance_cm": 400, "echo": false}`.
"""

from __future__ import annotations

from typing import Any

from umlbot.services.component_service import ComponentService
from umlbot.services.sonar.driver import DistanceSensor


class SonarService(ComponentService):
    """One distance sensor on the bus."""

    kind = "sonar"
    handlers = {"value": "value"}

    distance_cm: int | None = None
    echo: bool | None = None

    @property
    def sensor(self) -> DistanceSensor:
        sensor: DistanceSensor = self.driver
        return sensor

    def value(self) -> int:
        reading = self.sensor.read_distance_cm()
        echo = reading is not None
        distance = round(reading if reading is not None else self.sensor.max_range_cm)
        with self.lock:
            changed = (distance, echo) != (self.distance_cm, self.echo)
            self.distance_cm, self.echo = distance, echo
        if changed:
            self.changed()
        return distance

    def state(self) -> dict[str, Any]:
        with self.lock:
            return {"distance_cm": self.distance_cm, "echo": self.echo}
