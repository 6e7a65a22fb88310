"""`umlbot sim --record`: a rosbag2 MCAP file read back by readers that share no code with the
writer (Python `mcap` + `mcap-ros2-support`; rosbags' own reader; Foxglove's npm packages), the
same node sequence as the JSON-lines trace of the same run, a disk that fills up ending the
recording cleanly; `umlbot monitor --replay` and the studio's replay read MCAP as they read JSON
lines, and a cut or damaged MCAP is one clear error line."""

from __future__ import annotations

import json
import math
import os
import resource
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from record_support import MODEL, ROOT, RecordedRun, jsonl_nodes, read_with_mcap, read_with_node, recorded

pytestmark = [pytest.mark.network]

BASE = "/umlbot/car"
UMLBOT = [sys.executable, "-c", "from umlbot.cli import main; main()"]


__all__ = ["recorded"]  # the session's recorded run (a fixture)


@pytest.mark.timeout(120)
def test_the_recording_has_every_kind_of_message(recorded: RecordedRun) -> None:
    assert recorded.result.reason == "goal", recorded.result
    assert recorded.stats.dropped == 0 and recorded.stats.failed is None
    types, counts, messages, metadata = read_with_mcap(recorded.mcap)
    expected = {
        f"{BASE}/orchestrator/trace": "umlbot_msgs/msg/TraceEvent",
        f"{BASE}/calls": "umlbot_msgs/msg/FeatureCall",
        f"{BASE}/orchestrator/status": "umlbot_msgs/msg/OrchestratorStatus",
        f"{BASE}/LeftActuator/status": "umlbot_msgs/msg/ComponentStatus",
        f"{BASE}/LeftActuator/state": "umlbot_msgs/msg/ComponentState",
        f"{BASE}/DistanceRead/state": "umlbot_msgs/msg/ComponentState",
        f"{BASE}/sim/pose": "geometry_msgs/msg/PoseStamped",
        f"{BASE}/sim/sonar": "sensor_msgs/msg/Range",
        f"{BASE}/sim/motors": "sensor_msgs/msg/JointState",
        f"{BASE}/sim/track": "visualization_msgs/msg/MarkerArray",
    }
    for topic, msgtype in expected.items():
        assert types.get(topic) == msgtype, topic
        assert counts[topic] >= 1, topic
    assert counts[f"{BASE}/sim/track"] == 1
    assert counts[f"{BASE}/sim/pose"] > 20  # sampled every 50 ms of a run of seconds
    assert sum(counts.values()) == recorded.stats.messages

    # the file says which clock stamps it (rosbag2's custom_data in its metadata record)
    info = yaml.safe_load(metadata["rosbag2"]["serialized_metadata"])
    assert info["custom_data"]["umlbot.clock"] == "sim"
    assert info["custom_data"]["umlbot.robot"] == "car"
    assert info["message_count"] == sum(counts.values())
    # what `ros2 bag info` prints of a single MCAP file comes from this record (rosbag2's
    # metadata, version 9 since Jazzy): the storage, and every topic with its type and count
    assert info["storage_identifier"] == "mcap" and info["version"] >= 5
    listed = {t["topic_metadata"]["name"]: t for t in info["topics_with_message_count"]}
    assert {name: t["message_count"] for name, t in listed.items()} == dict(counts)
    assert all(listed[topic]["topic_metadata"]["type"] == msgtype for topic, msgtype in types.items())
    assert all(t["topic_metadata"]["serialization_format"] == "cdr" for t in listed.values())

    by_topic: dict[str, list[Any]] = {}
    for topic, message, _ in messages:
        by_topic.setdefault(topic, []).append(message)
    # every ping is a Range in metres within the HC-SR04's range (or +inf: no echo)
    ranges = [m.range for m in by_topic[f"{BASE}/sim/sonar"]]
    assert all(0.02 <= r <= 4.0 or r == math.inf for r in ranges)
    assert any(r < 4.0 for r in ranges)
    # the car moved from its start to the goal
    poses = [(m.pose.position.x, m.pose.position.y) for m in by_topic[f"{BASE}/sim/pose"]]
    final = recorded.result.final_pose
    assert math.dist(poses[-1], final[:2]) < 0.05
    assert math.dist(poses[0], poses[-1]) > 1.0
    # calls: the motors' dutycycle with its argument, an answer and a latency
    calls = by_topic[f"{BASE}/calls"]
    duty = [c for c in calls if c.component == "LeftActuator" and c.feature == "dutycycle"]
    assert duty and all(c.answered and c.ok and c.latency_ms >= 0 for c in duty)
    assert all(0 <= json.loads(c.args_json)[0] <= 100 for c in duty)
    sonar_calls = [c for c in calls if c.component == "DistanceRead" and c.feature == "value"]
    assert sonar_calls and all(c.value_json.strip("-").isdigit() for c in sonar_calls if c.ok)
    statuses = [(m.component, m.state) for m in by_topic[f"{BASE}/LeftActuator/status"]]
    assert statuses[0] == ("LeftActuator", "online")  # and offline when its service stopped
    assert by_topic[f"{BASE}/LeftActuator/status"][0].impl == "l298n"
    orchestrator = [m.state for m in by_topic[f"{BASE}/orchestrator/status"]]
    assert "running" in orchestrator


