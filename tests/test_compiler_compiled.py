"""The compiled model file: deterministic bytes, round trip, version refusal, what it holds."""

from __future__ import annotations

import json
import os
import shutil
import stat
from pathlib import Path

import pytest
from compiler_support import HEADER, MAIN

from umlbot.base.errors import CompiledModelError, ConfigError
from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import (
    FORMAT_VERSION,
    AcceptNode,
    ActionNode,
    CompiledModel,
    DatastoreNode,
    DecisionNode,
    ForkNode,
    JoinNode,
    SendNode,
    dump_compiled,
    load_compiled,
    write_compiled,
)
from umlbot.compiler.expr import Binary, BuiltinTarget, Call, Const, FeatureTarget, LaneTarget, Ref

ROBOT_CAR = Path(__file__).resolve().parent.parent / "models" / "robot_car"

EVERY_KIND = HEADER + """\
  - lane: Pi
    nodes:
      - {id: start, kind: start}
      - {id: count0, kind: datastore, name: count, value: 0}
      - {id: ask, kind: send, signal: ping, payload: count * 2 + 1}
      - {id: wait, kind: accept, signal: pong, store: answer}
      - {id: both, kind: fork, targets: [left, right]}
      - {id: left, kind: action, call: Motor.direction(true), next: inner}
      - {id: inner, kind: fork, targets: [s1, s2]}
      - {id: s1, kind: action, call: usleep(100), next: inner_join}
      - {id: s2, kind: action, call: msleep(1), next: inner_join}
      - {id: inner_join, kind: join, next: joined}
      - {id: right, kind: action, call: Helper(), next: joined}
      - {id: joined, kind: join}
      - {id: count1, kind: datastore, name: count, value: count + 1}
      - id: loop
        kind: decision
        branches:
          - {else: done}
          - {if: count < 3 and not Application.exit, then: ask}
      - {id: done, kind: action, call: Motor.enabled(false)}
      - {id: end, kind: end}
  - lane: Helper
    nodes:
      - {id: start, kind: start}
      - {id: far, kind: datastore, name: far, value: Sonar.value() / 2 > Pi.count}
      - {id: end, kind: end}
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "model.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_every_node_kind_compiles_to_a_resolved_graph(tmp_path: Path) -> None:
    model = compile_model(write(tmp_path, EVERY_KIND))
    pi = model.lanes["Pi"]
    assert (pi.virtual, pi.component, pi.start) == (False, "Pi", "start")
    assert pi.datastores == ["answer", "count"]
    assert model.lanes["Helper"].virtual and model.lanes["Helper"].component is None
    assert model.signals == ["ping", "pong"]
    nodes = pi.nodes
    assert isinstance(nodes["both"], ForkNode) and nodes["both"].join == "joined"
    assert isinstance(nodes["inner"], ForkNode) and nodes["inner"].join == "inner_join"
    joined = nodes["joined"]
    assert isinstance(joined, JoinNode) and joined.incoming == ["inner_join", "right"]
    assert joined.next == "count1"
    send = nodes["ask"]
    assert isinstance(send, SendNode) and send.signal == "ping"
    assert send.payload == Binary(operator="+", left=Binary(operator="*", left=Ref(lane="Pi", name="count"),
                                                             right=Const(value=2)), right=Const(value=1))
    accept = nodes["wait"]
    assert isinstance(accept, AcceptNode) and accept.store == "answer" and accept.next == "both"
    call = nodes["right"]
    assert isinstance(call, ActionNode) and call.call.target == LaneTarget(lane="Helper")
    decision = nodes["loop"]
    assert isinstance(decision, DecisionNode)
    # the else output is always last, whatever its place in the source
    assert [b.target for b in decision.branches] == ["ask", "done"]
    assert decision.branches[1].guard is None and decision.branches[1].label == "else"
    guard = decision.branches[0].guard
    assert isinstance(guard, Binary) and guard.operator == "and"
    assert guard.right.model_dump() == {"op": "unary", "operator": "not", "operand": Call(
        target=BuiltinTarget(name="Application.exit")).model_dump()}
    far = model.lanes["Helper"].nodes["far"]
    assert isinstance(far, DatastoreNode)
    assert far.value == Binary(
        operator=">",
        left=Binary(operator="/", left=Call(target=FeatureTarget(component="Sonar", feature="value")),
                    right=Const(value=2)),
        right=Ref(lane="Pi", name="count"))
    assert model.components["Motor"].model_dump() == {
        "kind": "actuator", "impl": "l298n", "service": "motor", "driver": "mock", "settings": {},
        "features": ["direction", "dutycycle", "enabled"], "ports": {"drive": "enabled"},
        "safe_stop": [{"feature": "enabled", "args": [False]}]}
    assert nodes["count1"].line == 31 and pi.file == "model.yaml" and pi.line == 17


def test_compile_is_deterministic(tmp_path: Path) -> None:
    first = dump_compiled(compile_model(ROBOT_CAR))
    copy = tmp_path / "elsewhere" / "robot_car"
    shutil.copytree(ROBOT_CAR, copy)
    second = dump_compiled(compile_model(copy))
    assert first == second
    assert dump_compiled(compile_model(ROBOT_CAR)) == first
    assert b"elsewhere" not in second and str(ROBOT_CAR).encode() not in first


def test_source_hash_follows_the_content(tmp_path: Path) -> None:
    copy = tmp_path / "robot_car"
    shutil.copytree(ROBOT_CAR, copy)
    before = compile_model(copy).source_hash
    assert before.startswith("sha256:") and len(before) == len("sha256:") + 64
    main = copy / "activities" / "main.yaml"
    main.write_text(main.read_text(encoding="utf-8") + "# one more line\n", encoding="utf-8")
    assert compile_model(copy).source_hash != before


def test_round_trip(tmp_path: Path) -> None:
    model = compile_model(write(tmp_path, EVERY_KIND))
    data = dump_compiled(model)
    target = tmp_path / "out.json"
    target.write_bytes(data)
    loaded = load_compiled(target)
    assert loaded == model
    assert load_compiled(data) == model
    assert dump_compiled(loaded) == data
    assert json.loads(data)["format_version"] == FORMAT_VERSION


def test_a_newer_format_version_is_refused(tmp_path: Path) -> None:
    data = json.loads(dump_compiled(compile_model(write(tmp_path, HEADER + MAIN))))
    data["format_version"] = FORMAT_VERSION + 1
    path = tmp_path / "future.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    newer = rf"format version {FORMAT_VERSION + 1} is newer than this umlbot reads \(up to {FORMAT_VERSION}\)"
    with pytest.raises(CompiledModelError, match=newer + "; upgrade umlbot"):
        load_compiled(path)


def test_an_older_format_version_is_refused_with_the_way_out(tmp_path: Path) -> None:
    """A file of format 1 has no safe stops: run, its actuators would never be stopped."""
    data = json.loads(dump_compiled(compile_model(write(tmp_path, HEADER + MAIN))))
    data["format_version"] = 1
    for component in data["components"].values():
        del component["safe_stop"]
    with pytest.raises(CompiledModelError, match=r"format version 1 was written by an older umlbot \(this "
                                                   rf"one reads {FORMAT_VERSION}\); compile the model again"):
        load_compiled(json.dumps(data).encode())


@pytest.mark.parametrize("content", [b"", b"\xff\xfe", b"[1, 2]", b"{}", b'{"format_version": "1"}',
                                     b'{"format_version": 2}', b'{"format_version": 2, "name": 3}',
                                     b"[" * 100_000])
def test_corrupt_files_are_refused(content: bytes) -> None:
    with pytest.raises(CompiledModelError):
        load_compiled(content)


def test_unreadable_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(CompiledModelError, match="cannot read compiled model"):
        load_compiled(tmp_path / "missing.json")


def test_compiled_types_validate_what_they_load() -> None:
    model = CompiledModel(name="x", source_hash="sha256:0")
    data = json.loads(dump_compiled(model))
    data["lanes"] = {"L": {"name": "L", "virtual": True, "start": "s",
                           "nodes": {"s": {"id": "s", "kind": "teleport"}}}}
    with pytest.raises(CompiledModelError, match="corrupt compiled model"):
        load_compiled(json.dumps(data).encode())


def test_null_literal_compares_with_an_unwritten_datastore(tmp_path: Path) -> None:
    text = HEADER + """\
  - lane: Pi
    nodes:
      - {id: start, kind: start}
      - {id: wait, kind: accept, signal: go, store: speed}
      - {id: d, kind: decision, branches: [{if: speed == null, then: end}, {else: set}]}
      - {id: set, kind: action, call: Motor.dutycycle(speed)}
      - {id: end, kind: end}
"""
    model = compile_model(write(tmp_path, text))
    decision = model.lanes["Pi"].nodes["d"]
    assert isinstance(decision, DecisionNode)
    assert decision.branches[0].guard == Binary(operator="==", left=Ref(lane="Pi", name="speed"),
                                                right=Const(value=None))


def test_write_compiled_replaces_the_file_whole(tmp_path: Path) -> None:
    model = compile_model(ROBOT_CAR)
    target = tmp_path / "new" / "car.json"  # its folder is made
    write_compiled(model, target)
    assert target.read_bytes() == dump_compiled(model)
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask  # an ordinary file, not 0600
    target.write_bytes(b"old")
    target.chmod(0o640)
    write_compiled(model, target)
    assert load_compiled(target) == model
    assert stat.S_IMODE(target.stat().st_mode) == 0o640  # the replaced file's mode is kept
    assert sorted(p.name for p in target.parent.iterdir()) == ["car.json"]  # no temporary left


def test_write_compiled_names_a_path_it_cannot_write(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"cannot write .*file/car.json: .*file is not a folder"):
        write_compiled(compile_model(ROBOT_CAR), tmp_path / "file" / "car.json")
    assert (tmp_path / "file").read_text(encoding="utf-8") == "x"
