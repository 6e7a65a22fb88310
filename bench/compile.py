"""Compile benchmark: generated models of 100, 1 000 and 10 000 activity nodes.

Each model has the robot car's components and swimlanes of about 100 nodes (datastores, feature
calls, builtin calls, decisions, fork/join pairs, calls of virtual swimlanes). The time measured is
`umlbot compile` without the process start: read, check, build and serialise the compiled model.
Each size is compiled REPEAT times: `compile_s` is the best wall time, `median_s` the median,
`cpu_s` the best process CPU time. The last line printed is one JSON object:
{"results": [{"nodes": n, "compile_s": t, "median_s": m, "cpu_s": c}, ...]}.
Target: 10 000 nodes in at most 1 s.
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import dump_compiled

SIZES = (100, 1_000, 10_000)
LANE_NODES = 100
#: each size is compiled this many times; compile_s is the best run (the machine is shared).
REPEAT = 5

MODEL = """\
name: bench
components:
  RaspberryPI: {kind: system}
  LeftActuator: {kind: actuator, ports: {drive: enabled}}
  RightActuator: {kind: actuator}
  Sensor: {kind: actuator}
  DistanceRead: {kind: sensor, ports: {range: value}}
links:
  - {from: LeftActuator.drive, to: DistanceRead.range}
"""

DEPLOYMENT = """\
driver: mock
components:
  RaspberryPI: {impl: raspberrypi}
  LeftActuator: {impl: l298n, settings: {in1: 22, in2: 23}}
  RightActuator: {impl: l298n, settings: {in1: 24, in2: 25}}
  Sensor: {impl: servo, settings: {gpio: 18}}
  DistanceRead: {impl: hcsr04, settings: {trigger: 8, echo: 7}}
"""


def lane_text(name: str, size: int, callee: str | None) -> str:
    """One swimlane of `size` nodes: start, repeated blocks of 10 nodes, end."""
    lines = [f"lane: {name}", "nodes:", "  - {id: start, kind: start}"]
    count = 2
    block = 0
    while count + 10 <= size:
        b = f"b{block}"
        call = f"{callee}" if callee else "msleep(1)"
        lines += [
            f"  - {{id: {b}_x, kind: datastore, name: x{block}, value: {block} * 2 + 1}}",
            f"  - {{id: {b}_read, kind: datastore, name: d{block}, value: DistanceRead.value()}}",
            f"  - {{id: {b}_dir, kind: action, call: LeftActuator.direction(x{block} > 3)}}",
            f"  - id: {b}_choose",
            "    kind: decision",
            f"    branches: [{{if: d{block} > 20 and not Application.exit, then: {b}_fork}}, "
            f"{{else: {b}_call}}]",
            f"  - {{id: {b}_fork, kind: fork, targets: [{b}_left, {b}_right]}}",
            f"  - {{id: {b}_left, kind: action, call: LeftActuator.enabled(true), next: {b}_join}}",
            f"  - {{id: {b}_right, kind: action, call: Sensor.angle(90), next: {b}_join}}",
            f"  - {{id: {b}_join, kind: join, next: {b}_call}}",
            f"  - {{id: {b}_call, kind: action, call: {call}}}",
            f"  - {{id: {b}_wait, kind: action, call: usleep(x{block} * 10)}}",
        ]
        count += 10
        block += 1
    while count < size:
        lines.append(f"  - {{id: pad{count}, kind: action, call: msleep(1)}}")
        count += 1
    lines.append("  - {id: end, kind: end}")
    return "\n".join(lines) + "\n"


def generate(root: Path, nodes: int) -> Path:
    """Write a model folder with `nodes` activity nodes in swimlanes of LANE_NODES."""
    (root / "activities").mkdir(parents=True)
    (root / "model.yaml").write_text(MODEL, encoding="utf-8")
    (root / "deployment.yaml").write_text(DEPLOYMENT, encoding="utf-8")
    lanes = max(1, nodes // LANE_NODES)
    for index in range(lanes):
        # lane 0 is RaspberryPI; each virtual lane i is called by lane i-1 (a chain, no recursion)
        name = "RaspberryPI" if index == 0 else f"Helper{index}"
        callee = f"Helper{index + 1}" if index + 1 < lanes else None
        size = nodes - LANE_NODES * (lanes - 1) if index == lanes - 1 else LANE_NODES
        (root / "activities" / f"lane{index:04d}.yaml").write_text(lane_text(name, size, callee),
                                                                   encoding="utf-8")
    return root


def main() -> None:
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for nodes in SIZES:
            root = generate(Path(tmp) / f"m{nodes}", nodes)
            walls: list[float] = []
            cpus: list[float] = []
            for _ in range(REPEAT):
                started, started_cpu = time.perf_counter(), time.process_time()
                model = compile_model(root)
                data = dump_compiled(model)
                walls.append(time.perf_counter() - started)
                cpus.append(time.process_time() - started_cpu)
            counted = sum(len(lane.nodes) for lane in model.lanes.values())
            assert counted == nodes, (counted, nodes)
            print(f"{nodes:>6} nodes: best {min(walls):.3f} s, median {statistics.median(walls):.3f} s, "
                  f"cpu {min(cpus):.3f} s ({len(data)} bytes)", file=sys.stderr)
            results.append({"nodes": nodes, "compile_s": round(min(walls), 4),
                            "median_s": round(statistics.median(walls), 4),
                            "cpu_s": round(min(cpus), 4)})
    print(json.dumps({"results": results}))


if __name__ == "__main__":
    main()
