"""umlbot studio's server over real sockets: the model it serves, the robot's traffic it forwards
from a real broker, the snapshot a late page gets, replays, and who may connect."""

from __future__ import annotations

import asyncio
import json
import shutil
import socket
import subprocess
import time
from pathlib import Path
from typing import Any

import aiohttp
import pytest
from conftest import BrokerProcess
from robot_run import CAR_MODEL, Proc, compile_car, processes, umlbot_argv
from studio_support import BROKEN_MODEL, events_of, read_frames, studio

from umlbot.compiler.api import check_model
from umlbot.studio.model_view import model_view

ROBOT = "car"


def test_model_view_keeps_the_models_ids_and_flows() -> None:
    result = check_model(CAR_MODEL)
    assert result.model is not None
    view = model_view(result.model)
    assert [c["name"] for c in view["components"]] == sorted(result.model.components)
    lanes = {lane["name"]: lane for d in view["diagrams"] for lane in d["lanes"]}
    assert set(lanes) == set(result.model.lanes)
    main = lanes["RaspberryPI"]
    assert {n["id"] for n in main["nodes"]} == set(result.model.lanes["RaspberryPI"].nodes)
    choose = [e for e in main["edges"] if e["source"] == "choose"]
    assert [e["label"] for e in choose][-1] == "else"
    assert all(e["target"] in {n["id"] for n in main["nodes"]} for e in main["edges"])
    assert {d["file"] for d in view["diagrams"]} == {lane.file for lane in result.model.lanes.values()}


def _hello(url: str) -> dict[str, Any]:
    frames = read_frames(url, lambda f: len(f) >= 1)
    assert frames[0]["type"] == "hello"
    return frames[0]


def test_a_model_with_errors_is_served_with_the_checkers_messages(tmp_path: Path) -> None:
    model = tmp_path / "bad.yaml"
    model.write_text(BROKEN_MODEL, encoding="utf-8")
    check = subprocess.run(umlbot_argv("check", str(model)), capture_output=True, text=True, timeout=60,
                           check=False, cwd=tmp_path)
    assert check.returncode == 1
    with studio(["studio", str(model), "--port", "0"], tmp_path) as proc:
        hello = _hello(proc.url)
    assert hello["model"] is None
    texts = [d["text"] for d in hello["diagnostics"]]
    printed = [line for line in (check.stdout + check.stderr).splitlines() if ": error: " in line
               or ": warning: " in line]
    assert texts and set(texts) == set(printed)


def test_live_traffic_reaches_the_page_and_a_late_page_gets_the_snapshot(
    mosquitto_broker: BrokerProcess, raw_client: Any, tmp_path: Path
) -> None:
    raw = raw_client(mosquitto_broker)
    base = f"umlbot/{ROBOT}"
    with studio(["studio", str(CAR_MODEL), "--port", "0", "--robot", ROBOT], tmp_path,
                mosquitto_broker.url) as proc:
        hello = _hello(proc.url)
        assert hello["mode"] == "live" and hello["robot"] == ROBOT and hello["model"]["name"] == "car"
        assert hello["diagnostics"] == []

        def published(frames: list[dict[str, Any]]) -> bool:
            # publish once the page is attached; repeat the retained status until it shows up
            if len(frames) == 2:
                raw.publish(f"{base}/LeftActuator/status", '{"state":"online","impl":"l298n"}', retain=True)
            return any(e.get("component") == "LeftActuator" for e in events_of(frames, "availability"))

        read_frames(proc.url, published)
        batch = [{"lane": "RaspberryPI", "node": n, "kind": "action", "start": 10.0 + i, "end": 10.5 + i,
                  "duration_ms": 500.0, "level": "info", "detail": n}
                 for i, n in enumerate(("stop_all", "halt"))]
        raw.publish(f"{base}/orchestrator/trace", json.dumps(batch[0]))
        raw.publish(f"{base}/orchestrator/trace", json.dumps(batch[1]))
        raw.publish(f"{base}/LeftActuator/call/enabled",
                    json.dumps({"id": "c7", "reply_to": f"{base}/_reply/t", "args": [True]}))
        raw.publish(f"{base}/_reply/t", '{"id":"c7","ok":true,"value":null}')
        raw.publish(f"{base}/orchestrator/status", '{"state":"failed","reason":"broker lost"}', retain=True)

        # a page that opens now gets all of it in its snapshot, in order, with frame numbers 1, 2, …
        frames = read_frames(proc.url, lambda f: len(events_of(f, "trace")) >= 2
                             and len(events_of(f, "call")) >= 1 and len(events_of(f, "orchestrator")) >= 1)
        raw.publish(f"{base}/LeftActuator/status", b"", retain=True)
        raw.publish(f"{base}/orchestrator/status", b"", retain=True)
    seqs = [f["seq"] for f in frames if f["type"] == "events"]
    assert seqs == list(range(1, len(seqs) + 1))
    traces = events_of(frames, "trace")
    assert [(e["node"], e["time"], e["duration_ms"]) for e in traces] == [("stop_all", 10.5, 500.0),
                                                                          ("halt", 11.5, 500.0)]
    (call,) = events_of(frames, "call")
    assert (call["component"], call["feature"], call["args"], call["ok"]) == ("LeftActuator", "enabled",
                                                                              [True], True)
    (status,) = events_of(frames, "orchestrator")
    assert (status["state"], status["detail"]) == ("failed", "broker lost")


