"""Stereo camera benchmark: depth frames per second on one core, and the latency from the sim
rendering a frame to `distance()` answering with it.

The process is pinned to one core and OpenCV to one thread. Scenes are the bundled `corridor`
track seen from its start and from 1 m further (textured walls at 0.3..2.5 m).

Each figure is the fastest of N calls (the median is given for the depth too): the machine
this runs on is shared.

- `raw_sgbm_fps`: the baseline, OpenCV's StereoSGBM alone on the whole image, same parameters;
- `depth_fps`: `DepthEngine.compute` as the drivers run it (rectify, match the rows around the
  horizon, the mirrored pass for the left-most columns, filters, per-column summary);
- `render_fps`: the simulator's rendering of one pair;
- `latency_ms`: from `World.render_stereo` being called to `StereoService.distance(0)` returning
  (render + depth + summary; in process, no broker: a call through the broker adds its round trip,
  see docs/performance.md);
- `pi4_depth_fps_est`, `pi5_depth_fps_est`: `depth_fps` divided by an assumed single-core speed
  ratio of this machine to a Pi 4 (6x) and a Pi 5 (2.5x) for NEON/SSE-vectorised integer code such
  as SGBM (not measured on a Pi: an estimate, see docs/performance.md).

The last line printed is one JSON object with these figures per image size.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from umlbot.base.library import BUILTIN
from umlbot.services.stereo.calibration import ideal_calibration
from umlbot.services.stereo.depth import DepthEngine, require_cv2
from umlbot.services.stereo.service import StereoService
from umlbot.services.stereo.sim import SimStereoCamera, SimStereoSettings
from umlbot.sim.geometry import Pose
from umlbot.sim.track import find_track, load_track
from umlbot.sim.world import World

cv2: Any = require_cv2()
MEDIANS: list[float] = []
PI4_RATIO = 6.0
PI5_RATIO = 2.5


def timed(function: Any, repeat: int) -> float:
    """The fastest of `repeat` calls, seconds (after one warm-up call): on a shared, loaded machine
    the fastest call is the one least slowed by the others (the median is printed too)."""
    function()
    samples = []
    for _ in range(repeat):
        started = time.perf_counter()
        function()
        samples.append(time.perf_counter() - started)
    MEDIANS.append(statistics.median(samples))
    return min(samples)


def size_figures(width: int, height: int, repeat: int) -> dict[str, Any]:
    track = load_track(find_track("corridor"))
    world = World(track)
    start = track.start.pose
    poses = [start, Pose(start.x, start.y + 1.0, start.heading)]
    images = [world.render_stereo(width, height)]
    frames = []
    for pose in poses:
        world._pose = pose  # the benchmark places the car; nothing drives it
        picture = world.render_stereo(width, height)
        import numpy as np

        shape = (picture.height_px, picture.width_px)
        frames.append((np.frombuffer(picture.left, np.uint8).reshape(shape),
                       np.frombuffer(picture.right, np.uint8).reshape(shape)))
    calibration = ideal_calibration(width, height, images[0].focal_px, images[0].baseline_m)
    engine = DepthEngine(calibration)
    raw = cv2.StereoSGBM_create(minDisparity=0, numDisparities=engine.num_disparities, blockSize=5,
                                P1=200, P2=800, disp12MaxDiff=1, uniquenessRatio=10,
                                speckleWindowSize=60, speckleRange=2, preFilterCap=31,
                                mode=cv2.STEREO_SGBM_MODE_SGBM_3WAY)
    raw_s = statistics.fmean(timed(lambda f=f: raw.compute(*f), repeat) for f in frames)
    depth_s = statistics.fmean(timed(lambda f=f: engine.compute(*f), repeat) for f in frames)
    depth_median_s = statistics.fmean(MEDIANS[-len(frames):])
    turn = iter(range(10**9))

    def move() -> None:
        # a new pose each time: a car standing still keeps its picture (and its depth)
        world._pose = Pose(start.x, start.y + 0.001 * (next(turn) % 500), start.heading)

    def render() -> None:
        move()
        world.render_stereo(width, height)

    render_s = timed(render, repeat)
    camera = SimStereoCamera("Eye", world, SimStereoSettings(width_px=width, height_px=height))
    impl = next(i for i in BUILTIN.implementations if i.id == "stereo_camera")
    service = StereoService("Eye", impl, camera, {"frame_max_age_s": 0})

    def answer() -> None:
        move()
        service.distance(0)

    latency_s = timed(answer, repeat)
    depth_fps = 1.0 / depth_s
    return {
        "size": f"{width}x{height}",
        "num_disparities": engine.num_disparities,
        "raw_sgbm_fps": round(1.0 / raw_s, 1),
        "depth_fps": round(depth_fps, 1),
        "depth_fps_median": round(1.0 / depth_median_s, 1),
        "render_fps": round(1.0 / render_s, 1),
        "latency_ms": round(latency_s * 1000, 1),
        "pi4_depth_fps_est": round(depth_fps / PI4_RATIO, 1),
        "pi5_depth_fps_est": round(depth_fps / PI5_RATIO, 1),
        "answer_ahead_cm": service.distance(0),
    }


def main() -> int:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    cv2.setNumThreads(1)
    repeat = int(sys.argv[1]) if len(sys.argv) > 1 else 15
    results = [size_figures(320, 240, repeat), size_figures(640, 480, max(5, repeat // 3))]
    for r in results:
        print(f"{r['size']:8s} depth {r['depth_fps']:6.1f} fps "
              f"(raw SGBM whole image {r['raw_sgbm_fps']:6.1f}), "
              f"render {r['render_fps']:6.1f} fps, render->distance() {r['latency_ms']:6.1f} ms, "
              f"Pi 4 ~{r['pi4_depth_fps_est']} fps, Pi 5 ~{r['pi5_depth_fps_est']} fps (estimates)")
    print(json.dumps({"one_core": True, "opencv": cv2.__version__, "load_average": os.getloadavg()[0],
                      "results": results,
                      "target_320x240_fps": 15, "met": results[0]["depth_fps"] >= 15}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
