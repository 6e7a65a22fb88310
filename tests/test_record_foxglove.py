"""`umlbot sim --foxglove`: the live server tested with Foxglove's own npm client
(@foxglove/ws-protocol, subprotocol foxglove.sdk.v1): channels advertised, CDR and protobuf
messages decoded, the scene's car moves, and the server is on loopback."""

from __future__ import annotations

import json
import queue
import shutil
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest
from record_support import MODEL, ROOT, WEB

pytestmark = [pytest.mark.network]

BASE = "/umlbot/car"


def _lines(stream: Any, into: queue.Queue[str]) -> None:
    for line in stream:
        into.put(line)


@pytest.mark.timeout(120)
def test_foxglove_client_sees_the_channels_and_the_car_move(tmp_path: Path) -> None:
    node = shutil.which("node")
    assert node is not None, "node is needed"
    assert (WEB / "node_modules" / "@foxglove" / "ws-protocol").is_dir(), "make web first (npm ci)"
    argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "sim", str(MODEL), "--port", "0",
            "--speed", "2", "--foxglove", "--foxglove-port", "0", "--record", str(tmp_path / "run.mcap")]
    sim = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, cwd=ROOT)
    lines: queue.Queue[str] = queue.Queue()
    assert sim.stdout is not None
    threading.Thread(target=_lines, args=(sim.stdout, lines), daemon=True).start()
    try:
        url = ""
        while not url:
            line = lines.get(timeout=60)
            if line.startswith("foxglove: "):
                url = line.split()[1]
        assert url.startswith("ws://127.0.0.1:")  # loopback, like the studio
        scene, pose, trace = f"{BASE}/sim/scene", f"{BASE}/sim/pose", f"{BASE}/orchestrator/trace"
        client = subprocess.run([node, "test/interop/foxglove_client.mjs", url, "2500", scene, pose, trace],
                                cwd=WEB, capture_output=True, text=True, timeout=90, check=False)
        assert client.returncode == 0, client.stderr
        assert sim.wait(90) == 0
    finally:
        if sim.poll() is None:
            sim.kill()
            sim.wait(5)
    seen = json.loads(client.stdout)
    assert seen["errors"] == []
    channels = {c["topic"]: (c["encoding"], c["schemaName"]) for c in seen["channels"]}
    assert channels[pose] == ("cdr", "geometry_msgs/msg/PoseStamped")
    assert channels[f"{BASE}/sim/sonar"] == ("cdr", "sensor_msgs/msg/Range")
    assert channels[f"{BASE}/orchestrator/trace"] == ("cdr", "umlbot_msgs/msg/TraceEvent")
    assert channels[f"{BASE}/calls"] == ("cdr", "umlbot_msgs/msg/FeatureCall")
    assert channels[scene] == ("protobuf", "foxglove.SceneUpdate")
    assert channels[f"{BASE}/log"] == ("protobuf", "foxglove.Log")  # the trace as log lines
    assert seen["counts"][f"{BASE}/orchestrator/trace"] > 10
    updates = seen["decoded"][scene]
    cars = [e for u in updates for e in u["entities"] if e["id"] == "car"]
    assert len(cars) > 10
    first, last = (car["cubes"][0]["pose"]["position"] for car in (cars[0], cars[-1]))
    assert abs(last["y"] - first["y"]) + abs(last["x"] - first["x"]) > 0.2  # the car drove
    tracks = [e for u in updates for e in u["entities"] if e["id"] == "track"]
    assert tracks and len(tracks[0]["lines"][0]["points"]) >= 4  # the walls
    poses = seen["decoded"].get(pose)  # (the run lasts long enough for a late client: speed 2)
    assert poses and poses[-1]["header"]["frame_id"] == "world", seen["counts"]


def test_the_layout_in_docs_is_the_one_umlbot_makes() -> None:
    from umlbot.record.layout import layout_json

    committed = (ROOT / "docs" / "foxglove-layout.json").read_text(encoding="utf-8")
    assert committed == layout_json("car"), \
        "regenerate it: python -m umlbot.record.layout > docs/foxglove-layout.json"
    layout = json.loads(committed)
    text = json.dumps(layout)
    for topic in ("/umlbot/car/sim/scene", "/umlbot/car/sim/sonar.range", "/umlbot/car/sim/motors.effort[0]",
                  "/umlbot/car/calls", "/umlbot/car/log"):
        assert topic in text


def test_a_taken_foxglove_port_is_one_line_before_the_run(tmp_path: Path) -> None:
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "sim", str(MODEL), "--port", "0",
                "--foxglove", "--foxglove-port", str(port)]
        done = subprocess.run(argv, capture_output=True, text=True, timeout=60, cwd=ROOT, check=False)
    assert done.returncode == 1
    assert done.stderr.strip() == (f"error: cannot start the Foxglove server on 127.0.0.1:{port}: "
                                   "Address already in use (--foxglove-port 0 picks a free port)")
