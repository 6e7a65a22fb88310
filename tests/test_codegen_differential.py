"""Differential: each model runs under the interpreter (`umlbot run`'s orchestrator) and under its
generated C++ program, against the same deterministic mock services on a real Mosquitto.

What must agree: per (lane, node), every execution's kind, value, error and level, in order; per
lane, the whole sequence where the lane has no fork and is not a virtual lane (whose calls from
several lanes interleave); the commands each mock driver received, in order; the exit code. Timing
and the interleaving of concurrent flows are exempt. A model that loops until an exit request
runs as many rounds as the timing of that request allows: there, every per-node list and command
list is compared on the common prefix, and both must have run the same nodes.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from codegen_support import CppRun, built_programs, lane_sequences, outcomes, wait_for
from conftest import BrokerProcess, RawClient
from orchestrator_support import MODELS, ROBOT_CAR, Rig, rig

from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import CompiledModel, ForkNode

# the first test builds every program (tests/codegen_support.py): ~1-2 min on a loaded machine, once
pytestmark = [pytest.mark.network, pytest.mark.timeout(600)]

Nodes = Callable[[], list[str]]


@dataclass(frozen=True)
class Scenario:
    """A model, what to do while it runs, and the exit code both engines must give."""

    path: Path
    stimulus: str = ""
    code: int = 0
    loops: bool = False


SCENARIOS: dict[str, Scenario] = {
    "fork": Scenario(MODELS / "fork.yaml"),
    "sensor_decision": Scenario(MODELS / "sensor_decision.yaml"),
    "reentrant": Scenario(MODELS / "reentrant.yaml"),
    "no_match": Scenario(MODELS / "no_match.yaml"),
    "values": Scenario(MODELS / "codegen_values.yaml", code=1),
    "signals": Scenario(MODELS / "signals.yaml", stimulus="go"),
    "held_signals": Scenario(MODELS / "held_signals.yaml", stimulus="notes"),
    "exit_loop": Scenario(MODELS / "exit_loop.yaml", stimulus="exit:nap", loops=True),
    "drive_and_read": Scenario(MODELS / "drive_and_read.yaml", stimulus="exit:nap", loops=True),
    "robot_car": Scenario(ROBOT_CAR, stimulus="exit:running", loops=True),
}


@pytest.fixture(scope="session")
def programs() -> dict[str, Path]:
    """Every scenario's generated program, built once per session (cached by its sources)."""
    return built_programs()


def _stimulate(kind: str, raw: RawClient, nodes: Nodes) -> None:
    """Wait for the run to be running, then do what the scenario says."""
    deadline_s = 10.0
    while True:  # the retained status: `running` once the lanes started
        message = raw.get(timeout=deadline_s, topic="umlbot/test/orchestrator/status")
        if json.loads(message.payload)["state"] == "running":
            break
    if kind == "go":
        raw.publish("umlbot/test/signal/go", "55")
    elif kind == "notes":
        raw.publish("umlbot/test/signal/note", "1")
        raw.publish("umlbot/test/signal/note", "hello there")
        raw.publish("umlbot/test/signal/go", "")
    elif kind.startswith("exit:"):
        node = kind.removeprefix("exit:")
        assert wait_for(lambda: nodes().count(node) >= 3, 10.0), f"{node} never ran three times: {nodes()}"
        raw.publish("umlbot/test/orchestrator/exit", json.dumps({"reason": "differential test"}))


def _commands(r: Rig) -> dict[str, list[Any]]:
    found: dict[str, list[Any]] = {}
    for host in r.hosts.values():
        for name, driver in host.drivers.items():
            commands = getattr(driver, "commands", None)
            if commands is not None:  # the calls; not the service's own safety stops (`stop`),
                # which follow the orchestrator's final status as fast as each run's rig closes
                found[name] = [tuple(c) for c in commands if tuple(c)[:1] != ("stop",)]
    return found


Outcome = tuple[int, list[dict[str, Any]], dict[str, Any]]


def _interpreter(broker: BrokerProcess, scenario: Scenario, raw: RawClient) -> Outcome:
    with rig(broker.url, scenario.path) as r:
        running = r.start()
        if scenario.stimulus:
            _stimulate(scenario.stimulus, raw, r.nodes)
        code = running.wait(20.0)
        return code, list(r.events), _commands(r)


def _generated(broker: BrokerProcess, scenario: Scenario, program: Path, raw: RawClient,
               workdir: Path) -> tuple[int, list[dict[str, Any]], dict[str, Any], str]:
    with rig(broker.url, scenario.path) as r:
        run = CppRun(program, broker.url, workdir).start()
        if scenario.stimulus:
            _stimulate(scenario.stimulus, raw, run.nodes)
        code, err = run.wait(20.0)
        return code, run.events(), _commands(r), err


def _prefix(a: list[Any], b: list[Any]) -> tuple[list[Any], list[Any]]:
    """The rounds both ran before the exit request (the last one may have seen it in one only)."""
    n = max(0, min(len(a), len(b)) - 1)
    return a[:n], b[:n]


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_interpreter_and_generated_program_agree(
    name: str, programs: dict[str, Path], mosquitto_broker: BrokerProcess,
    raw_client: Callable[..., RawClient], tmp_path: Path,
) -> None:
    scenario = SCENARIOS[name]
    model: CompiledModel = compile_model(scenario.path)
    raw = raw_client(mosquitto_broker)
    raw.subscribe("umlbot/test/orchestrator/status")
    py_code, py_events, py_commands = _interpreter(mosquitto_broker, scenario, raw)
    # the first run's retained final status would stop the second run's fresh services: clear it
    raw.publish("umlbot/test/orchestrator/status", b"", retain=True)
    raw2 = raw_client(mosquitto_broker)  # a fresh subscription: no status of the first run left over
    raw2.subscribe("umlbot/test/orchestrator/status")
    cpp_code, cpp_events, cpp_commands, err = _generated(
        mosquitto_broker, scenario, programs[name], raw2, tmp_path)

    assert (py_code, cpp_code) == (scenario.code, scenario.code), err[-3000:]
    assert py_events and cpp_events
    py_nodes, cpp_nodes = outcomes(py_events), outcomes(cpp_events)
    assert set(py_nodes) == set(cpp_nodes), err[-2000:]
    for key in py_nodes:
        mine, theirs = py_nodes[key], cpp_nodes[key]
        if scenario.loops:
            mine, theirs = _prefix(mine, theirs)
        assert mine == theirs, key
    forked = {lane.name for lane in model.lanes.values()
              if lane.virtual or any(isinstance(n, ForkNode) for n in lane.nodes.values())}
    py_lanes, cpp_lanes = lane_sequences(py_events), lane_sequences(cpp_events)
    for lane, sequence in py_lanes.items():
        if lane in forked:
            continue
        theirs = cpp_lanes[lane]
        if scenario.loops:  # the rounds before the exit request, then the same way out
            n = min(len(sequence), len(theirs)) - 3
            assert sequence[:n] == theirs[:n], lane
            assert sequence[-1] == theirs[-1], lane
        else:
            assert sequence == theirs, lane
    assert set(py_commands) == set(cpp_commands)
    for component, commands in py_commands.items():
        theirs = cpp_commands[component]
        if scenario.loops:
            mine, theirs_cut = _prefix(commands, theirs)
            assert mine == theirs_cut, component
            assert commands[-1:] == theirs[-1:], component  # the safe stop on the way out
        else:
            assert commands == theirs, component