def test_replay_serves_the_recorded_events(tmp_path: Path) -> None:
    trace = tmp_path / "run.jsonl"
    lines = [{"lane": "RaspberryPI", "node": n, "kind": "action", "start": 100.0 + i, "end": 100.25 + i,
              "duration_ms": 250.0, "level": "info", "detail": n} for i, n in enumerate(("stop_all", "halt"))]
    trace.write_text("".join(json.dumps(line) + "\n" for line in lines), encoding="utf-8")
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        hello = _hello(proc.url)
    assert hello["mode"] == "replay" and hello["replay"]["file"] == "run.jsonl"
    replayed = [(e["node"], e["time"]) for e in hello["replay"]["events"] if e["type"] == "trace"]
    assert replayed == [("stop_all", 100.25), ("halt", 101.25)]


def _line(lane: str, node: str, kind: str, end: float, ms: float, **extra: Any) -> str:
    event = {"lane": lane, "node": node, "kind": kind, "start": end - ms / 1000, "end": end,
             "duration_ms": ms, "level": "error" if "error" in extra else "info", **extra}
    return json.dumps(event) + "\n"


def test_a_replay_lists_the_calls_the_notes_and_how_the_run_ended(tmp_path: Path) -> None:
    trace = tmp_path / "run.jsonl"
    lines = [
        _line("Glance", "look_left", "action", 100.0, 4.5, detail="Sensor.angle(135)"),
        _line("Glance", "settle_left", "action", 100.1, 100.0, detail="msleep(RaspberryPI.glance_ms)"),
        _line("Glance", "left", "datastore", 100.2, 5.25, value=42, detail="left = DistanceRead.value()"),
        _line("Ghost", "look_up", "action", 100.3, 1.0, detail="Neck.tilt(10)"),  # another model's
        _line("Glance", "right", "datastore", 102.5, 2003.5, detail="right = DistanceRead.value()",
              error="CallTimeout: no reply from DistanceRead.value within 2 s"),
        _line("RaspberryPI", "stop_all", "action", 102.6, 20.0, detail="Stop"),
    ]
    # the run was killed while it wrote its last line
    trace.write_text("".join(lines) + lines[0][:40], encoding="utf-8")
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        replay = _hello(proc.url)["replay"]
        proc.stop()
        stderr = proc.log_text()
    cut = "run.jsonl:7: the last line is cut off"
    ghost = "1 event names a node not in the model (e.g. Ghost/look_up)"
    assert [n[:len(cut)] if n.startswith(cut) else n[:len(ghost)] for n in replay["notes"]] == [cut, ghost]
    assert f"warning: {cut}" in stderr and ghost in stderr
    events = replay["events"]
    assert [e["node"] for e in events if e["type"] == "trace"] == [
        "look_left", "settle_left", "left", "look_up", "right", "stop_all"]
    calls = [{k: c.get(k) for k in ("time", "component", "feature", "args", "detail", "ok", "value", "error",
                                     "latency_ms")} for c in events if c["type"] == "call"]
    assert calls == [
        {"time": 100.0, "component": "Sensor", "feature": "angle", "args": [135],
         "detail": "Sensor.angle(135)", "ok": True, "value": None, "error": None, "latency_ms": 4.5},
        {"time": 100.2, "component": "DistanceRead", "feature": "value", "args": [],
         "detail": "DistanceRead.value()", "ok": True, "value": 42, "error": None, "latency_ms": 5.25},
        {"time": 102.5, "component": "DistanceRead", "feature": "value", "args": [],
         "detail": "DistanceRead.value()", "ok": False, "value": None,
         "error": "CallTimeout: no reply from DistanceRead.value within 2 s", "latency_ms": 2003.5},
    ]
    status = [(e["time"], e["state"], e["detail"]) for e in events if e["type"] == "orchestrator"]
    fault = "Glance/right: CallTimeout: no reply from DistanceRead.value within 2 s"
    assert status == [(100.0, "running", "from the trace"), (102.5, "failed", fault)]


