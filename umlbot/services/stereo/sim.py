"""The sim stereo camera: the simulated world renders the left and right images, OpenCV matches them.

Settings: `width_px`, `height_px` (default 320 x 240), `sim_calibration` (a calibration file; by
default the simulated rig's ideal calibration, which the world reports with each picture; the
real camera's `calibration` is ignored here),
`min_range_cm` (the nearest distance the matcher searches, default 24). The depth pipeline is
exactly the real camera's (`umlbot.services.stereo.depth`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from umlbot.base.errors import DriverError, SimError
from umlbot.base.registry import DriverFactory
from umlbot.services.simworld import WorldHandle, connect_world
from umlbot.services.stereo.calibration import Calibration, ideal_calibration, load_calibration
from umlbot.services.stereo.depth import DepthEngine, require_cv2
from umlbot.services.stereo.driver import DepthFrame


class SimStereoSettings(BaseModel):
    """Settings of the simulated stereo camera; the real camera's device settings are ignored."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    width_px: int = Field(default=320, ge=64, le=2048)
    height_px: int = Field(default=240, ge=48, le=2048)
    sim_calibration: str | None = Field(default=None, description="calibration file (default: ideal rig)")
    min_range_cm: float = Field(default=24.0, ge=5, le=200)


class SimStereoCamera:
    """A `StereoCamera` looking at the simulated world."""

    def __init__(self, component: str, world: WorldHandle, settings: SimStereoSettings,
                 calibration: Calibration | None = None) -> None:
        require_cv2()
        self.component = component
        self.settings = settings
        self._world = world
        self._calibration = calibration
        self._engine: DepthEngine | None = None
        self._last: tuple[bytes, bytes, DepthFrame] | None = None
        self._closed = False
        #: wall seconds from the world's picture to the depth frame, of the last frame
        self.last_latency_s = 0.0

    def _engine_for(self, images: Any) -> DepthEngine:
        if self._engine is None:
            calibration = self._calibration or ideal_calibration(
                images.width_px, images.height_px, images.focal_px, images.baseline_m)
            self._engine = DepthEngine(calibration, min_range_m=self.settings.min_range_cm / 100.0)
        return self._engine

    def read_depth(self) -> DepthFrame:
        import time

        import numpy as np

        if self._closed:
            raise DriverError(f"{self.component}: driver is closed")
        started = time.perf_counter()
        try:
            images = self._world.render_stereo(self.settings.width_px, self.settings.height_px)
        except SimError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc
        last = self._last
        if last is not None and last[0] == images.left and last[1] == images.right:
            # the same picture (the car stood still): the same depth, without matching again
            self.last_latency_s = time.perf_counter() - started
            return dataclasses.replace(last[2], time_s=images.time_s)
        shape = (images.height_px, images.width_px)
        left = np.frombuffer(images.left, dtype=np.uint8).reshape(shape)
        right = np.frombuffer(images.right, dtype=np.uint8).reshape(shape)
        try:
            frame = self._engine_for(images).compute(left, right, images.time_s)
        except ValueError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc
        self.last_latency_s = time.perf_counter() - started
        self._last = (images.left, images.right, frame)
        return frame

    def time_s(self) -> float:
        try:
            return self._world.time_s()
        except SimError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc

    def close(self) -> None:
        self._closed = True


def create(component: str, settings: SimStereoSettings) -> SimStereoCamera:
    """Build the sim camera of `component` against the world of this process."""
    calibration = load_calibration(settings.sim_calibration) if settings.sim_calibration else None
    try:
        world = connect_world()
    except SimError as exc:
        raise DriverError(f"{component}: {exc}") from exc
    return SimStereoCamera(component, world, settings, calibration)


FACTORY = DriverFactory(SimStereoSettings, create)
