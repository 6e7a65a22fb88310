"""Plane geometry for the simulated world: points, segments, ray casting, rectangle overlap.

Everything is in metres and radians; angles count counter-clockwise from the +x axis.
"""

from __future__ import annotations

import math
from typing import NamedTuple


class Point(NamedTuple):
    """A point in the plane (metres)."""

    x: float
    y: float


class Segment(NamedTuple):
    """A straight wall from `a` to `b`."""

    a: Point
    b: Point


class Pose(NamedTuple):
    """Where the car's centre is and where it points (radians, counter-clockwise from +x)."""

    x: float
    y: float
    heading: float


_EPS = 1e-12


def _cross(ax: float, ay: float, bx: float, by: float) -> float:
    return ax * by - ay * bx


def ray_distance(origin: Point, angle: float, segment: Segment) -> float | None:
    """Distance along the ray from `origin` at `angle` to `segment`, or None when it misses."""
    dx, dy = math.cos(angle), math.sin(angle)
    sx, sy = segment.b.x - segment.a.x, segment.b.y - segment.a.y
    denom = _cross(dx, dy, sx, sy)
    if abs(denom) < _EPS:
        return None  # parallel: a grazing wall gives no echo
    qx, qy = segment.a.x - origin.x, segment.a.y - origin.y
    t = _cross(qx, qy, sx, sy) / denom  # along the ray
    u = _cross(qx, qy, dx, dy) / denom  # along the segment, 0..1
    if t < 0 or u < -1e-9 or u > 1 + 1e-9:
        return None
    return t


def cast_hit(origin: Point, angle: float, walls: list[Segment]) -> tuple[float, Segment] | None:
    """The nearest wall along one ray and the distance to it, or None when nothing is hit."""
    best: tuple[float, Segment] | None = None
    for wall in walls:
        d = ray_distance(origin, angle, wall)
        if d is not None and (best is None or d < best[0]):
            best = (d, wall)
    return best


def cast(origin: Point, angle: float, walls: list[Segment]) -> float | None:
    """Distance to the nearest wall along one ray, or None when nothing is hit."""
    hit = cast_hit(origin, angle, walls)
    return None if hit is None else hit[0]


def incidence(angle: float, wall: Segment) -> float:
    """The angle (radians, 0..pi/2) between a ray at `angle` and the normal of `wall`."""
    length = math.hypot(wall.b.x - wall.a.x, wall.b.y - wall.a.y)
    if length < _EPS:
        return 0.0  # a point-like wall echoes from every side
    along = abs(_cross(math.cos(angle), math.sin(angle),
                       (wall.b.x - wall.a.x) / length, (wall.b.y - wall.a.y) / length))
    return math.acos(min(1.0, along))


def segments_intersect(p: Segment, q: Segment) -> bool:
    """True when two closed segments share at least one point."""

    def orient(a: Point, b: Point, c: Point) -> float:
        return _cross(b.x - a.x, b.y - a.y, c.x - a.x, c.y - a.y)

    def on_segment(a: Point, b: Point, c: Point) -> bool:
        return min(a.x, b.x) - 1e-12 <= c.x <= max(a.x, b.x) + 1e-12 and (
            min(a.y, b.y) - 1e-12 <= c.y <= max(a.y, b.y) + 1e-12
        )

    d1 = orient(q.a, q.b, p.a)
    d2 = orient(q.a, q.b, p.b)
    d3 = orient(p.a, p.b, q.a)
    d4 = orient(p.a, p.b, q.b)
    if ((d1 > 0 > d2) or (d1 < 0 < d2)) and ((d3 > 0 > d4) or (d3 < 0 < d4)):
        return True
    return (
        (abs(d1) < _EPS and on_segment(q.a, q.b, p.a))
        or (abs(d2) < _EPS and on_segment(q.a, q.b, p.b))
        or (abs(d3) < _EPS and on_segment(p.a, p.b, q.a))
        or (abs(d4) < _EPS and on_segment(p.a, p.b, q.b))
    )


