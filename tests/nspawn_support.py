"""A real systemd for the deploy units: Debian bookworm booted with systemd-nspawn.

tests/test_systemd_nspawn.py installs the car in it with deploy/install.sh, as a user does on a
Raspberry Pi, and checks what the units do under systemd. The pieces:

- `unavailable()`: why this machine cannot boot a container (not root, a missing program, no
  cgroup2 hierarchy), or None;
- `root_tree()`: the debootstrapped root, built once (1 to 5 min: the mirror decides) and cached
  under ~/.cache/umlbot/nspawn-root-<hash of suite, mirror and packages>; each run mounts an
  overlay on it, so the cache is never written to and a run starts in well under a second;
- `wheelhouse()`: the wheels of umlbot's dependencies (and of pip, setuptools, wheel) for the
  root's Python, downloaded on the host with the host's own pip settings (index, CA bundle,
  constraints) and cached by hash of the requirements. The container has no network
  (`--private-network`): its pip installs from this folder only (PIP_NO_INDEX, PIP_FIND_LINKS),
  bind-mounted read-only;
- `copy_checkout()`: the files of this checkout that git knows (committed or not), copied to
  where a user would clone umlbot;
- `Container`: boots the tree with systemd as PID 1 and enters it with nsenter (the host has no
  systemd of its own, so there is no machinectl).
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
import tomllib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
SUITE = "bookworm"
MIRROR = "http://deb.debian.org/debian"
#: what the root holds besides minbase: systemd as PID 1, python3-venv for install.sh's venv,
#: Mosquitto as on the robot.
PACKAGES = ("systemd", "systemd-sysv", "dbus", "python3-venv", "mosquitto")
CACHE = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "umlbot"
#: the unified cgroup hierarchy in the container (nspawn mounts one even on a host with a hybrid
#: hierarchy): with it, and the bpf() system call (`--system-call-filter=bpf`), the container's
#: systemd enforces DevicePolicy= and IPAddressDeny=; without either, it silently does not.
NSPAWN_ENV = {"SYSTEMD_NSPAWN_UNIFIED_HIERARCHY": "1"}
#: the environment of every command run inside (none of the host's: its pip settings, PATH).
INSIDE_ENV = ("PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin", "HOME=/root",
              "LANG=C.UTF-8", "SYSTEMD_PAGER=", "SYSTEMD_COLORS=0")
DEBOOTSTRAP_TIMEOUT_S = 600.0
PIP_TIMEOUT_S = 600.0
BOOT_TIMEOUT_S = 60.0
POWEROFF_TIMEOUT_S = 30.0
POWEROFF_RESEND_S = 5.0
#: room for what a run writes over the root (after install.sh: about 270 MB).
LAYER_SIZE = "2g"
CAP_SYS_ADMIN = 21


def log(message: str) -> None:
    """A progress line on stderr (shown with `pytest -s`: `make test-systemd`)."""
    print(f"nspawn: {message}", file=sys.stderr, flush=True)


def unavailable() -> str | None:
    """Why this machine cannot boot a systemd-nspawn container, or None when it can."""
    if os.geteuid() != 0:
        return f"systemd-nspawn needs root (running as uid {os.geteuid()})"
    with open("/proc/self/status", encoding="ascii") as status:
        caps = next(int(line.split()[1], 16) for line in status if line.startswith("CapEff:"))
    if not caps & (1 << CAP_SYS_ADMIN):
        return "root without CAP_SYS_ADMIN (an unprivileged container): systemd-nspawn cannot mount"
    for program, package in (("systemd-nspawn", "systemd-container"), ("debootstrap", "debootstrap"),
                             ("nsenter", "util-linux")):
        if shutil.which(program) is None and not Path("/usr/sbin", program).exists():
            return f"no {program} on this machine (Debian package {package})"
    if not _cgroup_mounts("cgroup2"):
        return "no cgroup2 hierarchy mounted: systemd in the container needs one (cgroup v1 only)"
    if "overlay" not in Path("/proc/filesystems").read_text(encoding="ascii"):
        return "the kernel has no overlay file system (the cached root is mounted under an overlay)"
    return None


def _cgroup_mounts(*kinds: str) -> list[Path]:
    """Where the cgroup file systems of these kinds (`cgroup2`, `cgroup`) are mounted."""
    mounts = []
    for line in Path("/proc/self/mountinfo").read_text(encoding="utf-8").splitlines():
        fields, _, rest = line.partition(" - ")
        if rest.split()[0] in kinds:
            mounts.append(Path(fields.split()[4]))
    return mounts


def _program(name: str) -> str:
    found = shutil.which(name) or next(
        (str(p) for p in (Path("/usr/sbin", name), Path("/sbin", name)) if p.exists()), None)
    if found is None:
        raise RuntimeError(f"{name} is not installed")
    return found


def _digest(*parts: str) -> str:
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:12]


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Hold an exclusive lock on `path` (two test runs building one cache wait for each other)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def _unmount_under(folder: Path) -> None:
    """Unmount whatever is mounted at or under `folder`, deepest first (debootstrap cut short
    leaves /proc and /sys mounted in its target), so that deleting it never reaches the host's."""
    prefix = str(folder.resolve())
    mounts = Path("/proc/self/mountinfo").read_text(encoding="utf-8").splitlines()
    points = {line.split()[4] for line in mounts}
    inside = [point for point in points if point == prefix or point.startswith(prefix + "/")]
    for point in sorted(inside, key=len, reverse=True):
        subprocess.run(["umount", "--lazy", point], capture_output=True, timeout=30, check=False)


