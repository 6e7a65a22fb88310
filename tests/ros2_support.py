"""The independent ROS 2 peer of the ROS 2 tests: a Fast DDS program (tests/ros2_peer/peer.cpp)
built once per source hash into a temporary folder, driven line by line over stdin/stdout. It
moves raw CDR bytes; the tests encode and decode them with rosbags."""

from __future__ import annotations

import fcntl
import hashlib
import os
import queue
import random
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

from umlbot.services.ros2.msgtypes import Types, dds_topic_name, dds_type_name

PEER_SOURCE = Path(__file__).parent / "ros2_peer"


def build_peer() -> Path:
    """The peer's executable, built with cmake + ninja on first use (keyed by its sources)."""
    digest = hashlib.sha256()
    for name in ("peer.cpp", "CMakeLists.txt"):
        digest.update((PEER_SOURCE / name).read_bytes())
    folder = Path(tempfile.gettempdir()) / f"umlbot-fastdds-peer-{digest.hexdigest()[:16]}"
    folder.mkdir(exist_ok=True)
    exe = folder / "build" / "peer"
    with open(folder / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not exe.exists():
            build = folder / "build"
            shutil.rmtree(build, ignore_errors=True)
            subprocess.run(["cmake", "-S", str(PEER_SOURCE), "-B", str(build), "-G", "Ninja",
                            "-DCMAKE_BUILD_TYPE=Release"], check=True, capture_output=True)
            subprocess.run(["ninja", "-C", str(build)], check=True, capture_output=True)
    return exe


def session_domain() -> int:
    """A ROS 2 domain of its own for this test process (other runs on the machine use others)."""
    return random.Random(os.getpid() ^ time.time_ns()).randint(30, 220)


class FastDdsPeer:
    """One running peer process; `publish`, `subscribe`, `next_message`."""

    def __init__(self, exe: Path, domain_id: int) -> None:
        self.types = Types.load()
        self.process = subprocess.Popen([str(exe), str(domain_id)], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, text=True)
        self.lines: queue.Queue[str] = queue.Queue()
        self.backlog: list[str] = []
        threading.Thread(target=self._pump, daemon=True).start()
        self.expect("ready")

    def _pump(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.put(line.strip())

    def send(self, line: str) -> None:
        assert self.process.stdin is not None
        self.process.stdin.write(line + "\n")
        self.process.stdin.flush()

    def expect(self, prefix: str, timeout: float = 10.0) -> str:
        """The first line starting with `prefix`; other lines stay for later `expect`s."""
        for index, line in enumerate(self.backlog):
            if line.startswith(prefix):
                return self.backlog.pop(index)
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"the Fast DDS peer said no {prefix!r} within {timeout} s")
            try:
                line = self.lines.get(timeout=remaining)
            except queue.Empty:
                continue
            if line.startswith(prefix):
                return line
            self.backlog.append(line)

    def subscribe(self, topic: str, typename: str) -> None:
        self.send(f"sub {dds_topic_name(topic)} {dds_type_name(typename)}")
        self.expect("subscribed")

    def publish_raw(self, topic: str, dds_type: str, data: bytes) -> None:
        self.send(f"pub {dds_topic_name(topic)} {dds_type} {data.hex()}")
        self.expect("published")

    def publish(self, topic: str, typename: str, message: Any) -> None:
        data = bytes(self.types.store.serialize_cdr(message, typename))
        self.publish_raw(topic, dds_type_name(typename), data)

    def next_message(self, topic: str, typename: str, timeout: float = 10.0) -> Any:
        line = self.expect(f"msg {dds_topic_name(topic)} ", timeout)
        return self.types.store.deserialize_cdr(bytes.fromhex(line.split()[2]), typename)

    def close(self) -> None:
        if self.process.poll() is None:
            try:
                self.send("quit")
                self.process.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                self.process.kill()
                self.process.wait()

    def kill(self) -> None:
        self.process.kill()
        self.process.wait()


def message(typename: str, **fields: Any) -> Any:
    """A rosbags message of `typename` with every field zero but those given (nested as dicts)."""
    store = Types.load().store
    cls = store.types[typename]
    values: dict[str, Any] = {}
    for name, (kind, detail) in store.fielddefs[typename][1]:
        given = fields.get(name)
        if kind == 2:
            values[name] = message(detail, **(given or {}))
        elif given is not None:
            values[name] = given
        else:
            values[name] = {"string": ""}.get(detail[0], False if detail[0] == "bool" else 0)
    return cls(**values)