@pytest.mark.timeout(60)
def test_jsonl_and_mcap_of_one_run_give_the_same_nodes(recorded: RecordedRun) -> None:
    _, _, messages, _ = read_with_mcap(recorded.mcap)
    trace = [m for topic, m, _ in messages if topic == f"{BASE}/orchestrator/trace"]
    from_mcap = sorted((m.seq, m.lane, m.node) for m in trace)
    from_jsonl = jsonl_nodes(recorded.jsonl)
    assert len(from_jsonl) > 100
    assert from_mcap == from_jsonl
    # log time is the node's end, in the run's (sim) clock
    ends = {m.seq: m.end for m in trace}
    assert all(abs(log_ns / 1e9 - ends[m.seq]) < 1e-6 for topic, m, log_ns in messages
               if topic == f"{BASE}/orchestrator/trace")


@pytest.mark.timeout(60)
def test_rosbags_reads_the_file_as_a_rosbag2_mcap(recorded: RecordedRun) -> None:
    from rosbags.rosbag2 import Reader

    from umlbot.base import rosmsg

    store = rosmsg.typestore()
    with Reader(recorded.mcap) as reader:  # the file alone, as `ros2 bag info run.mcap` opens it
        assert reader.message_count == recorded.stats.messages
        topics = {c.topic: c.msgtype for c in reader.connections}
        assert topics[f"{BASE}/sim/pose"] == "geometry_msgs/msg/PoseStamped"
        pose = next(reader.messages(connections=[c for c in reader.connections
                                                 if c.topic == f"{BASE}/sim/pose"]))
        decoded: Any = store.deserialize_cdr(pose[2], "geometry_msgs/msg/PoseStamped")
        assert decoded.header.frame_id == "world"


@pytest.mark.timeout(90)
def test_foxglove_npm_packages_read_and_decode_it(recorded: RecordedRun) -> None:
    pose, trace, calls = f"{BASE}/sim/pose", f"{BASE}/orchestrator/trace", f"{BASE}/calls"
    read = read_with_node(recorded.mcap, pose, trace, calls)
    assert read["profile"] == "ros2" and read["done"] is True
    _, counts, _, _ = read_with_mcap(recorded.mcap)
    assert {topic: entry["count"] for topic, entry in read["topics"].items()} == dict(counts)
    assert read["topics"][pose]["schema"] == "geometry_msgs/msg/PoseStamped"
    assert read["topics"][f"{BASE}/sim/sonar"]["schema"] == "sensor_msgs/msg/Range"
    final = recorded.result.final_pose
    last = read["decoded"][pose][-1]["message"]
    assert math.dist((last["pose"]["position"]["x"], last["pose"]["position"]["y"]), final[:2]) < 0.05
    assert last["header"]["frame_id"] == "world"
    nodes = sorted((int(m["message"]["seq"]), m["message"]["lane"], m["message"]["node"])  # uint64: text
                   for m in read["decoded"][trace])
    assert nodes == jsonl_nodes(recorded.jsonl)
    duty = [m["message"] for m in read["decoded"][calls]
            if m["message"]["component"] == "RightActuator" and m["message"]["feature"] == "dutycycle"]
    assert duty and all(c["answered"] and c["ok"] for c in duty)