def rectangle_corners(pose: Pose, length: float, width: float) -> list[Point]:
    """The four corners of a `length` x `width` rectangle centred on `pose`, counter-clockwise."""
    c, s = math.cos(pose.heading), math.sin(pose.heading)
    hl, hw = length / 2, width / 2
    return [
        Point(pose.x + c * lx - s * ly, pose.y + s * lx + c * ly)
        for lx, ly in ((hl, -hw), (hl, hw), (-hl, hw), (-hl, -hw))
    ]


def point_in_polygon(point: Point, corners: list[Point]) -> bool:
    """True when `point` lies inside the convex polygon `corners` (counter-clockwise)."""
    n = len(corners)
    for i in range(n):
        a, b = corners[i], corners[(i + 1) % n]
        if _cross(b.x - a.x, b.y - a.y, point.x - a.x, point.y - a.y) < 0:
            return False
    return True


def rectangle_hits(corners: list[Point], walls: list[Segment]) -> bool:
    """True when a wall crosses or lies inside the rectangle given by its corners."""
    edges = [Segment(corners[i], corners[(i + 1) % 4]) for i in range(4)]
    xs = [p.x for p in corners]
    ys = [p.y for p in corners]
    lo_x, hi_x, lo_y, hi_y = min(xs), max(xs), min(ys), max(ys)
    for wall in walls:
        # cheap bounding-box rejection first: most walls are far away
        if max(wall.a.x, wall.b.x) < lo_x or min(wall.a.x, wall.b.x) > hi_x:
            continue
        if max(wall.a.y, wall.b.y) < lo_y or min(wall.a.y, wall.b.y) > hi_y:
            continue
        if point_in_polygon(wall.a, corners) or any(segments_intersect(wall, e) for e in edges):
            return True
    return False