def _remove(folder: Path) -> None:
    _unmount_under(folder)
    shutil.rmtree(folder, ignore_errors=True)


def root_tree() -> Path:
    """The debootstrapped root, built on the first call and cached (a complete one holds
    `.umlbot-root-complete`: a build cut short is made again)."""
    root = CACHE / f"nspawn-root-{_digest(SUITE, MIRROR, 'minbase', *PACKAGES)}"
    stamp = root / ".umlbot-root-complete"
    with _locked(root.with_name(root.name + ".lock")):
        if stamp.exists():
            log(f"cached root {root}")
            return root
        partial = root.with_name(root.name + ".partial")
        _remove(partial)
        _remove(root)
        log(f"building the root with debootstrap ({SUITE}, {', '.join(PACKAGES)}) into {root}")
        started = time.monotonic()
        result = subprocess.run(
            [_program("debootstrap"), "--variant=minbase", f"--include={','.join(PACKAGES)}", SUITE,
             str(partial), MIRROR],
            capture_output=True, text=True, timeout=DEBOOTSTRAP_TIMEOUT_S, check=False)
        _unmount_under(partial)
        if result.returncode != 0:
            raise RuntimeError(f"debootstrap failed ({result.returncode}):\n{result.stdout[-3000:]}"
                               f"\n{result.stderr[-3000:]}")
        (partial / stamp.name).write_text(f"{SUITE} {MIRROR} {' '.join(PACKAGES)}\n", encoding="utf-8")
        partial.rename(root)
        log(f"root built in {time.monotonic() - started:.0f} s")
        return root


def requirements() -> list[str]:
    """What the container's pip installs: umlbot's dependencies with the `pi` extra, the build
    requirements of umlbot itself (install.sh builds it from the checkout) and pip (which
    install.sh upgrades first)."""
    project = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    return [*project["project"]["dependencies"], *project["project"]["optional-dependencies"]["pi"],
            *project["build-system"]["requires"], "pip"]


def wheelhouse(root: Path) -> Path:
    """A folder of wheels for `requirements()` and the Python of `root`, downloaded by the host's
    pip (with its settings: index, CA bundle, constraints) and cached by hash of both."""
    python = os.readlink(root / "usr" / "bin" / "python3").removeprefix("python")  # e.g. 3.11
    wanted = requirements()
    folder = CACHE / f"nspawn-wheels-{_digest(python, *wanted)}"
    stamp = folder / ".umlbot-wheels-complete"
    with _locked(folder.with_name(folder.name + ".lock")):
        if stamp.exists():
            return folder
        shutil.rmtree(folder, ignore_errors=True)
        log(f"downloading the wheels for Python {python} into {folder}")
        result = subprocess.run(
            [sys.executable, "-m", "pip", "download", "--quiet", "--only-binary=:all:",
             f"--python-version={python}", f"--dest={folder}", *wanted],
            capture_output=True, text=True, timeout=PIP_TIMEOUT_S, check=False)
        if result.returncode != 0:
            raise RuntimeError(f"pip download failed ({result.returncode}):\n{result.stderr[-3000:]}")
        stamp.write_text("\n".join(wanted) + "\n", encoding="utf-8")
        return folder


