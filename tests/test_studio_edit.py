"""The studio's editing over real sockets: operations as text edits, checks with `umlbot check`'s
messages, undo/redo, saving (atomic, inside the folder, byte-identical round trip), files changed
on disk, a new model, and who may write."""

from __future__ import annotations

import asyncio
import difflib
import http.client
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import aiohttp
import pytest
from click.testing import CliRunner
from compiler_support import position, with_left_out
from conftest import BrokerProcess
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from robot_run import CAR_MODEL, umlbot_argv
from studio_support import Editor, events_of, read_frames, snapshot, studio

from umlbot.base import files as user_files
from umlbot.cli import cli
from umlbot.compiler.api import check_model
from umlbot.compiler.compiled import dump_compiled
from umlbot.studio.edit import EditError, apply_ops, parse_ops
from umlbot.studio.model_view import model_view, source_view
from umlbot.studio.workspace import LAYOUT_FILE, Workspace, model_files, read_layout, safe_path

REPO = Path(__file__).resolve().parent.parent


def _bench_compile() -> Any:
    spec = importlib.util.spec_from_file_location("bench_compile", REPO / "bench" / "compile.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["bench_compile"] = module
    spec.loader.exec_module(module)
    return module


def _texts(root: Path) -> dict[str, str]:
    files = model_files(root)
    texts = {rel: data.decode("utf-8") for rel, data in files.items() if isinstance(data, bytes)}
    assert len(texts) == len(files), "every file of the model was read"
    return texts


def _apply(files: dict[str, str], ops: list[dict[str, Any]]) -> dict[str, str]:
    out: dict[str, str | None] = dict(files)
    out.update(apply_ops(files, parse_ops(ops)))
    return {rel: text for rel, text in out.items() if text is not None}


def _check(root: Path, files: dict[str, str]) -> Any:
    return check_model(root, files={rel: text.encode() for rel, text in files.items()})


def _changed_lines(before: str, after: str) -> tuple[list[str], list[str]]:
    removed, added = [], []
    for line in difflib.ndiff(before.splitlines(), after.splitlines()):
        if line.startswith("- "):
            removed.append(line[2:])
        elif line.startswith("+ "):
            added.append(line[2:])
    return removed, added


# --- operations as text edits ------------------------------------------------------------------------


def test_set_node_changes_only_that_value_and_compiles_to_the_new_value() -> None:
    files = _texts(CAR_MODEL)
    out = _apply(files, [{"op": "set_node", "lane": "RaspberryPI", "id": "set_speed",
                          "fields": {"value": "55"}}])
    removed, added = _changed_lines(files["activities/main.yaml"], out["activities/main.yaml"])
    assert removed == ["  - {id: set_speed, kind: datastore, name: speed_percent, value: 70}"]
    assert added == ["  - {id: set_speed, kind: datastore, name: speed_percent, value: 55}"]
    assert all(out[rel] == files[rel] for rel in files if rel != "activities/main.yaml")
    result = _check(CAR_MODEL, out)
    assert result.model is not None
    node = result.model.lanes["RaspberryPI"].nodes["set_speed"]
    assert node.label == "speed_percent = 55"


def test_every_node_of_the_car_rewritten_with_its_own_fields_leaves_the_files_identical() -> None:
    """set_node of a node's own values is a no-op: located and written exactly."""
    files = _texts(CAR_MODEL)
    view = source_view(_check(CAR_MODEL, files).source)
    ops = [{"op": "set_node", "lane": lane["name"], "id": node["id"],
            "fields": {k: v for k, v in node["fields"].items() if isinstance(v, str)}}
           for diagram in view["diagrams"] for lane in diagram["lanes"] for node in lane["nodes"]]
    assert len(ops) > 50
    assert _apply(files, ops) == files


def test_building_the_stop_lane_from_a_starter_gives_the_reference_cars_stop(tmp_path: Path) -> None:
    ws = Workspace(tmp_path / "my_robot")
    assert ws.empty
    ws.new_model(None)
    ops: list[dict[str, Any]] = [
        {"op": "add_lane", "lane": "Stop"},
        {"op": "add_node", "lane": "Stop", "node": {"id": "both", "kind": "fork"}},
        {"op": "add_node", "lane": "Stop", "node": {"id": "left_off", "kind": "action",
                                                   "call": "LeftActuator.enabled(false)"}},
        {"op": "add_node", "lane": "Stop", "node": {"id": "right_off", "kind": "action"}},
        {"op": "set_node", "lane": "Stop", "id": "right_off",
         "fields": {"call": "RightActuator.enabled(false)"}},
        {"op": "add_node", "lane": "Stop", "node": {"id": "stopped", "kind": "join"}},
        {"op": "connect", "lane": "Stop", "source": "start", "target": "both"},
        {"op": "connect", "lane": "Stop", "source": "both", "target": "left_off"},
        {"op": "connect", "lane": "Stop", "source": "both", "target": "right_off"},
        {"op": "connect", "lane": "Stop", "source": "left_off", "target": "stopped"},
        {"op": "connect", "lane": "Stop", "source": "right_off", "target": "stopped"},
        {"op": "connect", "lane": "Stop", "source": "stopped", "target": "end"},
        {"op": "add_node", "lane": "RaspberryPI", "node": {"id": "halt", "kind": "action",
                                                          "call": "Stop"}},
        {"op": "connect", "lane": "RaspberryPI", "source": "start", "target": "halt"},
        {"op": "connect", "lane": "RaspberryPI", "source": "halt", "target": "end"},
    ]
    answer = ws.edit(ws.version, ops)
    assert answer["compiled"], answer["diagnostics"]
    assert ws.result is not None and ws.result.model is not None
    ws.save(ws.version)
    built = check_model(tmp_path / "my_robot")
    reference = check_model(CAR_MODEL)
    assert built.model is not None and reference.model is not None
    mine = model_view(built.model)
    ref = model_view(reference.model)

    def lane(view: dict[str, Any], name: str) -> dict[str, Any]:
        return next(x for d in view["diagrams"] for x in d["lanes"] if x["name"] == name)

    def shape(x: dict[str, Any]) -> tuple[Any, ...]:
        return (sorted((n["id"], n["kind"], n["label"]) for n in x["nodes"]),
                sorted((e["source"], e["target"], e["label"]) for e in x["edges"]))

    assert shape(lane(mine, "Stop")) == shape(lane(ref, "Stop"))
    text = (tmp_path / "my_robot" / "activities" / "stop.yaml").read_text(encoding="utf-8")
    assert "  - {id: left_off, kind: action, call: LeftActuator.enabled(false), next: stopped}\n" in text


def test_edits_on_a_generated_model_touch_only_the_edited_lines(tmp_path: Path) -> None:
    root = _bench_compile().generate(tmp_path / "gen", 1_000)
    files = _texts(root)
    before = _check(root, files)
    assert before.model is not None
    rel = "activities/lane0003.yaml"
    ops: list[dict[str, Any]] = [
        {"op": "set_node", "lane": "Helper3", "id": "b2_wait", "fields": {"call": "usleep(5)"}},
        {"op": "set_guard", "lane": "Helper3", "source": "b4_choose", "target": "b4_fork",
         "guard": "d4 > 30"},
        {"op": "add_node", "lane": "Helper3", "node": {"id": "extra", "kind": "action", "call": "msleep(2)"}},
        {"op": "connect", "lane": "Helper3", "source": "extra", "target": "b1_x"},
        {"op": "connect", "lane": "Helper3", "source": "b0_wait", "target": "extra"},
    ]
    out = _apply(files, ops)
    assert [r for r in files if out[r] != files[r]] == [rel]
    removed, added = _changed_lines(files[rel], out[rel])
    assert removed == ["  - {id: b0_wait, kind: action, call: usleep(x0 * 10)}",
                       "  - {id: b2_wait, kind: action, call: usleep(x2 * 10)}",
                       "    branches: [{if: d4 > 20 and not Application.exit, then: b4_fork}, "
                       "{else: b4_call}]"]
    assert added == ["  - {id: b0_wait, kind: action, call: usleep(x0 * 10), next: extra}",
                     "  - {id: b2_wait, kind: action, call: usleep(5)}",
                     "    branches: [{if: d4 > 30, then: b4_fork}, {else: b4_call}]",
                     "  - {id: extra, kind: action, call: msleep(2), next: b1_x}"]
    after = _check(root, out)
    assert after.model is not None, [str(d) for d in after.diagnostics]
    lane = after.model.lanes["Helper3"]
    assert lane.nodes["b0_wait"].next == "extra" and lane.nodes["extra"].next == "b1_x"
    assert len(lane.nodes) == len(before.model.lanes["Helper3"].nodes) + 1


def test_a_decisions_second_output_waits_for_its_guard_and_the_else_stays_last(tmp_path: Path) -> None:
    # the reviewer's steps: decision1 -> action1, then decision1 -> end. No guard was typed, so none
    # may be made up: the new output's guard is empty, drawn "?", and the checker reports it on the
    # decision until the user types one
    ws = Workspace(tmp_path / "bot")
    ws.new_model("bot")
    ws.edit(ws.version, [
        {"op": "add_node", "lane": "RaspberryPI", "node": {"id": "decision1", "kind": "decision"}},
        {"op": "add_node", "lane": "RaspberryPI", "node": {"id": "action1", "kind": "action",
                                                          "call": "msleep(10)"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "start", "fields": {"next": "decision1"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "action1", "fields": {"next": "end"}},
    ])
    connect = {"op": "connect", "lane": "RaspberryPI", "source": "decision1"}
    ws.edit(ws.version, [{**connect, "target": "action1"}])
    answer = ws.edit(ws.version, [{**connect, "target": "end"}])
    text = ws.texts()["activities/main.yaml"]
    assert "branches: [{if: '', then: end}, {else: action1}]" in text, text
    assert not answer["compiled"]
    on_decision = [d for d in answer["diagnostics"] if d["node"] == "decision1"]
    assert [d["message"] for d in on_decision] == [
        "decision output without guard: write {if: <guard>, then: <node>} or {else: <node>}"]
    lane = next(lane for d in answer["model"]["diagrams"] for lane in d["lanes"]
                if lane["name"] == "RaspberryPI")
    assert {(e["target"], e["label"]) for e in lane["edges"] if e["source"] == "decision1"} == {
        ("action1", "else"), ("end", "?")}
    answer = ws.edit(ws.version, [{"op": "set_guard", "lane": "RaspberryPI", "source": "decision1",
                                   "target": "end", "guard": "Application.exit"}])
    assert answer["compiled"], answer["diagnostics"]
    text = ws.texts()["activities/main.yaml"]
    assert "branches: [{if: Application.exit, then: end}, {else: action1}]" in text, text
    # a guard given with the connection goes before the else too; a second else is refused
    ws.edit(ws.version, [{**connect, "target": "action1", "guard": "1 > 2"}])
    assert "[{if: Application.exit, then: end}, {if: 1 > 2, then: action1}, {else: action1}]" \
        in ws.texts()["activities/main.yaml"]
    with pytest.raises(EditError, match="has an else output already"):
        ws.edit(ws.version, [{**connect, "target": "end", "guard": "else"}])


def test_new_nodes_are_labelled_with_what_is_written_and_nothing_made_up(tmp_path: Path) -> None:
    ws = Workspace(tmp_path / "bot")
    ws.new_model("bot")
    answer = ws.edit(ws.version, [
        {"op": "add_node", "lane": "RaspberryPI", "node": {"id": kind + "1", "kind": kind}}
        for kind in ("datastore", "send", "accept", "action")])

    def labels(answer: dict[str, Any]) -> dict[str, str]:
        return {n["id"]: n["label"] for d in answer["model"]["diagrams"] for lane in d["lanes"]
                for n in lane["nodes"]}

    assert labels(answer) | {"start": "start", "end": "end"} == {
        "start": "start", "end": "end", "datastore1": "datastore1", "send1": "send", "accept1": "accept",
        "action1": "action1"}
    answer = ws.edit(ws.version, [
        {"op": "set_node", "lane": "RaspberryPI", "id": "datastore1", "fields": {"value": "0"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "send1", "fields": {"payload": "1"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "accept1", "fields": {"store": "got"}}])
    assert {k: v for k, v in labels(answer).items() if k.endswith("1")} == {
        "datastore1": "? = 0", "send1": "send(1)", "accept1": "accept -> got", "action1": "action1"}
    answer = ws.edit(ws.version, [
        {"op": "set_node", "lane": "RaspberryPI", "id": "datastore1", "fields": {"name": "count"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "send1", "fields": {"signal": "tick"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "accept1", "fields": {"signal": "tick"}}])
    assert {k: v for k, v in labels(answer).items() if k.endswith("1")} == {
        "datastore1": "count = 0", "send1": "send tick(1)", "accept1": "accept tick -> got",
        "action1": "action1"}


def test_the_answer_names_the_files_a_lane_can_be_added_to(tmp_path: Path) -> None:
    ws = Workspace(tmp_path / "bot")
    ws.new_model("bot")
    assert ws.answer()["lane_files"] == []  # the starter's main.yaml is one lane, not a list
    with pytest.raises(EditError, match="holds no block list of 'lanes:'"):
        ws.edit(ws.version, [{"op": "add_lane", "lane": "Wait", "file": "activities/main.yaml"}])
    car = Workspace(shutil.copytree(CAR_MODEL, tmp_path / "car"))
    assert car.hello()["lane_files"] == ["activities/measure.yaml", "activities/motion.yaml"]
    car.edit(car.version, [{"op": "add_lane", "lane": "Wait", "file": "activities/measure.yaml"}])
    assert "  - lane: Wait" in car.texts()["activities/measure.yaml"]
    # a file with an empty (flow-style) list takes none: the page does not offer it
    (tmp_path / "car" / "activities" / "extra.yaml").write_text("lanes: []\n", encoding="utf-8")
    assert [f["type"] for f in car.poll()] == ["files"]
    assert car.answer()["lane_files"] == ["activities/measure.yaml", "activities/motion.yaml"]


def test_fields_set_in_any_order_are_written_in_the_order_people_write_them(tmp_path: Path) -> None:
    # connect first, type the call after: the file reads `call: …, next: …` as models/robot_car does
    ws = Workspace(tmp_path / "bot")
    ws.new_model("bot")
    ws.edit(ws.version, [
        {"op": "add_node", "lane": "RaspberryPI", "node": {"id": "action1", "kind": "action"}},
        {"op": "connect", "lane": "RaspberryPI", "source": "action1", "target": "end"},
        {"op": "set_node", "lane": "RaspberryPI", "id": "action1", "fields": {"call": "msleep(10)"}},
        {"op": "add_node", "lane": "RaspberryPI", "node": {"id": "keep", "kind": "datastore"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "keep", "fields": {"next": "end"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "keep", "fields": {"value": "3"}},
        {"op": "set_node", "lane": "RaspberryPI", "id": "keep", "fields": {"name": "count"}},
    ])
    text = ws.texts()["activities/main.yaml"]
    assert "{id: action1, kind: action, call: msleep(10), next: end}" in text, text
    assert "{id: keep, kind: datastore, name: count, value: 3, next: end}" in text, text


def test_impossible_operations_name_the_problem() -> None:
    files = _texts(CAR_MODEL)
    cases = [
        ({"op": "add_node", "lane": "Nope", "node": {"kind": "end"}}, "no swimlane 'Nope'"),
        ({"op": "add_node", "lane": "Stop", "node": {"id": "both", "kind": "end"}}, "has a node 'both'"),
        ({"op": "add_node", "lane": "Stop", "node": {"kind": "action", "guard": "x"}}, "no 'guard'"),
        ({"op": "set_node", "lane": "Stop", "id": "both", "fields": {"call": "x"}},
         "fork node has no 'call'"),
        ({"op": "connect", "lane": "Stop", "source": "end", "target": "start"}, "no outgoing flow"),
        ({"op": "set_deployment", "component": "Sensor", "impl": "servo", "settings": {"gpio": 40}},
         "Sensor: invalid settings: gpio"),
        ({"op": "frobnicate"}, "unknown op 'frobnicate'"),
    ]
    for op, message in cases:
        with pytest.raises(EditError, match=message):
            apply_ops(files, parse_ops([op]))


def test_paths_outside_the_model_folder_are_refused(tmp_path: Path) -> None:
    root = tmp_path / "m"
    root.mkdir()
    (tmp_path / "outside").mkdir()
    os.symlink(tmp_path / "outside", root / "activities")
    for rel in ("../x.yaml", "/etc/passwd", "activities/x.yaml", "", "a/../../x"):
        with pytest.raises(ValueError):
            safe_path(root, rel)
    assert safe_path(root, "model.yaml") == (root / "model.yaml").resolve()


# --- the server ------------------------------------------------------------------------------------


def test_open_then_save_without_edits_writes_nothing(car: tuple[Path, Editor]) -> None:
    root, editor = car
    before = snapshot(root)
    mtimes = {p: p.stat().st_mtime_ns for p in root.rglob("*") if p.is_file()}
    hello = read_frames(editor.url, lambda f: len(f) >= 1)[0]
    assert hello["edit"]["token"] == editor.token and hello["edit"]["dirty"] is False
    status, answer = editor.post("save", {"version": hello["edit"]["version"]})
    assert status == 200 and answer["saved"] == []
    assert snapshot(root) == before
    assert {p: p.stat().st_mtime_ns for p in root.rglob("*") if p.is_file()} == mtimes


def test_an_edit_of_a_file_linked_from_outside_the_folder_is_refused_at_once(tmp_path: Path) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    outside = tmp_path / "outside.yaml"
    outside.write_text("lanes:\n  - lane: Elsewhere\n    nodes:\n      - {id: start, kind: start}\n"
                       "      - {id: end, kind: end}\n      - {from: start, to: end}\n", encoding="utf-8")
    (root / "activities" / "link.yaml").symlink_to(outside)
    before = outside.read_bytes()
    editor = Editor(root)
    try:
        status, answer = editor.post("edit", {"version": 0, "ops": [
            {"op": "add_lane", "lane": "Halt", "file": "activities/link.yaml"}]})
        assert status == 400, answer
        assert "'activities/link.yaml' is not a path inside the model folder" in answer["error"], answer
        # nothing changed, and an edit elsewhere is saved as usual
        status, answer = editor.post("edit", {"version": answer.get("version", 0), "ops": [
            {"op": "set_node", "lane": "RaspberryPI", "id": "set_speed", "fields": {"value": "60"}}]})
        assert status == 200, answer
        status, saved = editor.post("save", {"version": answer["version"]})
        assert status == 200 and saved["saved"] == ["activities/main.yaml"], saved
    finally:
        editor.thread.stop()
    assert outside.read_bytes() == before


def test_generated_model_round_trip_and_undo_is_byte_identical(tmp_path: Path) -> None:
    root = _bench_compile().generate(tmp_path / "gen", 500)
    before = snapshot(root)
    editor = Editor(root)
    try:
        status, answer = editor.post("edit", {"version": 0, "ops": [
            {"op": "set_node", "lane": "Helper2", "id": "b3_x", "fields": {"value": "7"}},
            {"op": "remove_node", "lane": "Helper2", "id": "b3_wait"}]})
        assert status == 200 and answer["changed"] == ["activities/lane0002.yaml"] and answer["dirty"]
        status, answer = editor.post("undo", {})
        assert status == 200 and not answer["dirty"]
        status, answer = editor.post("save", {"version": answer["version"]})
        assert status == 200 and answer["saved"] == []
    finally:
        editor.thread.stop()
    assert snapshot(root) == before


def test_an_edit_answers_with_umlbot_checks_messages_on_the_node(car: tuple[Path, Editor]) -> None:
    root, editor = car
    status, answer = editor.post("edit", {"version": 0, "ops": [
        {"op": "connect", "lane": "RaspberryPI", "source": "choose", "target": "halt",
         "guard": "Measure.center > 'far'"}]})
    assert status == 200 and not answer["compiled"]
    assert answer["model"]["diagrams"]  # the editor still draws the model
    shown = [d for d in answer["diagnostics"] if d["severity"] == "error"]
    assert [(d["lane"], d["node"]) for d in shown] == [("RaspberryPI", "choose")]
    # the same text on disk gives the same lines from `umlbot check`
    status, saved = editor.post("save", {"version": answer["version"]})
    assert status == 200 and saved["saved"] == ["activities/main.yaml"]
    check = subprocess.run(umlbot_argv("check", str(root)), capture_output=True, text=True, timeout=60,
                           check=False)
    assert check.returncode == 1
    printed = [line for line in check.stdout.splitlines() + check.stderr.splitlines() if ": error: " in line]
    assert printed == [d["text"] for d in shown]
    # undo brings the old text back; redo the new one
    status, undone = editor.post("undo", {})
    assert status == 200 and undone["compiled"] and undone["dirty"]
    status, redone = editor.post("redo", {})
    assert status == 200 and not redone["compiled"] and not redone["dirty"]


def test_a_refused_edit_names_the_field_in_words_for_the_page(car: tuple[Path, Editor]) -> None:
    """A bad setting or name is answered with the field it is about and a message without the
    operation's number (what the page shows next to that field)."""
    _, editor = car
    version = editor.workspace.version
    status, answer = editor.post("edit", {"version": version, "ops": [
        {"op": "add_component", "name": "Buzzer", "kind": "actuator", "impl": "passive_buzzer",
         "settings": {"gpio": 40}}]})
    assert status == 400, answer
    assert answer["fields"] == {"settings.gpio": "must be at most 27"}, answer
    assert "operation 1" not in answer["message"] and "gpio" in answer["message"], answer
    assert answer["error"].startswith("operation 1 (add_component): ")  # the full text stays for logs
    status, answer = editor.post("edit", {"version": version, "ops": [
        {"op": "add_component", "name": "Robbie the car", "kind": "actuator"}]})
    assert status == 400 and set(answer["fields"]) == {"name"}, answer
    status, answer = editor.post("edit", {"version": version, "ops": [
        {"op": "add_port", "component": "Sensor", "port": "my port", "feature": "angle"}]})
    assert status == 400 and set(answer["fields"]) == {"port"}, answer


def test_writes_need_the_token_the_origin_and_the_current_version(car: tuple[Path, Editor]) -> None:
    root, editor = car
    before = snapshot(root)
    op = {"version": 0, "ops": [{"op": "remove_lane", "lane": "Stop"}]}
    assert editor.post("edit", op, token="guess")[0] == 403
    assert editor.post("edit", op, headers={"Origin": "http://evil.example"})[0] == 403
    assert editor.post("edit", {**op, "version": 5})[0] == 409
    status, answer = editor.post("edit", {"version": 0, "ops": [{"op": "add_node", "lane": "Nope",
                                                                 "node": {"kind": "end"}}]})
    assert status == 400 and "no swimlane 'Nope'" in answer["error"]
    status, answer = editor.post("edit", op, headers={"Origin": editor.url.rstrip("/")})
    assert status == 200 and answer["version"] == 1
    assert snapshot(root) == before  # nothing written before a save


def test_a_file_changed_on_disk_is_taken_in_or_reported_as_a_conflict(car: tuple[Path, Editor]) -> None:
    root, editor = car
    main = root / "activities" / "main.yaml"
    measure = root / "activities" / "measure.yaml"

    def frames_after(change: Any, kind: str) -> list[dict[str, Any]]:
        return read_frames(editor.url, lambda f: (len(f) == 1 and change() is None)
                           or any(x.get("type") == kind for x in f[1:]), timeout=20)

    # clean: a change on disk is reloaded and pushed
    text = main.read_text(encoding="utf-8").replace("value: 70}", "value: 65}")
    assert "value: 65}" in text
    frames = frames_after(lambda: main.write_text(text, encoding="utf-8"), "files")
    pushed = next(f for f in frames if f.get("type") == "files")
    assert pushed["changed"] == ["activities/main.yaml"] and pushed["reason"] == "changed on disk"
    assert editor.get("files")["files"]["activities/main.yaml"] == text
    # dirty: my edit of main.yaml and a change on disk of the same file conflict
    version = pushed["version"]
    status, answer = editor.post("edit", {"version": version, "ops": [
        {"op": "set_node", "lane": "RaspberryPI", "id": "set_turn", "fields": {"value": "400"}}]})
    assert status == 200
    theirs = text.replace("value: 8}", "value: 9}")
    assert theirs != text
    frames = frames_after(lambda: main.write_text(theirs, encoding="utf-8"), "conflict")
    assert next(f for f in frames if f.get("type") == "conflict")["changed"] == ["activities/main.yaml"]
    status, refused = editor.post("save", {"version": answer["version"]})
    assert status == 409 and refused["conflict"] == ["activities/main.yaml"]
    assert main.read_text(encoding="utf-8") == theirs  # nothing overwritten
    # a change of a file I did not edit is taken in, my edit stays
    measure.write_text(measure.read_text(encoding="utf-8") + "# a note\n", encoding="utf-8")
    deadline = time.monotonic() + 10
    while "# a note" not in editor.get("files")["files"]["activities/measure.yaml"]:
        assert time.monotonic() < deadline
        time.sleep(0.1)
    files = editor.get("files")
    assert "value: 400}" in files["files"]["activities/main.yaml"]
    # keep mine: save with force
    status, saved = editor.post("save", {"version": files["version"], "force": True})
    assert status == 200 and saved["saved"] == ["activities/main.yaml"]
    assert "value: 400}" in main.read_text(encoding="utf-8")
    assert "value: 8}" in main.read_text(encoding="utf-8")  # mine was made from the earlier text


def test_reload_discards_my_edits(car: tuple[Path, Editor]) -> None:
    root, editor = car
    before = snapshot(root)
    status, answer = editor.post("edit", {"version": 0, "ops": [{"op": "remove_lane", "lane": "Measure"}]})
    assert status == 200 and answer["changed"] == ["activities/measure.yaml"]
    assert "lane: Measure" not in editor.get("files")["files"]["activities/measure.yaml"]
    status, answer = editor.post("reload", {})
    assert status == 200 and not answer["dirty"] and answer["compiled"]
    assert editor.post("undo", {})[0] == 409  # nothing to undo after a reload
    assert snapshot(root) == before


def test_layout_is_kept_in_its_own_file(car: tuple[Path, Editor]) -> None:
    root, editor = car
    status, answer = editor.post("edit", {"version": 0, "ops": [
        {"op": "set_layout", "diagram": "activity-main", "positions": {"RaspberryPI/start": [10, 20.55]}}]})
    assert status == 200 and answer["dirty"] and answer["changed"] == []
    status, saved = editor.post("save", {"version": answer["version"]})
    assert saved["saved"] == [LAYOUT_FILE]
    layout = json.loads((root / LAYOUT_FILE).read_text(encoding="utf-8"))
    assert layout == {"positions": {"activity-main": {"RaspberryPI/start": [10.0, 20.6]}}}
    assert check_model(root).model is not None


@pytest.mark.parametrize("content, problem", [
    (b'{"positions": {"\xc3\xa9\xff": 1}}', ":1:18: not UTF-8 text: byte 0xff: invalid start byte"),
    (b'{"positions":\n  {"a": [1, 2],}}', ":2:16: not valid JSON: Expecting property name enclosed in "
                                         "double quotes"),
    (b"[1, 2]", ":1:1: not a layout (a JSON object with 'positions')"),
    (b"[" * 100_000 + b"]" * 100_000, ": not valid JSON: nested too deeply"),
    (b'{"positions": {"a": [' + b"9" * 5000 + b", 1]}}",
     f": not valid JSON: integer too long: more than {sys.get_int_max_str_digits()} digits"),
])
def test_a_layout_file_that_cannot_be_read_is_named_once(tmp_path: Path, content: bytes,
                                                          problem: str) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    (root / LAYOUT_FILE).write_bytes(content)
    workspace = Workspace(root)
    assert workspace.layout == {} and workspace.layout_problem == f"{root / LAYOUT_FILE}{problem}"
    workspace.reload()
    assert workspace.layout_problem == f"{root / LAYOUT_FILE}{problem}"
    (root / LAYOUT_FILE).write_text('{"positions": {}}', encoding="utf-8")
    workspace.reload()  # a good file again: its positions, no problem
    assert workspace.layout == {"positions": {}}
    assert read_layout(root) == ({"positions": {}}, None)


def test_no_layout_file_is_no_problem_and_a_folder_is_one(tmp_path: Path) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    assert Workspace(root).layout_problem is None
    (root / LAYOUT_FILE).mkdir()
    assert Workspace(root).layout_problem == f"cannot read {root / LAYOUT_FILE}: Is a directory"


def test_studio_says_on_start_that_the_layout_file_was_not_read(tmp_path: Path) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    (root / LAYOUT_FILE).write_bytes(b"{\n\xff}")
    with studio(["studio", str(root), "--port", "0"], tmp_path) as proc:
        pass
    lines = [line for line in proc.log_text().splitlines() if LAYOUT_FILE in line]
    assert lines == [f"  {root / LAYOUT_FILE}:2:1: not UTF-8 text: byte 0xff: invalid start byte: the page "
                     "starts without the saved positions (saving rewrites the file)"]
    assert "Traceback" not in proc.log_text()


# --- a model file that cannot be read -----------------------------------------------------------------

UNREADABLE_CASES = ["not UTF-8", "a folder", "a dangling link", "too large", "no read permission"]


def _make_unreadable(path: Path, case: str) -> str | None:
    """Make the model file `path` unreadable as `case` says; the end of the line `umlbot check`
    prints for it, or None when it is read after all (root reads a file without read permission)."""
    if case == "not UTF-8":
        path.write_bytes(b"lanes:\n  - lane: Measure\xff\n")
        return ":2:18: error: not UTF-8 text: byte 0xff: invalid start byte"
    if case == "a folder":
        path.unlink()
        path.mkdir()
        return ":1:1: error: cannot read: Is a directory"
    if case == "a dangling link":
        path.unlink()
        path.symlink_to(path.with_name("gone.yaml"))
        return ":1:1: error: cannot read: No such file or directory"
    if case == "too large":
        path.write_bytes(b"#" * (user_files.MAX_FILE_BYTES + 1))
        return f":1:1: error: file too large ({user_files.MAX_FILE_BYTES + 1} bytes, at most " \
               f"{user_files.MAX_FILE_BYTES})"
    assert case == "no read permission"
    path.chmod(0)
    return None if os.geteuid() == 0 else ":1:1: error: cannot read: Permission denied"


def _fingerprint(path: Path) -> tuple[int, int, int, int, bytes | str]:
    status = path.lstat()
    try:
        content: bytes | str = path.read_bytes()
    except OSError as exc:
        content = str(exc.strerror)
    return status.st_ino, status.st_mode, status.st_size, status.st_mtime_ns, content


@pytest.mark.parametrize("case", UNREADABLE_CASES)
def test_the_studio_shows_umlbot_checks_lines_for_a_file_it_cannot_read(tmp_path: Path, case: str) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    # main.yaml calls Measure and Glance of measure.yaml: a studio that skipped the file showed
    # "unknown swimlane" for them and never named it
    measure = root / "activities" / "measure.yaml"
    problem = _make_unreadable(measure, case)
    check = CliRunner().invoke(cli, ["check", str(root)])
    workspace = Workspace(root)
    shown = [d["text"] for d in workspace.check()["diagnostics"]]
    assert shown == check.stdout.splitlines()
    if problem is None:  # run as root: the file is read, and the car is fine
        assert shown == [] and check.exit_code == 0 and workspace.result is not None
        assert workspace.result.model is not None
    else:  # with how many checks of main.yaml wait for it to be read
        assert len(shown) == 1 and with_left_out(f"{measure}{problem}").fullmatch(shown[0])
        assert check.exit_code == 1


@pytest.mark.parametrize("case", UNREADABLE_CASES)
def test_the_studio_shows_the_other_files_defects_beside_a_file_it_cannot_read(tmp_path: Path,
                                                                            case: str) -> None:
    # before, the unreadable file was the only problem shown: a typo in motion.yaml (which does
    # not depend on measure.yaml) showed only once it was fixed
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    motion = root / "activities" / "motion.yaml"
    text = motion.read_text(encoding="utf-8")
    line, column = position(text, "direction(true)")
    motion.write_text(text.replace("direction(true)", "direktion(true)", 1), encoding="utf-8")
    typo = (f"{motion}:{line}:{column}: error: unknown feature 'direktion' of actuator component "
            "'LeftActuator' (known: enabled, direction, dutycycle)")
    measure = root / "activities" / "measure.yaml"
    problem = _make_unreadable(measure, case)
    check = CliRunner().invoke(cli, ["check", str(root)])
    shown = [d["text"] for d in Workspace(root).check()["diagnostics"]]
    assert shown == check.stdout.splitlines() and check.exit_code == 1
    if problem is None:  # run as root: the file is read
        assert shown == [typo]
    else:  # no "unknown swimlane" for main.yaml's calls of Measure and Glance
        assert shown[1:] == [typo] and with_left_out(f"{measure}{problem}").fullmatch(shown[0])


def test_no_operation_writes_over_a_file_that_cannot_be_read() -> None:
    files: dict[str, str | None] = {**_texts(CAR_MODEL), "activities/measure.yaml": None,
                                    "deployment.yaml": None}
    refused = "cannot be read \\(its error is in the problems\\): the studio does not write over it"
    cases = [
        ({"op": "add_lane", "lane": "Look", "file": "activities/measure.yaml"},
         f"activities/measure.yaml {refused}"),
        # deployment.yaml comes before deployment.txt: it is the one the compiler reads
        ({"op": "set_deployment", "component": "Sensor", "impl": "servo", "settings": {"gpio": 18}},
         f"deployment.yaml {refused}"),
        ({"op": "add_node", "lane": "Measure", "node": {"kind": "end"}},
         "no swimlane 'Measure' in the files that can be read \\(activities/measure.yaml cannot be read\\)"),
    ]
    for op, message in cases:
        with pytest.raises(EditError, match=message):
            apply_ops(files, parse_ops([op]))
    # a new swimlane goes to a new file, beside the unreadable one of the same name
    assert list(apply_ops(files, parse_ops([{"op": "add_lane", "lane": "Measure"}]))) == [
        "activities/measure_2.yaml"]


@pytest.mark.parametrize("case", ["not UTF-8", "a folder", "no read permission"])
def test_saving_leaves_a_file_it_cannot_read_as_it_was(tmp_path: Path, case: str) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    measure = root / "activities" / "measure.yaml"
    problem = _make_unreadable(measure, case)
    before = _fingerprint(measure)
    editor = Editor(root)
    try:
        into_it = {"op": "add_lane", "lane": "Look", "file": "activities/measure.yaml"}
        status, answer = editor.post("edit", {"version": 0, "ops": [into_it]})
        if problem is not None:
            assert status == 400 and "activities/measure.yaml cannot be read" in answer["error"]
        else:  # run as root: the file is read, so it can be edited; take the edit back
            assert status == 200 and answer["changed"] == ["activities/measure.yaml"]
            status, answer = editor.post("undo", {})
            assert status == 200 and not answer["dirty"]
        elsewhere = {"op": "set_node", "lane": "MoveForward", "id": "left_forward",
                     "fields": {"call": "LeftActuator.direction(false)"}}
        status, answer = editor.post("edit", {"version": answer.get("version", 0), "ops": [elsewhere]})
        assert status == 200 and answer["changed"] == ["activities/motion.yaml"]
        status, saved = editor.post("save", {"version": answer["version"]})
        assert status == 200 and saved["saved"] == ["activities/motion.yaml"] and not saved["dirty"]
        assert "LeftActuator.direction(false)" in (root / "activities" / "motion.yaml").read_text("utf-8")
        assert _fingerprint(measure) == before
        if problem is not None:  # fixed on disk, it is taken in like any change on disk

            def fix_after_hello(frames: list[dict[str, Any]]) -> bool:
                if len(frames) == 1:
                    if measure.is_dir():
                        measure.rmdir()
                    shutil.copyfile(CAR_MODEL / "activities" / "measure.yaml", measure)
                    measure.chmod(0o644)
                return any(frame.get("type") == "files" for frame in frames[1:])

            frames = read_frames(editor.url, fix_after_hello, timeout=20)
            pushed = next(f for f in frames if f.get("type") == "files")
            assert pushed["changed"] == ["activities/measure.yaml"]
            assert pushed["diagnostics"] == [] and pushed["compiled"]
    finally:
        editor.thread.stop()


def test_library_comes_from_the_component_library(car: tuple[Path, Editor]) -> None:
    _, editor = car
    lib = editor.get("library")
    servo = next(i for i in lib["implementations"] if i["id"] == "servo")
    assert servo["features"]["angle"]["params"][0]["maximum"] == 180
    assert "CModelActuator" in servo["aliases"]
    assert "gpio" in servo["settings_schema"]["properties"]
    # the compiler's node kinds, in its order, each with a word on what it does: the page's palette
    assert list(lib["node_kinds"]) == ["start", "end", "action", "datastore", "decision", "fork", "join",
                                       "send", "accept"]
    assert all(kind["doc"] for kind in lib["node_kinds"].values())
    assert lib["node_kinds"]["action"]["fields"]["call"]["required"] is True
    # the fields written as an expression (edited with completion) and those that are flows
    types = {name: f["type"] for kind in lib["node_kinds"].values() for name, f in kind["fields"].items()}
    assert {name for name, t in types.items() if t == "expression"} == {"call", "value", "payload"}
    assert {name for name, t in types.items() if t in ("node", "nodes", "branches")} == {
        "next", "targets", "branches"}
    assert {b["name"] for b in lib["builtins"]} == {"usleep", "msleep", "Application.exit"}


def test_a_plugins_part_gets_its_settings_from_its_hardware_driver(car: tuple[Path, Editor]) -> None:
    # the example plugin's buzzer has lgpio, mock and sim drivers (no pigpio): its settings are
    # those of lgpio, so the page asks for the pin and a deployment without it is refused
    _, editor = car
    buzzer = next(i for i in editor.get("library")["implementations"] if i["id"] == "passive_buzzer")
    schema = buzzer["settings_schema"]
    assert schema is not None and schema["required"] == ["gpio"]
    assert schema["properties"]["gpio"]["maximum"] == 27
    version = editor.post("edit", {"version": 0, "ops": []})[1]["version"]
    add = {"op": "add_component", "name": "Buzzer", "kind": "sounder", "impl": "passive_buzzer"}
    status, answer = editor.post("edit", {"version": version, "ops": [add]})
    assert status == 400, answer
    assert answer["error"].endswith("Buzzer: invalid settings: gpio: Field required"), answer
    status, answer = editor.post("edit", {"version": version, "ops": [{**add, "settings": {"gpio": 40}}]})
    assert status == 400 and "gpio: Input should be less than or equal to 27" in answer["error"], answer
    status, answer = editor.post("edit", {"version": version, "ops": [{**add, "settings": {"gpio": 12}}]})
    assert status == 200 and answer["compiled"], answer
    deployment = editor.get("files")["files"]["deployment.yaml"]
    assert "Buzzer: {impl: passive_buzzer, settings: {gpio: 12}}" in deployment


def test_studio_on_a_new_folder_offers_and_writes_the_starter(tmp_path: Path) -> None:
    folder = tmp_path / "my_robot"
    with studio(["studio", "--new", str(folder), "--port", "0"], tmp_path) as proc:
        # the terminal says there is no model there yet and what the page offers
        proc.wait_line("offers a starter model")
        said = f"umlbot studio: {folder} does not exist yet: the page offers a starter model"
        assert said in proc.lines[-1], proc.lines
        hello = read_frames(proc.url, lambda f: len(f) >= 1)[0]
        assert hello["edit"]["empty"] is True
        assert "error(s)" not in proc.log_text(), proc.log_text()  # no model yet is no error

        async def new() -> tuple[int, dict[str, Any]]:
            async with aiohttp.ClientSession() as client, client.post(
                    f"{proc.url}api/new", json={"token": hello["edit"]["token"], "name": "my_robot"}) as r:
                return r.status, await r.json()

        status, answer = asyncio.run(new())
        assert status == 200 and answer["compiled"], answer
    assert sorted(answer["saved"]) == ["activities/main.yaml", "deployment.yaml", "model.yaml"]
    check = subprocess.run(umlbot_argv("check", str(folder)), capture_output=True, text=True, timeout=60,
                           check=False)
    assert check.returncode == 0, check.stdout + check.stderr
    # as the reference car: `auto` runs on a Pi 5 too (pigpio does not)
    compiled = check_model(folder).model
    assert compiled is not None
    assert {c.driver for c in compiled.components.values()} == {"auto"}


def test_the_robot_followed_is_the_models_name_once_it_is_created_or_renamed(
        mosquitto_broker: BrokerProcess, raw_client: Any, tmp_path: Path) -> None:
    # --robot's default is "$UMLBOT_ROBOT, else the model's name": a model created (or renamed)
    # in the studio is followed under its own name from then on, and the page is told
    raw = raw_client(mosquitto_broker)
    folder = tmp_path / "newbot"
    with studio(["studio", "--new", str(folder), "--port", "0"], tmp_path, mosquitto_broker.url) as proc:
        hello = read_frames(proc.url, lambda f: len(f) >= 1)[0]
        assert hello["robot"] == "car"  # nothing to name it after yet
        token = hello["edit"]["token"]

        def create(frames: list[dict[str, Any]]) -> bool:
            if len(frames) == 2:  # the hello and the snapshot: this page is attached
                status, answer = _post(proc.url, "new", {"token": token, "name": "mybot"})
                assert status == 200 and answer["compiled"], answer
            return any(f["type"] == "robot" for f in frames)

        frames = read_frames(proc.url, create)
        assert [f["robot"] for f in frames if f["type"] == "robot"] == ["mybot"]

        def online(frames: list[dict[str, Any]]) -> bool:  # the new robot's topics are followed
            if len(frames) >= 2:
                raw.publish("umlbot/mybot/LeftActuator/status", '{"state":"online","impl":"l298n"}',
                            retain=True)
            return any(e.get("robot") == "mybot" for e in events_of(frames, "availability"))

        frames = read_frames(proc.url, online)
        raw.publish("umlbot/mybot/LeftActuator/status", b"", retain=True)
        assert frames[0]["robot"] == "mybot"
        # renamed on disk: followed under the new name
        model_file = folder / "model.yaml"
        model_file.write_text(model_file.read_text(encoding="utf-8").replace("mybot", "otherbot"),
                              encoding="utf-8")
        frames = read_frames(proc.url, lambda f: any(x["type"] == "robot" for x in f), timeout=10)
        assert [f["robot"] for f in frames if f["type"] == "robot"] == ["otherbot"]
        assert read_frames(proc.url, lambda f: len(f) >= 1)[0]["robot"] == "otherbot"
    # a robot id given with --robot stays
    other = tmp_path / "fixed"
    with studio(["studio", "--new", str(other), "--port", "0", "--robot", "car7"], tmp_path,
                mosquitto_broker.url) as proc:
        hello = read_frames(proc.url, lambda f: len(f) >= 1)[0]
        status, _ = _post(proc.url, "new", {"token": hello["edit"]["token"], "name": "mybot"})
        assert status == 200
        assert read_frames(proc.url, lambda f: len(f) >= 1)[0]["robot"] == "car7"


def _post(url: str, name: str, body: dict[str, Any]) -> tuple[int, dict[str, Any]]:
    """A blocking POST to the studio at `url` (also from inside a `read_frames` condition)."""
    where = urlsplit(url)
    connection = http.client.HTTPConnection(where.hostname or "127.0.0.1", where.port, timeout=30)
    try:
        connection.request("POST", f"/api/{name}", body=json.dumps(body),
                           headers={"Content-Type": "application/json"})
        resp = connection.getresponse()
        return resp.status, json.loads(resp.read())
    finally:
        connection.close()


def test_completion_offers_features_datastores_lanes_and_argument_ranges(car: tuple[Path, Editor]) -> None:
    _, editor = car

    def complete(text: str, lane: str = "RaspberryPI") -> dict[str, Any]:
        status, answer = editor.post("complete", {"lane": lane, "text": text, "cursor": len(text),
                                                  "field": "call"})
        assert status == 200
        return answer

    assert [i["label"] for i in complete("LeftActuator.")["items"]] == ["enabled", "direction", "dutycycle"]
    assert [i["label"] for i in complete("Measure.")["items"]] == ["left", "right"]
    labels = {i["label"]: i["kind"] for i in complete("")["items"]}
    assert labels["speed_percent"] == "datastore" and labels["Stop"] == "lane"
    assert labels["msleep"] == "builtin" and labels["Sensor"] == "component"
    hint = complete("Sensor.angle(")["signature"]
    assert hint["params"][0] == {"name": "degrees", "type": "int", "minimum": 0, "maximum": 180, "unit": "°"}
    assert complete("RaspberryPI.writePin(4, ")["signature"]["active"] == 1
    assert complete("Measure.ri")["replace"] == [8, 10]
    # inside a bool argument its values come first; no sleeps or lane calls (they give no value),
    # another lane's datastores (Measure.left) yes
    labels_in_bool = [i["label"] for i in complete("LeftActuator.enabled(")["items"]]
    assert labels_in_bool[:2] == ["true", "false"], labels_in_bool
    assert "msleep" not in labels_in_bool and "Stop" not in labels_in_bool
    # ... nor a component whose features all give none (the motors, the servo): only those that
    # can be read (RaspberryPI.readPin, DistanceRead.value), and Application (exit is a bool)
    components_in_bool = {i["label"] for i in complete("LeftActuator.enabled(")["items"]
                          if i["kind"] == "component"}
    assert components_in_bool == {"RaspberryPI", "DistanceRead"}, components_in_bool
    assert "Application" in labels_in_bool
    features_in_bool = {i["label"] for i in complete("LeftActuator.enabled(RaspberryPI.")["items"]
                        if i["kind"] == "feature"}
    assert features_in_bool == {"readPin"}, features_in_bool  # not writePin (it gives none)
    assert complete("LeftActuator.enabled(LeftActuator.")["items"] == []
    # a guard is a value too; a call at the top of an action may use any feature
    status, guard = editor.post("complete", {"lane": "RaspberryPI", "text": "", "cursor": 0, "field": "if"})
    assert status == 200
    assert not {"LeftActuator", "msleep"} & {i["label"] for i in guard["items"]}
    assert "LeftActuator" in {i["label"] for i in complete("")["items"]}
    assert {i["label"]: i["insert"] for i in complete("LeftActuator.dutycycle(M")["items"]} == {
        "Measure": "Measure."}
    in_int = [i["label"] for i in complete("LeftActuator.dutycycle(")["items"]]
    assert in_int[-3:] == ["true", "false", "null"], in_int
    # a virtual lane is not offered as a call inside itself (recursion), the others are
    stop = {i["label"] for i in complete("", lane="Stop")["items"] if i["kind"] == "lane"}
    assert "Stop" not in stop and {"Measure", "TurnLeft"} <= stop


def test_run_drives_the_working_copy_in_the_simulator_and_the_page_follows(
        car: tuple[Path, Editor]) -> None:
    _, editor = car
    assert "s_bend" in editor.get("tracks")["tracks"]
    status, answer = editor.post("run", {"track": "s_bend"})
    assert status == 200 and answer["running"], answer
    assert editor.post("run", {"track": "s_bend"})[0] == 409  # one run at a time

    def until(frames: list[dict[str, Any]]) -> bool:
        xs = {f["car"]["x"] for f in frames if f.get("type") == "world"}
        traced = any(e.get("type") == "trace" for f in frames if f.get("type") == "events"
                     for e in f["events"])
        return len(xs) > 1 and traced

    frames = read_frames(editor.url, until, timeout=120)
    run = frames[0]["edit"]["run"]
    if not run["running"]:  # the page opened before the sim's broker ran: the frame follows
        run = next(f for f in frames if f.get("type") == "run")
    assert run["robot"] == "car" and run["track"]["name"]
    status, answer = editor.post("stop", {})
    assert status == 200 and answer["running"] is False
    assert answer["result"]["reason"] in ("interrupted", "goal", "collision"), answer
    # a page opened after the run draws its track and gets the car where the run left it
    late = read_frames(editor.url, lambda f: any(x.get("type") == "world" for x in f))
    assert late[0]["edit"]["run"]["running"] is False and late[0]["edit"]["run"]["track"]["name"] == "s_bend"
    (world,) = [f for f in late if f.get("type") == "world"]
    last = [f for f in frames if f.get("type") == "world"][-1]
    start = late[0]["edit"]["run"]["track"]["start"]
    assert world["t"] >= last["t"] and (world["car"]["x"], world["car"]["y"]) != (start["x"], start["y"])
    assert editor.post("run", {"track": "../../etc/passwd"})[0] == 400
    assert editor.post("run", {"track": "s_bend", "speed": 1000})[0] == 400


def test_a_robot_built_in_an_empty_folder_checks_and_drives_in_the_simulator(tmp_path: Path) -> None:
    """From nothing to a car that drives, through the server only; then `umlbot check` and
    `umlbot sim` on the saved files."""
    folder = tmp_path / "my_robot"
    editor = Editor(folder)
    try:
        status, answer = editor.post("new", {"name": "my_robot"})
        assert status == 200 and answer["compiled"]

        def action(lane: str, node_id: str, call: str) -> dict[str, Any]:
            return {"op": "add_node", "lane": lane, "node": {"id": node_id, "kind": "action", "call": call}}

        ops: list[dict[str, Any]] = [
            {"op": "add_lane", "lane": "Stop"},
            {"op": "remove_node", "lane": "Stop", "id": "end"},
            {"op": "add_node", "lane": "Stop", "node": {"id": "both", "kind": "fork"}},
            action("Stop", "left_off", "LeftActuator.enabled(false)"),
            action("Stop", "right_off", "RightActuator.enabled(false)"),
            {"op": "add_node", "lane": "Stop", "node": {"id": "stopped", "kind": "join"}},
            {"op": "add_node", "lane": "Stop", "node": {"id": "end", "kind": "end"}},
            {"op": "connect", "lane": "Stop", "source": "both", "target": "left_off"},
            {"op": "connect", "lane": "Stop", "source": "both", "target": "right_off"},
            {"op": "connect", "lane": "Stop", "source": "left_off", "target": "stopped"},
            {"op": "remove_node", "lane": "RaspberryPI", "id": "end"},
            action("RaspberryPI", "left_forward", "LeftActuator.direction(true)"),
            action("RaspberryPI", "right_forward", "RightActuator.direction(true)"),
            action("RaspberryPI", "power_left", "LeftActuator.dutycycle(60)"),
            action("RaspberryPI", "power_right", "RightActuator.dutycycle(60)"),
            action("RaspberryPI", "left_on", "LeftActuator.enabled(true)"),
            action("RaspberryPI", "right_on", "RightActuator.enabled(true)"),
            action("RaspberryPI", "drive", "msleep(1500)"),
            action("RaspberryPI", "halt", "Stop"),
            {"op": "add_node", "lane": "RaspberryPI", "node": {"id": "end", "kind": "end"}},
        ]
        status, answer = editor.post("edit", {"version": answer["version"], "ops": ops})
        assert status == 200, answer
        assert answer["compiled"], [d["text"] for d in answer["diagnostics"]]
        status, saved = editor.post("save", {"version": answer["version"]})
        assert status == 200 and "activities/stop.yaml" in saved["saved"]
    finally:
        editor.thread.stop()
    check = subprocess.run(umlbot_argv("check", str(folder)), capture_output=True, text=True, timeout=60,
                           check=False)
    assert check.returncode == 0, check.stdout + check.stderr
    sim = subprocess.run(umlbot_argv("sim", str(folder), "--speed", "5", "--port", "0", "--timeout", "30",
                                     "--json"), capture_output=True, text=True, timeout=180, check=False,
                         cwd=REPO)
    result = json.loads(sim.stdout.strip().splitlines()[-1])
    assert result["distance_m"] > 0.2, result
    assert result["reason"] in ("orchestrator ended", "collision", "goal"), result


# --- property-like: random edits of real models ------------------------------------------------------

_GENERATED: dict[str, Any] = {}


def _generated_files(tmp_root: Path) -> tuple[Path, dict[str, str], Any]:
    if not _GENERATED:
        root = _bench_compile().generate(tmp_root / "gen", 600)
        files = _texts(root)
        _GENERATED.update(root=root, files=files, compiled=_check(root, files).model)
    return _GENERATED["root"], _GENERATED["files"], _GENERATED["compiled"]


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, str], Any]:
    return _generated_files(tmp_path_factory.mktemp("gen"))


@pytest.mark.parametrize("model", ["car", "generated"])
@given(data=st.data())
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_random_value_edits_change_exactly_those_nodes(model: str, data: st.DataObject,
                                                       generated: tuple[Path, dict[str, str], Any]) -> None:
    if model == "car":
        root, files = CAR_MODEL, _texts(CAR_MODEL)
        compiled = check_model(CAR_MODEL).model
    else:
        root, files, compiled = generated
    assert compiled is not None
    candidates = sorted((lane.name, node.id, node.kind) for lane in compiled.lanes.values()
                        for node in lane.nodes.values() if node.kind in ("action", "datastore"))
    picked = data.draw(st.lists(st.sampled_from(candidates), min_size=1, max_size=6, unique=True))
    values = data.draw(st.lists(st.integers(0, 5000), min_size=len(picked), max_size=len(picked)))
    ops: list[dict[str, Any]] = []
    unchanged = 0  # a node given the text it has already (e.g. msleep(1) again): its line stays
    for (lane, node_id, kind), value in zip(picked, values, strict=True):
        field = "call" if kind == "action" else "value"
        text = f"msleep({value})" if kind == "action" else f"{value} + 1"
        node = compiled.lanes[lane].nodes[node_id]
        unchanged += node.label == (text if kind == "action" else f"{getattr(node, 'name', '')} = {text}")
        ops.append({"op": "set_node", "lane": lane, "id": node_id, "fields": {field: text}})
    out = _apply(files, ops)
    # (b) only the picked nodes' lines differ, and only in their value
    for rel, before in files.items():
        removed, added = _changed_lines(before, out[rel])
        assert len(removed) == len(added)
        for old, new in zip(removed, added, strict=True):
            assert re.sub(r"(call|value): [^,}]+(?=[,}])|(call|value): .*$", "X", old) == \
                re.sub(r"(call|value): [^,}]+(?=[,}])|(call|value): .*$", "X", new), (old, new)
    assert sum(len(_changed_lines(files[r], out[r])[1]) for r in files) == len(picked) - unchanged
    # (a) the compiled model is the original with those nodes' values changed
    result = _check(root, out)
    assert result.model is not None, [str(d) for d in result.diagnostics]
    changed = {(lane, node_id) for lane, node_id, _ in picked}
    for old_lane in compiled.lanes.values():
        new_lane = result.model.lanes[old_lane.name]
        for node in old_lane.nodes.values():
            if (old_lane.name, node.id) in changed:
                expected = ops[[(p[0], p[1]) for p in picked].index((old_lane.name, node.id))]["fields"]
                shown = new_lane.nodes[node.id].label
                assert shown.endswith(next(iter(expected.values()))), shown
                assert new_lane.nodes[node.id].model_dump(exclude={"label", "call", "value"}) == \
                    node.model_dump(exclude={"label", "call", "value"})
            else:
                assert new_lane.nodes[node.id] == node


@given(data=st.data())
@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_nodes_added_and_removed_again_leave_the_files_as_they_were(
        data: st.DataObject, generated: tuple[Path, dict[str, str], Any]) -> None:
    _, files, compiled = generated
    lanes = sorted(compiled.lanes)
    picked = data.draw(st.lists(st.sampled_from(lanes), min_size=1, max_size=4, unique=True))
    added = [{"op": "add_node", "lane": lane, "node": {"id": f"new_{i}", "kind": "action",
                                                       "call": "msleep(1)"}} for i, lane in enumerate(picked)]
    out = _apply(files, added)
    for rel in files:
        removed_lines, added_lines = _changed_lines(files[rel], out[rel])
        assert removed_lines == []
        assert all(re.fullmatch(r" +- \{id: new_\d+, kind: action, call: msleep\(1\)\}", x)
                   for x in added_lines)
    back = _apply(out, [{"op": "remove_node", "lane": lane, "id": f"new_{i}"}
                        for i, lane in enumerate(picked)])
    assert back == files


def test_edits_follow_the_style_of_the_file_block_flow_crlf_and_no_final_newline() -> None:
    files: dict[str, str | None] = {
        "activities/a.yaml": "lane: A   # the lane\nnodes:\n  - id: start\n    kind: start\n"
                             "  # a comment\n  - id: d\n    kind: decision\n    branches:\n"
                             "      - if: x > 1\n        then: e\n  - id: e\n    kind: end",
        "activities/b.yaml": "lane: B\r\nnodes:\r\n  - {id: start, kind: start}\r\n"
                             "  - {id: end, kind: end}\r\n",
        "activities/c.yaml": "lane: C\nnodes: []\n",
        "activities/e.yaml": "lane: E\nnodes:\n- {id: start, kind: start}\n- {id: end, kind: end}\n",
    }
    out = apply_ops(files, parse_ops([
        {"op": "set_node", "lane": "A", "id": "start", "fields": {"next": "d"}},
        {"op": "connect", "lane": "A", "source": "d", "target": "e", "guard": "else"},
        {"op": "add_node", "lane": "A", "node": {"id": "n", "kind": "action",
                                                 "call": "RaspberryPI.writePin(17, 1)"}},
        {"op": "set_guard", "lane": "A", "source": "d", "target": "e", "guard": "x > 2"},
        {"op": "add_node", "lane": "B", "node": {"id": "n", "kind": "action", "call": "Stop"}},
        {"op": "add_node", "lane": "C", "node": {"id": "start", "kind": "start"}},
        {"op": "add_node", "lane": "C", "node": {"id": "end", "kind": "end"}},
        {"op": "add_node", "lane": "E", "node": {"id": "x", "kind": "join"}},
        {"op": "set_node", "lane": "E", "id": "start", "fields": {"next": "x"}},
        {"op": "remove_node", "lane": "E", "id": "end"},
    ]))
    assert out == {
        "activities/a.yaml": "lane: A   # the lane\nnodes:\n  - id: start\n    kind: start\n"
                             "    next: d\n  # a comment\n  - id: d\n    kind: decision\n    branches:\n"
                             "      - if: x > 2\n        then: e\n      - {else: e}\n"
                             "  - id: e\n    kind: end\n"
                             "  - {id: n, kind: action, call: 'RaspberryPI.writePin(17, 1)'}\n",
        "activities/b.yaml": "lane: B\r\nnodes:\r\n  - {id: start, kind: start}\r\n"
                             "  - {id: end, kind: end}\r\n  - {id: n, kind: action, call: Stop}\r\n",
        "activities/c.yaml": "lane: C\nnodes: [{id: start, kind: start}, {id: end, kind: end}]\n",
        "activities/e.yaml": "lane: E\nnodes:\n- {id: start, kind: start, next: x}\n- {id: x, kind: join}\n",
    }


def test_a_page_opened_after_a_save_gets_the_saved_model_as_the_hellos_model(tmp_path: Path) -> None:
    folder = tmp_path / "fresh"
    editor = Editor(folder)
    try:
        assert read_frames(editor.url, lambda f: len(f) >= 1)[0]["model"] is None
        assert editor.post("new", {"name": "fresh"})[0] == 200
        hello = read_frames(editor.url, lambda f: len(f) >= 1)[0]
        assert hello["model"]["name"] == "fresh"
        assert [lane["name"] for d in hello["model"]["diagrams"] for lane in d["lanes"]] == ["RaspberryPI"]
        assert hello["diagnostics"] == []
    finally:
        editor.thread.stop()


@pytest.mark.parametrize("how", ["SIGTERM", "SIGINT"])
def test_unsaved_edits_are_kept_when_the_studio_quits_and_offered_at_the_next_start(
        tmp_path: Path, how: str) -> None:
    import signal

    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    before = snapshot(folder)
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        hello = read_frames(proc.url, lambda f: len(f) >= 1)[0]
        edit = hello["edit"]
        assert edit["recovery"] is None
        op = {"op": "set_node", "lane": "Stop", "id": "left_off",
              "fields": {"call": "LeftActuator.enabled(true)"}}
        status, answer = _post(proc.url, "edit", {"token": edit["token"], "version": edit["version"],
                                                  "ops": [op]})
        assert status == 200 and answer["dirty"], answer
        proc.popen.send_signal(signal.SIGTERM if how == "SIGTERM" else signal.SIGINT)
        assert proc.popen.wait(20) == 0
        log = proc.log_text()
    # the model's files are as they were; the edit is in the recovery file, and stderr says so
    assert {k: v for k, v in snapshot(folder).items() if k != ".umlbot-studio-recovery.json"} == before
    kept = [line for line in log.splitlines() if "unsaved edits" in line]
    assert len(kept) == 1, log
    assert "activities/motion.yaml" in kept[0] and ".umlbot-studio-recovery.json" in kept[0], log
    recovery = json.loads((folder / ".umlbot-studio-recovery.json").read_text(encoding="utf-8"))
    assert "LeftActuator.enabled(true)" in recovery["files"]["activities/motion.yaml"]

    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        edit = read_frames(proc.url, lambda f: len(f) >= 1)[0]["edit"]
        assert edit["recovery"]["files"] == ["activities/motion.yaml"] and edit["recovery"]["time"]
        assert not edit["dirty"]
        status, answer = _post(proc.url, "recover", {"token": edit["token"], "action": "restore"})
        assert status == 200 and answer["dirty"] and answer["changed"] == ["activities/motion.yaml"], answer
        assert not (folder / ".umlbot-studio-recovery.json").exists()
        assert snapshot(folder) == before  # restored into the page, not yet saved
        status, answer = _post(proc.url, "save", {"token": edit["token"], "version": answer["version"]})
        assert status == 200 and answer["saved"] == ["activities/motion.yaml"], answer
        motion = (folder / "activities" / "motion.yaml").read_text(encoding="utf-8")
        assert "LeftActuator.enabled(true)" in motion
        proc.stop()
        assert "unsaved" not in proc.log_text()  # nothing unsaved: nothing kept, nothing said
    assert not (folder / ".umlbot-studio-recovery.json").exists()


def test_kept_edits_can_be_discarded(tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    before = snapshot(folder)
    (folder / ".umlbot-studio-recovery.json").write_text(json.dumps(
        {"time": "2026-01-02 03:04:05", "files": {"activities/motion.yaml": "lanes: []\n"}, "layout": None}))
    workspace = Workspace(folder)
    assert workspace.hello()["recovery"] == {"time": "2026-01-02 03:04:05",
                                             "files": ["activities/motion.yaml"], "layout": False}
    answer = workspace.recover("discard")
    assert not answer["dirty"] and answer["changed"] == []
    assert workspace.hello()["recovery"] is None
    assert snapshot(folder) == {k: v for k, v in before.items() if k != ".umlbot-studio-recovery.json"}
    assert not (folder / ".umlbot-studio-recovery.json").exists()


# --- renames -----------------------------------------------------------------------------------------

CAR_RENAMES = [
    {"op": "rename_component", "component": "DistanceRead", "new_name": "Sonar"},
    {"op": "rename_node", "lane": "RaspberryPI", "id": "moving_forward", "new_id": "drive_step"},
    {"op": "rename_lane", "lane": "Measure", "new_name": "Sweep"},
]
CAR_NAMES = {"DistanceRead": "Sonar", "moving_forward": "drive_step", "Measure": "Sweep"}


def _only_tokens_renamed(before: str, after: str, names: dict[str, str]) -> int:
    """How many words were renamed between the texts; fails when anything else differs, or a
    word inside a comment changed."""
    words_before, words_after = re.split(r"(\W+)", before), re.split(r"(\W+)", after)
    assert len(words_before) == len(words_after)
    renamed = 0
    for old, new in zip(words_before, words_after, strict=True):
        if old != new:
            assert names.get(old) == new, (old, new)
            renamed += 1
    comments = [line.partition("#")[2] for line in before.splitlines()]
    assert comments == [line.partition("#")[2] for line in after.splitlines()]
    return renamed


def test_renames_in_the_car_change_only_the_renamed_words_and_compile_to_the_same_model(
        tmp_path: Path) -> None:
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    before = snapshot(root)
    files = _texts(root)
    out = _apply(files, CAR_RENAMES)
    renamed = {rel: _only_tokens_renamed(files[rel], out[rel], CAR_NAMES) for rel in files}
    # the component's entry, its link, both deployment files; the node; the lane and its readers
    assert renamed == {"model.yaml": 2, "deployment.yaml": 1, "deployment.txt": 1,
                       "activities/main.yaml": 1 + 1 + 2 + 14, "activities/measure.yaml": 1 + 5,
                       "activities/motion.yaml": 0}
    assert "# the HC-SR04 range finder" in out["model.yaml"]  # comments and alignment stay
    for rel, text in out.items():
        (root / rel).write_text(text, encoding="utf-8")
    check = subprocess.run(umlbot_argv("check", str(root)), capture_output=True, text=True, timeout=60,
                           check=False)
    assert check.returncode == 0, check.stdout + check.stderr
    original = check_model(CAR_MODEL).model
    renamed_model = check_model(root).model
    assert original is not None and renamed_model is not None
    mapped = re.sub(r"\b(DistanceRead|moving_forward|Measure)\b", lambda m: CAR_NAMES[m.group()],
                    dump_compiled(original).decode())
    expected, got = json.loads(mapped), json.loads(dump_compiled(renamed_model))
    assert expected.pop("source_hash") != got.pop("source_hash")  # the texts differ
    assert expected == got
    # the studio does the same; one undo gives the files back byte for byte, redo the renames
    for rel in out:
        (root / rel).write_bytes(before[rel])
    ws = Workspace(root)
    answer = ws.edit(0, CAR_RENAMES)
    assert answer["compiled"] and answer["changed"] == sorted(rel for rel in out if out[rel] != files[rel])
    assert ws.texts() == out
    ws.undo()
    assert {rel: data for rel, data in ws.files.items()} == {
        rel: data for rel, data in before.items() if rel in ws.files}
    assert not ws.dirty
    ws.redo()
    assert ws.texts() == out


def test_a_renamed_nodes_flows_and_position_follow_it_and_undo_moves_the_position_back(
        car: tuple[Path, Editor]) -> None:
    root, editor = car
    status, answer = editor.post("edit", {"version": 0, "ops": [
        {"op": "set_layout", "diagram": "activity-motion", "positions": {"Stop/left_off": [5, 6],
                                                                         "Stop/end": [7, 8]}},
        {"op": "set_layout", "diagram": "components", "positions": {"Sensor": [1, 2]}}]})
    assert status == 200
    status, answer = editor.post("edit", {"version": answer["version"], "ops": [
        {"op": "rename_node", "lane": "Stop", "id": "left_off", "new_id": "left-off"},
        {"op": "rename_component", "component": "Sensor", "new_name": "Servo"}]})
    assert status == 200 and answer["compiled"], answer
    assert answer["layout"]["positions"] == {"activity-motion": {"Stop/left-off": [5, 6], "Stop/end": [7, 8]},
                                             "components": {"Servo": [1, 2]}}
    stop = next(lane for d in answer["model"]["diagrams"] for lane in d["lanes"] if lane["name"] == "Stop")
    assert [n["id"] for n in stop["nodes"]][2] == "left-off"
    assert stop["nodes"][1]["fields"]["targets"] == ["left-off", "right_off"]
    motion = editor.get("files")["files"]["activities/motion.yaml"]
    assert ("      - {id: left-off, kind: action, call: LeftActuator.enabled(false), next: stopped}\n"
            in motion)
    status, answer = editor.post("undo", {})
    assert status == 200 and answer["changed"] == sorted(model_files(root))  # Sensor is everywhere
    assert answer["layout"]["positions"] == {"activity-motion": {"Stop/left_off": [5, 6], "Stop/end": [7, 8]},
                                             "components": {"Sensor": [1, 2]}}
    assert editor.workspace.files == model_files(root)
    status, answer = editor.post("redo", {})
    assert answer["layout"]["positions"]["components"] == {"Servo": [1, 2]}


def test_references_are_the_parsers_names_not_matching_text() -> None:
    files = {
        "model.yaml": "name: m\ncomponents:\n  Left: {kind: actuator}\n  LeftX: {kind: actuator}\n"
                      "  'Pi': {kind: system}\n",
        "deployment.txt": "Left = l298n  # Left side\nLeftX=l298n\nPi=raspberrypi\n",
        "activities/main.yaml": (
            "lane: Pi\nnodes:\n"
            "  - {id: start, kind: start}\n"
            "  - {id: a, kind: action, call: Left.enabled(true)}\n"
            "  - {id: b, kind: action, call: LeftX.enabled(Left.ok)}   # Left stays in comments\n"
            "  - {id: c, kind: datastore, name: s, value: \"'Left' + Sub.Left\"}\n"
            "  - {id: d, kind: datastore, name: Sub, value: 1}\n"
            "  - {id: e, kind: action, call: Sub}\n"
            "  - {id: f, kind: send, signal: go, payload: \"Sub.t +\\n Sub()\"}\n"
            "  - {id: end, kind: end}\n"),
        "activities/sub.yaml": "lane: Sub\nnodes:\n  - {id: start, kind: start}\n"
                               "  - {id: t, kind: datastore, name: t, value: Sub.t}\n"
                               "  - {id: end, kind: end}\n",
    }
    out = _apply(files, [{"op": "rename_component", "component": "Left", "new_name": "Right"},
                         {"op": "rename_lane", "lane": "Sub", "new_name": "Helper"},
                         {"op": "rename_component", "component": "Pi", "new_name": "Board"}])
    assert out["model.yaml"] == ("name: m\ncomponents:\n  Right: {kind: actuator}\n"
                                 "  LeftX: {kind: actuator}\n  'Board': {kind: system}\n")
    assert out["deployment.txt"] == "Right = l298n  # Left side\nLeftX=l298n\nBoard=raspberrypi\n"
    assert out["activities/main.yaml"] == (
        "lane: Board\nnodes:\n"
        "  - {id: start, kind: start}\n"
        "  - {id: a, kind: action, call: Right.enabled(true)}\n"
        "  - {id: b, kind: action, call: LeftX.enabled(Right.ok)}   # Left stays in comments\n"
        "  - {id: c, kind: datastore, name: s, value: \"'Left' + Helper.Left\"}\n"
        "  - {id: d, kind: datastore, name: Sub, value: 1}\n"
        "  - {id: e, kind: action, call: Sub}\n"  # the lane's own datastore Sub, not the lane
        "  - {id: f, kind: send, signal: go, payload: \"Helper.t +\\n Helper()\"}\n"  # escaped: written anew
        "  - {id: end, kind: end}\n")
    assert out["activities/sub.yaml"] == ("lane: Helper\nnodes:\n  - {id: start, kind: start}\n"
                                          "  - {id: t, kind: datastore, name: t, value: Helper.t}\n"
                                          "  - {id: end, kind: end}\n")


@pytest.mark.parametrize("op, field, message", [
    ({"op": "rename_node", "lane": "Stop", "id": "both", "new_id": "left off"}, "new_id", "not a plain name"),
    ({"op": "rename_node", "lane": "Stop", "id": "both", "new_id": "stopped"}, "new_id",
     "has a node 'stopped'"),
    ({"op": "rename_lane", "lane": "Stop", "new_name": "2stop"}, "new_name", "not a plain name"),
    ({"op": "rename_lane", "lane": "Stop", "new_name": "Glance"}, "new_name", "a swimlane 'Glance'"),
    ({"op": "rename_lane", "lane": "Stop", "new_name": "Sensor"}, "new_name", "a component 'Sensor'"),
    ({"op": "rename_lane", "lane": "RaspberryPI", "new_name": "Pi"}, "new_name", "rename the component"),
    ({"op": "rename_component", "component": "Sensor", "new_name": "Stop"}, "new_name", "a swimlane 'Stop'"),
    ({"op": "rename_component", "component": "Sensor", "new_name": "LeftActuator"}, "new_name",
     "another component"),
    ({"op": "rename_lane", "lane": "Glance", "new_name": "ahead"}, "new_name",
     "datastore 'ahead'"),  # `call: Glance` in RaspberryPI would read its datastore `ahead`
])
def test_a_refused_rename_names_the_field(op: dict[str, Any], field: str, message: str) -> None:
    with pytest.raises(EditError, match=message) as info:
        apply_ops(_texts(CAR_MODEL), parse_ops([op]))
    assert set(info.value.fields) == {field}


def test_a_name_the_compiler_refuses_is_refused_at_its_field_with_the_compilers_line(
        car: tuple[Path, Editor]) -> None:
    # the compiler decides what a name may be: a swimlane named after a builtin is refused with
    # exactly the line `umlbot check` prints for it; a node id `msleep` the compiler accepts is
    # accepted (the studio has no rule of its own)
    root, editor = car
    version = editor.get("files")["version"]
    status, answer = editor.post("edit", {"version": version, "ops": [
        {"op": "rename_lane", "lane": "Stop", "new_name": "msleep"}]})
    assert status == 400, answer
    copy = root.parent / "copy"
    shutil.copytree(root, copy)
    motion = copy / "activities" / "motion.yaml"
    motion.write_text(motion.read_text(encoding="utf-8").replace("- lane: Stop ", "- lane: msleep "),
                      encoding="utf-8")
    check = subprocess.run(umlbot_argv("check", str(copy)), capture_output=True, text=True,
                           timeout=60, check=False)
    line = next(x for x in (check.stdout + check.stderr).splitlines() if "'msleep' is a reserved" in x)
    assert answer["fields"] == {"new_name": line.replace(str(copy), str(root))}
    assert editor.get("files")["version"] == version  # nothing changed
    for op, field, name in (
            ({"op": "rename_component", "component": "Sensor", "new_name": "Application"}, "new_name",
             "Application"),
            ({"op": "add_lane", "lane": "usleep"}, "lane", "usleep")):
        status, answer = editor.post("edit", {"version": version, "ops": [op]})
        assert status == 400, answer
        assert f"error: '{name}' is a reserved name" in answer["fields"][field], answer
    status, answer = editor.post("edit", {"version": version, "ops": [
        {"op": "rename_node", "lane": "Stop", "id": "left_off", "new_id": "msleep"}]})
    assert status == 200 and answer["compiled"], answer
    assert answer["renamed"] == [{"kind": "node", "old": "left_off", "new": "msleep", "lane": "Stop"}]
    # an undo names what it renamed back (the page keeps the node selected under its old id)
    status, answer = editor.post("undo", {})
    assert status == 200
    assert answer["renamed"] == [{"kind": "node", "old": "msleep", "new": "left_off", "lane": "Stop"}]


def test_a_pin_wired_twice_is_said_at_the_setting_with_umlbot_checks_line(car: tuple[Path, Editor]) -> None:
    from umlbot.base.deployment import shared_pin_message

    root, editor = car
    version = editor.get("files")["version"]
    status, answer = editor.post("edit", {"version": version, "ops": [
        {"op": "set_deployment", "component": "RightActuator", "impl": "l298n",
         "settings": {"in1": 22, "in2": 25}}]})
    assert status == 200, answer
    shared = [d for d in answer["diagnostics"] if d.get("component") == "RightActuator"]
    assert len(shared) == 1, answer["diagnostics"]
    assert shared[0]["field"] == "settings.in1"
    assert shared[0]["message"] == shared_pin_message(22, "RightActuator", "in1", "LeftActuator", "in1")
    (root / "deployment.yaml").write_text(editor.get("files")["files"]["deployment.yaml"], encoding="utf-8")
    check = subprocess.run(umlbot_argv("check", str(root)), capture_output=True, text=True,
                           timeout=60, check=False)
    assert check.returncode == 1 and shared[0]["text"] in (check.stdout + check.stderr).splitlines()
    # a new component on a pin in use is added (its name is fine): the problem is its setting's
    status, answer = editor.post("edit", {"version": answer["version"], "ops": [
        {"op": "add_component", "name": "Pan", "kind": "actuator", "impl": "servo",
         "settings": {"gpio": 18}}]})
    assert status == 200, answer
    assert [(d["component"], d["field"]) for d in answer["diagnostics"] if "'Pan'" in d["message"]] == [
        ("Pan", "settings.gpio")]


def test_set_text_replaces_a_files_whole_text_and_is_undone_like_any_edit(tmp_path: Path) -> None:
    # the page's text view of a file with a YAML syntax error applies what the person typed
    root = tmp_path / "car"
    shutil.copytree(CAR_MODEL, root)
    measure = root / "activities" / "measure.yaml"
    good = measure.read_text(encoding="utf-8")
    measure.write_text(good.replace("kind: start}", "kind: start", 1), encoding="utf-8")
    ws = Workspace(root)
    assert any("invalid YAML" in d["message"] for d in ws.answer()["diagnostics"])
    answer = ws.edit(ws.version, [{"op": "set_text", "file": "activities/measure.yaml", "text": good}])
    assert answer["compiled"] and answer["diagnostics"] == [], answer["diagnostics"]
    assert ws.files["activities/measure.yaml"] == good.encode("utf-8")
    ws.undo()
    assert "invalid YAML" in ws.answer()["diagnostics"][0]["message"]
    with pytest.raises(EditError, match="does not exist"):
        ws.edit(ws.version, [{"op": "set_text", "file": "activities/nothing.yaml", "text": "x"}])
    with pytest.raises(EditError, match="needs 'text'"):
        ws.edit(ws.version, [{"op": "set_text", "file": "activities/measure.yaml"}])


def test_a_run_is_told_to_the_terminal_in_one_plain_line_with_why_the_motors_stood_still() -> None:
    from umlbot.studio.run import run_line

    ended = {"reason": "goal", "goal_reached": True, "sim_s": 12.34, "distance_m": 2.5, "collisions": 0,
             "failure": None, "stood_still": None}
    line = run_line("corridor", 2.0, ended)
    assert line == "umlbot studio: run on corridor at 2x: the car reached the goal (12.3 s simulated, 2.50 m)"
    stopped = run_line("s_bend", 1.0, {"reason": "timeout", "sim_s": 60.0, "distance_m": 0.4,
                                       "stood_still": "LeftActuator: watchdog"})
    assert stopped.endswith("time is up: the goal was not reached (60.0 s simulated, 0.40 m); "
                            "motors stopped: LeftActuator: watchdog")
    assert "\n" not in stopped
