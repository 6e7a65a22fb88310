"""Track files as a user writes and names them: where `--track` looks, what a mistake in a file
says, warnings, refused tracks drawn with `--plot`, and the run's wall-time bounds."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

from umlbot.base.errors import SimError
from umlbot.sim import CarSpec
from umlbot.sim.reach import goal_problem_at, start_problem
from umlbot.sim.runner import WALL_STALL_S, SimOptions, WallGuard, run_sim, wall_limit_s
from umlbot.sim.track import bundled_tracks, find_track, load_track, parse_track, track_warnings

ROOT = Path(__file__).resolve().parents[1]
CAR = CarSpec()

#: a 0.6 m x 2.45 m box, the goal at its far end (the reviewer's bad tracks are variations of it)
BOX = """\
name: box
start: {x: 0, y: 0.3, heading_deg: 90}
goal: {x_min: -0.3, x_max: 0.3, y_min: 2.0, y_max: 2.5}
walls:
  - [[-0.3, 0.05], [-0.3, 2.5], [0.3, 2.5], [0.3, 0.05], [-0.3, 0.05]]
"""


# --- where --track looks ------------------------------------------------------------------------


def test_a_bare_name_is_a_bundled_track() -> None:
    assert find_track("zigzag") == bundled_tracks()["zigzag"]


def test_an_existing_file_is_taken_even_with_a_bundled_name(tmp_path: Path,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    mine = tmp_path / "s_bend.yaml"
    mine.write_text(BOX, encoding="utf-8")
    assert find_track(mine) == mine
    monkeypatch.chdir(tmp_path)
    (tmp_path / "corridor").write_text(BOX, encoding="utf-8")
    assert find_track("corridor") == Path("corridor")  # a file that is there comes first


@pytest.mark.parametrize("given", ["/tmp/x/nothere/s_bend.yaml", "zigzag.yml", "tracks/corridor",
                                   "ZIGZAG.YAML"])
def test_a_path_that_is_not_there_is_an_error_naming_it(given: str, tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SimError) as excinfo:
        find_track(given)
    message = str(excinfo.value)
    assert f"no track file {given!r}: no such file" in message
    stem = Path(given).stem
    if stem in bundled_tracks():
        assert f"the bundled track of that name is '--track {stem}'" in message
    else:
        assert "bundled" not in message


def test_an_unknown_bare_name_lists_the_bundled_tracks() -> None:
    with pytest.raises(SimError, match=r"no track 'zigzagg': .*bundled: .*zigzag"):
        find_track("zigzagg")


def test_the_cli_refuses_a_mistyped_path_and_its_help_names_every_plot_format(tmp_path: Path) -> None:
    from umlbot.cli import cli

    runner = CliRunner()
    result = runner.invoke(cli, ["sim", str(ROOT / "models" / "robot_car"), "--track",
                                  str(tmp_path / "nothere" / "s_bend.yaml")])
    assert isinstance(result.exception, SimError)  # `umlbot` prints it as `error: …`, exit 1
    assert f"no track file '{tmp_path / 'nothere' / 's_bend.yaml'}'" in str(result.exception)
    help_text = " ".join(runner.invoke(cli, ["sim", "--help"]).output.split())
    assert ".png, .svg or .pdf" in help_text
    assert "PNG or SVG" not in help_text


# --- what a mistake in a file says ------------------------------------------------------------


def test_every_problem_of_a_track_is_reported_at_once_each_at_its_line() -> None:
    text = ("name: typo\nstart: {x: 0, y: 0.3, heading: 90}\n"
            "goal: {xmin: -0.3, x_max: 0.3, y_min: 2.0, y_max: 2.5}\nwalls:\n"
            "  - [[-0.3, 0.05], [-0.3, 2.5], [0.3, 2.5]]\n"
            "  - [[0.1, 1.0]]\n"
            "  - [0.1, 1.0]\n")
    with pytest.raises(SimError) as excinfo:
        parse_track(text, "typo.yaml")
    message = str(excinfo.value)
    assert message.startswith("typo.yaml:2:"), message
    assert "start.heading: Extra inputs are not permitted" in message
    assert "goal.x_min: Field required" in message
    assert "walls.1: Value error, a wall needs at least 2 points ([x, y]), got 1 (6:5)" in message
    assert "walls.2: Value error, a wall is a list of [x, y] points, such as [[0, 0], [1, 0]], " \
           "not one point [0.1, 1.0] (7:5)" in message


def test_a_wall_of_one_point_is_an_error_at_that_wall() -> None:
    with pytest.raises(SimError, match=r"^t.yaml:6:5: invalid track: walls.1: .*at least 2 points"):
        parse_track(BOX + "  - [[0.1, 1.0]]\n", "t.yaml")


def test_the_docstring_example_is_a_valid_track_with_its_defaults() -> None:
    from umlbot.sim import track as module

    example = (module.__doc__ or "").split("::")[1].split("The goal")[0]
    parsed = parse_track("\n".join(line[4:] for line in example.splitlines()))
    assert parsed.walls[1][2] == (-1.6, 2.0)
    assert parse_track(BOX.replace(", heading_deg: 90", "")).start.heading_deg == 90.0


# --- warnings -----------------------------------------------------------------------------------


def test_a_track_in_centimetres_and_a_start_in_the_goal_are_warned_about() -> None:
    cm = parse_track("name: cm\nstart: {x: 0, y: 30}\ngoal: {x_min: -30, x_max: 30, y_min: 200, y_max: 250}\n"
                     "walls:\n  - [[-30, 5], [-30, 250], [30, 250], [30, 5], [-30, 5]]\n")
    assert track_warnings(cm) == [
        "the track spans 245 m: tracks are in metres (was it written in centimetres?)"]
    in_goal = parse_track(BOX.replace("y_min: 2.0", "y_min: 0.05"))
    assert track_warnings(in_goal) == ["the start (0, 0.3) is inside the goal region: the run ends at once "
                                       "with the goal reached"]
    assert track_warnings(parse_track(BOX)) == []
    for name, path in bundled_tracks().items():
        assert track_warnings(load_track(path)) == [], name


# --- refused tracks -----------------------------------------------------------------------------


def test_a_start_on_a_wall_names_the_wall_its_line_and_where(tmp_path: Path) -> None:
    path = tmp_path / "startwall.yaml"
    path.write_text(BOX.replace("y: 0.3", "y: 0.1") + "  - [[1, 1], [2, 1]]\n", encoding="utf-8")
    problem = start_problem(load_track(path), CAR.length_m, CAR.width_m)
    assert problem is not None
    assert f"overlaps wall 0 ({path}:5) near (0.00, 0.05)" in problem.message
    assert problem.spot == pytest.approx((0.0, 0.05))
    side = BOX + "  - [[0.6, 0.2], [0.05, 0.2]]\n"  # the second wall pokes into the car's side
    problem = start_problem(parse_track(side, "side.yaml"), CAR.length_m, CAR.width_m)
    assert problem is not None and "overlaps wall 1 (side.yaml:6) near (0.05, 0.20)" in problem.message
    assert start_problem(parse_track(BOX), CAR.length_m, CAR.width_m) is None


def test_a_start_outside_the_walls_is_called_the_start() -> None:
    problem = goal_problem_at(parse_track(BOX.replace("x: 0, y: 0.3", "x: 2, y: 0.3")), CAR.width_m)
    assert problem is not None
    assert problem.message.startswith("the start (2, 0.3) lies outside the walls"), problem.message
    assert "goal region lies outside" not in problem.message
    assert problem.spot == (2.0, 0.3)
    goal_out = goal_problem_at(parse_track(BOX.replace("x_min: -0.3, x_max: 0.3", "x_min: 1.0, x_max: 1.5")),
                               CAR.width_m)
    assert goal_out is not None and goal_out.message.endswith("the goal region lies outside the walls")


@pytest.mark.parametrize(("change", "words"), [
    (("y: 0.3", "y: 0.1"), "start footprint"),
    (("x: 0, y: 0.3", "x: 2, y: 0.3"), "the start (2, 0.3) lies outside the walls"),
    (("y_min: 2.0", "y_min: 2.0"), "walls close it off"),
], ids=["start-on-wall", "start-outside", "walled-off"])
@pytest.mark.parametrize("suffix", [".png", ".svg", ".pdf"])
def test_a_refused_track_is_drawn_with_plot(change: tuple[str, str], words: str, suffix: str,
                                            tmp_path: Path) -> None:
    path = tmp_path / "bad.yaml"
    text = BOX.replace(*change)
    if words == "walls close it off":
        text += "  - [[-0.3, 1.5], [0.3, 1.5]]\n"
    path.write_text(text, encoding="utf-8")
    picture = tmp_path / "out" / f"bad{suffix}"
    with pytest.raises(SimError) as excinfo:
        run_sim(SimOptions(model=ROOT / "models" / "robot_car", track=path, port=0, plot=picture))
    message = str(excinfo.value)
    assert message.startswith(f"{path}: ") and words in message, message
    assert message.endswith(f"(the track is drawn in {picture})")
    magic = {".png": b"\x89PNG", ".svg": b"<?xml", ".pdf": b"%PDF"}[suffix]
    assert picture.read_bytes().startswith(magic)


def test_the_legend_lies_outside_the_axes(tmp_path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from umlbot.sim import plot

    fig, ax = plt.subplots(figsize=(7, 7))
    try:
        ax.plot([0, 1], [0, 1], "o", label="start")
        plot.finish_figure(fig, ax, tmp_path / "x.png")
        renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
        drawn = ax.get_legend()
        assert drawn is not None
        legend = drawn.get_window_extent(renderer)
        axes = ax.get_window_extent(renderer)
        assert legend.x0 > axes.x1, (legend, axes)
    finally:
        plt.close(fig)


# --- wall-time bounds ---------------------------------------------------------------------------


def test_a_run_whose_sim_time_moves_is_not_cut_however_slowly_it_moves() -> None:
    # --speed 100 --timeout 600: the old bound was 2 x 600 / 100 + 10 = 22 s, and a world that
    # keeps up 15x real time needs 40 s; the run must end at its sim time-out at any speed
    for speed in (1.0, 10.0, 100.0, 2000.0):
        guard = WallGuard(600.0, speed)
        wall = 0.0
        for step in range(1, 4001):  # 10 ms of sim time per wall second: 1/100 real time
            wall = step * 0.1
            assert guard.check(wall, step * 0.001 * 15) is None, (speed, wall)
        assert wall == 400.0


def test_a_run_whose_sim_time_stands_still_ends_after_the_stall_bound() -> None:
    guard = WallGuard(600.0, 100.0, stall_s=30.0)
    assert guard.check(0.0, 0.0) is None
    assert guard.check(10.0, 5.0) is None
    assert guard.check(39.9, 5.0) is None
    cut = guard.check(40.0, 5.0)
    assert cut is not None and "sim time stood still at 5.0 s for 30 s of wall time" in cut
    assert WallGuard(1.0, 1.0).stall_s == WALL_STALL_S


def test_the_safety_net_does_not_shrink_with_speed() -> None:
    assert wall_limit_s(600.0, 100.0) == wall_limit_s(600.0, 1.0) == 2 * 600 + 60
    assert wall_limit_s(600.0, 0.5) == 2 * 1200 + 60  # paced slower than real time: more
    guard = WallGuard(10.0, 100.0, stall_s=1e9)
    sim = 0.0
    for wall in range(1, 80):
        sim += 0.01
        assert guard.check(float(wall), sim) is None
    cut = guard.check(80.0, sim + 0.01)
    assert cut is not None and "wall-time limit of 80 s reached" in cut