def test_a_replay_without_a_fault_says_where_the_trace_ends(tmp_path: Path) -> None:
    trace = tmp_path / "run.jsonl"
    trace.write_text(_line("RaspberryPI", "stop_all", "action", 5.0, 1.0, detail="Stop")
                     + _line("RaspberryPI", "halt", "action", 7.5, 1.0, detail="halt"), encoding="utf-8")
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        replay = _hello(proc.url)["replay"]
    assert replay["notes"] == []
    status = [(e["time"], e["state"]) for e in replay["events"] if e["type"] == "orchestrator"]
    assert status == [(5.0, "running"), (7.5, "trace ended")]


@pytest.mark.parametrize("text", ["", "\n\n  \n"])
def test_an_empty_trace_file_is_an_error(tmp_path: Path, text: str) -> None:
    trace = tmp_path / "empty.jsonl"
    trace.write_text(text, encoding="utf-8")
    result = subprocess.run(umlbot_argv("studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"),
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 1, result.stdout
    assert f"{trace}: no trace events" in result.stderr and "Traceback" not in result.stderr


def test_a_broken_trace_file_is_one_clear_error(tmp_path: Path) -> None:
    trace = tmp_path / "run.jsonl"
    trace.write_text('{"lane": "x"}\n', encoding="utf-8")
    result = subprocess.run(umlbot_argv("studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"),
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 1
    assert f"{trace}:1: not a trace event" in result.stderr
    assert "Traceback" not in result.stderr


def test_non_loopback_bind_needs_allow_remote(tmp_path: Path) -> None:
    result = subprocess.run(umlbot_argv("studio", str(CAR_MODEL), "--host", "0.0.0.0", "--port", "0"),
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 1
    assert "--allow-remote" in result.stderr and "Traceback" not in result.stderr


def test_a_studio_others_can_reach_is_read_only(tmp_path: Path) -> None:
    # with --allow-remote the write token would go to anyone who opens a socket: no editing at all
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    with studio(["studio", str(folder), "--host", "0.0.0.0", "--allow-remote", "--port", "0"],
                tmp_path) as proc:
        port = proc.url.rstrip("/").rsplit(":", 1)[1]
        url = f"http://127.0.0.1:{port}/"
        hello = read_frames(url, lambda f: len(f) >= 1)[0]
        assert hello["model"] is not None and hello.get("edit") is None

        async def post() -> int:
            async with aiohttp.ClientSession() as client, client.post(
                    f"{url}api/edit", json={"version": 0, "ops": []}) as response:
                return response.status

        assert asyncio.run(post()) == 404
        assert "read-only: the page can be reached from other machines" in proc.log_text()
    assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before
    # and a new model cannot be started there
    result = subprocess.run(umlbot_argv("studio", "--new", str(tmp_path / "new"), "--host", "0.0.0.0",
                                        "--allow-remote", "--port", "0"),
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 2 and "needs a loopback --host" in result.stderr, result.stderr


def test_foreign_origins_and_rebound_host_names_are_refused(tmp_path: Path) -> None:
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        port = proc.url.rstrip("/").rsplit(":", 1)[1]

        async def status(path: str, headers: dict[str, str]) -> int:
            async with aiohttp.ClientSession() as client:
                try:
                    async with client.ws_connect(f"http://127.0.0.1:{port}{path}", headers=headers):
                        return 101
                except aiohttp.WSServerHandshakeError as exc:
                    return exc.status

        assert asyncio.run(status("/ws", {"Origin": "http://evil.example"})) == 403
        assert asyncio.run(status("/ws", {"Host": f"evil.example:{port}"})) == 403
        assert asyncio.run(status("/ws", {"Origin": f"http://127.0.0.1:{port}"})) == 101
        assert asyncio.run(status("/ws", {"Origin": f"http://localhost:{port}",
                                          "Host": f"localhost:{port}"})) == 101


def test_a_rebinding_page_cannot_write_with_allow_remote_on_loopback(tmp_path: Path) -> None:
    """--allow-remote on the default 127.0.0.1 leaves the page editable, so the Host check must
    hold: a page of evil.example whose name was rebound to 127.0.0.1 gets neither the socket's
    hello (with the write token) nor any write, even with the token."""
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    before = {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()}
    with studio(["studio", str(folder), "--allow-remote", "--port", "0"], tmp_path) as proc:
        port = proc.url.rstrip("/").rsplit(":", 1)[1]
        base = f"http://127.0.0.1:{port}"
        evil = {"Host": f"evil.example:{port}", "Origin": f"http://evil.example:{port}"}
        token = read_frames(base, lambda f: len(f) >= 1)[0]["edit"]["token"]  # the real page's

        async def attack() -> dict[str, int]:
            statuses: dict[str, int] = {}
            async with aiohttp.ClientSession() as client:
                try:
                    async with client.ws_connect(f"{base}/ws", headers=evil):
                        statuses["ws"] = 101
                except aiohttp.WSServerHandshakeError as exc:
                    statuses["ws"] = exc.status
                async with client.get(f"{base}/", headers=evil) as response:
                    statuses["page"] = response.status
                async with client.get(f"{base}/api/files", headers=evil) as response:
                    statuses["files"] = response.status
                for name, body in (("edit", {"version": 0, "ops": [{"op": "remove_lane", "lane": "Stop"}]}),
                                   ("save", {"version": 1}), ("run", {"track": "s_bend"})):
                    async with client.post(f"{base}/api/{name}", json={"token": token, **body},
                                           headers=evil) as response:
                        statuses[name] = response.status
                        if response.status != 200:
                            assert "evil.example" in (await response.json())["error"]
            return statuses

        statuses = asyncio.run(attack())
        assert statuses == {"ws": 403, "page": 403, "files": 403, "edit": 403, "save": 403, "run": 403}
        # the names of this machine's loopback still work (the page opened as the docs say)
        for host in (f"127.0.0.1:{port}", f"localhost:{port}", "127.0.0.1"):
            hello = read_frames(base, lambda f: len(f) >= 1, headers={"Host": host})[0]
            assert hello["edit"]["token"], host
    assert {p: p.read_bytes() for p in folder.rglob("*") if p.is_file()} == before


def test_the_port_in_use_is_one_clear_error(tmp_path: Path) -> None:
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        port = proc.url.rstrip("/").rsplit(":", 1)[1]
        result = subprocess.run(umlbot_argv("studio", str(CAR_MODEL), "--port", port),
                                capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 1
    assert f"cannot listen on 127.0.0.1:{port}" in result.stderr and "Traceback" not in result.stderr
    assert "(another studio? choose another port with --port)" in result.stderr


def test_sim_names_its_own_option_when_the_studio_port_is_taken(tmp_path: Path) -> None:
    # `umlbot sim` has no --port for the studio (its --port is the broker's): the hint must say
    # --studio-port
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = subprocess.run(umlbot_argv("sim", str(CAR_MODEL), "--port", "0", "--timeout", "5",
                                            "--studio", "--studio-port", str(port)),
                                capture_output=True, text=True, timeout=120, check=False, cwd=tmp_path)
    assert result.returncode == 1, result.stderr
    assert f"cannot listen on 127.0.0.1:{port}" in result.stderr and "Traceback" not in result.stderr
    assert "(another studio? choose another port with --studio-port)" in result.stderr


@pytest.mark.parametrize("remote", [["--allow-remote"], []])
def test_a_host_name_that_does_not_resolve_is_one_line_without_the_port_hint(tmp_path: Path,
                                                                           remote: list[str]) -> None:
    # without --allow-remote too: the name is the first thing to fix, not the missing flag
    result = subprocess.run(umlbot_argv("studio", str(CAR_MODEL), "--host", "no.such.host.invalid",
                                        *remote, "--port", "0"),
                            capture_output=True, text=True, timeout=60, check=False, cwd=tmp_path)
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "cannot listen on --host no.such.host.invalid: the name is not known" in lines[0]
    assert "--port" not in lines[0] and "--allow-remote" not in lines[0]


def test_a_missing_model_is_a_usage_error(tmp_path: Path) -> None:
    # (a new model is asked for with --new: tests/test_studio_edit.py)
    result = subprocess.run(umlbot_argv("studio", str(tmp_path / "no" / "nothing")), capture_output=True,
                            text=True, timeout=60, check=False)
    assert result.returncode == 2 and "does not exist" in result.stderr
    result = subprocess.run(umlbot_argv("studio", "--new", str(tmp_path / "no" / "nothing")),
                            capture_output=True, text=True, timeout=60, check=False)
    assert result.returncode == 2 and "needs an existing parent folder" in result.stderr, result.stderr


def run_studio_briefly(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(umlbot_argv("studio", *args, "--port", "0"), capture_output=True, text=True,
                          timeout=60, check=False)


def test_a_path_that_is_no_model_is_an_error_that_says_how_to_start_a_new_model(tmp_path: Path) -> None:
    # a typo of a model folder: not a new model there, but the folder meant, and how to ask for one
    models = tmp_path / "models"
    shutil.copytree(CAR_MODEL, models / "robot_car")
    result = run_studio_briefly(str(models / "robot_cr"))
    assert result.returncode == 2, result.stderr
    assert f"did you mean {models / 'robot_car'}?" in result.stderr, result.stderr
    assert f"umlbot studio --new {models / 'robot_cr'}" in result.stderr, result.stderr
    assert not (models / "robot_cr").exists()
    # a file that is no model (README.md) is not served as a model with one error
    readme = tmp_path / "README.md"
    readme.write_text("# hello\n", encoding="utf-8")
    result = run_studio_briefly(str(readme))
    assert result.returncode == 2 and "is not a model" in result.stderr, result.stderr
    # a folder holding other things (the repository's root)
    (tmp_path / "notes.txt").write_text("x", encoding="utf-8")
    result = run_studio_briefly(str(tmp_path))
    assert result.returncode == 2 and "holds no model" in result.stderr, result.stderr
    assert f"umlbot studio --new {tmp_path}" in result.stderr, result.stderr
    # --new on a model refuses rather than hide it
    result = run_studio_briefly("--new", str(models / "robot_car"))
    assert result.returncode == 2 and "already holds a model" in result.stderr, result.stderr


def test_a_page_opened_after_a_sim_run_gets_its_last_world(tmp_path: Path) -> None:
    # `umlbot sim --studio` keeps the page served after the run "so that you can look at it": a page
    # that opens then must get the car where the run left it, its last pings and the summary
    with studio(["sim", str(CAR_MODEL), "--port", "0", "--speed", "10", "--studio", "--studio-port", "0"],
                tmp_path) as proc:
        proc.wait_line("the run has ended")
        frames = read_frames(proc.url, lambda f: any(x["type"] == "world" for x in f))
    hello = frames[0]
    kinds = [f["type"] for f in frames]
    assert kinds[0] == "hello" and kinds.index("events") < kinds.index("world"), kinds
    assert events_of(frames, "trace"), "the run's trace is in the snapshot"
    (world,) = [f for f in frames if f["type"] == "world"]
    start = hello["track"]["start"]
    assert world["goal"] is True and world["t"] > 1.0 and world["collisions"] == 0
    moved = abs(world["car"]["x"] - start["x"]) + abs(world["car"]["y"] - start["y"])
    assert moved > 0.5, (world["car"], start)
    assert world["pings"], "the last second's pings"
    assert all(world["t"] - ping["t"] <= 1.0 for ping in world["pings"]), world["pings"]


def test_the_page_says_why_the_broker_is_not_reached_and_that_it_keeps_trying(tmp_path: Path) -> None:
    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with studio(["studio", str(CAR_MODEL), "--port", "0", "--broker", f"mqtt://127.0.0.1:{port}"],
                tmp_path) as proc:
        frames = read_frames(proc.url, lambda f: any((e.get("attempts") or 0) >= 4
                                                     for e in events_of(f, "broker")))
        proc.stop()
        stderr = proc.log_text()
    broker = events_of(frames, "broker")
    assert all(e["url"] == f"mqtt://127.0.0.1:{port}" and e["connected"] is False for e in broker), broker
    failed = [e for e in broker if e.get("problem")]
    assert failed and all(e["problem"] == "Connection refused" for e in failed), broker
    assert all(0 <= e["retry_in_s"] <= 5.0 for e in failed), failed
    attempts = [e["attempts"] for e in failed]
    assert attempts == sorted(attempts) and attempts[-1] >= 4  # it keeps trying
    # logged: the first failure as a warning, the retries of the same outage not every time
    assert stderr.count("mqtt_connect_failed") == 1, stderr


def test_the_page_says_the_broker_is_connected_and_calls_time_out_after_the_models_time_out(
    mosquitto_broker: BrokerProcess, raw_client: Any, tmp_path: Path
) -> None:
    # robot_car's call_timeout_s is 2 s: a call nobody answers is reported after 2 s (not the
    # monitor's 5 s), at the time it was made
    raw = raw_client(mosquitto_broker)
    with studio(["studio", str(CAR_MODEL), "--port", "0", "--robot", ROBOT], tmp_path,
                mosquitto_broker.url) as proc:
        read_frames(proc.url, lambda f: any(e["connected"] for e in events_of(f, "broker")))
        sent = time.time()
        raw.publish(f"umlbot/{ROBOT}/DistanceRead/call/value",
                    json.dumps({"id": "q1", "reply_to": f"umlbot/{ROBOT}/_reply/t", "args": []}))
        frames = read_frames(proc.url, lambda f: bool(events_of(f, "call")), timeout=10.0)
        seen = time.time()
    (call,) = events_of(frames, "call")
    assert (call["feature"], call["ok"], call["error"]) == ("value", False, "no reply within 2 s")
    assert "latency_ms" not in call
    assert sent - 0.5 <= call["time"] <= sent + 0.5, (sent, call["time"])  # the request's time
    assert seen - sent < 4.5  # reported after about 2 s (checked once a second), not 5


def test_unanswered_calls_are_reported_after_the_time_out_their_caller_used(
    mosquitto_broker: BrokerProcess, raw_client: Any, tmp_path: Path
) -> None:
    """Components that say they are online but never answer: the orchestrator's start-up stop
    calls time out after the run's call time-out (1.5 s), its fail-safe stop calls on the way out
    after 1 s — and the page is told each one's own time-out, not the run's for all."""
    compiled = compile_car(tmp_path)
    raw = raw_client(mosquitto_broker)
    for name in ("LeftActuator", "RightActuator", "Sensor", "DistanceRead", "RaspberryPI"):
        raw.publish(f"umlbot/{ROBOT}/{name}/status", json.dumps({"state": "online"}), retain=True)
    with processes() as made, studio(["studio", str(CAR_MODEL), "--port", "0", "--robot", ROBOT], tmp_path,
                                     mosquitto_broker.url) as proc:
        read_frames(proc.url, lambda f: any(e["connected"] for e in events_of(f, "broker")))
        run = Proc("run", umlbot_argv("run", str(compiled), "--robot", ROBOT, "--call-timeout", "1.5"),
                   tmp_path, mosquitto_broker.url)
        made.append(run)
        assert run.popen.wait(30) == 1  # it could not stop the actuators at start-up: a fault

        def both(frames: list[dict[str, Any]]) -> bool:
            return {e.get("error") for e in events_of(frames, "call")} >= {"no reply within 1.5 s",
                                                                            "no reply within 1 s"}

        frames = read_frames(proc.url, both, timeout=15.0)
    calls = events_of(frames, "call")
    at_start = [e for e in calls if e["error"] == "no reply within 1.5 s"]
    on_the_way_out = [e for e in calls if e["error"] == "no reply within 1 s"]
    assert len(at_start) + len(on_the_way_out) == len(calls), calls
    assert {(e["component"], e["feature"]) for e in on_the_way_out} == {
        (e["component"], e["feature"]) for e in at_start}  # the same stop calls, twice
    assert min(e["time"] for e in on_the_way_out) > max(e["time"] for e in at_start) + 1.0
    assert "within 1 s" in run.log_text()  # what the orchestrator itself said about them


def test_a_ping_is_drawn_to_the_wall_point_its_echo_came_from() -> None:
    # the beam is ~15° wide: an echo from a wall off the centre line is drawn where it came from,
    # not along the centre line (where it would end beyond the wall)
    from umlbot.sim.geometry import Point
    from umlbot.sim.world import Ping
    from umlbot.studio.sources import _ping

    off_centre = _ping(Ping(1.0, Point(0.0, 0.0), 0.0, 50, Point(0.48, 0.13)))
    assert (off_centre["x1"], off_centre["y1"]) == (0.48, 0.13)
    no_echo = _ping(Ping(1.0, Point(0.0, 0.0), 0.0, None))
    assert (no_echo["x1"], no_echo["y1"], no_echo["cm"]) == (4.0, 0.0, None)
