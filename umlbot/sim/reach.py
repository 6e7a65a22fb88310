"""Can the car reach the goal at all? A grid check of a track, made when a run loads it.

The walls are drawn on a grid of `CELL_M` (2 cm) cells and inflated by the car's half-width: a
cell is blocked when its centre lies closer to a wall than half the car's width (less half a
cell, so the grid never closes a gap the car fits through). The free cells reachable from the
start (8-neighbours) are flooded; when none of the cells under the goal rectangle is reached, the
track is refused. The check is necessary, not sufficient: a car that fits through every gap may
still be unable to turn into one (it is 0.26 m long), which only a run shows.

The flood works on runs of free cells along each row, not on single cells, so a track of a few
square metres is checked in milliseconds. The grid has at most `MAX_CELLS` cells: a bigger track
is checked on coarser cells, up to `MAX_CELL_M`; a track larger still (about 3 000 m², such as
walls spread over kilometres) is not checked.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

from umlbot.base.logs import get_logger
from umlbot.sim.geometry import Segment, rectangle_corners, rectangle_hits

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from umlbot.sim.track import Track

log = get_logger(__name__)

CELL_M = 0.02
MAX_CELL_M = 0.04  # coarser, and a wall inflated by 6.5 cm could let the flood slip across it
MAX_CELLS = 2_000_000

#: runs of free cells of one row: parallel lists of first and last column (inclusive), sorted
_Runs = tuple[list[int], list[int]]


class _Grid:
    """The track's bounding box (walls, start, goal, with a free border) in square cells."""

    def __init__(self, track: Track, pad_m: float) -> None:
        start, goal = track.start, track.goal
        xs = [p[0] for line in track.walls for p in line] + [start.x, goal.x_min, goal.x_max]
        ys = [p[1] for line in track.walls for p in line] + [start.y, goal.y_min, goal.y_max]
        self.x0, self.y0 = min(xs) - pad_m, min(ys) - pad_m
        width, height = max(xs) + pad_m - self.x0, max(ys) + pad_m - self.y0
        self.cell = max(CELL_M, math.sqrt(width * height / MAX_CELLS))
        self.nx = math.ceil(width / self.cell) + 1
        self.ny = math.ceil(height / self.cell) + 1

    def col(self, x: float) -> int:
        return min(self.nx - 1, max(0, math.floor((x - self.x0) / self.cell)))

    def row(self, y: float) -> int:
        return min(self.ny - 1, max(0, math.floor((y - self.y0) / self.cell)))


def _blocked(grid: _Grid, walls: list[Segment], radius_m: float) -> npt.NDArray[np.bool_]:
    """Cells whose centre lies closer than `radius_m` to a wall."""
    import numpy as np

    blocked = np.zeros((grid.ny, grid.nx), dtype=bool)
    h, r2 = grid.cell, radius_m * radius_m
    for wall in walls:
        ax, ay, bx, by = wall.a.x, wall.a.y, wall.b.x, wall.b.y
        i0, i1 = grid.col(min(ax, bx) - radius_m), grid.col(max(ax, bx) + radius_m)
        j0, j1 = grid.row(min(ay, by) - radius_m), grid.row(max(ay, by) + radius_m)
        cx = grid.x0 + (np.arange(i0, i1 + 1) + 0.5) * h
        cy = grid.y0 + (np.arange(j0, j1 + 1) + 0.5) * h
        px, py = cx[None, :] - ax, cy[:, None] - ay
        dx, dy = bx - ax, by - ay
        length2 = dx * dx + dy * dy
        # the nearest point of the wall to each cell centre: a fraction t along it
        t = np.clip((px * dx + py * dy) / length2, 0.0, 1.0) if length2 > 0 else np.zeros_like(px * py)
        qx, qy = px - t * dx, py - t * dy
        blocked[j0:j1 + 1, i0:i1 + 1] |= qx * qx + qy * qy < r2
    return blocked


def _runs(blocked: npt.NDArray[np.bool_]) -> list[_Runs]:
    """Per row, the runs of free cells."""
    import numpy as np

    rows: list[_Runs] = []
    for line in blocked:
        edges = np.diff(np.concatenate(([1], line.astype(np.int8), [1])))
        starts = np.flatnonzero(edges == -1)
        ends = np.flatnonzero(edges == 1) - 1
        rows.append((starts.tolist(), ends.tolist()))
    return rows


def _overlapping(runs: _Runs, lo: int, hi: int) -> range:
    """Indices of the runs that share a column with lo..hi."""
    starts, ends = runs
    first = bisect_left(ends, lo)
    last = bisect_left(starts, hi + 1)
    return range(first, last)


def _flood(rows: list[_Runs], seed_row: int, seed_lo: int, seed_hi: int,
           diagonal: bool) -> set[tuple[int, int]]:
    """The runs (row, index) connected to the free cells of rows seed_row±1, columns seed_lo..hi."""
    reach: set[tuple[int, int]] = set()
    todo: deque[tuple[int, int]] = deque()
    for j in range(max(0, seed_row - 1), min(len(rows), seed_row + 2)):
        for k in _overlapping(rows[j], seed_lo, seed_hi):
            reach.add((j, k))
            todo.append((j, k))
    grow = 1 if diagonal else 0
    while todo:
        j, k = todo.popleft()
        lo, hi = rows[j][0][k] - grow, rows[j][1][k] + grow
        for nj in (j - 1, j + 1):
            if 0 <= nj < len(rows):
                for nk in _overlapping(rows[nj], lo, hi):
                    if (nj, nk) not in reach:
                        reach.add((nj, nk))
                        todo.append((nj, nk))
    return reach


