"""The studio's incremental check equals a check from scratch after every edit (issue 28).

`IncrementalCheck` (what the studio checks its working copy with) reuses what a swimlane whose
text did not change read to and was checked to. Here seeded random sequences of the edits the
studio makes (the operations of `umlbot.studio.edit`: datastore values, guards, calls, nodes and
flows added and removed, renames of nodes and swimlanes, swimlanes added and removed; good ones and
bad ones; text typed into a file, YAML broken and mended; undo) are applied one after the other,
and after each the incremental result is compared with `check_model` of the same files from
scratch: the same diagnostics, the same compiled model, the same source model.
"""

from __future__ import annotations

import random
import sys
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

from umlbot.compiler.api import CheckResult, IncrementalCheck, check_model
from umlbot.compiler.source import read_model_folder
from umlbot.studio.edit import EditError, apply_ops, parse_ops

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "bench"))

from compile import DEPLOYMENT, MODEL, lane_text  # noqa: E402  (bench/compile.py: generated lanes)

Files = dict[str, bytes]

GUARDS = ["true", "false", "not Application.exit", "1 > 2", "'a' < 'b'", "x1 > 3",
          "3 +", "'far' > 2", "Nope.x > 1", "count > 0 and true"]
CALLS = ["msleep(1)", "usleep(5)", "msleep(", "Nope.go()", "LeftActuator.enabled(true)",
         "RightActuator.direction(false)", "Sonar.distance()", "msleep('x')", "MoveForward", "Stop",
         "Helper1", "Helper2", "RaspberryPI"]
VALUES = ["0", "1 + 2", "x1 + 1", "'text'", "true", "1.5", "count + 1", "x +", "Sonar.distance()",
          "Helper1.x1", "RaspberryPI.x1 * 2", "msleep(1)"]
KINDS = ["action", "datastore", "decision", "fork", "join", "send", "accept", "end"]
NAMES = ["alpha", "beta", "gamma", "x1", "count", "MoveForward", "Stop", "Helper1", "msleep", "end"]


def generated_model(root: Path, lanes: int) -> Path:
    """A model folder like the studio benchmark's (swimlanes of 20 nodes that call each other)."""
    (root / "activities").mkdir(parents=True)
    (root / "model.yaml").write_text(MODEL, encoding="utf-8")
    (root / "deployment.yaml").write_text(DEPLOYMENT, encoding="utf-8")
    parts = ["# generated", "lanes:"]
    for index in range(lanes):
        name = "RaspberryPI" if index == 0 else f"Helper{index}"
        callee = f"Helper{index + 1}" if index + 1 < lanes else None
        text = lane_text(name, 20, callee)
        parts.append("\n".join(("  - " if i == 0 else "    ") + line
                               for i, line in enumerate(text.rstrip("\n").splitlines())))
    (root / "activities" / "all.yaml").write_text("\n".join(parts) + "\n", encoding="utf-8")
    return root


def car_model(root: Path) -> Path:
    """The reference car, copied (its activities: comments, flow-style nodes, several files)."""
    for rel, data in read_model_folder(REPO / "models" / "robot_car").items():
        assert isinstance(data, bytes)
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_bytes(data)
    return root


def lanes_of(result: CheckResult) -> dict[str, list[tuple[str, str]]]:
    """Swimlane -> its nodes (id, kind), as the page would know them."""
    if result.source is None:
        return {}
    return {lane.name: [(node.id, node.kind) for node in lane.nodes] for lane in result.source.lanes}


