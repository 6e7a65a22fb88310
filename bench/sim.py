"""Simulator benchmark: the reference robot car on every track in models/tracks/ at speed 10.

Each run is a full `umlbot sim` in this process (embedded amqtt broker on a free port, the world,
the motor, sonar, servo and gpio services, the orchestrator), as `make sim` does it. Printed per
run: goal, collisions, sim and wall seconds, executed actions and the median action latency (a
feature call through the broker, wall milliseconds). The last line printed is one JSON object:
{"results": [{"track", "goal", "collisions", "sim_s", "wall_s", "actions", "action_p50_ms"}, ...]}.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from umlbot.logs import configure_logging
from umlbot.sim.runner import SimOptions, run_sim
from umlbot.sim.track import tracks_dir

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--speed", type=float, default=10.0)
    parser.add_argument("--model", type=Path, default=ROOT / "models" / "robot_car")
    parser.add_argument("--processes", action="store_true", help="services as child processes")
    args = parser.parse_args()
    configure_logging("WARNING")
    results = []
    for track in sorted(tracks_dir().glob("*.yaml")):
        result = run_sim(SimOptions(model=args.model, track=track, speed=args.speed, port=0,
                                    timeout_s=600.0, processes=args.processes))
        row = {
            "track": result.track,
            "goal": result.goal_reached,
            "collisions": result.collisions,
            "sim_s": round(result.sim_s, 2),
            "wall_s": round(result.wall_s, 2),
            "actions": result.actions,
            "action_p50_ms": None if result.action_p50_ms is None else round(result.action_p50_ms, 3),
        }
        print(f"{row['track']:12s} goal={row['goal']!s:5s} collisions={row['collisions']} "
              f"sim={row['sim_s']:6.1f}s wall={row['wall_s']:5.1f}s actions={row['actions']:4d} "
              f"p50={row['action_p50_ms']} ms", flush=True)
        results.append(row)
    print(json.dumps({"results": results}))
    return 0 if all(r["goal"] and r["collisions"] == 0 for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
