"""The simulated stereo camera: left and right images of the track, rendered by ray casting.

Two ideal pinhole cameras (no lens distortion, parallel axes) sit side by side at the front of
the car, `baseline_m` apart, `height_m` above the floor, looking straight ahead. The walls are
extruded to `wall_height_m` and painted with a texture the matcher can lock on to: a sum of
sinusoids of random direction and wavelengths between 1.5 and 40 cm in (position along the wall,
height), the same on every wall but shifted per wall, within `TEXTURE_DEG` of the horizon (where the
depth pipeline looks; above and below, a wall is plain). Each component is faded out where it is finer
than a pixel at that distance (procedural anti-aliasing), so far walls are smooth rather than
noisy. The floor and the sky are plain: they give the matcher nothing, as plain surfaces do to a
real camera. One ray is cast per column (numpy, every wall at once); the rows follow from the
column's depth, so a frame costs O(width x walls + width x height).

Conventions: image x to the right, y down; `angle_deg` of a column counts counter-clockwise
(positive = to the left), as the world's headings do. Pixel values are 8-bit grey levels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from umlbot.sim.geometry import Pose, Segment

#: how many sinusoids make the wall texture, and their wavelengths (metres)
_TEXTURE_COMPONENTS = 24
_WAVELENGTH_M = (0.015, 0.40)
#: the walls are textured within this many degrees of the horizon (the depth pipeline matches +-10)
TEXTURE_DEG = 16.0
_SKY = 190.0
_FLOOR = 70.0


@dataclass(frozen=True)
class StereoRig:
    """The camera pair's geometry: image size, horizontal field of view, baseline and mounting."""

    width_px: int = 320
    height_px: int = 240
    hfov_deg: float = 60.0
    baseline_m: float = 0.08
    height_m: float = 0.10
    forward_m: float = 0.12  # ahead of the car's centre
    wall_height_m: float = 0.30
    noise_grey: float = 1.5  # sensor noise (standard deviation, grey levels)

    @property
    def focal_px(self) -> float:
        return (self.width_px / 2) / math.tan(math.radians(self.hfov_deg) / 2)

    @property
    def cx(self) -> float:
        return (self.width_px - 1) / 2

    @property
    def cy(self) -> float:
        return (self.height_px - 1) / 2

    def camera_matrix(self) -> list[list[float]]:
        f = self.focal_px
        return [[f, 0.0, self.cx], [0.0, f, self.cy], [0.0, 0.0, 1.0]]

    def scaled(self, width_px: int, height_px: int) -> StereoRig:
        """The same rig with another image size (same field of view)."""
        return StereoRig(width_px, height_px, self.hfov_deg, self.baseline_m, self.height_m,
                         self.forward_m, self.wall_height_m, self.noise_grey)


def _texture_table(seed: int = 7) -> np.ndarray:
    """(components, 4): wavenumber along the wall, wavenumber in height (rad/m), phase, amplitude."""
    rng = np.random.default_rng(seed)
    lo, hi = _WAVELENGTH_M
    wavelengths = np.exp(rng.uniform(math.log(lo), math.log(hi), _TEXTURE_COMPONENTS))
    directions = rng.uniform(0, math.pi, _TEXTURE_COMPONENTS)
    k = 2 * math.pi / wavelengths
    phases = rng.uniform(0, 2 * math.pi, _TEXTURE_COMPONENTS)
    amplitude = np.full(_TEXTURE_COMPONENTS, 1.0)
    return np.stack([k * np.cos(directions), k * np.sin(directions), phases, amplitude], axis=1)


_TEXTURE = _texture_table()


def wall_arrays(walls: list[Segment]) -> np.ndarray:
    """(walls, 5): ax, ay, bx, by, offset of the wall's texture."""
    rows = [(w.a.x, w.a.y, w.b.x, w.b.y, 3.7 * i) for i, w in enumerate(walls)]
    return np.array(rows, dtype=np.float64).reshape(-1, 5)


