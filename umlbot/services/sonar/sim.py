"""The sim sonar driver: an HC-SR04 whose pings are cast into the simulated world.

Same deployment settings as the real sensor (pins ignored). The world does the physics (beam,
no echo from a wall hit too obliquely, 2..400 cm, 1 cm resolution, optional noise and lost
echoes); as in the real driver, `samples` > 1 takes the median of the pings that got an echo
(None when none did) and an echo beyond `max_range_cm` reads `max_range_cm`.
"""

from __future__ import annotations

import statistics

from pydantic import BaseModel, ConfigDict, Field

from umlbot.base.errors import DriverError, SimError
from umlbot.base.registry import DriverFactory
from umlbot.services.simworld import WorldHandle, connect_world


class SimSonarSettings(BaseModel):
    """Settings of a simulated HC-SR04; the real sensor's pin settings are accepted and ignored."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    samples: int = Field(default=1, ge=1, le=15, description="median of this many pings")
    max_range_cm: float = Field(default=400.0, gt=0, le=1000, description="reported when no echo")


class SimDistanceSensor:
    """A `DistanceSensor` reading the simulated world."""

    def __init__(self, component: str, world: WorldHandle, samples: int = 1,
                 max_range_cm: float = 400.0) -> None:
        self.component = component
        self.max_range_cm = max_range_cm
        self._world = world
        self._samples = samples
        self._closed = False

    def read_distance_cm(self) -> float | None:
        if self._closed:
            raise DriverError(f"{self.component}: driver is closed")
        try:
            readings = [self._world.read_sonar_cm() for _ in range(self._samples)]
        except SimError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc
        echoes = [min(float(r), self.max_range_cm) for r in readings if r is not None]
        if not echoes:
            return None
        return float(statistics.median(echoes))

    def close(self) -> None:
        self._closed = True


def create(component: str, settings: SimSonarSettings) -> SimDistanceSensor:
    """Build the sim sensor of `component` against the world of this process."""
    try:
        world = connect_world()
    except SimError as exc:
        raise DriverError(f"{component}: {exc}") from exc
    return SimDistanceSensor(component, world, settings.samples, settings.max_range_cm)


FACTORY = DriverFactory(SimSonarSettings, create)