def copy_checkout(dest: Path) -> None:
    """Copy the files git knows in this checkout (tracked, and untracked but not ignored) to `dest`."""
    listed = subprocess.run(["git", "-C", str(REPO), "ls-files", "-z", "--cached", "--others",
                             "--exclude-standard"],
                            capture_output=True, check=True, timeout=60).stdout.decode().split("\0")
    for name in filter(None, listed):
        source = REPO / name
        if not source.exists() and not source.is_symlink():
            continue  # deleted in the work tree
        target = dest / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if source.is_symlink():
            target.symlink_to(os.readlink(source))
        else:
            shutil.copy2(source, target)


@dataclass
class Inside:
    """A command's result inside the container."""

    returncode: int
    stdout: str
    stderr: str


class Container:
    """The cached root under an overlay, booted with systemd-nspawn (private network, no
    registration with a host systemd, which there is none of)."""

    def __init__(self, root: Path, workdir: Path, name: str, binds: Sequence[tuple[Path, str]] = ()) -> None:
        self.root = root
        self.workdir = workdir
        self.name = name
        self.binds = list(binds)
        self.merged = workdir / "merged"
        self.boot_log = workdir / "boot.log"
        self.nspawn: subprocess.Popen[bytes] | None = None
        self.init_pid = 0
        self.boots = 0

    # --- life -----------------------------------------------------------------------------------

    @property
    def cgroups(self) -> list[Path]:
        """This container's own cgroup in each hierarchy that has it (a v2 one, which nspawn
        mirrors into the v1 `name=systemd` one of a hybrid host)."""
        return [mount / f"umlbot-{self.name}" for mount in _cgroup_mounts("cgroup2", "cgroup")
                if (mount / f"umlbot-{self.name}").is_dir()]

    def mount(self) -> None:
        """The overlay: the cached root below, this run's changes above, in memory (a tmpfs: what
        install.sh writes, some 9 000 files and 270 MB, is written fast and gone at once)."""
        layer = self.workdir / "layer"
        for folder in (layer, self.merged):
            folder.mkdir(parents=True, exist_ok=True)
        subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={LAYER_SIZE},mode=0755", "umlbot-nspawn",
                        str(layer)], check=True, capture_output=True, timeout=30)
        (layer / "upper").mkdir()
        (layer / "work").mkdir()
        subprocess.run(
            ["mount", "-t", "overlay", "overlay", "-o",
             f"lowerdir={self.root},upperdir={layer / 'upper'},workdir={layer / 'work'}",
             str(self.merged)], check=True, capture_output=True, timeout=30)

    def boot(self) -> None:
        """Boot systemd and wait until it has started everything (`is-system-running --wait`)."""
        self.boots += 1
        # nspawn puts the container in `payload` under its own cgroup (--keep-unit): started from
        # one of its own, no two containers (two test runs) share a cgroup tree, and whatever is
        # left of it can be killed at the end
        cgroup = _cgroup_mounts("cgroup2")[0] / f"umlbot-{self.name}"
        cgroup.mkdir(exist_ok=True)
        argv = ["sh", "-c", 'echo $$ > "$0/cgroup.procs" && exec "$@"', str(cgroup),
                _program("systemd-nspawn"), "--boot", "--quiet", f"--directory={self.merged}",
                f"--machine={self.name}", "--private-network", "--register=no", "--keep-unit",
                "--system-call-filter=bpf", "--console=read-only",
                *(f"--bind-ro={host}:{inside}" for host, inside in self.binds)]
        with self.boot_log.open("ab") as output:
            self.nspawn = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=output,
                                           stderr=subprocess.STDOUT, env={**os.environ, **NSPAWN_ENV},
                                           start_new_session=True)
        deadline = time.monotonic() + BOOT_TIMEOUT_S
        self.init_pid = 0
        while not self.init_pid:
            if self.nspawn.poll() is not None:
                raise RuntimeError(f"systemd-nspawn exited ({self.nspawn.returncode}):\n{self.boot_text()}")
            if time.monotonic() > deadline:
                raise RuntimeError(f"no systemd in the container in {BOOT_TIMEOUT_S} s:\n{self.boot_text()}")
            self.init_pid = self._init_pid()
            time.sleep(0.02)
        while True:  # `offline` (or nothing) until systemd has made /run/systemd/system and its socket
            result = self.run("systemctl", "is-system-running", "--wait", check=False,
                              timeout=max(1.0, deadline - time.monotonic()))
            state = result.stdout.strip()
            if state not in ("", "offline") or time.monotonic() > deadline:
                break
            time.sleep(0.05)
        if state not in ("running", "degraded"):
            raise RuntimeError(f"the container's systemd is {state!r} ({result.stderr.strip()}):\n"
                               f"{self.boot_text()}")
        if state == "degraded":
            log("degraded: " + self.run("systemctl", "--failed", "--no-legend", check=False).stdout)

    def _init_pid(self) -> int:
        """The container's PID 1 as the host sees it: the child of systemd-nspawn running systemd."""
        assert self.nspawn is not None
        with contextlib.suppress(OSError):
            for task in Path(f"/proc/{self.nspawn.pid}/task").iterdir():
                for child in (task / "children").read_text(encoding="ascii").split():
                    if Path(f"/proc/{child}/comm").read_text(encoding="ascii").strip() == "systemd":
                        return int(child)
        return 0

    def poweroff(self) -> None:
        """Shut the container down (systemd stops every unit first); after a time-out, or when
        something outlived it, kill every process of its cgroup. Its cgroups are removed."""
        started = time.monotonic()
        while self.nspawn is not None and self.nspawn.poll() is None:
            if time.monotonic() - started > POWEROFF_TIMEOUT_S:
                log(f"{self.name} did not power off in {POWEROFF_TIMEOUT_S} s: killed")
                break
            # nspawn asks PID 1 to power off; again after a while: a systemd still starting up
            # (a boot that failed) may not have been listening yet
            self.nspawn.send_signal(signal.SIGTERM)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.nspawn.wait(POWEROFF_RESEND_S)
        # killing nspawn alone would leave the container's PID 1 running: kill the whole tree
        self._kill_cgroups()
        if self.nspawn is not None:
            self.nspawn.wait(POWEROFF_TIMEOUT_S)
            log(f"{self.name} powered off in {time.monotonic() - started:.1f} s")
        self.nspawn = None
        self.init_pid = 0

    def _kill_cgroups(self) -> None:
        """SIGKILL every process in this container's cgroups until none is left, then remove them."""
        deadline = time.monotonic() + POWEROFF_TIMEOUT_S
        for top in self.cgroups:
            folders = sorted((Path(d) for d, _, _ in os.walk(top)), key=lambda d: len(d.parts), reverse=True)
            while True:
                pids = [int(pid) for folder in folders
                        for pid in (folder / "cgroup.procs").read_text(encoding="ascii").split()]
                if not pids or time.monotonic() > deadline:
                    break
                for pid in pids:
                    with contextlib.suppress(ProcessLookupError):
                        os.kill(pid, signal.SIGKILL)
                time.sleep(0.05)
            for folder in folders:  # deepest first: a cgroup goes once it has no children
                with contextlib.suppress(OSError):
                    folder.rmdir()

    def reboot(self) -> None:
        self.poweroff()
        self.boot()

    def remove(self) -> None:
        """Power off, unmount the overlay and delete this run's files (the cached root stays)."""
        self.poweroff()
        _remove(self.workdir)

    def boot_text(self) -> str:
        return self.boot_log.read_text(encoding="utf-8", errors="replace")[-4000:]

    # --- inside ---------------------------------------------------------------------------------

    def path(self, inside: str) -> Path:
        """The host's path of a file of the container (its root is the overlay)."""
        return self.merged / inside.lstrip("/")

    def run(self, *argv: str, check: bool = True, timeout: float = 60.0, cwd: str = "/",
            env: Sequence[str] = ()) -> Inside:
        """Run `argv` in all the container's namespaces, with a clean environment."""
        result = subprocess.run(
            ["nsenter", "-t", str(self.init_pid), "-a", "--", "env", "-i", f"--chdir={cwd}",
             *INSIDE_ENV, *env, *argv],
            capture_output=True, text=True, timeout=timeout, check=False)
        if check and result.returncode != 0:
            raise RuntimeError(f"{' '.join(argv)} failed in the container ({result.returncode}):\n"
                               f"{result.stdout[-3000:]}\n{result.stderr[-3000:]}")
        return Inside(result.returncode, result.stdout, result.stderr)

    def systemctl(self, *args: str, check: bool = True) -> str:
        return self.run("systemctl", *args, check=check).stdout

    def show(self, unit: str, *properties: str) -> dict[str, str]:
        """`systemctl show` of `unit`, as a dict of the properties asked for."""
        text = self.systemctl("show", unit, *(f"--property={p}" for p in properties))
        return dict(line.split("=", 1) for line in text.splitlines() if "=" in line)

    def host_pid(self, inside_pid: int) -> int:
        """The host's pid of a container process (`NSpid` ends with its pid in the container)."""
        namespace = os.readlink(f"/proc/{self.init_pid}/ns/pid")
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            with contextlib.suppress(OSError, StopIteration):
                if os.readlink(entry / "ns" / "pid") != namespace:
                    continue
                status = (entry / "status").read_text(encoding="ascii").splitlines()
                nspid = next(line for line in status if line.startswith("NSpid:")).split()[1:]
                if int(nspid[-1]) == inside_pid:
                    return int(entry.name)
        raise LookupError(f"no process {inside_pid} in the container {self.name}")

    def journal(self, *units: str, lines: int = 40) -> str:
        args = [f"--unit={unit}" for unit in units]
        return self.run("journalctl", "--no-pager", "--output=short-monotonic", f"--lines={lines}", *args,
                        check=False).stdout

    def in_network(self, argv: Sequence[str]) -> list[str]:
        """`argv` (a host program) run in the container's network namespace only: it reaches the
        container's loopback, with the host's files."""
        return ["nsenter", "-t", str(self.init_pid), "-n", "--", *argv]


