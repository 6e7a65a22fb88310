"""The stereo depth pipeline against the simulator's ground truth, and its refusals of bad input.

Walls are rendered by `umlbot.sim.camera` (ideal rig, seeded sensor noise), matched by
`umlbot.services.stereo.depth` (OpenCV SGBM), and each column's distance is compared with the
distance the renderer's ray cast gives for that column.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from umlbot.base.errors import ConfigError
from umlbot.services.stereo.calibration import ideal_calibration, load_calibration, save_calibration
from umlbot.services.stereo.depth import DepthEngine, require_cv2
from umlbot.sim.camera import CameraRenderer, StereoRig, cast_columns
from umlbot.sim.geometry import Point, Pose, Segment

RIG = StereoRig()
POSE = Pose(0.0, 0.0, 0.0)


def wall_ahead(distance_m: float, incidence_deg: float) -> list[Segment]:
    """A long wall crossing the camera's axis `distance_m` ahead, turned by `incidence_deg`."""
    a = math.radians(incidence_deg)
    cx = distance_m + RIG.forward_m
    dx, dy = -math.sin(a), math.cos(a)
    return [Segment(Point(cx - 6 * dx, -6 * dy), Point(cx + 6 * dx, 6 * dy))]


@pytest.fixture(scope="module")
def engine() -> DepthEngine:
    return DepthEngine(ideal_calibration(RIG.width_px, RIG.height_px, RIG.focal_px, RIG.baseline_m))


def columns(frame_columns: tuple[float | None, ...]) -> np.ndarray:
    return np.array([np.nan if c is None else c for c in frame_columns], dtype=float)


@pytest.mark.parametrize("incidence_deg", [0, 30, -30, 45, -45, 60, -60])
def test_depth_accuracy_against_ground_truth(engine: DepthEngine, incidence_deg: int) -> None:
    errors: list[float] = []
    checked = 0
    for distance in (0.3, 0.6, 1.0, 1.5, 2.0, 2.5):
        renderer = CameraRenderer(wall_ahead(distance, incidence_deg), RIG, seed=int(distance * 10))
        left, right = renderer.render(POSE)
        (lx, ly), _ = renderer.camera_origins(POSE)
        truth_m, _, _, cos_incidence = cast_columns(renderer.walls, lx, ly, renderer.column_angles)
        truth_cm = truth_m * 100
        frame = engine.compute(left, right)
        assert frame.problem is None
        measured = columns(frame.columns_cm)
        # the range: 0.3..2.5 m, up to 60° incidence (a column's own ray meets the turned
        # wall a little more or less obliquely than the axis does)
        in_range = (truth_cm >= 29.5) & (truth_cm <= 250.5) & (cos_incidence >= math.cos(math.radians(62)))
        seen = in_range & ~np.isnan(measured)
        if in_range.sum() < 10:
            continue  # this side of the turned wall lies in the columns the matcher cannot see
        checked += 1
        # the left-most columns cannot be matched (their match lies outside the right image)
        assert seen.sum() >= 0.6 * in_range.sum(), (distance, seen.sum(), in_range.sum())
        relative = np.abs(measured[seen] - truth_cm[seen]) / truth_cm[seen]
        assert relative.max() <= 0.15, (distance, incidence_deg, float(relative.max()))
        assert float(np.median(relative)) <= 0.03, (distance, incidence_deg)
        errors.extend(relative.tolist())
    assert checked >= 3
    assert float(np.median(errors)) <= 0.03


def test_plain_and_dark_walls_give_no_reading(engine: DepthEngine) -> None:
    plain = CameraRenderer(wall_ahead(1.0, 0), RIG, texture_gain=0.0)
    frame = engine.compute(*plain.render(POSE))
    assert all(c is None for c in frame.columns_cm)
    assert frame.problem is not None and "texture" in frame.problem
    dark = CameraRenderer(wall_ahead(1.0, 0), RIG, brightness=0.03)
    frame = engine.compute(*dark.render(POSE))
    assert all(c is None for c in frame.columns_cm)
    assert frame.problem is not None


