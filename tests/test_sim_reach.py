"""The goal check made when a run loads a track: a goal the car cannot get to is refused."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from umlbot.base.errors import SimError
from umlbot.sim import CarSpec, SimOptions, run_sim
from umlbot.sim.reach import goal_problem
from umlbot.sim.track import load_track, parse_track, tracks_dir

ROOT = Path(__file__).resolve().parents[1]
WIDTH = CarSpec().width_m

#: a 0.7 m corridor north, 1.5 m long, closed at both ends; the goal at its far end
BOX = """
name: box
start: {x: 0, y: 0.3, heading_deg: 90}
goal: {x_min: -0.3, x_max: 0.3, y_min: 1.2, y_max: 1.45}
walls:
  - [[-0.35, 0.05], [-0.35, 1.5], [0.35, 1.5], [0.35, 0.05], [-0.35, 0.05]]
"""


def _behind_gap(gap_m: float, slanted: bool = False) -> str:
    """The box with a cross wall at y = 0.8 leaving a gap of `gap_m` on its right-hand side.

    `slanted`: the whole track turned by 45° about the origin (the goal: a 0.1 m square round
    the turned centre of the first), so the gap lies across the grid's diagonal.
    """
    text = BOX + f"  - [[-0.35, 0.8], [{0.35 - gap_m:.4f}, 0.8]]\n"
    if not slanted:
        return text
    track = parse_track(text)
    c = s = math.sqrt(0.5)

    def turned(x: float, y: float) -> str:
        return f"[{c * x - s * y:.4f}, {s * x + c * y:.4f}]"

    gx, gy = c * 0.0 - s * 1.3, s * 0.0 + c * 1.3
    walls = "".join(f"  - [{', '.join(turned(x, y) for x, y in line)}]\n" for line in track.walls)
    return (f"name: turned\nstart: {{x: {-s * 0.3:.4f}, y: {c * 0.3:.4f}, heading_deg: 135}}\n"
            f"goal: {{x_min: {gx - 0.05:.4f}, x_max: {gx + 0.05:.4f}, "
            f"y_min: {gy - 0.05:.4f}, y_max: {gy + 0.05:.4f}}}\n"
            f"walls:\n{walls}")


@pytest.mark.parametrize("track", sorted(tracks_dir().glob("*.yaml")), ids=lambda p: p.stem)
def test_every_bundled_track_is_accepted(track: Path) -> None:
    assert goal_problem(load_track(track), WIDTH) is None


def test_a_goal_outside_closed_walls_is_refused() -> None:
    track = parse_track(BOX.replace("y_min: 1.2, y_max: 1.45", "y_min: 3.0, y_max: 3.5"))
    problem = goal_problem(track, WIDTH)
    assert problem is not None
    assert "not reachable from the start for a car 0.15 m wide" in problem
    assert "outside the walls" in problem


def test_a_goal_walled_off_inside_the_track_is_refused() -> None:
    walled = BOX + "  - [[-0.35, 1.1], [0.35, 1.1]]\n"
    problem = goal_problem(parse_track(walled), WIDTH)
    assert problem is not None and problem.endswith("walls close it off from the start"), problem
    assert "outside" not in problem


@pytest.mark.parametrize("slanted", [False, True], ids=["square", "45deg"])
def test_a_goal_behind_a_gap_narrower_than_the_car_is_refused(slanted: bool) -> None:
    problem = goal_problem(parse_track(_behind_gap(0.10, slanted)), WIDTH)
    assert problem is not None
    assert "gap narrower than the car (0.15 m)" in problem


@pytest.mark.parametrize("slanted", [False, True], ids=["square", "45deg"])
@pytest.mark.parametrize("gap_m", [0.15, 0.16, 0.30])
def test_a_gap_as_wide_as_the_car_is_never_refused(gap_m: float, slanted: bool) -> None:
    assert goal_problem(parse_track(_behind_gap(gap_m, slanted)), WIDTH) is None


def test_the_gap_is_measured_against_the_car_given() -> None:
    track = parse_track(_behind_gap(0.25))
    assert goal_problem(track, WIDTH) is None
    problem = goal_problem(track, 0.30)
    assert problem is not None and "for a car 0.3 m wide" in problem


def test_a_goal_on_a_wall_is_refused() -> None:
    # 4 cm deep along the far wall: no point of it is 7.5 cm from the wall
    on_wall = BOX.replace("y_min: 1.2, y_max: 1.45", "y_min: 1.46, y_max: 1.5")
    problem = goal_problem(parse_track(on_wall), WIDTH)
    assert problem is not None and "the goal region lies on a wall" in problem


def test_an_open_track_is_accepted_wherever_its_goal_is() -> None:
    # two walls, nothing closed: the car may drive round them
    open_track = parse_track("name: open\nstart: {x: 0, y: 0.3}\n"
                             "goal: {x_min: 5, x_max: 6, y_min: -3, y_max: -2}\n"
                             "walls: [[[-0.4, 0], [-0.4, 2]], [[0.4, 0], [0.4, 2]]]\n")
    assert goal_problem(open_track, WIDTH) is None


def test_a_huge_track_is_not_checked_and_costs_no_time(tmp_path: Path) -> None:
    # 60 000 walls over 60 km: the grid would be far too big, the check is skipped
    lines = ["name: big", "start: {x: 0, y: 0.3, heading_deg: 90}",
             "goal: {x_min: 5, x_max: 6, y_min: 5, y_max: 6}", "walls:",
             "  - [[-0.4, 0], [-0.4, 2.5], [0.4, 2.5], [0.4, 0], [-0.4, 0]]"]
    lines += [f"  - [[{x}, 10], [{x}, 11]]" for x in range(10, 60_010)]
    track = parse_track("\n".join(lines) + "\n")
    started = time.perf_counter()
    assert goal_problem(track, WIDTH) is None  # its goal is outside the box, but not looked at
    assert time.perf_counter() - started < 1.0


def test_a_large_track_is_checked_on_coarser_cells() -> None:
    # 60 m x 40 m (6 M cells of 2 cm): checked on cells of about 3.5 cm; the goal is boxed in
    track = parse_track("name: hall\nstart: {x: 1, y: 1}\n"
                        "goal: {x_min: 50, x_max: 51, y_min: 30, y_max: 31}\n"
                        "walls:\n  - [[0, 0], [0, 40], [60, 40], [60, 0], [0, 0]]\n"
                        "  - [[49, 29], [49, 32], [52, 32], [52, 29], [49, 29]]\n")
    started = time.perf_counter()
    problem = goal_problem(track, WIDTH)
    assert problem is not None and problem.endswith("walls close it off from the start")
    assert time.perf_counter() - started < 5.0


def test_a_run_refuses_the_track_and_names_its_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad_goal.yaml"
    bad.write_text(_behind_gap(0.10), encoding="utf-8")
    with pytest.raises(SimError) as excinfo:
        run_sim(SimOptions(model=ROOT / "models" / "robot_car", track=bad, port=0))
    message = str(excinfo.value)
    assert message.startswith(f"{bad}: goal region not reachable"), message
    assert "narrower than the car" in message