def random_ops(rng: random.Random, lanes: dict[str, list[tuple[str, str]]]) -> list[dict[str, Any]]:
    """One edit of the studio's kinds on a random swimlane and node of the model."""
    lane = rng.choice(sorted(lanes))
    nodes = lanes[lane] or [("start", "start")]
    node, _ = rng.choice(nodes)
    other, _ = rng.choice(nodes)

    def of_kind(*kinds: str) -> str:
        found = [n for n, k in nodes if k in kinds]
        return rng.choice(found) if found else node

    what = rng.choice(["value", "guard", "call", "add", "remove", "connect", "disconnect",
                       "rename_node", "rename_lane", "add_lane", "remove_lane", "signal", "batch"])
    if what == "value":
        return [{"op": "set_node", "lane": lane, "id": of_kind("datastore"),
                 "fields": {"value": rng.choice(VALUES)}}]
    if what == "guard":
        decision = of_kind("decision")
        return [{"op": "set_guard", "lane": lane, "source": decision, "target": other,
                 "guard": rng.choice(GUARDS)}]
    if what == "call":
        return [{"op": "set_node", "lane": lane, "id": of_kind("action"),
                 "fields": {"call": rng.choice(CALLS)}}]
    if what == "add":
        kind = rng.choice(KINDS)
        fields: dict[str, Any] = {"action": {"call": rng.choice(CALLS)},
                                  "datastore": {"name": rng.choice(NAMES), "value": rng.choice(VALUES)},
                                  "send": {"signal": "tick"}, "accept": {"signal": "tick"}}.get(kind, {})
        new = f"n{rng.randrange(1000)}"
        return [{"op": "add_node", "lane": lane, "node": {"id": new, "kind": kind, **fields}},
                {"op": "connect", "lane": lane, "source": node, "target": new}]
    if what == "remove":
        return [{"op": "remove_node", "lane": lane, "id": node}]
    if what == "connect":
        return [{"op": "connect", "lane": lane, "source": node, "target": other}]
    if what == "disconnect":
        return [{"op": "disconnect", "lane": lane, "source": node, "target": other}]
    if what == "rename_node":
        return [{"op": "rename_node", "lane": lane, "id": node, "new_id": rng.choice(NAMES) + "_n"}]
    if what == "rename_lane":
        new_name = rng.choice([*NAMES, f"Lane{rng.randrange(9)}"])
        return [{"op": "rename_lane", "lane": lane, "new_name": new_name}]
    if what == "add_lane":
        return [{"op": "add_lane", "lane": f"New{rng.randrange(50)}"}]
    if what == "remove_lane":
        return [{"op": "remove_lane", "lane": lane}]
    if what == "signal":
        return [{"op": "set_node", "lane": lane, "id": of_kind("send", "accept"),
                 "fields": {"signal": rng.choice(["tick", "tock", "bad name"])}}]
    # a batch, as the properties panel sends: a guard and a call in one request
    return [{"op": "set_guard", "lane": lane, "source": of_kind("decision"), "target": other,
             "guard": rng.choice(GUARDS)},
            {"op": "set_node", "lane": lane, "id": of_kind("action"), "fields": {"call": rng.choice(CALLS)}}]


def typed(rng: random.Random, files: Files) -> Files:
    """Text typed into an activity file (the studio's text view): a line deleted, doubled, broken
    YAML, a character changed, a comment or blank line added (which moves the lines below)."""
    rel = rng.choice(sorted(r for r in files if r.startswith("activities/")))
    lines = files[rel].decode("utf-8").split("\n")
    at = rng.randrange(len(lines))
    how = rng.choice(["delete", "double", "break", "char", "comment", "blank", "alias"])
    if how == "delete":
        del lines[at]
    elif how == "double":
        lines.insert(at, lines[at])
    elif how == "break":
        lines.insert(at, rng.choice(["  - lane: [", "    nodes: {", "\tbad", "lanes: 3", "  - lane: X",
                                     "      - {id: q, kind: action, call: 'a"]))
    elif how == "char" and lines[at]:
        column = rng.randrange(len(lines[at]))
        lines[at] = lines[at][:column] + rng.choice("x:-{ }#'") + lines[at][column + 1:]
    elif how == "comment":
        lines.insert(at, rng.choice(["# a note", "  # indented note", "    # deeper note"]))
    elif how == "blank":
        lines.insert(at, "")
    elif how == "alias":
        lines.insert(at, "      - &a {id: anchored, kind: end}")
    return {**files, rel: "\n".join(lines).encode("utf-8")}


