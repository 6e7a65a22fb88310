"""The stereo camera service's features, in centimetres and degrees (positive = to the left).

- `distance(angle_deg)`: the distance to the nearest surface in that direction (the median of the
  columns within `beam_deg` / 2 of it), or `NO_READING` (-1);
- `nearest()`: the distance to the nearest surface anywhere in view, or -1;
- `nearestBearing()`: the direction of that nearest surface (0 without a reading);
- `freeWidth()`: how wide the way straight ahead is free up to `look_ahead_cm` (0 when the way
  straight ahead is blocked or there is no reading).

A frame is reused for `frame_max_age_s` (driver time, sim time in the simulator), so that a model
asking several questions in a row gets answers about the same picture. The retained state carries
the last frame's summary; a frame without any reading says why (`problem`). A camera that delivers
no frame raises `DriverError`: an error reply, and the orchestrator's fail-safe as for any
component.
"""

from __future__ import annotations

import base64
import math
import statistics
from typing import Any

from umlbot.services.component_service import ComponentService
from umlbot.services.stereo.driver import NO_READING, DepthFrame, StereoCamera


class StereoService(ComponentService):
    """One stereo camera on the bus."""

    kind = "stereo"
    handlers = {"distance": "distance", "nearest": "nearest", "nearestBearing": "nearest_bearing",
                "freeWidth": "free_width"}

    _frame: DepthFrame | None = None
    _frame_at: float = -math.inf
    _summary: dict[str, Any] | None = None
    _stopped: str | None = None

    @property
    def camera(self) -> StereoCamera:
        camera: StereoCamera = self.driver
        return camera

    def _setting(self, key: str, default: float) -> float:
        value = self.settings.get(key, default)
        return float(value) if isinstance(value, int | float) and not isinstance(value, bool) else default

    def frame(self) -> DepthFrame:
        """The current depth frame (a fresh one when the last is older than `frame_max_age_s`)."""
        max_age = self._setting("frame_max_age_s", 0.05)
        now = self.camera.time_s()
        with self.lock:
            if self._frame is not None and max_age > 0 and now - self._frame_at <= max_age:
                return self._frame
        try:
            frame = self.camera.read_depth()
        except Exception as exc:
            with self.lock:
                self._frame, self._stopped = None, str(exc)
            self.changed()
            raise
        with self.lock:
            self._frame, self._frame_at, self._stopped = frame, now, None
            self._summary = self._summarise(frame)
        self.changed()
        return frame

    def _columns(self, frame: DepthFrame, low_deg: float, high_deg: float) -> list[float]:
        return [cm for angle, cm in zip(frame.angles_deg, frame.columns_cm, strict=True)
                if cm is not None and low_deg <= angle <= high_deg]

    def _distance(self, frame: DepthFrame, angle_deg: float) -> int:
        half = self._setting("beam_deg", 4.0) / 2
        values = self._columns(frame, angle_deg - half, angle_deg + half)
        # at least a third of the beam's columns must agree there is a surface
        wanted = max(1, sum(1 for a in frame.angles_deg if abs(a - angle_deg) <= half) // 3)
        if frame.problem is not None or len(values) < wanted:
            return NO_READING
        return round(statistics.median(values))

    def _nearest(self, frame: DepthFrame) -> tuple[int, int]:
        """(cm, bearing) of the nearest surface: the smallest of the columns' 5-column medians;
        the bearing is the middle of the run of columns within 2 % of it."""
        if frame.problem is not None:
            return NO_READING, 0
        cols, angles = frame.columns_cm, frame.angles_deg
        smoothed: list[float | None] = []
        for i in range(len(cols)):
            window = [c for c in cols[max(0, i - 2): i + 3] if c is not None]
            smoothed.append(statistics.median(window) if len(window) >= 3 else None)
        known = [(cm, i) for i, cm in enumerate(smoothed) if cm is not None]
        if not known:
            return NO_READING, 0
        best, at = min(known)
        low = high = at
        while low > 0 and (smoothed[low - 1] or math.inf) <= best * 1.02:
            low -= 1
        while high < len(cols) - 1 and (smoothed[high + 1] or math.inf) <= best * 1.02:
            high += 1
        return round(best), round((angles[low] + angles[high]) / 2)

    def _free_width(self, frame: DepthFrame) -> int:
        reach = self._setting("look_ahead_cm", 60.0)
        if frame.problem is not None or self._distance(frame, 0.0) == NO_READING:
            return 0
        ahead = self._distance(frame, 0.0)
        if ahead < reach:
            return 0
        centre = min(range(len(frame.angles_deg)), key=lambda i: abs(frame.angles_deg[i]))
        width = 0.0
        for step in (-1, 1):  # to one side, then the other: until a column nearer than reach
            i, edge = centre, 0.0
            while 0 <= i < len(frame.angles_deg):
                cm = frame.columns_cm[i]
                if cm is not None and cm < reach:
                    break
                edge = abs(reach * math.tan(math.radians(frame.angles_deg[i])))
                i += step
            width += edge
        return round(width)

    def _summarise(self, frame: DepthFrame) -> dict[str, Any]:
        nearest, bearing = self._nearest(frame)
        low, high = frame.fov_deg
        return {
            "reading": nearest != NO_READING,
            "problem": frame.problem,
            "nearest_cm": nearest,
            "bearing_deg": bearing,
            "ahead_cm": self._distance(frame, 0.0),
            "free_width_cm": self._free_width(frame),
            "valid_share": round(frame.valid_share, 3),
            "fov_deg": [round(low, 1), round(high, 1)],
            "frame_time_s": round(frame.time_s, 3),
            "compute_ms": round(frame.compute_s * 1000, 1),
            # a small grey picture of the depth for viewers (the studio's sim panel): near is
            # bright, no reading black; row-major bytes, base64
            "depth_image": base64.b64encode(frame.depth_image).decode() if frame.depth_image else None,
            "depth_size": list(frame.depth_size),
        }

    def distance(self, angle_deg: int) -> int:
        return self._distance(self.frame(), float(angle_deg))

    def nearest(self) -> int:
        return self._nearest(self.frame())[0]

    def nearest_bearing(self) -> int:
        return self._nearest(self.frame())[1]

    def free_width(self) -> int:
        return self._free_width(self.frame())

    def state(self) -> dict[str, Any]:
        with self.lock:
            if self._stopped is not None:
                return {"reading": False, "camera": "stopped", "problem": self._stopped}
            if self._summary is None:
                return {"reading": False, "camera": "idle", "problem": None}
            return {"camera": "running", **self._summary}
