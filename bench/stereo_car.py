"""The stereo car against the sonar car: goals, collisions and the distance driven per track.

Both reference models (`models/robot_car`, sonar only; `models/stereo_car`, sonar and stereo
camera) drive each track with seeds 0..N-1, the sonar noisy as in bench/sim.py (1 cm Gaussian,
5 % lost echoes). One line per run, then one per track: goals, collisions and the mean distance
driven by each car. The last line is JSON: {"runs": [{"model", "track", "seed", "goal",
"collisions", "distance_m", "sim_s", "wall_s"}, ...], "tracks": [{"track", "robot_car_m",
"angled", "stereo_car_m", "robot_car_goals", "stereo_car_goals", ...}], "stereo_car": {"success_rate",
"collisions"}}. Exit status 1 when the stereo car missed a goal or collided.

    python bench/stereo_car.py                                     # bundled tracks, 5 seeds
    python bench/stereo_car.py --tracks-dir bench/tracks/unseen --no-bundled --seeds 1
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from umlbot.base.logs import configure_logging
from umlbot.sim import SimOptions, run_sim
from umlbot.sim.track import load_track, tracks_dir

ROOT = Path(__file__).resolve().parent.parent
MODELS = {"robot_car": ROOT / "models" / "robot_car", "stereo_car": ROOT / "models" / "stereo_car"}


def is_angled(path: Path) -> bool:
    """A track with a wall that is neither along x nor along y (a corridor at an angle)."""
    return any(abs(w.a.x - w.b.x) > 1e-6 and abs(w.a.y - w.b.y) > 1e-6 for w in load_track(path).segments)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--speed", type=float, default=10.0, help="sim seconds per wall second")
    parser.add_argument("--tracks-dir", action="append", default=[], type=Path)
    parser.add_argument("--no-bundled", action="store_true")
    parser.add_argument("--track", action="append", default=[], help="only these track names")
    parser.add_argument("--model", action="append", default=[], choices=sorted(MODELS),
                        help="only these models (default both)")
    parser.add_argument("--timeout", type=float, default=300.0, help="sim seconds per run")
    args = parser.parse_args()
    configure_logging("WARNING")
    tracks = [] if args.no_bundled else sorted(tracks_dir().glob("*.yaml"))
    for folder in args.tracks_dir:
        tracks += sorted(folder.glob("*.yaml"))
    if args.track:
        tracks = [t for t in tracks if t.stem in args.track]
    models = args.model or sorted(MODELS)
    runs: list[dict[str, Any]] = []
    for track in tracks:
        for model in models:
            for seed in range(args.seeds):
                result = run_sim(SimOptions(model=MODELS[model], track=track, speed=args.speed, port=0,
                                            timeout_s=args.timeout, seed=seed, sonar_noise_cm=1.0,
                                            sonar_drop=0.05))
                row = {"model": model, "track": result.track, "seed": seed, "goal": result.ok,
                       "reason": result.reason, "collisions": result.collisions,
                       "distance_m": round(result.distance_m, 2), "sim_s": round(result.sim_s, 1),
                       "wall_s": round(result.wall_s, 1), "failure": result.failure}
                why = row["reason"] + (f": {row['failure']}" if row["failure"] else "")
                print(f"{model:10s} {row['track']:20s} seed={seed} goal={row['goal']!s:5s} "
                      f"collisions={row['collisions']} distance={row['distance_m']:5.2f} m "
                      f"sim={row['sim_s']:6.1f}s wall={row['wall_s']:5.1f}s ({why})", flush=True)
                runs.append(row)
    table = []
    angled = {load_track(t).name for t in tracks if is_angled(t)}
    for track in dict.fromkeys(r["track"] for r in runs):
        line: dict[str, Any] = {"track": track, "angled": track in angled}
        for model in models:
            mine = [r for r in runs if r["track"] == track and r["model"] == model]
            line[f"{model}_m"] = round(statistics.fmean(r["distance_m"] for r in mine), 2)
            line[f"{model}_goals"] = f"{sum(r['goal'] for r in mine)}/{len(mine)}"
            line[f"{model}_collisions"] = sum(r["collisions"] for r in mine)
        table.append(line)
        print("  ".join(f"{k}={v}" for k, v in line.items()))
    stereo = [r for r in runs if r["model"] == "stereo_car"]
    rate = round(100.0 * sum(r["goal"] for r in stereo) / len(stereo), 1) if stereo else None
    figures = {"success_rate": rate, "collisions": sum(r["collisions"] for r in stereo)}
    print(json.dumps({"runs": runs, "tracks": table, "stereo_car": figures}))
    return 0 if stereo and all(r["goal"] for r in stereo) else 1


if __name__ == "__main__":
    sys.exit(main())