def assert_same(root: Path, files: Files, incremental: IncrementalCheck, step: str) -> CheckResult:
    got = incremental.check(root, files=files)
    want = check_model(root, files=files)
    assert [str(d) for d in got.diagnostics] == [str(d) for d in want.diagnostics], step
    assert got.model == want.model, step
    assert got.source == want.source, step
    return got


def run_sequence(root: Path, seed: int, steps: int) -> Counter[str]:
    rng = random.Random(seed)
    files: Files = {rel: data for rel, data in read_model_folder(root).items() if isinstance(data, bytes)}
    incremental = IncrementalCheck()
    result = assert_same(root, files, incremental, "first check")
    known = lanes_of(result)
    history: list[Files] = [files]
    good: list[Files] = [files]  # states that compiled: a person mends a model, or undoes
    done: Counter[str] = Counter()
    for step in range(steps):
        roll = rng.random()
        if roll < 0.15:
            files, what = typed(rng, files), "typed"
        elif roll < 0.22 and len(history) > 1:
            files, what = history[rng.randrange(len(history))], "undo"
        elif roll < 0.4 and not result.ok:
            files, what = good[rng.randrange(len(good))], "mended"
        else:
            raw = random_ops(rng, known)
            texts = {rel: data.decode("utf-8") for rel, data in files.items()}
            try:
                changes = apply_ops(texts, parse_ops(raw))
            except EditError:
                done["refused"] += 1
                continue
            files = dict(files)
            for rel, text in changes.items():
                if text is None:
                    files.pop(rel, None)
                else:
                    files[rel] = text.encode("utf-8")
            what = raw[0]["op"]
        result = assert_same(root, files, incremental, f"seed {seed}, step {step} ({what})")
        done[what] += 1
        done["ok" if result.ok else "errors"] += 1
        history.append(files)
        if result.ok:
            good.append(files)
        if result.source is not None and result.source.lanes:
            known = lanes_of(result)
    done.update({f"lanes {k}": v for k, v in incremental.lanes.stats.items()})
    return done


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_incremental_equals_full_on_the_car(tmp_path: Path, seed: int) -> None:
    done = run_sequence(car_model(tmp_path / "car"), seed, 80)
    # the sequence made edits of many kinds, good and bad, and the lanes were really reused
    assert done["ok"] > 0 and done["errors"] > 0, done
    assert sum(done[k] for k in ("set_node", "set_guard", "add_node", "remove_node", "connect")) >= 10, done
    assert done["lanes reused"] > done["lanes read"], done


@pytest.mark.parametrize("seed", [4, 5])
def test_incremental_equals_full_on_a_generated_model(tmp_path: Path, seed: int) -> None:
    done = run_sequence(generated_model(tmp_path / "gen", 6), seed, 80)
    assert done["ok"] > 0 and done["errors"] > 0, done
    assert done["lanes reused"] > done["lanes read"], done


