"""Stereo calibration from chessboard image pairs (OpenCV), for `umlbot calibrate stereo`.

Each pair shows the same printed chessboard to both cameras at once. The inner corners are found
in both images (`cv2.findChessboardCorners`, refined to sub-pixel), each camera is calibrated on
its own (`cv2.calibrateCamera`), then the pair (`cv2.stereoCalibrate` with the intrinsics fixed),
which gives the right camera's rotation and translation: the baseline, in the unit of
`square_m` (metres). Pairs where either image does not show the whole board are skipped and
reported; fewer than `MIN_PAIRS` usable pairs is an error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from umlbot.base.errors import ConfigError
from umlbot.services.stereo.calibration import Calibration, Intrinsics
from umlbot.services.stereo.depth import require_cv2

MIN_PAIRS = 5


@dataclass(frozen=True)
class CalibrationResult:
    calibration: Calibration
    used: list[str]
    skipped: list[str]


def _corners(cv2: Any, image: np.ndarray, inner: tuple[int, int]) -> np.ndarray | None:
    found, corners = cv2.findChessboardCorners(
        image, inner, cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found:
        return None
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.001)
    result: np.ndarray = cv2.cornerSubPix(image, corners, (5, 5), (-1, -1), criteria)
    return result


def calibrate_pairs(pairs: Sequence[tuple[str, Any, Any]], inner: tuple[int, int],
                    square_m: float) -> CalibrationResult:
    """Calibrate from (name, left grey image, right grey image) pairs."""
    cv2 = require_cv2()
    board = np.zeros((inner[0] * inner[1], 3), np.float32)
    board[:, :2] = np.mgrid[0:inner[0], 0:inner[1]].T.reshape(-1, 2) * square_m
    objects, lefts, rights, used, skipped = [], [], [], [], []
    size: tuple[int, int] | None = None
    for name, left, right in pairs:
        left, right = np.asarray(left), np.asarray(right)
        this = (left.shape[1], left.shape[0])
        if right.shape != left.shape or (size is not None and this != size):
            skipped.append(f"{name}: the images differ in size")
            continue
        size = this
        cl, cr = _corners(cv2, left, inner), _corners(cv2, right, inner)
        if cl is None or cr is None:
            which = "left" if cl is None else "right"
            skipped.append(f"{name}: the whole board is not seen by the {which} camera")
            continue
        objects.append(board)
        lefts.append(cl)
        rights.append(cr)
        used.append(name)
    if len(used) < MIN_PAIRS or size is None:
        raise ConfigError(f"only {len(used)} usable chessboard pair(s), at least {MIN_PAIRS} needed "
                          f"(skipped: {'; '.join(skipped) or 'none'})")
    _, k1, d1, _, _ = cv2.calibrateCamera(objects, lefts, size, None, None)
    _, k2, d2, _, _ = cv2.calibrateCamera(objects, rights, size, None, None)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-6)
    rms, k1, d1, k2, d2, rot, trans, _, _ = cv2.stereoCalibrate(
        objects, lefts, rights, k1, d1, k2, d2, size, criteria=criteria, flags=cv2.CALIB_FIX_INTRINSIC)
    calibration = Calibration(
        image_size=size,
        left=Intrinsics(matrix=k1.tolist(), distortion=d1.ravel().tolist()),
        right=Intrinsics(matrix=k2.tolist(), distortion=d2.ravel().tolist()),
        rotation=rot.tolist(), translation=trans.ravel().tolist(), rms_px=round(float(rms), 4),
        pairs=len(used))
    return CalibrationResult(calibration, used, skipped)


def read_pairs(folder: Path) -> list[tuple[str, Any, Any]]:
    """The pairs in `folder`: `left*.png` with the `right*.png` of the same suffix (any image
    format OpenCV reads: png, jpg, bmp)."""
    cv2 = require_cv2()
    if not folder.is_dir():
        raise ConfigError(f"{folder}: not a folder of chessboard image pairs")
    pairs = []
    for left_path in sorted(folder.glob("left*")):
        right_path = left_path.with_name("right" + left_path.name[len("left"):])
        if not right_path.exists():
            raise ConfigError(f"{left_path}: no {right_path.name} beside it")
        left = cv2.imread(str(left_path), cv2.IMREAD_GRAYSCALE)
        right = cv2.imread(str(right_path), cv2.IMREAD_GRAYSCALE)
        if left is None or right is None:
            raise ConfigError(f"{left_path if left is None else right_path}: not an image OpenCV can read")
        pairs.append((left_path.name[len("left"):], left, right))
    if not pairs:
        raise ConfigError(f"{folder}: no left*.png / right*.png image pairs there")
    return pairs
