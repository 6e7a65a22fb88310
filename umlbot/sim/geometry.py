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
