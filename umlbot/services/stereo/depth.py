"""Depth from an image pair: rectification and semi-global block matching (OpenCV).

`DepthEngine(calibration)` precomputes the rectification maps (`cv2.stereoRectify`,
`cv2.initUndistortRectifyMap`) and a `cv2.StereoSGBM` matcher whose disparity range covers
`min_range_m` and beyond; `compute(left, right)` returns a `DepthFrame`. A pixel counts only when
the matcher found a unique match (uniqueness ratio, left-right check, speckle filter) *and* the
left image has texture there (mean horizontal gradient over a small window): a plain or dark
surface gives no reading, never the smoothed guess the matcher fills in. Each column's distance is
the median over the valid pixels of a band of rows around the horizon (where the walls are), as a
horizontal distance along the column's ray. Before matching, the pair's overall horizontal shift
is measured (phase correlation): a pair whose right image is shifted the wrong way had its
cameras swapped, and the whole frame has no reading.

OpenCV is the optional extra `umlbot[stereo]`; `require_cv2()` says how to install it.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from umlbot.base.errors import ConfigError
from umlbot.services.stereo.calibration import Calibration
from umlbot.services.stereo.driver import DepthFrame

INSTALL_HINT = "pip install 'umlbot[stereo]'"


def require_cv2() -> Any:
    """The `cv2` module, or a `ConfigError` saying how to install it."""
    try:
        import cv2
    except ImportError as exc:
        raise ConfigError(f"the stereo camera needs OpenCV, which is not installed: {INSTALL_HINT} "
                          f"(or pip install opencv-python-headless numpy) [{exc}]") from exc
    return cv2


def _column_quantiles(band: np.ndarray, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per column of `band` (NaN = no value): the median and the lower and upper quartiles of its
    `counts` values (NaN where a column has none); one sort for all columns."""
    ordered = np.sort(band, axis=0)  # NaNs sort last
    columns = np.arange(band.shape[1])
    last = np.maximum(counts - 1, 0)

    def at(fraction: float) -> np.ndarray:
        position = last * fraction
        low = np.floor(position).astype(np.int64)
        high = np.ceil(position).astype(np.int64)
        weight = position - low
        value = ordered[low, columns] * (1 - weight) + ordered[high, columns] * weight
        return np.where(counts > 0, value, np.nan)

    return at(0.5), at(0.25), at(0.75)


