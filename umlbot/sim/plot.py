"""The picture at the end of a run: the track, the car's path, its sonar pings (matplotlib, Agg)."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import TYPE_CHECKING, Any

from umlbot.base.errors import SimError
from umlbot.sim.geometry import rectangle_corners
from umlbot.sim.world import CarSpec, World

if TYPE_CHECKING:
    from umlbot.sim.track import Track

#: pings drawn at most (the newest); a long run makes thousands.
MAX_PINGS = 1500


def check_plot_path(path: str | Path) -> Path:
    """The plot file as a Path; SimError unless it ends in .png, .svg or .pdf."""
    out = Path(path)
    if out.suffix.lower() not in (".png", ".svg", ".pdf"):
        raise SimError(f"plot file {out} must end in .png, .svg or .pdf")
    return out


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")  # no display needed; also safe in threads and on servers
    import matplotlib.pyplot as plt

    return plt


def _draw_walls_and_goal(ax: Any, track: Track) -> None:
    from matplotlib.patches import Rectangle

    goal = track.goal
    ax.add_patch(Rectangle((goal.x_min, goal.y_min), goal.x_max - goal.x_min, goal.y_max - goal.y_min,
                           color="tab:green", alpha=0.25, label="goal"))
    for i, seg in enumerate(track.segments):
        ax.plot([seg.a.x, seg.b.x], [seg.a.y, seg.b.y], color="black", linewidth=2.5,
                label="wall" if i == 0 else None)


def finish_figure(fig: Any, ax: Any, out: Path) -> None:
    """Axes, grid, and the legend outside the axes (right of them), where it hides nothing."""
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize="small")
    fig.savefig(out, dpi=110, bbox_inches="tight")


def plot_track(track: Track, path: str | Path, problem: str = "",
               spot: tuple[float, float] | None = None, car: CarSpec | None = None) -> Path:
    """Draw a track alone — walls, goal, the car's footprint at the start and, when given, the
    spot of its `problem` — into `path` and return the path: the picture of a refused track."""
    from matplotlib.patches import Polygon

    plt = _pyplot()
    car = car or CarSpec()
    out = check_plot_path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(7, 7))
    try:
        _draw_walls_and_goal(ax, track)
        start = track.start
        ax.plot([start.x], [start.y], "o", color="tab:blue", label="start")
        ax.add_patch(Polygon(rectangle_corners(start.pose, car.length_m, car.width_m), closed=True,
                             fill=False, edgecolor="tab:blue", linewidth=1.5, label="car at the start"))
        if spot is not None:
            ax.plot([spot[0]], [spot[1]], "x", color="tab:red", markersize=12, mew=2.5, label="problem")
        ax.set_title(f"{track.name}: refused" + ("\n" + textwrap.fill(problem, 80) if problem else ""),
                     fontsize="small")
        finish_figure(fig, ax, out)
    finally:
        plt.close(fig)
    return out


def plot_run(world: World, path: str | Path, title: str = "") -> Path:
    """Draw the run into `path` (.png, .svg or .pdf by its suffix) and return the path."""
    from matplotlib.patches import Polygon

    plt = _pyplot()
    out = check_plot_path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    track = world.track
    snap = world.snapshot()
    fig, ax = plt.subplots(figsize=(7, 7))
    try:
        _draw_walls_and_goal(ax, track)
        # each echo where it came from: the point of the wall its ray met (on the wall, never
        # beyond it; the ray may lie off the beam's centre); a ping recorded without that point
        # (an older trace) is drawn hollow at the measured range along the beam's centre
        echoes: list[tuple[float, float]] = []
        unplaced: list[tuple[float, float]] = []
        for ping in world.pings[-MAX_PINGS:]:
            if ping.distance_cm is None:
                continue
            if ping.hit is not None:
                hx, hy = ping.hit
                echoes.append((hx, hy))
            else:
                d = ping.distance_cm / 100.0
                hx, hy = ping.origin.x + d * math.cos(ping.angle), ping.origin.y + d * math.sin(ping.angle)
                unplaced.append((hx, hy))
            ax.plot([ping.origin.x, hx], [ping.origin.y, hy], color="tab:orange", alpha=0.06, linewidth=0.8)
        if echoes:
            ax.plot([p[0] for p in echoes], [p[1] for p in echoes], ".", color="tab:orange",
                    markersize=3, alpha=0.6, label="echo (where it came from)")
        if unplaced:
            ax.plot([p[0] for p in unplaced], [p[1] for p in unplaced], "o", markerfacecolor="none",
                    color="tab:purple", markersize=3, alpha=0.5, label="echo (range along the beam)")
        xs = [p[1] for p in world.path]
        ys = [p[2] for p in world.path]
        ax.plot(xs, ys, color="tab:blue", linewidth=1.5, label="path")
        start = track.start
        ax.plot([start.x], [start.y], "o", color="tab:blue", label="start")
        ax.add_patch(Polygon(rectangle_corners(snap.pose, world.car.length_m, world.car.width_m),
                             closed=True, fill=False, edgecolor="tab:blue", linewidth=1.5))
        for i, (cx, cy) in enumerate(world.collision_points):
            ax.plot([cx], [cy], "x", color="tab:red", markersize=10, mew=2,
                    label="collision" if i == 0 else None)
        outcome = "goal reached" if snap.goal_reached else "goal not reached"
        ax.set_title(title or f"{track.name}: {outcome}, {snap.collisions} collision(s), "
                     f"{snap.distance_m:.2f} m in {snap.time_s:.1f} s")
        finish_figure(fig, ax, out)
    finally:
        plt.close(fig)
    return out