class WallIndex:
    """The walls in a uniform grid, so a ray or a footprint tests only the walls near it.

    A ray walks the grid's cells in order (Amanatides-Woo) and stops at the first cell that ends
    beyond its nearest hit; a footprint tests the walls of the cells under its bounding box. Both
    give exactly what the plain scans (`cast_hit`, `rectangle_hits`) give over the whole list:
    the nearest hit, ties going to the wall earlier in the list. Tracks with at most
    `LINEAR_MAX` walls are simply scanned. Cells are square, sized to about one wall per cell,
    at most `MAX_CELLS_PER_AXIS` along each axis; a wall that would span more than
    `MAX_CELLS_PER_WALL` cells is tested by every query instead.
    """

    LINEAR_MAX = 64
    MIN_CELL_M = 0.25
    MAX_CELLS_PER_AXIS = 4096
    MAX_CELLS_PER_WALL = 256
    _PAD = 1e-6  # walls are filed into every cell they come this close to (rounding)

    def __init__(self, walls: list[Segment]) -> None:
        self.walls = walls
        self._cells: dict[tuple[int, int], list[int]] = {}
        self._everywhere: list[int] = []
        self.gridded = len(walls) > self.LINEAR_MAX
        if not self.gridded:
            return
        xs = [p.x for wall in walls for p in wall]
        ys = [p.y for wall in walls for p in wall]
        self._x0, self._y0 = min(xs) - 2 * self._PAD, min(ys) - 2 * self._PAD
        width, height = max(xs) - self._x0 + 2 * self._PAD, max(ys) - self._y0 + 2 * self._PAD
        cell = max(self.MIN_CELL_M, math.sqrt(width * height / len(walls)))
        self._cw = max(cell, width / self.MAX_CELLS_PER_AXIS)
        self._ch = max(cell, height / self.MAX_CELLS_PER_AXIS)
        self._nx = max(1, math.ceil(width / self._cw))
        self._ny = max(1, math.ceil(height / self._ch))
        for index, wall in enumerate(walls):
            pad = self._PAD + 1e-9 * math.hypot(wall.b.x - wall.a.x, wall.b.y - wall.a.y)
            i0, j0 = self._cell_of(min(wall.a.x, wall.b.x) - pad, min(wall.a.y, wall.b.y) - pad)
            i1, j1 = self._cell_of(max(wall.a.x, wall.b.x) + pad, max(wall.a.y, wall.b.y) + pad)
            if (i1 - i0 + 1) * (j1 - j0 + 1) > self.MAX_CELLS_PER_WALL:
                self._everywhere.append(index)
                continue
            for i in range(i0, i1 + 1):
                for j in range(j0, j1 + 1):
                    self._cells.setdefault((i, j), []).append(index)

    def _cell_of(self, x: float, y: float) -> tuple[int, int]:
        i = min(self._nx - 1, max(0, math.floor((x - self._x0) / self._cw)))
        j = min(self._ny - 1, max(0, math.floor((y - self._y0) / self._ch)))
        return i, j

    def cast_hit(self, origin: Point, angle: float) -> tuple[float, Segment] | None:
        """`cast_hit(origin, angle, walls)` over this index's walls."""
        if not self.gridded:
            return cast_hit(origin, angle, self.walls)
        best: tuple[float, int] | None = None

        def test(index: int) -> None:
            nonlocal best
            d = ray_distance(origin, angle, self.walls[index])
            if d is not None and (best is None or (d, index) < best):
                best = (d, index)

        for index in self._everywhere:
            test(index)
        dx, dy = math.cos(angle), math.sin(angle)
        x1, y1 = self._x0 + self._nx * self._cw, self._y0 + self._ny * self._ch
        # where the ray enters the grid's box (slabs), and leaves it
        t_in, t_out = 0.0, math.inf
        for o, d, lo, hi in ((origin.x, dx, self._x0, x1), (origin.y, dy, self._y0, y1)):
            if abs(d) < _EPS:
                if not lo <= o <= hi:
                    t_in, t_out = 1.0, 0.0
                continue
            ta, tb = (lo - o) / d, (hi - o) / d
            t_in, t_out = max(t_in, min(ta, tb)), min(t_out, max(ta, tb))
        if t_in <= t_out:
            seen: set[int] = set()
            i, j = self._cell_of(origin.x + dx * t_in, origin.y + dy * t_in)
            step_i, step_j = (1 if dx > 0 else -1), (1 if dy > 0 else -1)
            # ray parameter at the next vertical / horizontal cell boundary, and per cell
            if abs(dx) < _EPS:
                t_x, delta_x = math.inf, math.inf
            else:
                edge_x = self._x0 + (i + (1 if dx > 0 else 0)) * self._cw
                t_x, delta_x = (edge_x - origin.x) / dx, self._cw / abs(dx)
            if abs(dy) < _EPS:
                t_y, delta_y = math.inf, math.inf
            else:
                edge_y = self._y0 + (j + (1 if dy > 0 else 0)) * self._ch
                t_y, delta_y = (edge_y - origin.y) / dy, self._ch / abs(dy)
            while 0 <= i < self._nx and 0 <= j < self._ny:
                for index in self._cells.get((i, j), ()):
                    if index not in seen:
                        seen.add(index)
                        test(index)
                t_exit = min(t_x, t_y)
                if best is not None and best[0] < t_exit - 1e-9:
                    break  # every later cell lies farther along the ray
                if t_exit > t_out + 1e-9:
                    break
                if t_x < t_y:
                    i += step_i
                    t_x += delta_x
                else:
                    j += step_j
                    t_y += delta_y
        return None if best is None else (best[0], self.walls[best[1]])

    def rectangle_hits(self, corners: list[Point]) -> bool:
        """`rectangle_hits(corners, walls)` over this index's walls."""
        if not self.gridded:
            return rectangle_hits(corners, self.walls)
        i0, j0 = self._cell_of(min(p.x for p in corners), min(p.y for p in corners))
        i1, j1 = self._cell_of(max(p.x for p in corners), max(p.y for p in corners))
        near = set(self._everywhere)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                near.update(self._cells.get((i, j), ()))
        return rectangle_hits(corners, [self.walls[index] for index in sorted(near)])
