"""A mock stereo camera: scripted depths, no images, no OpenCV.

Settings: `mock_depths` (frames in order; each frame is a list of (angle_deg, cm) surfaces, `cm`
null = no reading there; a frame given as a string is a problem, "no reading" for the whole frame),
`mock_repeat` ("last" or "cycle"), `mock_distance_cm` (every direction reads this when the script
is empty, default 150; null = no reading), `mock_fov_deg` (the field of view, default 60),
`mock_stopped` (true: the camera delivers no frames, every read raises `DriverError`).
"""

from __future__ import annotations

import time
from typing import Literal

from pydantic import Field

from umlbot.base.errors import DriverError
from umlbot.base.registry import DriverFactory
from umlbot.services.mock_support import MockDriver, MockSettings
from umlbot.services.stereo.driver import DepthFrame

MockFrame = list[tuple[float, float | None]] | str


class MockStereoSettings(MockSettings):
    """Mock stereo camera settings."""

    mock_depths: list[MockFrame] = Field(default_factory=list)
    mock_repeat: Literal["last", "cycle"] = "last"
    mock_distance_cm: float | None = 150.0
    mock_fov_deg: float = Field(default=60.0, gt=0, le=180)
    mock_columns: int = Field(default=61, ge=3, le=2000)
    mock_stopped: bool = False


class MockStereoCamera(MockDriver):
    """Satisfies `StereoCamera`; each column reads the scripted surface nearest to its angle."""

    def __init__(self, component: str, settings: MockStereoSettings | None = None) -> None:
        settings = settings or MockStereoSettings()
        super().__init__(component, settings)
        self.settings = settings
        self.script: list[MockFrame] = list(settings.mock_depths)
        self.distance_cm = settings.mock_distance_cm
        self.stopped = settings.mock_stopped
        self.reads = 0
        self._position = 0
        n, half = settings.mock_columns, settings.mock_fov_deg / 2
        self.angles = tuple(half - 2 * half * i / (n - 1) for i in range(n))  # left to right

    def set_distance(self, cm: float | None) -> None:
        """From now on every direction reads `cm` (None = no reading); drops the script."""
        with self._cond:
            self.script, self._position, self.distance_cm = [], 0, cm

    def set_stopped(self, stopped: bool) -> None:
        """Stop (or restart) delivering frames."""
        with self._cond:
            self.stopped = stopped

    def _next(self) -> MockFrame | None:
        if self._position < len(self.script):
            self._position += 1
            return self.script[self._position - 1]
        if self.script and self.settings.mock_repeat == "cycle":
            self._position = 1
            return self.script[0]
        return self.script[-1] if self.script else None

    def read_depth(self) -> DepthFrame:
        self._enter("read_depth")
        with self._cond:
            if self.stopped:
                raise DriverError(f"{self.component}: the camera delivers no frames")
            self.reads += 1
            scripted = self._next()
            now = time.monotonic()
            if isinstance(scripted, str):
                return DepthFrame(now, self.angles, (None,) * len(self.angles), problem=scripted)
            if scripted is None:
                columns = (self.distance_cm,) * len(self.angles)
            else:
                points = sorted(scripted)
                columns = tuple(min(points, key=lambda p: abs(p[0] - a))[1] for a in self.angles)
            share = sum(c is not None for c in columns) / len(columns)
            return DepthFrame(now, self.angles, columns, valid_share=share)

    def time_s(self) -> float:
        return time.monotonic()

    def close(self) -> None:
        with self._cond:
            self._record("close")
            self.closed = True
            self._changed()


FACTORY = DriverFactory(MockStereoSettings, MockStereoCamera)
