"""A mock distance sensor: returns a scripted sequence of distances; no hardware.

Settings: `mock_distances` (the readings in order, `null` = no echo), `mock_repeat` ("last" keeps
returning the last reading when the script is used up, "cycle" starts again), `mock_distance_cm`
(the reading when the script is empty, default 100), `max_range_cm` (reported for no echo).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Literal

from pydantic import Field

from umlbot.base.registry import DriverFactory
from umlbot.services.mock_support import MockDriver, MockSettings


class MockSonarSettings(MockSettings):
    """Mock sonar settings."""

    mock_distances: list[float | None] = Field(default_factory=list)
    mock_repeat: Literal["last", "cycle"] = "last"
    mock_distance_cm: float | None = 100.0
    max_range_cm: float = Field(default=400.0, gt=0)


class MockDistanceSensor(MockDriver):
    """Satisfies `DistanceSensor`; `reads` counts the readings taken."""

    def __init__(self, component: str, settings: MockSonarSettings | None = None) -> None:
        settings = settings or MockSonarSettings()
        super().__init__(component, settings)
        self.max_range_cm = settings.max_range_cm
        self.repeat = settings.mock_repeat
        self.script: list[float | None] = list(settings.mock_distances)
        self.distance_cm: float | None = settings.mock_distance_cm
        self.reads = 0
        self._position = 0

    def set_distance(self, cm: float | None) -> None:
        """From now on always read `cm` (None = no echo); drops the rest of the script."""
        with self._cond:
            self.script = []
            self._position = 0
            self.distance_cm = cm

    def queue_distances(self, readings: Iterable[float | None]) -> None:
        """Append readings to the script."""
        with self._cond:
            self.script.extend(readings)

    def read_distance_cm(self) -> float | None:
        self._enter("read_distance_cm")
        with self._cond:
            self.reads += 1
            if self._position < len(self.script):
                value = self.script[self._position]
                self._position += 1
            elif self.script and self.repeat == "cycle":
                self._position = 1
                value = self.script[0]
            elif self.script:
                value = self.script[-1]
            else:
                value = self.distance_cm
            self._changed()
            return value

    def close(self) -> None:
        with self._cond:
            self._record("close")
            self.closed = True
            self._changed()


FACTORY = DriverFactory(MockSonarSettings, MockDistanceSensor)