@dataclass(frozen=True)
class Message:
    """One MQTT message as tests/mqtt_recorder.py saw it (`t`: time.monotonic() on arrival)."""

    t: float
    topic: str
    payload: Any  # the JSON payload, or None when empty or not JSON
    retain: bool


class Recorder:
    """Every message under a topic filter of the container's broker, in arrival order."""

    def __init__(self, container: Container, url: str, topic: str) -> None:
        script = Path(__file__).with_name("mqtt_recorder.py")
        self.process = subprocess.Popen(container.in_network([sys.executable, str(script), url, topic]),
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.messages: list[Message] = []
        self.errors: list[str] = []
        self.subscribed = threading.Event()
        self._cond = threading.Condition()
        self._reader = threading.Thread(target=self._read, name="mqtt-recorder", daemon=True)
        self._reader.start()
        if not self.subscribed.wait(15.0):
            self.close()
            raise RuntimeError(f"the recorder did not subscribe to {topic}: {self.errors}")

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            data = json.loads(line)
            if "error" in data:
                self.errors.append(data["error"])
                self.subscribed.set()
                continue
            if data.get("subscribed"):
                self.subscribed.set()
                continue
            try:
                payload = json.loads(data["payload"]) if data["payload"] else None
            except ValueError:
                payload = None
            with self._cond:
                self.messages.append(Message(data["t"], data["topic"], payload, data["retain"]))
                self._cond.notify_all()

    def close(self) -> None:
        with contextlib.suppress(OSError):
            if self.process.stdin is not None:
                self.process.stdin.close()
        try:
            self.process.wait(5.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(5.0)

    def select(self, topic: str, after: float = 0.0, before: float = float("inf")) -> list[Message]:
        with self._cond:
            return [m for m in self.messages if m.topic == topic and after <= m.t < before]

    def latest(self, topic: str, before: float = float("inf")) -> Message | None:
        found = self.select(topic, before=before)
        return found[-1] if found else None

    def wait_for(self, topic: str, predicate: Callable[[Any], bool], after: float,
                 timeout: float) -> Message | None:
        """The first message on `topic` that arrived at or after `after` and whose payload
        satisfies `predicate`, waiting at most `timeout` seconds from now; None if none came."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for message in self.messages:
                    if message.topic == topic and message.t >= after and predicate(message.payload):
                        return message
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._cond.wait(remaining)


def retained(container: Container, url: str, topic: str, settle_s: float = 1.0) -> dict[str, Any]:
    """The retained messages under `topic` as a new subscriber gets them: topic -> payload."""
    recorder = Recorder(container, url, topic)
    try:
        time.sleep(settle_s)  # retained messages come right after the subscription's acknowledgement
        return {m.topic: m.payload for m in recorder.messages if m.retain}
    finally:
        recorder.close()