def test_a_stale_reuse_would_be_caught(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The comparison catches a swimlane kept from before what it names changed: with the scope's
    key made blind (a memo that does not see that another swimlane's datastore changed type), the
    incremental result differs from the check from scratch, and `assert_same` says so."""
    root = generated_model(tmp_path / "gen", 3)
    files: Files = {rel: data for rel, data in read_model_folder(root).items() if isinstance(data, bytes)}
    text = files["activities/all.yaml"].decode("utf-8")
    first = "name: x0, value: 0 * 2 + 1"
    assert text.count(first) == 3
    # RaspberryPI's x0 reads Helper1's x0; then Helper1's x0 becomes a text (same lines)
    reads = text.replace(first, "name: x0, value: Helper1.x0 + 1", 1)
    typed_text = reads.replace(first, "name: x0, value: \"'zero'\"", 1)
    before = {**files, "activities/all.yaml": reads.encode("utf-8")}
    after = {**files, "activities/all.yaml": typed_text.encode("utf-8")}
    assert check_model(root, files=before).ok
    assert not check_model(root, files=after).ok  # '+' needs numbers, got str and int
    good = IncrementalCheck()
    assert_same(root, before, good, "before")
    assert_same(root, after, good, "after")
    from umlbot.compiler import checker

    monkeypatch.setattr(checker._Checker, "scope_key", lambda self: ())
    blind = IncrementalCheck()
    assert_same(root, before, blind, "before")
    with pytest.raises(AssertionError):
        assert_same(root, after, blind, "after")


TRICKY = [
    # comments between and inside swimlanes, at the list's indent and at none
    "# top\nlanes:   # the list\n  - lane: A\n    nodes:\n      - {id: s, kind: start}\n"
    "  # between\n# at none\n      - {id: e, kind: end}\n\n  - lane: B\n    nodes: [{id: s, kind: start},\n"
    "      {id: e, kind: end}]\n",
    # a quoted scalar whose second line looks like the next swimlane
    "lanes:\n  - lane: A\n    nodes:\n      - {id: s, kind: start, next: \"e\n  - lane: Fake\"}\n"
    "      - {id: e, kind: end}\n  - lane: B\n    nodes: []\n",
    # a block scalar, a plain scalar over two lines
    "lanes:\n  - lane: A\n    nodes:\n      - id: c\n        kind: action\n        call: |\n"
    "          msleep(1)\n"
    "      - id: d\n        kind: action\n        call: msleep(\n          2)\n  - lane: B\n    nodes: 3\n",
    # the list at no indent; an anchor and its alias in two swimlanes (read whole)
    "lanes:\n- lane: A\n  nodes: &n [{id: s, kind: start}]\n- lane: B\n  nodes: *n\n",
    # a duplicate key, another key of the file, a second document
    "lanes:\n  - lane: A\n    lane: B\n    nodes: []\n",
    "lanes:\n  - lane: A\n    nodes: []\nother: 1\n",
    "lanes:\n  - lane: A\n    nodes: []\n---\nlanes: []\n",
    # one swimlane without a list; an empty file; not YAML
    "lane: A\nnodes:\n  - {id: s, kind: start}\n", "", "lanes:\n  - lane: [\n",
]


@pytest.mark.parametrize("text", TRICKY)
def test_pieces_read_as_the_whole_file(tmp_path: Path, text: str) -> None:
    root = generated_model(tmp_path / "gen", 1)
    files: Files = {rel: data for rel, data in read_model_folder(root).items() if isinstance(data, bytes)}
    files["activities/tricky.yaml"] = text.encode("utf-8")
    incremental = IncrementalCheck()
    assert_same(root, files, incremental, "first")
    assert_same(root, files, incremental, "again")  # what was kept


def test_the_studios_answer_equals_one_made_from_scratch(tmp_path: Path) -> None:
    """The studio's answer after each edit (its model view with the swimlanes' views it kept, its
    diagnostics) equals the one made from a check from scratch of the same working copy."""
    from umlbot.studio.model_view import source_view
    from umlbot.studio.workspace import Workspace

    root = car_model(tmp_path / "car")
    ws = Workspace(root)
    ws.check()
    rng = random.Random(11)
    made = 0
    for _ in range(40):
        assert ws.result is not None
        try:
            ws.edit(ws.version, random_ops(rng, lanes_of(ws.result) or {"RaspberryPI": []}))
        except EditError:
            continue
        made += 1
        got = dict(ws.answer_cache)
        fresh = check_model(root, files=ws.files)
        assert fresh.source is not None
        assert got["model"] == source_view(fresh.source)
        ws.check(fresh)  # the same answer made without what was kept for this working copy
        assert got["diagnostics"] == ws.answer_cache["diagnostics"]
    assert made >= 15
