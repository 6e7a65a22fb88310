"""What every stereo camera driver must provide: one depth frame at a time.

A driver (real, sim, mock) answers `read_depth()` with a `DepthFrame`: the horizontal distance to
the nearest surface for each image column (None where there is no reading), the column's
direction, and why a frame has no reading at all. Images, rectification and block matching stay
inside the drivers (`umlbot.services.stereo.depth`); the service above speaks centimetres and
degrees only, and imports neither numpy nor OpenCV.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

#: what a distance feature answers when there is no reading (never a made-up distance); every
#: guard like `distance > clearance` then takes the way as blocked
NO_READING = -1


@dataclass(frozen=True)
class DepthFrame:
    """The depth summary of one image pair.

    `columns_cm[i]` is the distance (cm, horizontal, along the column's ray) to the surface seen in
    column i near the horizon, or None; `angles_deg[i]` the column's direction from straight ahead
    (positive = left). `problem` says why the whole frame has no reading (cameras swapped, too
    dark), None otherwise. `depth_image` is a small grey picture of the depth (row-major bytes,
    `depth_size` = (width, height), near = bright, no reading = 0) for viewers; may be empty.
    """

    time_s: float
    angles_deg: tuple[float, ...]
    columns_cm: tuple[float | None, ...]
    problem: str | None = None
    valid_share: float = 0.0
    depth_image: bytes = b""
    depth_size: tuple[int, int] = (0, 0)
    compute_s: float = 0.0
    extra: dict[str, float] = field(default_factory=dict)

    @property
    def fov_deg(self) -> tuple[float, float]:
        """The directions (right-most, left-most) the frame covers."""
        if not self.angles_deg:
            return (0.0, 0.0)
        return (min(self.angles_deg), max(self.angles_deg))


@runtime_checkable
class StereoCamera(Protocol):
    """A calibrated camera pair that gives depth frames."""

    def read_depth(self) -> DepthFrame:
        """The depth of a fresh image pair.

        Raises `DriverError` when the camera delivers no frame within its time-out (unplugged,
        stopped); a frame with nothing to measure is a `DepthFrame` with `problem` set or columns
        of None, never a guess.
        """

    def time_s(self) -> float:
        """The driver's clock (seconds): sim time in the simulator, monotonic time otherwise."""

    def close(self) -> None:
        """Release the cameras; idempotent."""