def cast_columns(walls: np.ndarray, ox: float, oy: float, angles: np.ndarray,
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One horizontal ray per angle from (ox, oy): distance (inf = no wall), the hit wall's index,
    the hit's position along the wall (m) and the cosine of the incidence."""
    dx, dy = np.cos(angles)[:, None], np.sin(angles)[:, None]
    ax, ay, bx, by = walls[:, 0], walls[:, 1], walls[:, 2], walls[:, 3]
    sx, sy = bx - ax, by - ay
    denom = dx * sy - dy * sx
    qx, qy = ax - ox, ay - oy
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (qx * sy - qy * sx) / denom
        u = (qx * dy - qy * dx) / denom
    ok = (np.abs(denom) > 1e-12) & (t > 1e-6) & (u >= -1e-9) & (u <= 1 + 1e-9)
    t = np.where(ok, t, np.inf)
    index = np.argmin(t, axis=1) if len(walls) else np.zeros(len(angles), dtype=int)
    columns = np.arange(len(angles))
    dist = t[columns, index] if len(walls) else np.full(len(angles), np.inf)
    lengths = np.hypot(sx, sy)
    along = (u[columns, index] * lengths[index]) if len(walls) else np.zeros(len(angles))
    cos_inc = np.abs(dx[:, 0] * sy[index] - dy[:, 0] * sx[index]) / np.maximum(lengths[index], 1e-12)
    return dist, index, along, cos_inc


class CameraRenderer:
    """Renders the rig's left and right images of a set of walls from a car pose."""

    def __init__(self, walls: list[Segment], rig: StereoRig | None = None, *,
                 texture_gain: float = 1.0, brightness: float = 1.0, seed: int | None = 0) -> None:
        self.rig = rig or StereoRig()
        self.walls = wall_arrays(walls)
        self.texture_gain = texture_gain  # 0: plain walls (nothing for the matcher)
        self.brightness = brightness  # < 0.1: a dark scene
        self._rng = np.random.default_rng(seed)
        r = self.rig
        u = np.arange(r.width_px, dtype=np.float64)
        #: each column's angle from the optical axis, radians, positive = to the left
        self.column_angles = -np.arctan((u - r.cx) / r.focal_px)
        self._rows = (np.arange(r.height_px, dtype=np.float64) - r.cy) / r.focal_px  # down
        band = round(r.focal_px * math.tan(math.radians(TEXTURE_DEG)))
        centre = round(r.cy)
        self._textured = slice(max(0, centre - band), min(r.height_px, centre + band + 1))

    def camera_origins(self, pose: Pose) -> tuple[tuple[float, float], tuple[float, float]]:
        """Where the left and the right camera are in the plane."""
        r = self.rig
        c, s = math.cos(pose.heading), math.sin(pose.heading)
        fx, fy = pose.x + r.forward_m * c, pose.y + r.forward_m * s
        half = r.baseline_m / 2
        return (fx - half * s, fy + half * c), (fx + half * s, fy - half * c)

    def ground_truth_m(self, pose: Pose) -> np.ndarray:
        """The left camera's horizontal distance to the first wall per column (inf: none)."""
        (lx, ly), _ = self.camera_origins(pose)
        return cast_columns(self.walls, lx, ly, pose.heading + self.column_angles)[0]

    def render(self, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
        """(left, right) 8-bit grey images, height x width."""
        left, right = self.camera_origins(pose)
        return self._render_one(left, pose.heading), self._render_one(right, pose.heading)

    def _render_one(self, origin: tuple[float, float], heading: float) -> np.ndarray:
        r = self.rig
        dist, index, along, cos_inc = cast_columns(self.walls, origin[0], origin[1],
                                                   heading + self.column_angles)
        depth = dist * np.cos(self.column_angles)  # along the optical axis
        finite = np.isfinite(depth)
        safe_depth = np.where(finite, depth, 1e9)
        # height of the point each pixel sees on the column's wall
        z = r.height_m - self._rows[:, None] * safe_depth[None, :]
        on_wall = finite[None, :] & (z >= 0) & (z <= r.wall_height_m)
        s = along + (self.walls[index, 4] if len(self.walls) else 0.0)
        # a pixel's footprint on the wall (m), wider where the wall is seen obliquely
        footprint = safe_depth / r.focal_px / np.maximum(cos_inc, 0.15)
        image = np.where(self._rows[:, None] < 0, _SKY, _FLOOR) * np.ones((1, r.width_px))
        wall = np.full((r.height_px, r.width_px), 128.0)
        if self.texture_gain > 0:
            # textured only where the depth pipeline looks (the rows within TEXTURE_DEG of the
            # horizon; it matches +-10 deg): that halves the work, the rest of a wall is plain
            rows = self._textured
            zt = z[rows].astype(np.float32)
            st = s.astype(np.float32)[None, :]
            texture = np.zeros(zt.shape, dtype=np.float32)
            term = np.empty_like(texture)
            for ks, kz, phase, amplitude in _TEXTURE:
                wavelength = 2 * math.pi / math.hypot(ks, kz)
                fade = (amplitude * np.exp(-((2.0 * footprint / wavelength) ** 2))).astype(np.float32)
                if float(fade.max()) < 0.01:
                    continue  # finer than a pixel everywhere in this picture
                np.multiply(zt, np.float32(kz), out=term)
                term += st * np.float32(ks) + np.float32(phase)
                np.cos(term, out=term)
                term *= fade[None, :]
                texture += term
            wall[rows] = 128.0 + self.texture_gain * 16.0 * texture
        image = np.where(on_wall, wall, image) * self.brightness
        if r.noise_grey > 0:
            image = image + self._rng.normal(0.0, r.noise_grey, image.shape)
        return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def render_chessboard_pair(
    rig: StereoRig, rotation: Any, translation: Any, *, inner: tuple[int, int] = (9, 6),
    square_m: float = 0.025, supersample: int = 3, seed: int = 0,
) -> tuple[np.ndarray, np.ndarray]:
    """A printed chessboard held in front of the rig: (left, right) images.

    `rotation` (3x3) and `translation` (3) place the board in the left camera's frame (x right,
    y down, z ahead); the board's own x, y run along its rows and columns from its corner square;
    `inner` is the count of inner corners (columns, rows), and a white margin of one square
    surrounds the pattern, as on a printed board.
    """
    rot = np.asarray(rotation, dtype=np.float64)
    t = np.asarray(translation, dtype=np.float64)
    rng = np.random.default_rng(seed)
    n = rot[:, 2]
    cols, rows = inner[0] + 1, inner[1] + 1
    images = []
    for cam_x in (0.0, rig.baseline_m):
        centre = np.array([cam_x, 0.0, 0.0])
        acc = np.zeros((rig.height_px, rig.width_px))
        for i in range(supersample):
            for j in range(supersample):
                du, dv = (i + 0.5) / supersample - 0.5, (j + 0.5) / supersample - 0.5
                uu, vv = np.meshgrid(np.arange(rig.width_px) + du, np.arange(rig.height_px) + dv)
                d = np.stack([(uu - rig.cx) / rig.focal_px, (vv - rig.cy) / rig.focal_px,
                              np.ones_like(uu)], axis=-1)
                with np.errstate(divide="ignore", invalid="ignore"):
                    lam = float(n @ (t - centre)) / (d @ n)
                p = centre + lam[..., None] * d - t
                local = p @ rot  # board coordinates
                bx, by = local[..., 0] / square_m, local[..., 1] / square_m
                on_pattern = (bx >= 0) & (bx < cols) & (by >= 0) & (by < rows) & (lam > 0)
                on_board = (bx >= -1) & (bx < cols + 1) & (by >= -1) & (by < rows + 1) & (lam > 0)
                black = on_pattern & ((np.floor(bx) + np.floor(by)) % 2 == 0)
                value = np.where(on_board, np.where(black, 25.0, 230.0), 110.0)
                acc += value
        image = acc / supersample**2 + rng.normal(0.0, 1.0, acc.shape)
        images.append(np.clip(np.rint(image), 0, 255).astype(np.uint8))
    return images[0], images[1]
