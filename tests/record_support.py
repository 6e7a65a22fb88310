"""One recorded sim run shared by the recording tests, and readers that use no umlbot code."""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml

from umlbot.record import SimRecording
from umlbot.sim.runner import SimOptions, SimResult, run_sim
from umlbot.sim.track import tracks_dir

ROOT = Path(__file__).resolve().parents[1]
WEB = ROOT / "umlbot" / "studio" / "web"
MODEL = ROOT / "models" / "robot_car"
TRACK = tracks_dir() / "s_bend.yaml"


@dataclass
class RecordedRun:
    mcap: Path
    jsonl: Path
    result: SimResult
    stats: Any


@pytest.fixture(scope="session")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> RecordedRun:
    """One recorded sim run for every recording test of the session."""
    return record_sim(tmp_path_factory.mktemp("recorded"))


def record_sim(folder: Path, speed: float = 20.0) -> RecordedRun:
    """The reference car on the s_bend track with `--record` and `--trace` (JSON lines)."""
    mcap, jsonl = folder / "run.mcap", folder / "run.jsonl"
    recording = SimRecording(mcap, model="robot_car")
    options = SimOptions(model=MODEL, track=TRACK, speed=speed, port=0, timeout_s=120.0, trace_file=jsonl)
    try:
        result = run_sim(options, observe=recording.observe, trace_listener=recording.on_trace)
    finally:
        stats = recording.close()
    return RecordedRun(mcap, jsonl, result, stats)


Read = tuple[dict[str, str], Counter[str], list[tuple[str, Any, int]], dict[str, Any]]


def read_with_mcap(path: Path) -> Read:
    """Read a recording with the `mcap` + `mcap-ros2-support` packages alone: topic -> schema
    name, messages per topic, every (topic, decoded message, log time), the metadata records."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with path.open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        assert header.profile == "ros2"
        types: dict[str, str] = {}
        counts: Counter[str] = Counter()
        messages: list[tuple[str, Any, int]] = []
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            assert schema is not None and schema.encoding == "ros2msg"
            assert channel.message_encoding == "cdr"
            # the one channel field MCAP's ros2 profile requires (`ros2 bag play` takes the
            # publisher's QoS from it): a YAML list
            assert isinstance(yaml.safe_load(channel.metadata["offered_qos_profiles"]), list)
            types[channel.topic] = schema.name
            counts[channel.topic] += 1
            messages.append((channel.topic, decoded, message.log_time))
        metadata = {record.name: dict(record.metadata) for record in reader.iter_metadata()}
    return types, counts, messages, metadata


def jsonl_nodes(path: Path) -> list[tuple[int, str, str]]:
    return [(e["seq"], e["lane"], e["node"]) for e in map(json.loads, path.read_text().splitlines())]


def read_with_node(path: Path, *topics: str) -> dict[str, Any]:
    """Read a recording with Foxglove's npm packages (@mcap/core, @foxglove/rosmsg2-serialization):
    umlbot/studio/web/test/interop/read_mcap.mjs, run by node."""
    import shutil
    import subprocess

    node = shutil.which("node")
    assert node is not None, "node is needed (make web installs the studio's npm packages)"
    assert (WEB / "node_modules" / "@mcap" / "core").is_dir(), "run make web (npm ci) first"
    done = subprocess.run([node, "test/interop/read_mcap.mjs", str(path), *topics], cwd=WEB,
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    result: dict[str, Any] = json.loads(done.stdout)
    return result
