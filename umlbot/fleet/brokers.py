"""Mosquitto processes for a fleet on one machine: a hub and one leaf broker per robot.

`Mosquitto` is one broker process from a configuration text, on loopback, that can be stopped,
killed and started again on the same port (the fault tests kill the hub). `LocalFleet` starts a
hub and a leaf per robot whose bridge (`bridge_conf`) carries `umlbot/<robot>/#` to the hub.
"""

from __future__ import annotations

import os
import pwd
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from umlbot.base.errors import ConfigError
from umlbot.fleet.config import Hub, bridge_conf, check_robot_id

START_TIMEOUT_S = 10.0
STOP_TIMEOUT_S = 5.0


def find_mosquitto() -> str:
    """The Mosquitto binary (PATH, then /usr/sbin), or a ConfigError saying how to get it."""
    found = shutil.which("mosquitto")
    for candidate in (found, "/usr/sbin/mosquitto", "/usr/local/sbin/mosquitto"):
        if candidate and os.access(candidate, os.X_OK):
            return candidate
    raise ConfigError("a fleet on one machine needs Mosquitto (Debian: apt-get install mosquitto)")


def free_port() -> int:
    """A TCP port free on loopback right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def port_accepts(port: int) -> bool:
    """Something accepts connections on 127.0.0.1:`port`."""
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=0.2):
            return True
    except OSError:
        return False


def _own_user() -> str:
    # Mosquitto started as root drops to the user `mosquitto`, which cannot read our files.
    return pwd.getpwuid(os.geteuid()).pw_name


@dataclass
class Mosquitto:
    """One Mosquitto process on 127.0.0.1:`port`, configured by `config` (listener added here)."""

    name: str
    port: int
    config: str
    workdir: Path
    proc: subprocess.Popen[bytes] | None = field(default=None, repr=False)
    starts: int = 0

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    @property
    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    @property
    def log_file(self) -> Path:
        return self.workdir / f"{self.name}.log"

    def start(self, wait: bool = True) -> None:
        """Start (or start again) on the same port; with `wait`, returns once it listens."""
        if self.running:
            return
        self.starts += 1
        conf = self.workdir / f"{self.name}.conf"
        conf.write_text(
            f"listener {self.port} 127.0.0.1\n{self.config}\nuser {_own_user()}\n"
            "log_dest stderr\nlog_type error\nlog_type warning\nlog_type notice\n",
            encoding="utf-8",
        )
        with self.log_file.open("ab") as log:
            self.proc = subprocess.Popen([find_mosquitto(), "-c", str(conf)], stdout=log,
                                         stderr=subprocess.STDOUT, cwd=self.workdir)
        if wait:
            self.wait_listening()

    def wait_listening(self) -> None:
        deadline = time.monotonic() + START_TIMEOUT_S
        while not port_accepts(self.port):
            if self.proc is None or self.proc.poll() is not None:
                raise ConfigError(f"Mosquitto {self.name} exited at start-up: {self.log_tail()}")
            if time.monotonic() > deadline:
                self.kill()
                raise ConfigError(
                    f"Mosquitto {self.name} did not listen on {self.port} in {START_TIMEOUT_S} s")
            time.sleep(0.02)

    def stop(self) -> None:
        """SIGTERM (its clients get no will: a clean goodbye), then SIGKILL after a while."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(STOP_TIMEOUT_S)
        self.proc = None

    def kill(self) -> None:
        """SIGKILL: the broker dies as a power cut or a crash would end it."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(STOP_TIMEOUT_S)
        self.proc = None

    def log_tail(self, chars: int = 2000) -> str:
        try:
            return self.log_file.read_text(encoding="utf-8", errors="replace")[-chars:]
        except OSError:
            return ""


class LocalFleet:
    """A hub Mosquitto and one leaf Mosquitto per robot, bridged, on loopback (no TLS, no users:
    a machine's own loopback; a real hub is set up with deploy/fleet.py, see docs/fleet.md)."""

    def __init__(self, robots: list[str], workdir: Path | None = None, hub_port: int | None = None,
                 bridge_port: int | None = None, hub_extra: str = "") -> None:
        """`bridge_port`: where the bridges connect instead of the hub's port (a link in between);
        `hub_extra`: more lines for the hub's configuration (bench/fleet.py: `sys_interval 1`)."""
        if len(set(robots)) != len(robots):
            raise ConfigError("robot ids must differ")
        for robot in robots:
            check_robot_id(robot)
        self._tmp: tempfile.TemporaryDirectory[str] | None = None
        if workdir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="umlbot-fleet-")
            workdir = Path(self._tmp.name)
        self.workdir = workdir
        self.hub = Mosquitto("hub", hub_port or free_port(),
                             "allow_anonymous true\npersistence false\nset_tcp_nodelay true\n" + hub_extra,
                             workdir)
        hub = Hub("127.0.0.1", bridge_port or self.hub.port, tls=False)
        self.leaves = {
            robot: Mosquitto(f"leaf-{robot}", free_port(),
                             "allow_anonymous true\npersistence false\nset_tcp_nodelay true\n"
                             + bridge_conf(robot, hub), workdir)
            for robot in robots
        }

    def start(self) -> None:
        """The hub first, then every leaf (each bridges to the hub as soon as it runs)."""
        try:
            self.hub.start()
            for leaf in self.leaves.values():
                leaf.start(wait=False)
            for leaf in self.leaves.values():
                leaf.wait_listening()
        except BaseException:
            self.stop()
            raise

    def leaf_url(self, robot: str) -> str:
        return self.leaves[robot].url

    def stop(self) -> None:
        """Every broker, leaves first; safe to call twice."""
        for leaf in self.leaves.values():
            leaf.stop()
        self.hub.stop()
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> LocalFleet:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()
