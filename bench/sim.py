"""Simulator benchmark: the reference robot car on every bundled track, each with five noise seeds.

Each run is a full `umlbot sim` in this process (embedded amqtt broker on a free port, the world,
the motor, sonar, servo and gpio services, the orchestrator), as `make sim` does it, with the
sonar made noisy: Gaussian noise (1 cm) and lost echoes (5 %), seeded 0..4. One line is printed per
run (goal, collisions, sim and wall seconds, executed actions, median action latency through the
broker), then the figures: the success rate (goal reached without a collision), the collisions and
the mean sim time to the goal.

`--tracks-dir DIR` drives the tracks in DIR too, after the bundled ones, as a held-out set (tracks
the model was not tuned on, such as `bench/tracks/unseen/`): their figures are printed on their
own, one line per track and then the set's, and they do not count toward the exit status
(`--no-bundled`: only those).

The last line printed is one JSON object:
{"runs": [{"track", "seed", "goal", "reason", "collisions", "sim_s", "wall_s", "actions",
           "action_p50_ms"}, ...],
 "success_rate", "collisions", "mean_time_to_goal_s",
 "held_out": [{"dir", "runs", "success_rate", "collisions", "mean_time_to_goal_s"}, ...]}.
Exit status 1 when the success rate on the bundled tracks is below 100 % (or nothing was run).
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


def drive(tracks: list[Path], args: argparse.Namespace) -> list[dict[str, Any]]:
    """Every track with seeds 0..N-1, one printed line and one row per run."""
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
                "reason": result.reason,
                "collisions": result.collisions,
                "sim_s": round(result.sim_s, 2),
                "wall_s": round(result.wall_s, 2),
                "actions": result.actions,
                "action_p50_ms": None if result.action_p50_ms is None else round(result.action_p50_ms, 3),
            }
            print(f"{row['track']:19s} seed={seed} goal={row['goal']!s:5s} collisions={row['collisions']} "
                  f"sim={row['sim_s']:6.1f}s wall={row['wall_s']:5.1f}s actions={row['actions']:4d} "
                  f"p50={row['action_p50_ms']} ms ({row['reason']})", flush=True)
            runs.append(row)
    return runs


def figures(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """The success rate (goal reached without a collision), the collisions, the mean time to goal."""
    successes = [r for r in runs if r["goal"]]
    rate = 100.0 * len(successes) / len(runs) if runs else 0.0
    mean_s = round(statistics.fmean(r["sim_s"] for r in successes), 2) if successes else None
    return {"success_rate": round(rate, 2), "collisions": sum(r["collisions"] for r in runs),
            "mean_time_to_goal_s": mean_s}


def summary(label: str, tracks: int, runs: list[dict[str, Any]], args: argparse.Namespace) -> str:
    found = figures(runs)
    return (f"{label}: {tracks} tracks x {args.seeds} seeds (noise {args.noise:g} cm, {args.drop:g} % "
            f"lost echoes): success {found['success_rate']:.1f} %, collisions {found['collisions']}, "
            f"mean time to goal {found['mean_time_to_goal_s']} s (sim)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=10.0, help="sim seconds per wall second")
    parser.add_argument("--model", type=Path, default=ROOT / "models" / "robot_car")
    parser.add_argument("--track", action="append", default=[], metavar="NAME",
                        help="only this track (repeatable; a bundled or a --tracks-dir one); default: all")
    parser.add_argument("--tracks-dir", action="append", default=[], type=Path, metavar="DIR",
                        help="also drive the tracks in DIR, reported as a held-out set (repeatable)")
    parser.add_argument("--no-bundled", action="store_true", help="only the --tracks-dir tracks")
    parser.add_argument("--seeds", type=int, default=5, help="runs per track, seeded 0..N-1")
    parser.add_argument("--noise", type=float, default=1.0, help="sonar noise, standard deviation in cm")
    parser.add_argument("--drop", type=float, default=5.0, help="percentage of lost sonar echoes")
    parser.add_argument("--timeout", type=float, default=300.0, help="sim seconds per run")
    parser.add_argument("--processes", action="store_true", help="services as child processes")
    args = parser.parse_args()
    configure_logging("WARNING")
    sets: list[tuple[str, list[Path]]] = [
        ("bundled", [] if args.no_bundled else sorted(tracks_dir().glob("*.yaml")))]
    for folder in args.tracks_dir:
        if not folder.is_dir():
            parser.error(f"--tracks-dir {folder}: no such folder")
        sets.append((str(folder), sorted(folder.glob("*.yaml"))))
    if args.track:
        known = {t.stem for _, tracks in sets for t in tracks}
        unknown = sorted(set(args.track) - known)
        if unknown:
            parser.error(f"unknown track(s) {', '.join(unknown)} (known: {', '.join(sorted(known))})")
        sets = [(label, [t for t in tracks if t.stem in args.track]) for label, tracks in sets]
    (_, bundled), held_out = sets[0], sets[1:]
    runs = drive(bundled, args)
    held_out_runs = [(label, tracks, drive(tracks, args)) for label, tracks in held_out]
    if bundled:
        print(summary("bundled", len(bundled), runs, args))
    for label, tracks, rows in held_out_runs:
        for track in tracks:  # one line per track: reached, mean time, the failed seeds
            name = load_track(track).name
            mine = [r for r in rows if r["track"] == name]
            times = [r["sim_s"] for r in mine if r["goal"]]
            mean = f"{statistics.fmean(times):6.1f} s" if times else "      -"
            failed = ", ".join(f"seed {r['seed']} {r['reason']}" for r in mine if not r["goal"])
            print(f"  {name:19s} {len(times)}/{len(mine)} {mean}  {failed}".rstrip())
        print(summary(f"held out ({label})", len(tracks), rows, args))
    print(json.dumps({"runs": runs, **figures(runs),
                      "held_out": [{"dir": label, "runs": rows, **figures(rows)}
                                   for label, _, rows in held_out_runs]}))
    ran = runs or any(rows for _, _, rows in held_out_runs)
    return 0 if ran and all(r["goal"] for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
