"""Generated C++ orchestrator vs a raw C++ libmosquitto requester vs the Python orchestrator.

On one Mosquitto (started here, `set_tcp_nodelay true`) with one mock motor service process
(`umlbot service motor --driver mock`), three requesters do the same `LeftActuator.dutycycle(50)`
request/reply N times, one after the other, in the same run:

- `raw`: bench/codegen_raw.cpp, a bare libmosquitto client (TCP_NODELAY, MQTT 5 as the program)
  sending the envelope;
- `cpp`: the program `umlbot generate cpp` makes of a model whose lane loops over that action
  (`--no-trace`; per action: the duration of its trace event, from `--trace FILE`);
- `python`: `umlbot run` of the same compiled model, measured the same way.

Per engine: p50/p99 of an action in ms and the ratio to raw (targets for cpp: p50 ≤ 1.25 x, p99 ≤
1.5 x), the peak resident memory (VmHWM) of the process, and the time from its start (exec) to the
first feature call's start. Then the time to generate and build the reference car, and a model of
`--nodes` (2000) nodes. The last output line is one JSON object.

`--tracks` instead runs the reference car on every bundled track under both engines (`umlbot
sim`, both at `--speed 10` on the event-driven sim clock; the program with `--sim-clock`) and
prints per track whether each reached the goal, its collisions, sim and wall seconds.
`--wall-clock` runs the program in wall time instead (at `--cpp-speed`, as before it took part in
the sim clock).

    python bench/codegen.py [--n 2000] [--nodes 2000] [--no-builds]
    python bench/codegen.py --tracks [--cpp-speed 10] [--wall-clock]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from orchestrator import LOOP, ROBOT, compile_text, motor_service, run_broker
from rpc import percentile

from umlbot.codegen import build_cpp, generate_cpp
from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import write_compiled

HERE = Path(__file__).parent
ROOT = HERE.parent


def _peak_rss_kb(pid: int) -> int:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


def _run_engine(argv: list[str], trace: Path) -> dict[str, Any]:
    """Run one orchestrator to its end; per-action latencies from its trace, RSS, first call."""
    began = time.time()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "UMLBOT_BROKER": "", "UMLBOT_LOG_LEVEL": "WARNING"})
    peak = 0
    while proc.poll() is None:
        peak = max(peak, _peak_rss_kb(proc.pid))
        time.sleep(0.05)
    _, err = proc.communicate()
    if proc.returncode != 0:
        raise RuntimeError(f"{argv[0]} failed ({proc.returncode}): {err[-2000:]}")
    events = [json.loads(line) for line in trace.read_text(encoding="utf-8").splitlines()]
    actions = [e for e in events if e["node"] == "act"]
    latencies = [e["duration_ms"] for e in actions]
    return {
        "p50_ms": round(statistics.median(latencies), 4),
        "p99_ms": round(percentile(latencies, 99), 4),
        "rss_mb": round(peak / 1024, 2),
        "first_call_ms": round((actions[0]["start"] - began) * 1000, 1),
        "actions": len(actions),
    }


def _raw(program: Path, url: str, n: int) -> dict[str, Any]:
    port = url.rsplit(":", 1)[1]
    done = subprocess.run([str(program), "127.0.0.1", port, ROBOT, str(n)], capture_output=True, text=True,
                          timeout=600, check=True)
    samples = [float(line) / 1000.0 for line in done.stdout.split()]
    return {"p50_ms": round(statistics.median(samples), 4), "p99_ms": round(percentile(samples, 99), 4)}


def _timed_build(model: Any, where: Path) -> dict[str, float]:
    began = time.monotonic()
    generate_cpp(model, where)
    generated = time.monotonic()
    build_cpp(where, jobs=2)
    return {"generate_s": round(generated - began, 3), "build_s": round(time.monotonic() - generated, 1)}


def big_model_text(nodes: int) -> str:
    """One lane of `nodes` nodes: datastores and decisions in a chain (every expression kind)."""
    lines = ["lanes:", "  - lane: RaspberryPI", "    nodes:", "      - {id: start, kind: start}"]
    for i in range((nodes - 2) // 2):
        lines.append(f"      - {{id: s{i}, kind: datastore, name: v{i % 50}, value: {i} * 2 + 1}}")
        lines.append(f"      - {{id: d{i}, kind: decision, branches: [{{if: v{i % 50} > {i} and not "
                     f"Application.exit, then: s{i + 1}}}, {{else: end}}]}}")
    last = (nodes - 2) // 2
    lines[-1] = lines[-1].replace(f"then: s{last}", "then: end")
    lines.append("      - {id: end, kind: end}")
    return "\n".join(lines) + "\n"


def sim_tracks(cpp_speed: float, wall_clock: bool) -> dict[str, Any]:
    """Every bundled track under both engines."""
    from umlbot.sim import SimOptions, run_sim

    car = ROOT / "models" / "robot_car"
    rows = []
    for track in sorted((ROOT / "models" / "tracks").glob("*.yaml")):
        row: dict[str, Any] = {"track": track.stem}
        for engine, speed in (("python", 10.0), ("cpp", cpp_speed)):
            result = run_sim(SimOptions(model=car, track=track, speed=speed, port=0, timeout_s=300.0,
                                        engine=engine, wall_clock=wall_clock and engine == "cpp"))
            row[engine] = {"goal": result.goal_reached, "collisions": result.collisions,
                           "sim_s": round(result.sim_s, 1), "wall_s": round(result.wall_s, 1),
                           "reason": result.reason}
        rows.append(row)
        print(json.dumps(row), file=sys.stderr)
    return {"cpp_speed": cpp_speed, "cpp_clock": "wall" if wall_clock else "sim", "tracks": rows,
            "goals": {engine: sum(1 for row in rows if row[engine]["goal"]) for engine in ("python", "cpp")},
            "same_sim_s": sum(1 for row in rows if abs(row["python"]["sim_s"] - row["cpp"]["sim_s"]) <= 0.5)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=2000, help="actions per engine")
    parser.add_argument("--nodes", type=int, default=2000, help="nodes of the big model")
    parser.add_argument("--no-builds", action="store_true", help="skip the generate+build timings")
    parser.add_argument("--tracks", action="store_true", help="the car on every track, both engines")
    parser.add_argument("--cpp-speed", type=float, default=10.0, help="sim speed of the cpp engine")
    parser.add_argument("--wall-clock", action="store_true", help="--tracks: the program in wall time")
    args = parser.parse_args()
    if args.tracks:
        print(json.dumps(sim_tracks(args.cpp_speed, args.wall_clock)))
        return
    work = Path(tempfile.mkdtemp(prefix="umlbot-bench-codegen-"))
    result: dict[str, Any] = {"n": args.n}
    try:
        raw = work / "codegen_raw"
        subprocess.run(["g++", "-O2", "-std=c++17", str(HERE / "codegen_raw.cpp"), "-lmosquitto", "-o",
                        str(raw)], check=True)
        model = compile_text(LOOP.format(n=args.n))
        compiled = work / "loop.json"
        write_compiled(model, compiled)
        generate_cpp(model, work / "loop")
        program = build_cpp(work / "loop", jobs=2)
        with run_broker("mosquitto") as url, motor_service(url):
            common = ["--broker", url, "--robot", ROBOT, "--no-trace", "--log-level", "WARNING"]
            result["raw"] = _raw(raw, url, args.n)
            result["cpp"] = _run_engine([str(program), *common, "--trace", str(work / "cpp.jsonl")],
                                        work / "cpp.jsonl")
            result["python"] = _run_engine(
                [sys.executable, "-c", "from umlbot.cli import main; main()", "run", str(compiled), *common,
                 "--trace", str(work / "py.jsonl")], work / "py.jsonl")
        for engine in ("cpp", "python"):
            for q in ("p50", "p99"):
                result[engine][f"ratio_{q}"] = round(result[engine][f"{q}_ms"] / result["raw"][f"{q}_ms"], 2)
        if not args.no_builds:
            result["build_car"] = _timed_build(compile_model(ROOT / "models" / "robot_car"), work / "car")
            big = compile_text(big_model_text(args.nodes))
            result["build_big"] = {"nodes": sum(len(lane.nodes) for lane in big.lanes.values()),
                                   **_timed_build(big, work / "big")}
    finally:
        shutil.rmtree(work, ignore_errors=True)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