def _reaches(rows: list[_Runs], reach: set[tuple[int, int]], rows_lo: int, rows_hi: int,
             cols_lo: int, cols_hi: int) -> bool:
    return any((j, k) in reach for j in range(rows_lo, rows_hi + 1)
               for k in _overlapping(rows[j], cols_lo, cols_hi))


@dataclass(frozen=True)
class TrackProblem:
    """Why a track is refused, and the spot the problem is at when there is one (for the picture)."""

    message: str
    spot: tuple[float, float] | None = None


def _nearest(segment: Segment, x: float, y: float) -> tuple[float, float]:
    ax, ay, bx, by = segment.a.x, segment.a.y, segment.b.x, segment.b.y
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0 else min(1.0, max(0.0, ((x - ax) * dx + (y - ay) * dy) / length2))
    return ax + t * dx, ay + t * dy


def start_problem(track: Track, car_length_m: float, car_width_m: float) -> TrackProblem | None:
    """The wall the car's footprint at the start overlaps (its index, file line and the point of
    it nearest the car's centre), or None."""
    start = track.start
    corners = rectangle_corners(start.pose, car_length_m, car_width_m)
    for index, segment in enumerate(track.segments):
        if rectangle_hits(corners, [segment]):
            wall = track.wall_of_segment(index)
            spot = _nearest(segment, start.x, start.y)
            return TrackProblem(
                f"the car's start footprint ({car_length_m:g} m x {car_width_m:g} m round "
                f"({start.x:g}, {start.y:g}), heading {start.heading_deg:g}°) overlaps "
                f"{track.wall_place(wall)} near ({spot[0]:.2f}, {spot[1]:.2f}): move the start "
                f"at least {math.hypot(car_length_m, car_width_m) / 2:.2f} m from every wall", spot)
    return None


def goal_problem(track: Track, car_width_m: float) -> str | None:
    """Why a car `car_width_m` wide cannot reach the goal from the start, or None.

    None also when the track is too large for the grid (see the module docstring).
    """
    problem = goal_problem_at(track, car_width_m)
    return None if problem is None else problem.message


def goal_problem_at(track: Track, car_width_m: float) -> TrackProblem | None:
    """`goal_problem` with the spot it is at: the start or the goal when one lies outside the
    walls, the goal when it lies on a wall, none when the way is shut somewhere between."""
    half = car_width_m / 2
    grid = _Grid(track, pad_m=half + 3 * CELL_M)
    if grid.cell > MAX_CELL_M:
        log.info("track too large for the goal check: skipped", track=track.name,
                 cells=round(grid.nx * grid.ny))
        return None
    walls = track.segments
    goal = track.goal
    gi0, gi1 = grid.col(goal.x_min), grid.col(goal.x_max)
    gj0, gj1 = grid.row(goal.y_min), grid.row(goal.y_max)
    si, sj = grid.col(track.start.x), grid.row(track.start.y)
    width = f"{car_width_m:g} m"
    # the car's centre can stand where it is half the car's width from every wall
    rows = _runs(_blocked(grid, walls, half - grid.cell / 2))
    goal_centre = ((goal.x_min + goal.x_max) / 2, (goal.y_min + goal.y_max) / 2)
    if not any(_overlapping(rows[j], gi0, gi1) for j in range(gj0, gj1 + 1)):
        return TrackProblem(f"the goal region lies on a wall: no point of it is {half * 100:g} cm from "
                            f"every wall, so a car {width} wide cannot stand in it", goal_centre)
    reach = _flood(rows, sj, si - 1, si + 1, diagonal=True)
    if not reach:  # no free cell next to the start: the start check (its footprint) judges that
        return None
    if _reaches(rows, reach, gj0, gj1, gi0, gi1):
        return None
    # would a point get there? walls a cell thick each side, 4-neighbours: only a real gap lets it through
    point_rows = _runs(_blocked(grid, walls, grid.cell))
    point_reach = _flood(point_rows, sj, si - 1, si + 1, diagonal=False)
    prefix = f"goal region not reachable from the start for a car {width} wide: "
    if _reaches(point_rows, point_reach, gj0, gj1, gi0, gi1):
        return TrackProblem(prefix + f"every way to it passes a gap narrower than the car ({width})")
    # outside the walls: connected to the free border of the grid (row 0 is free: the grid's pad
    # is wider than a wall's inflation)
    outside = _flood(point_rows, 0, 0, 0, diagonal=False)
    start = track.start
    if point_reach & outside:
        return TrackProblem(f"the start ({start.x:g}, {start.y:g}) lies outside the walls: the goal "
                            "region is not reachable from it", (start.x, start.y))
    if _reaches(point_rows, outside, gj0, gj1, gi0, gi1):
        return TrackProblem(prefix + "the goal region lies outside the walls", goal_centre)
    return TrackProblem(prefix + "walls close it off from the start")