def _replay_json(path: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*UMLBOT, "monitor", "--replay", str(path), "--json", "--speed", "0"],
                          capture_output=True, text=True, timeout=60, check=False)


@pytest.mark.timeout(90)
def test_monitor_and_studio_replay_mcap_as_they_replay_jsonl(recorded: RecordedRun) -> None:
    from umlbot.studio.sources import replay_data

    from_mcap, from_jsonl = _replay_json(recorded.mcap), _replay_json(recorded.jsonl)
    assert from_mcap.returncode == 0, from_mcap.stderr
    lines = from_mcap.stdout.splitlines()
    assert len(lines) > 100
    assert list(map(json.loads, lines)) == list(map(json.loads, from_jsonl.stdout.splitlines()))
    studio_mcap = replay_data(recorded.mcap, "car", None)
    studio_jsonl = replay_data(recorded.jsonl, "car", None)
    assert studio_mcap["events"] == studio_jsonl["events"]
    assert studio_mcap["notes"] == []


@pytest.mark.timeout(60)
def test_a_cut_mcap_is_one_clear_error_naming_where_it_broke(recorded: RecordedRun, tmp_path: Path) -> None:
    data = recorded.mcap.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])
    done = _replay_json(cut)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, done.stderr
    assert f"{cut}: the MCAP file breaks off" in lines[0]
    assert f"of {len(data) // 2}" in lines[0] and "trace events were read before it" in lines[0]

    # a damaged record: the first chunk's length made absurd
    header_length = int.from_bytes(data[9:17], "little")
    chunk = 8 + 9 + header_length
    assert data[chunk] == 0x06  # rosbags writes the first chunk right after the header
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(data[:chunk + 1] + b"\xff" * 8 + data[chunk + 9:])
    done = _replay_json(damaged)
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert f"{damaged}: the MCAP file breaks off or is damaged after byte {chunk}" in done.stderr


def _limit_file_size(limit: int) -> None:  # runs in the child before exec
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))


@pytest.mark.timeout(120)
def test_a_full_disk_ends_the_recording_cleanly_and_the_robot_drives_on(tmp_path: Path) -> None:
    """The kernel refuses writes past RLIMIT_FSIZE (EFBIG, as ENOSPC on a full disk): a real
    failing write of the real file, not a fake."""
    limit = 150_000  # a full recording of this run is ~400 kB
    out = tmp_path / "run.mcap"
    # a chunk is closed every wall second: at speed 20 on an idle machine one chunk is ~200 kB,
    # more than the limit, and the cut file would hold none; at speed 5 a chunk is ~50 kB
    argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "sim", str(MODEL), "--port", "0",
            "--speed", "5", "--json", "--record", str(out)]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=110, cwd=ROOT,
                          preexec_fn=lambda: _limit_file_size(limit), env={**os.environ}, check=False)
    assert done.returncode == 0, done.stderr[-2000:]  # goal reached: the robot did not notice
    assert '"goal": true' in done.stdout
    assert "the recording stopped early" in done.stderr
    assert "File too large" in done.stderr
    size = out.stat().st_size
    assert 0 < size <= limit
    # the file ends with an MCAP footer and reads to its end with the mcap package
    assert out.read_bytes()[-8:] == b"\x89MCAP0\r\n"
    _, counts, messages, _ = read_with_mcap(out)
    assert sum(counts.values()) > 50
    by_node = read_with_node(out)  # and Foxglove's stream reader reads it to its end too
    assert by_node["done"] is True
    assert {topic: entry["count"] for topic, entry in by_node["topics"].items()} == dict(counts)
    assert any(topic == f"{BASE}/orchestrator/trace" for topic, _, _ in messages)