@pytest.mark.parametrize("distance_m", [0.5, 1.5])
def test_swapped_cameras_give_no_reading(engine: DepthEngine, distance_m: float) -> None:
    left, right = CameraRenderer(wall_ahead(distance_m, 20), RIG).render(POSE)
    frame = engine.compute(right, left)
    assert frame.problem is not None and "swapped" in frame.problem
    assert all(c is None for c in frame.columns_cm)


def test_wrong_image_size_is_refused(engine: DepthEngine) -> None:
    left = np.zeros((100, 100), dtype=np.uint8)
    with pytest.raises(ValueError, match="the left image is 100x100, the calibration is for 320x240"):
        engine.compute(left, left)


def test_calibration_file_errors(tmp_path: Path) -> None:
    missing = tmp_path / "none.json"
    with pytest.raises(ConfigError, match=r"no stereo calibration file there.*umlbot calibrate stereo"):
        load_calibration(missing)
    garbled = tmp_path / "garbled.json"
    garbled.write_text("{not json")
    with pytest.raises(ConfigError, match=r"garbled.json: the stereo calibration is not JSON"):
        load_calibration(garbled)
    good = ideal_calibration(320, 240, 277.0, 0.08)
    path = tmp_path / "cal.json"
    save_calibration(good, path)
    assert load_calibration(path) == good
    data = json.loads(path.read_text())
    data["left"]["matrix"] = [[1, 2], [3, 4]]
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=r"cal.json: stereo calibration left.matrix: .*3x3"):
        load_calibration(path)
    data = json.loads(path.read_text())
    data["left"]["matrix"] = good.left.matrix
    data["translation"] = [0.08, 0, 0]  # the right camera on the left
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match="swapped"):
        load_calibration(path)
    path.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ConfigError, match="not a stereo calibration file"):
        load_calibration(path)


def test_without_opencv_the_error_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "cv2", None)  # import cv2 now raises ImportError
    with pytest.raises(ConfigError, match=r"pip install 'umlbot\[stereo\]'"):
        require_cv2()


def test_the_core_and_the_sim_do_not_import_opencv() -> None:
    code = ("import sys, umlbot.services.stereo.service, umlbot.services.stereo.mock, umlbot.sim.world, "
            "umlbot.cli; assert 'cv2' not in sys.modules, 'cv2 imported'")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_the_camera_sees_an_angled_wall_the_sonar_misses() -> None:
    """A wall 1 m ahead of the car's centre at 60° to its path: the sonar's ping glances off (no
    echo: its realism is unchanged), the camera measures it."""
    from umlbot.services.stereo.sim import SimStereoCamera, SimStereoSettings
    from umlbot.sim import World, parse_track

    (wall,) = wall_ahead(1.0 - RIG.forward_m, 60)  # through (1.0, 0)
    track = parse_track(f"""
name: angled
start: {{x: 0, y: 0, heading_deg: 0}}
goal: {{x_min: -0.5, x_max: -0.3, y_min: -0.1, y_max: 0.1}}
walls:
  - [[{wall.a.x:.4f}, {wall.a.y:.4f}], [{wall.b.x:.4f}, {wall.b.y:.4f}]]
""")
    world = World(track)
    assert world.read_sonar_cm() is None
    frame = SimStereoCamera("Eye", world, SimStereoSettings()).read_depth()
    truth_cm = CameraRenderer(track.segments, RIG).ground_truth_m(track.start.pose) * 100  # left camera
    near_axis = [i for i, a in enumerate(frame.angles_deg) if abs(a) < 1]
    seen = [(frame.columns_cm[i], truth_cm[i]) for i in near_axis if frame.columns_cm[i] is not None]
    assert seen and all(abs(c - t) <= 0.03 * t for c, t in seen), seen
