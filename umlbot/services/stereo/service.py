"""The stereo camera service's features, in centimetres and degrees (positive = to the left).

- `distance(angle_deg)`: the distance to the nearest surface in that direction (the median of the
  columns within `beam_deg` / 2 of it), or `NO_READING` (-1);
- `nearest()`: the distance to the nearest surface anywhere in view, or -1;
- `nearestBearing()`: the direction of that nearest surface (0 without a reading);
- `freeWidth()`: how wide the way straight ahead is free up to `look_ahead_cm` (0 when the way
  straight ahead is blocked or there is no reading);
- `reach(angle_deg)`: how far (cm) a strip `car_width_cm` wide (default 24: the car and a margin)
  is free in that direction, i.e. the nearest seen surface within half that width of the line
  (`NO_READING` when the direction itself is unseen);
- `openBearing()`: the direction, within `open_limit_deg` (default 24) of straight ahead, in which
  `reach` is longest: the middle of the stretch of directions within 10 % of the longest (the
  middle of the gap, follow-the-gap style), 0 without a reading.

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
                "freeWidth": "free_width", "reach": "reach", "openBearing": "open_bearing"}

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

    @staticmethod
    def _points(frame: DepthFrame) -> list[tuple[float, float]]:
        """The seen surfaces as points (cm ahead, cm to the left)."""
        return [(cm * math.cos(math.radians(angle)), cm * math.sin(math.radians(angle)))
                for angle, cm in zip(frame.angles_deg, frame.columns_cm, strict=True) if cm is not None]

    def _reach(self, frame: DepthFrame, angle_deg: float,
               points: list[tuple[float, float]] | None = None) -> int:
        """cm a strip car_width_cm wide is free along angle_deg: the nearest seen point within half
        that width of the line (its distance along it); the line's own direction must be seen."""
        if frame.problem is not None or self._distance(frame, angle_deg) == NO_READING:
            return NO_READING
        half = self._setting("car_width_cm", 24.0) / 2
        theta = math.radians(angle_deg)
        cos_t, sin_t = math.cos(theta), math.sin(theta)
        free = self._setting("max_reach_cm", 400.0)
        for x, y in self._points(frame) if points is None else points:
            along, across = x * cos_t + y * sin_t, y * cos_t - x * sin_t
            if along > 0 and abs(across) <= half:
                free = min(free, along)
        return round(free)

    def _open_bearing(self, frame: DepthFrame) -> int:
        """The middle of the stretch of directions (1° apart) whose reach is within 10 % of the
        longest, the one holding the longest (nearest straight ahead on a tie); 0 without one."""
        limit = int(self._setting("open_limit_deg", 24.0))
        bearings = list(range(-limit, limit + 1))
        points = self._points(frame)
        reaches = [self._reach(frame, float(b), points) for b in bearings]
        best = max(reaches)
        if best <= 0:
            return 0
        at = min((i for i, r in enumerate(reaches) if r == best), key=lambda i: abs(bearings[i]))
        low = high = at
        while low > 0 and reaches[low - 1] >= 0.9 * best:
            low -= 1
        while high < len(reaches) - 1 and reaches[high + 1] >= 0.9 * best:
            high += 1
        return round((bearings[low] + bearings[high]) / 2)

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

    def reach(self, angle_deg: int) -> int:
        return self._reach(self.frame(), float(angle_deg))

    def open_bearing(self) -> int:
        return self._open_bearing(self.frame())

    def state(self) -> dict[str, Any]:
        with self.lock:
            if self._stopped is not None:
                return {"reading": False, "camera": "stopped", "problem": self._stopped}
            if self._summary is None:
                return {"reading": False, "camera": "idle", "problem": None}
            return {"camera": "running", **self._summary}
