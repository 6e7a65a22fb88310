"""The track file: a named 2D arena of walls, a start pose and a goal region (YAML, metres).

::

    name: left_bend
    description: a corridor that turns left          # optional
    start: {x: 0.0, y: 0.3, heading_deg: 90}          # car centre; 0° = +x, 90° = +y
    goal: {x_min: -1.6, x_max: -1.2, y_min: 2.0, y_max: 2.8}
    walls:                                           # each wall is a polyline of >= 2 points
      - [[-0.4, 0.0], [0.4, 0.0]]
      - [[-0.4, 0.0], [-0.4, 2.0], [-1.6, 2.0]]

The goal is reached when the car's centre is inside the goal rectangle.
"""

from __future__ import annotations

import math
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from umlbot.errors import SimError
from umlbot.files import load_yaml_node, read_text, validation_problem, where
from umlbot.sim.geometry import Point, Pose, Segment


class StartPose(BaseModel):
    """Where the car starts: centre in metres and heading in degrees (0 = +x, counter-clockwise)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    x: float
    y: float
    heading_deg: float = 90.0

    @property
    def pose(self) -> Pose:
        return Pose(self.x, self.y, math.radians(self.heading_deg))


class GoalRegion(BaseModel):
    """An axis-aligned rectangle; the run succeeds when the car's centre enters it."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    x_min: float
    x_max: float
    y_min: float
    y_max: float

    @model_validator(mode="after")
    def _not_empty(self) -> GoalRegion:
        if not (self.x_min < self.x_max and self.y_min < self.y_max):
            raise ValueError("goal needs x_min < x_max and y_min < y_max")
        return self

    def contains(self, x: float, y: float) -> bool:
        return self.x_min <= x <= self.x_max and self.y_min <= y <= self.y_max


class Track(BaseModel):
    """A track as read from its file; `segments` are the walls split into straight pieces."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(min_length=1)
    description: str = ""
    start: StartPose
    goal: GoalRegion
    walls: list[list[tuple[float, float]]] = Field(min_length=1)

    @field_validator("walls")
    @classmethod
    def _polylines(cls, walls: list[list[tuple[float, float]]]) -> list[list[tuple[float, float]]]:
        for i, line in enumerate(walls):
            if len(line) < 2:
                raise ValueError(f"wall {i} needs at least 2 points, got {len(line)}")
        return walls

    @property
    def segments(self) -> list[Segment]:
        return [
            Segment(Point(*line[i]), Point(*line[i + 1]))
            for line in self.walls
            for i in range(len(line) - 1)
        ]

    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) of every wall point and the goal."""
        xs = [p[0] for line in self.walls for p in line] + [self.goal.x_min, self.goal.x_max]
        ys = [p[1] for line in self.walls for p in line] + [self.goal.y_min, self.goal.y_max]
        return min(xs), max(xs), min(ys), max(ys)


def parse_track(text: str, source: str = "<track>") -> Track:
    """Read a track from YAML text; errors name the source and the field."""
    from compiler.yamlsrc import to_python

    root = load_yaml_node(text, source, SimError)
    data = to_python(root)
    if not isinstance(data, dict):
        raise SimError(f"{where(source, root)}: a track is a mapping with name, start, goal and walls")
    try:
        return Track.model_validate(data)
    except ValidationError as exc:
        raise SimError(validation_problem(exc.errors(), source, root, "invalid track", every=True)) from exc


def load_track(path: str | Path) -> Track:
    """Read a track file."""
    return parse_track(read_text(path, "track", SimError), str(path))


def tracks_dir() -> Path:
    """The folder of the bundled tracks (`models/tracks/` in the source tree)."""
    return Path(__file__).resolve().parents[2] / "models" / "tracks"


def bundled_tracks() -> dict[str, Path]:
    """The tracks that come with umlbot, by name (`s_bend`, …)."""
    folder = tracks_dir()
    return {p.stem: p for p in sorted(folder.glob("*.yaml"))} if folder.is_dir() else {}


def find_track(given: str | Path) -> Path:
    """The track `given` names: a file, else a bundled track's name (`corridor`, the names the
    studio offers) or file name (`models/tracks/s_bend.yaml` run from elsewhere). Something that
    is there but no file is returned as it is (reading it says what it is); `SimError` when there
    is nothing of that name."""
    path = Path(given)
    if path.exists():
        return path
    bundled = bundled_tracks()
    if path.suffix in ("", ".yaml", ".yml") and path.stem in bundled:
        return bundled[path.stem]
    raise SimError(f"no track {str(given)!r}: no such file, and no bundled track of that name "
                   f"(bundled: {', '.join(bundled)})")