class DepthEngine:
    """Rectify + match + summarise, for one calibration (one image size)."""

    def __init__(self, calibration: Calibration, *, min_range_m: float = 0.24, max_range_cm: float = 400.0,
                 block_px: int = 5, texture_min: float = 10.0, band_deg: float = 3.0,
                 view_deg: float = 10.0,
                 min_valid_rows: int = 3, max_spread: float = 0.06, swap_check: bool = True) -> None:
        cv2 = require_cv2()
        self._cv2 = cv2
        self.calibration = calibration
        problem = calibration.problem()
        if problem is not None:
            raise ConfigError(f"stereo calibration: {problem}")
        width, height = calibration.image_size
        self.size = (width, height)
        k1 = np.array(calibration.left.matrix, dtype=np.float64)
        k2 = np.array(calibration.right.matrix, dtype=np.float64)
        d1 = np.array(calibration.left.distortion, dtype=np.float64)
        d2 = np.array(calibration.right.distortion, dtype=np.float64)
        rot = np.array(calibration.rotation, dtype=np.float64)
        trans = np.array(calibration.translation, dtype=np.float64).reshape(3, 1)
        zero = getattr(cv2, "CALIB_ZERO_DISPARITY", getattr(cv2, "STEREO_ZERO_DISPARITY", 1024))
        r1, r2, p1, p2, _q, _roi1, _roi2 = cv2.stereoRectify(
            k1, d1, k2, d2, (width, height), rot, trans, flags=zero, alpha=0)
        self._maps = (
            cv2.initUndistortRectifyMap(k1, d1, r1, p1, (width, height), cv2.CV_16SC2),
            cv2.initUndistortRectifyMap(k2, d2, r2, p2, (width, height), cv2.CV_16SC2),
        )
        self.focal_px = float(p1[0, 0])
        self.cx = float(p1[0, 2])
        self.cy = float(p1[1, 2])
        self.baseline_m = abs(float(p2[0, 3]) / float(p2[0, 0]))
        self.max_range_cm = max_range_cm
        self.num_disparities = max(16, math.ceil(self.focal_px * self.baseline_m / min_range_m / 16) * 16)
        self.min_range_m = self.focal_px * self.baseline_m / self.num_disparities
        self.texture_min = texture_min
        self.min_valid_rows = min_valid_rows
        self.max_spread = max_spread
        self.swap_check = swap_check
        self._matcher = cv2.StereoSGBM_create(
            minDisparity=0, numDisparities=self.num_disparities, blockSize=block_px,
            P1=8 * block_px * block_px, P2=32 * block_px * block_px, disp12MaxDiff=1,
            uniquenessRatio=10, speckleWindowSize=60, speckleRange=2, preFilterCap=31,
            mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
        u = np.arange(width, dtype=np.float64)
        self._column_angles = -np.arctan((u - self.cx) / self.focal_px)  # positive = left
        self._cos = np.cos(self._column_angles)
        band = round(self.focal_px * math.tan(math.radians(band_deg)))
        centre = round(self.cy)
        view = max(band + 8, round(self.focal_px * math.tan(math.radians(view_deg))))
        #: the rows matched (the depth picture): the horizon +- view_deg, the walls' height
        self._view = slice(max(0, centre - view), min(height, centre + view + 1))
        #: the rows each column's distance is the median of, within the matched rows
        self._rows = slice(max(0, centre - band) - self._view.start,
                           min(height, centre + band + 1) - self._view.start)

    @property
    def angles_deg(self) -> np.ndarray:
        return np.degrees(self._column_angles)

    def _grey(self, image: Any, which: str) -> np.ndarray:
        array = np.asarray(image)
        if array.ndim == 3:
            array = self._cv2.cvtColor(array, self._cv2.COLOR_BGR2GRAY)
        if array.ndim != 2 or (array.shape[1], array.shape[0]) != self.size:
            shape = "x".join(str(n) for n in array.shape)
            raise ValueError(f"the {which} image is {shape}, the calibration is for "
                             f"{self.size[0]}x{self.size[1]}")
        return array.astype(np.uint8, copy=False)

    def rectify(self, left: Any, right: Any) -> tuple[np.ndarray, np.ndarray]:
        cv2 = self._cv2
        lg, rg = self._grey(left, "left"), self._grey(right, "right")
        (lx, ly), (rx, ry) = self._maps
        return (cv2.remap(lg, lx, ly, cv2.INTER_LINEAR), cv2.remap(rg, rx, ry, cv2.INTER_LINEAR))

    def shift_px(self, left: np.ndarray, right: np.ndarray) -> tuple[float, float]:
        """The right image's overall horizontal shift against the left one (negative for a
        correctly ordered pair: things appear further left in the right image) and how sure."""
        a, b = left[self._view].astype(np.float32), right[self._view].astype(np.float32)
        window = self._cv2.createHanningWindow((a.shape[1], a.shape[0]), self._cv2.CV_32F)
        (dx, _dy), response = self._cv2.phaseCorrelate(a, b, window)
        return float(dx), float(response)

    def compute(self, left: Any, right: Any, time_s: float = 0.0) -> DepthFrame:
        """The depth frame of one pair (`ValueError` when the images do not fit the calibration)."""
        cv2 = self._cv2
        started = time.perf_counter()
        lr, rr = self.rectify(left, right)
        angles = tuple(float(a) for a in self.angles_deg)
        width = self.size[0]
        if self.swap_check:
            dx, response = self.shift_px(lr, rr)
            if dx > 2.0 and response > 0.12:
                return DepthFrame(time_s, angles, (None,) * width,
                                  problem="cameras swapped? the right image is shifted to the right "
                                          "of the left one", compute_s=time.perf_counter() - started,
                                  extra={"shift_px": dx, "shift_response": response})
        lb, rb = np.ascontiguousarray(lr[self._view]), np.ascontiguousarray(rr[self._view])
        disparity = self._matcher.compute(lb, rb).astype(np.float32) / 16.0
        self._fill_left_strip(disparity, lb, rb)
        gradient = np.abs(cv2.Sobel(lb, cv2.CV_32F, 1, 0, ksize=3))
        texture = cv2.blur(gradient, (7, 7))
        valid = (disparity > 0.5) & (texture >= self.texture_min)
        depth_m = np.where(valid, self.focal_px * self.baseline_m / np.maximum(disparity, 0.5), np.nan)
        band = depth_m[self._rows]
        counts = np.sum(~np.isnan(band), axis=0)
        median, q25, q75 = _column_quantiles(band, counts)
        ranges_cm = median / self._cos * 100.0
        # a surface the camera can see is upright, so the rows of one column agree; rows that do
        # not are matches found by chance (a surface nearer than the disparity range, glare)
        with np.errstate(all="ignore"):
            spread = (q75 - q25) / median
        ok = ((counts >= self.min_valid_rows) & np.isfinite(ranges_cm) & (spread <= self.max_spread)
              & (ranges_cm <= self.max_range_cm))
        columns = tuple(round(float(c), 1) if good else None for c, good in zip(ranges_cm, ok, strict=True))
        share = float(np.mean(valid))
        problem = None
        if not any(ok):
            mean = float(np.mean(lb))
            problem = ("too dark to see" if mean < 25 else
                       "nothing to measure: no texture (plain surfaces) or everything out of range")
        image, size = self._depth_picture(depth_m)
        return DepthFrame(time_s, angles, columns, problem=problem, valid_share=share, depth_image=image,
                          depth_size=size, compute_s=time.perf_counter() - started)

    def _fill_left_strip(self, disparity: np.ndarray, left: np.ndarray, right: np.ndarray) -> None:
        """The left-most `num_disparities` columns of the left image cannot be searched (their
        match could lie left of the right image), so the matcher leaves them blank. They are seen
        from the right camera instead: the pair mirrored and swapped (the right image's left
        part is then searchable), its disparities carried over to the left image's columns
        (u_left = u_right + d; the nearest wins where two land on one column)."""
        nd = self.num_disparities
        width = left.shape[1]
        span = min(width, 2 * nd + 24)
        if span <= nd:
            return
        mirrored_left = np.ascontiguousarray(right[:, :span][:, ::-1])
        mirrored_right = np.ascontiguousarray(left[:, :span][:, ::-1])
        found = self._matcher.compute(mirrored_left, mirrored_right).astype(np.float32) / 16.0
        rows, cols = np.nonzero(found[:, nd:] > 0.5)
        d = found[rows, cols + nd]
        u_left = np.rint((span - 1 - (cols + nd)) + d).astype(np.int64)
        keep = (u_left >= 0) & (u_left < nd)
        fill = np.full((left.shape[0], nd), -1.0, dtype=np.float32)
        np.maximum.at(fill, (rows[keep], u_left[keep]), d[keep])
        strip = disparity[:, :nd]
        disparity[:, :nd] = np.where(strip > 0.5, strip, fill)

    def _depth_picture(self, depth_m: np.ndarray) -> tuple[bytes, tuple[int, int]]:
        """A small grey picture (near = bright, no reading = black), 80 pixels wide."""
        step = max(1, self.size[0] // 80)
        small = depth_m[::step, ::step]
        with np.errstate(invalid="ignore"):
            scaled = np.clip(255.0 * (1.0 - (small - self.min_range_m) / 3.0), 16, 255)
        picture = np.where(np.isnan(small), 0, scaled).astype(np.uint8)
        return picture.tobytes(), (picture.shape[1], picture.shape[0])
