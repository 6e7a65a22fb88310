"""The track file: a named 2D arena of walls, a start pose and a goal region (YAML, metres).

::

    name: left_bend
    description: a corridor that turns left          # optional, plain YAML: quote it if it has ": "
    start: {x: 0.0, y: 0.3, heading_deg: 90}          # car centre; 0° = +x, 90° = +y (default 90)
    goal: {x_min: -1.6, x_max: -1.2, y_min: 2.0, y_max: 2.8}
    walls:                                           # each wall is a polyline of >= 2 points
      - [[-0.4, 0.0], [0.4, 0.0]]
      - [[-0.4, 0.0], [-0.4, 2.0], [-1.6, 2.0]]

The goal is reached when the car's centre is inside the goal rectangle.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Annotated, Any

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    model_validator,
)

from umlbot.base.errors import SimError
from umlbot.base.files import load_yaml_node, read_text, validation_problem, where
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


#: a track whose walls and goal span more than this (metres) was probably written in centimetres
LARGE_TRACK_M = 50.0


def _wall_shape(value: Any) -> Any:
    """A wall written as one point (`[x, y]`) instead of a list of points gets a message that says so."""
    if isinstance(value, list | tuple) and value and all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value
    ):
        raise ValueError(f"a wall is a list of [x, y] points, such as [[0, 0], [1, 0]], not one point "
                         f"{list(value)}")
    if isinstance(value, list | tuple) and len(value) < 2:
        raise ValueError(f"a wall needs at least 2 points ([x, y]), got {len(value)}")
    return value


#: one wall: a polyline of two or more [x, y] points
Wall = Annotated[list[tuple[float, float]], BeforeValidator(_wall_shape)]


class Track(BaseModel):
    """A track as read from its file; `segments` are the walls split into straight pieces."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(min_length=1)
    description: str = ""
    start: StartPose
    goal: GoalRegion
    walls: list[Wall] = Field(min_length=1)
    #: the file and line each wall is written on ("s_bend.yaml:7"), when read from a file
    _wall_places: list[str] = PrivateAttr(default_factory=list)

    def __eq__(self, other: object) -> bool:
        """The same track: the same fields, wherever each was read from."""
        if not isinstance(other, Track):
            return NotImplemented
        return self.__dict__ == other.__dict__

    __hash__ = None  # type: ignore[assignment]  # its walls are lists: never hashable

    def wall_place(self, index: int) -> str:
        """`wall 2 (s_bend.yaml:9)`: a wall by its index in `walls` and where it is written."""
        places = self._wall_places
        return f"wall {index}" + (f" ({places[index]})" if index < len(places) else "")

    def wall_of_segment(self, segment: int) -> int:
        """The index in `walls` of the wall that `segments[segment]` is a piece of."""
        for i, line in enumerate(self.walls):
            if segment < len(line) - 1:
                return i
            segment -= len(line) - 1
        raise IndexError(segment)

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
    from umlbot.base.yamlsrc import to_python

    root = load_yaml_node(text, source, SimError)
    data = to_python(root)
    if not isinstance(data, dict):
        raise SimError(f"{where(source, root)}: a track is a mapping with name, start, goal and walls")
    try:
        track = Track.model_validate(data)
    except ValidationError as exc:
        raise SimError(validation_problem(exc.errors(), source, root, "invalid track", every=True)) from exc
    track._wall_places = [where(source, root, ("walls", i)).rsplit(":", 1)[0]
                          for i in range(len(track.walls))]
    return track


def track_warnings(track: Track) -> list[str]:
    """What looks wrong with a track but may be meant: a size that suggests centimetres, a start
    already in the goal."""
    found: list[str] = []
    x_min, x_max, y_min, y_max = track.bounds()
    size = max(x_max - x_min, y_max - y_min)
    if size > LARGE_TRACK_M:
        found.append(f"the track spans {size:g} m: tracks are in metres (was it written in centimetres?)")
    if track.goal.contains(track.start.x, track.start.y):
        found.append(f"the start ({track.start.x:g}, {track.start.y:g}) is inside the goal region: "
                     "the run ends at once with the goal reached")
    return found


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


def is_track_name(given: str | Path) -> bool:
    """True for a bare name (`corridor`): no directory separator and no .yaml/.yml suffix."""
    text = str(given)
    return (bool(text) and "/" not in text and os.sep not in text
            and not text.lower().endswith((".yaml", ".yml")))


def find_track(given: str | Path) -> Path:
    """The track `given` names: a file that is there, else, for a bare name (`corridor`: no
    directory separator, no .yaml/.yml suffix), the bundled track of that name (the names the
    studio offers). A path that is not there is an error naming it, never a bundled track of the
    same file name (`SimError`, which suggests the bundled name when there is one). Something that
    is there but no file is returned as it is (reading it says what it is)."""
    path = Path(given)
    if path.exists():
        return path
    bundled = bundled_tracks()
    if is_track_name(given):
        if str(given) in bundled:
            return bundled[str(given)]
        raise SimError(f"no track {str(given)!r}: no such file, and no bundled track of that name "
                       f"(bundled: {', '.join(bundled)})")
    hint = f"; the bundled track of that name is '--track {path.stem}'" if path.stem in bundled else ""
    raise SimError(f"no track file {str(given)!r}: no such file{hint}")
