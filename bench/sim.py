"""Simulator benchmark: the reference robot car on every bundled track, each with five noise seeds.

Each run is a full `umlbot sim` in this process (embedded amqtt broker on a free port, the world,
the motor, sonar, servo and gpio services, the orchestrator), as `make sim` does it, with the
sonar made noisy: Gaussian noise (1 cm) and lost echoes (5 %), seeded 0..4. One line is printed per
run (goal, collisions, sim and wall seconds, executed actions, median action latency through the
broker), then the figures: the success rate (goal reached without a collision), the collisions and
the mean sim time to the goal. The last line printed is one JSON object:
{"runs": [{"track", "seed", "goal", "collisions", "sim_s", "wall_s", "actions", "action_p50_ms"}, ...],
 "success_rate", "collisions", "mean_time_to_goal_s"}.
Exit status 1 when the success rate is below 100 %.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from umlbot.logs import configure_logging
from umlbot.sim.runner import SimOptions, run_sim
from umlbot.sim.track import tracks_dir

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=10.0, help="sim seconds per wall second")
    parser.add_argument("--model", type=Path, default=ROOT / "models" / "robot_car")
    parser.add_argument("--track", action="append", default=[], metavar="NAME",
                        help="only this bundled track (repeatable); default: all of them")
    parser.add_argument("--seeds", type=int, default=5, help="runs per track, seeded 0..N-1")
    parser.add_argument("--noise", type=float, default=1.0, help="sonar noise, standard deviation in cm")
    parser.add_argument("--drop", type=float, default=5.0, help="percentage of lost sonar echoes")
    parser.add_argument("--timeout", type=float, default=300.0, help="sim seconds per run")
    parser.add_argument("--processes", action="store_true", help="services as child processes")
    args = parser.parse_args()
    configure_logging("WARNING")
    tracks = sorted(tracks_dir().glob("*.yaml"))
    if args.track:
        known = {t.stem: t for t in tracks}
        unknown = sorted(set(args.track) - set(known))
        if unknown:
            parser.error(f"unknown track(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})")
        tracks = [known[name] for name in args.track]
    runs: list[dict[str, Any]] = []
    for track in tracks:
        for seed in range(args.seeds):
            result = run_sim(SimOptions(
                model=args.model, track=track, speed=args.speed, port=0, timeout_s=args.timeout,
                processes=args.processes, seed=seed, sonar_noise_cm=args.noise, sonar_drop=args.drop / 100.0))
            row = {
                "track": result.track,
                "seed": seed,
                "goal": result.ok,
                "collisions": result.collisions,
                "sim_s": round(result.sim_s, 2),
                "wall_s": round(result.wall_s, 2),
                "actions": result.actions,
                "action_p50_ms": None if result.action_p50_ms is None else round(result.action_p50_ms, 3),
            }
            print(f"{row['track']:17s} seed={seed} goal={row['goal']!s:5s} collisions={row['collisions']} "
                  f"sim={row['sim_s']:6.1f}s wall={row['wall_s']:5.1f}s actions={row['actions']:4d} "
                  f"p50={row['action_p50_ms']} ms ({result.reason})", flush=True)
            runs.append(row)
    successes = [r for r in runs if r["goal"]]
    rate = 100.0 * len(successes) / len(runs) if runs else 0.0
    collisions = sum(r["collisions"] for r in runs)
    mean_s = round(statistics.fmean(r["sim_s"] for r in successes), 2) if successes else None
    print(f"{len(tracks)} tracks x {args.seeds} seeds (noise {args.noise:g} cm, "
          f"{args.drop:g} % lost echoes): success {rate:.1f} %, collisions {collisions}, "
          f"mean time to goal {mean_s} s (sim)")
    print(json.dumps({"runs": runs, "success_rate": round(rate, 2), "collisions": collisions,
                      "mean_time_to_goal_s": mean_s}))
    return 0 if runs and len(successes) == len(runs) else 1


if __name__ == "__main__":
    sys.exit(main())
