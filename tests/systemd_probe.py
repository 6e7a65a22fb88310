"""What a process may do, as one JSON object on stdout: run inside the nspawn container.

tests/test_systemd_nspawn.py runs this script twice in the container booted by tests/nspawn.py:
under a copy of an installed umlbot unit whose only change is this script as ExecStart (so every
sandboxing directive of the unit applies to it), and as a control with only `User=umlbot`. Each
check names what it saw (`ro`, `EPERM`, `SIGSYS`, …), so that the test can tell that a directive,
and not the user's plain lack of rights, refused an action: the control must see something else.

Standard library only, Python 3.11 (Debian bookworm's, or the robot's venv).
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import json
import os
import pwd
import signal
import socket
import sys
import tempfile
from collections.abc import Callable

#: a character device node the test makes in the container's /dev (10:200 is /dev/net/tun,
#: which anyone may open: only a device policy can refuse it).
PROBE_DEVICE = "/dev/umlbot-probe"
#: a file the test writes into the container's own /tmp before the probes run.
TMP_MARKER = "/tmp/umlbot-probe-marker"
CLONE_NEWUSER = 0x10000000
PER_LINUX32 = 0x0008
SECCOMP_EXIT = 99  # a child's exit status when its call returned (no signal)

libc = ctypes.CDLL(None, use_errno=True)


def _error(exc: OSError) -> str:
    return errno.errorcode.get(exc.errno or 0, str(exc.errno))


def attempt(action: Callable[[], object]) -> str:
    """`ok`, or the errno name the action failed with."""
    try:
        action()
    except OSError as exc:
        return _error(exc)
    return "ok"


def in_child(action: Callable[[], str]) -> str:
    """Run `action` in a forked child (it may change or kill the process): its result, or the
    signal that killed it (`SIGSYS`: a system call filter)."""
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: report and leave at once, whatever happens
        os.close(read_end)
        try:
            result = action()
        except BaseException as exc:
            result = f"error {exc!r}"
        os.write(write_end, result.encode())
        os._exit(SECCOMP_EXIT)
    os.close(write_end)
    _, status = os.waitpid(pid, 0)
    with os.fdopen(read_end, "rb") as pipe:
        said = pipe.read().decode()
    if os.WIFSIGNALED(status):
        return signal.Signals(os.WTERMSIG(status)).name
    return said


def libc_call(name: str, *args: int) -> str:
    """`ok` or the errno name of a libc call that returns -1 on failure."""
    if getattr(libc, name)(*args) == -1:
        return errno.errorcode.get(ctypes.get_errno(), "?")
    return "ok"


def status_field(name: str) -> str:
    with open("/proc/self/status", encoding="ascii") as status:
        for line in status:
            key, _, value = line.partition(":")
            if key == name:
                return value.strip()
    return "absent"


def mount_mode(path: str) -> str:
    """`ro` when `path` is on a read-only mount, else `rw` (what ProtectSystem= sets)."""
    try:
        return "ro" if os.statvfs(path).f_flag & os.ST_RDONLY else "rw"
    except OSError as exc:
        return _error(exc)


def open_device(path: str) -> str:
    def read_it() -> None:
        with open(path, "rb", buffering=0):
            pass

    return attempt(read_it)


def socket_family(family: int, kind: int, proto: int = 0) -> str:
    def make() -> None:
        socket.socket(family, kind, proto).close()

    return attempt(make)


def created_file_mode() -> str:
    """The mode of a file created with 0666 (UMask= decides what is left)."""
    folder = os.environ.get("STATE_DIRECTORY") or tempfile.gettempdir()
    path = os.path.join(folder, f"probe-umask-{os.getpid()}")
    fd = os.open(path, os.O_CREAT | os.O_WRONLY | os.O_EXCL, 0o666)
    try:
        return oct(os.fstat(fd).st_mode & 0o777)[2:]
    finally:
        os.close(fd)
        os.unlink(path)


def set_suid() -> str:
    with tempfile.NamedTemporaryFile(dir=tempfile.gettempdir()) as handle:
        return attempt(lambda: os.chmod(handle.name, 0o4750))  # noqa: S103 - RestrictSUIDSGID= must refuse it


def listing(path: str) -> str:
    return attempt(lambda: os.listdir(path))


def main() -> int:
    checks: dict[str, str] = {
        "user": pwd.getpwuid(os.geteuid()).pw_name,
        "no_new_privs": status_field("NoNewPrivs"),
        "seccomp": status_field("Seccomp"),
        "cap_bounding": status_field("CapBnd"),
        "cap_ambient": status_field("CapAmb"),
        "mount:/usr": mount_mode("/usr"),
        "mount:/etc": mount_mode("/etc"),
        "mount:/opt/umlbot": mount_mode("/opt/umlbot"),
        "mount:/var": mount_mode("/var"),
        "mount:/var/lib/umlbot": mount_mode("/var/lib/umlbot"),
        "mount:/proc/sys/net": mount_mode("/proc/sys/net"),
        "mount:/sys/fs/cgroup": mount_mode("/sys/fs/cgroup"),
        "tmp_marker": "seen" if os.path.exists(TMP_MARKER) else "absent",
        "list:/home": listing("/home"),
        "proc:/proc/1": "seen" if os.path.exists("/proc/1") else "absent",
        "ns:uts": os.readlink("/proc/self/ns/uts"),
        "ns:mnt": os.readlink("/proc/self/ns/mnt"),
        "socket:AF_INET": socket_family(socket.AF_INET, socket.SOCK_STREAM),
        "socket:AF_UNIX": socket_family(socket.AF_UNIX, socket.SOCK_STREAM),
        "socket:AF_NETLINK": socket_family(socket.AF_NETLINK, socket.SOCK_RAW, 0),
        "device:/dev/null": open_device("/dev/null"),
        f"device:{PROBE_DEVICE}": open_device(PROBE_DEVICE),
        "umask": created_file_mode(),
        "chmod:suid": set_suid(),
        # in a child: each may change the process (a namespace, a personality) or kill it
        "syscall:unshare_user": in_child(lambda: libc_call("unshare", CLONE_NEWUSER)),
        "syscall:personality": in_child(lambda: libc_call("personality", PER_LINUX32)),
        "syscall:chroot": in_child(lambda: attempt(lambda: os.chroot("/"))),
        "syscall:nice": in_child(lambda: attempt(lambda: os.nice(1))),
    }
    with contextlib.suppress(BrokenPipeError):
        json.dump(checks, sys.stdout, sort_keys=True)
        sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
