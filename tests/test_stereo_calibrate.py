"""`umlbot calibrate stereo` on chessboard pairs the simulator renders: the calibration it writes
recovers the rig's focal length and baseline within 2 %, and drives the depth pipeline."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
from click.testing import CliRunner

from umlbot.cli import cli
from umlbot.services.stereo.calibration import load_calibration
from umlbot.services.stereo.depth import DepthEngine
from umlbot.sim.camera import StereoRig, render_chessboard_pair

RIG = StereoRig(width_px=640, height_px=480)
INNER = (9, 6)
SQUARE_M = 0.025


def rotation(rx_deg: float, ry_deg: float, rz_deg: float) -> np.ndarray:
    matrix, _ = cv2.Rodrigues(np.radians([rx_deg, ry_deg, rz_deg]))
    return np.asarray(matrix)


def board_poses() -> list[tuple[np.ndarray, np.ndarray]]:
    """Boards held at 0.35..0.6 m, tilted up to 30°, at various places in view of both cameras."""
    poses = []
    tilts = [(0, 0, 0), (25, 0, 5), (-20, 15, 0), (0, -25, -5), (15, 20, 10), (-15, -20, 0),
             (30, 0, -10), (0, 30, 0), (-25, -10, 8), (10, -15, -8)]
    for i, (rx, ry, rz) in enumerate(tilts):
        rot = rotation(rx, ry, rz)
        depth = 0.35 + 0.03 * (i % 8)
        centre = np.array([-0.02 + 0.01 * (i % 5), -0.01 + 0.01 * (i % 3), depth])
        half = np.array([(INNER[0] + 1) * SQUARE_M / 2, (INNER[1] + 1) * SQUARE_M / 2, 0.0])
        poses.append((rot, centre - rot @ half))
    return poses


def test_calibrate_stereo_recovers_focal_length_and_baseline(tmp_path: Path) -> None:
    folder = tmp_path / "pairs"
    folder.mkdir()
    for i, (rot, trans) in enumerate(board_poses()):
        left, right = render_chessboard_pair(RIG, rot, trans, inner=INNER, square_m=SQUARE_M, seed=i,
                                             supersample=2)
        cv2.imwrite(str(folder / f"left{i:02d}.png"), left)
        cv2.imwrite(str(folder / f"right{i:02d}.png"), right)
    out = tmp_path / "stereo.json"
    result = CliRunner().invoke(cli, ["calibrate", "stereo", str(folder), "-o", str(out),
                                      "--inner", "9x6", "--square-mm", "25"])
    assert result.exit_code == 0, result.output
    assert "baseline" in result.output
    calibration = load_calibration(out)
    assert calibration.image_size == (640, 480)
    assert math.isclose(calibration.focal_px, RIG.focal_px, rel_tol=0.02), calibration.focal_px
    assert math.isclose(calibration.baseline_m, RIG.baseline_m, rel_tol=0.02), calibration.baseline_m
    assert calibration.translation[0] < 0  # the right camera to the right
    engine = DepthEngine(calibration)
    assert math.isclose(engine.baseline_m, RIG.baseline_m, rel_tol=0.02)


def test_calibrate_stereo_refuses_a_folder_without_pairs(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["calibrate", "stereo", str(tmp_path), "-o", str(tmp_path / "x.json")])
    assert result.exit_code != 0
    assert "no left*.png / right*.png image pairs" in (result.output + str(result.exception))
    assert not (tmp_path / "x.json").exists()
