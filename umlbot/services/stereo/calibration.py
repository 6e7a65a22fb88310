"""The stereo calibration file: both cameras' intrinsics and where the right one sits.

JSON, written by `umlbot calibrate stereo` (or `ideal_calibration` for a simulated rig)::

    {"format": "umlbot-stereo-calibration", "version": 1,
     "image_size": [320, 240],
     "left":  {"matrix": [[f,0,cx],[0,f,cy],[0,0,1]], "distortion": [k1,k2,p1,p2,k3]},
     "right": {"matrix": ..., "distortion": ...},
     "rotation": [[...3x3...]], "translation": [tx, ty, tz],   # right camera in the left's frame, metres
     "rms_px": 0.21, "pairs": 12}

OpenCV's convention: `translation` maps a point from the left camera's frame to the right's, so
for a right camera to the right of the left one tx is negative (tx = -baseline). This module does
not need OpenCV; it reads and checks the file.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from umlbot.base.errors import ConfigError
from umlbot.base.files import write_atomically

FORMAT = "umlbot-stereo-calibration"


class Intrinsics(BaseModel):
    """One camera: its 3x3 matrix (pixels) and distortion coefficients (OpenCV order)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    matrix: list[list[float]]
    distortion: list[float] = Field(default_factory=lambda: [0.0] * 5)

    @field_validator("matrix")
    @classmethod
    def _three_by_three(cls, value: list[list[float]]) -> list[list[float]]:
        if len(value) != 3 or any(len(row) != 3 for row in value):
            raise ValueError("must be a 3x3 matrix")
        if not all(math.isfinite(x) for row in value for x in row):
            raise ValueError("must hold finite numbers")
        if value[0][0] <= 0 or value[1][1] <= 0:
            raise ValueError("focal lengths must be > 0")
        return value

    @field_validator("distortion")
    @classmethod
    def _coefficients(cls, value: list[float]) -> list[float]:
        if len(value) not in (4, 5, 8, 12, 14):
            raise ValueError("must have 4, 5, 8, 12 or 14 coefficients")
        if not all(math.isfinite(x) for x in value):
            raise ValueError("must hold finite numbers")
        return value


class Calibration(BaseModel):
    """A calibrated stereo pair (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    format: Literal["umlbot-stereo-calibration"] = "umlbot-stereo-calibration"
    version: Literal[1] = 1
    image_size: tuple[int, int]
    left: Intrinsics
    right: Intrinsics
    rotation: list[list[float]]
    translation: list[float]
    rms_px: float | None = None
    pairs: int | None = None

    @field_validator("image_size")
    @classmethod
    def _size(cls, value: tuple[int, int]) -> tuple[int, int]:
        if not (16 <= value[0] <= 8192 and 16 <= value[1] <= 8192):
            raise ValueError("width and height must be 16..8192 pixels")
        return value

    @field_validator("rotation")
    @classmethod
    def _rotation(cls, value: list[list[float]]) -> list[list[float]]:
        if len(value) != 3 or any(len(row) != 3 for row in value):
            raise ValueError("must be a 3x3 matrix")
        return value

    @field_validator("translation")
    @classmethod
    def _translation(cls, value: list[float]) -> list[float]:
        if len(value) != 3 or not all(math.isfinite(x) for x in value):
            raise ValueError("must be 3 finite numbers (metres)")
        if math.hypot(*value) < 1e-4:
            raise ValueError("the cameras cannot be at the same place (baseline 0)")
        return value

    @property
    def baseline_m(self) -> float:
        return math.sqrt(sum(x * x for x in self.translation))

    @property
    def focal_px(self) -> float:
        return self.left.matrix[0][0]

    def problem(self) -> str | None:
        """What makes this calibration unusable for depth, or None."""
        if self.translation[0] >= 0:
            return ("the right camera is to the left of the left camera (translation x >= 0): the "
                    "cameras are swapped, swap their settings or recalibrate")
        if abs(self.translation[0]) < 0.7 * self.baseline_m:
            return "the cameras are not side by side (the baseline is not horizontal): recalibrate"
        return None


def ideal_calibration(width_px: int, height_px: int, focal_px: float, baseline_m: float) -> Calibration:
    """The calibration of two ideal pinhole cameras side by side (the simulator's rig)."""
    cx, cy = (width_px - 1) / 2, (height_px - 1) / 2
    matrix = [[focal_px, 0.0, cx], [0.0, focal_px, cy], [0.0, 0.0, 1.0]]
    return Calibration(
        image_size=(width_px, height_px),
        left=Intrinsics(matrix=matrix), right=Intrinsics(matrix=matrix),
        rotation=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation=[-baseline_m, 0.0, 0.0],
    )


def load_calibration(path: str | Path) -> Calibration:
    """The calibration in `path`; `ConfigError` naming the file and what is wrong with it."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: no stereo calibration file there; make one with "
                          "'umlbot calibrate stereo' (docs/stereo.md)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read the stereo calibration: {exc}") from exc
    try:
        data: Any = json.loads(text)
    except ValueError as exc:
        raise ConfigError(f"{path}: the stereo calibration is not JSON ({exc})") from exc
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ConfigError(f"{path}: not a stereo calibration file (\"format\" must be {FORMAT!r})")
    try:
        calibration = Calibration.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        raise ConfigError(f"{path}: stereo calibration {where}: {first['msg']}") from exc
    problem = calibration.problem()
    if problem is not None:
        raise ConfigError(f"{path}: {problem}")
    return calibration


def save_calibration(calibration: Calibration, path: str | Path) -> None:
    """Write `calibration` to `path` atomically."""
    text = json.dumps(calibration.model_dump(mode="json"), indent=1) + "\n"
    write_atomically(Path(path), text.encode())
