"""The deploy units under a real systemd: the car installed by deploy/install.sh in a booted Debian.

tests/nspawn_support.py boots a Debian bookworm root with systemd-nspawn (systemd as PID 1,
private network, Mosquitto as on the robot); deploy/install.sh installs the car inside as a user
does on a Raspberry Pi (`--driver mock --secure`, pip from a wheelhouse: the container has no
network), and the container is rebooted so that the units start as on the robot's boot. The
tests then watch the robot's topics from the container's network namespace
(tests/mqtt_recorder.py) while they kill, freeze and stop units.

`make test-systemd` runs this module (`make test` does too); it is skipped, with the reason,
where this machine cannot run systemd-nspawn (not root, no systemd-nspawn or debootstrap, no
cgroup2). docs/deploy-pi.md ("How the units are tested") says what each test shows, and the
times.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml
from nspawn_support import (
    REPO,
    Container,
    Recorder,
    copy_checkout,
    log,
    retained,
    root_tree,
    unavailable,
    wheelhouse,
)

#: the first run builds the root (debootstrap: about a minute, more on a slow mirror).
pytestmark = [pytest.mark.systemd, pytest.mark.timeout(900)]

REASON = unavailable()
if REASON is not None:
    pytest.skip(f"cannot run systemd-nspawn on this machine: {REASON}", allow_module_level=True)

ROBOT = "car"
KINDS = ("motor", "sonar", "servo", "gpio")  # the kinds models/robot_car/deployment.yaml uses
SERVICE = "umlbot-service@{}.service"
ORCHESTRATOR = "umlbot-orchestrator.service"
UNITS = (*(SERVICE.format(kind) for kind in KINDS), ORCHESTRATOR)
COMPONENTS = ("RaspberryPI", "LeftActuator", "RightActuator", "Sensor", "DistanceRead")
MOTORS = ("LeftActuator", "RightActuator")
DEPLOYMENT = yaml.safe_load((REPO / "models" / "robot_car" / "deployment.yaml").read_text(encoding="utf-8"))
#: how long a motor turns without a command before its service stops it.
MOTOR_WATCHDOG_S = max(float(DEPLOYMENT["components"][m]["settings"]["watchdog_s"]) for m in MOTORS)
#: a stop that travels over MQTT (a last will, the orchestrator's fail-safe calls) arrives within
#: this; less than MOTOR_WATCHDOG_S, so that the motor service's own watchdog cannot be what
#: stopped the motors.
MQTT_STOP_S = 1.5
#: what systemd adds to a watchdog period before a frozen service's motors are stopped from
#: outside it: noticing the missed ping, killing the process, running the safe stop.
SYSTEMD_MARGIN_S = 3.0
#: how long a message published just before a signal may take to reach the recorder.
IN_FLIGHT_S = 0.3
#: how long a service takes to start and say `online` (Python, imports, broker connection).
START_S = 6.0
#: the probe (tests/systemd_probe.py) inside the container, the device node it tries to open and
#: the file it looks for in /tmp.
PROBE = "/usr/local/lib/umlbot-probe.py"
PROBE_DEVICE = "/dev/umlbot-probe"
TMP_MARKER = "/tmp/umlbot-probe-marker"
VENV_PYTHON = "/opt/umlbot/venv/bin/python"


def topic(*parts: str) -> str:
    return "/".join(("umlbot", ROBOT, *parts))


def running(payload: Any) -> bool:
    return isinstance(payload, dict) and payload.get("running") is True


def stopped(payload: Any) -> bool:
    return isinstance(payload, dict) and payload.get("running") is False


def status_is(state: str) -> Callable[[Any], bool]:
    return lambda payload: isinstance(payload, dict) and payload.get("state") == state


def seconds(span: str) -> float:
    """A systemd time span as `systemctl show` prints it (`2s`, `1min 30s`, `500ms`, `0`)."""
    units = {"us": 1e-6, "ms": 1e-3, "s": 1.0, "min": 60.0, "h": 3600.0}
    return sum(float(value) * units[unit] for value, unit in re.findall(r"([\d.]+)(us|ms|min|s|h)", span))


@dataclass
class Car:
    container: Container
    recorder: Recorder
    monitor_url: str

    def unit(self, name: str) -> dict[str, str]:
        return self.container.show(name, "ActiveState", "SubState", "MainPID", "NRestarts", "Result",
                                   "ExecMainStatus", "RestartUSec", "TimeoutStopUSec", "WatchdogUSec")

    def journal(self, *units: str) -> str:
        return self.container.journal(*(units or ("umlbot-*",)), lines=60)


@pytest.fixture(scope="module")
def car(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Car]:
    """The car installed by install.sh and booted; removed (overlay and all) at the end."""
    started = time.monotonic()
    root = root_tree()
    wheels = wheelhouse(root)
    workdir = tmp_path_factory.mktemp("nspawn")
    container = Container(root, workdir / "container", f"umlbot-test-{os.getpid()}",
                          binds=[(wheels, "/root/wheelhouse")])
    recorder: Recorder | None = None
    try:
        container.mount()
        checkout = container.path("/root/umlbot")
        copy_checkout(checkout)
        umlbot = Path(sys.executable).with_name("umlbot")  # the compiled model, as on a laptop
        subprocess.run([str(umlbot), "compile", str(REPO / "models" / "robot_car"),
                        "-o", str(container.path("/root/robot_car.json"))],
                       check=True, capture_output=True, timeout=120)
        prepared = time.monotonic()
        container.boot()
        booted = time.monotonic()
        # as deploy-pi.md says, from the checkout; the robot has no network here: pip takes the
        # wheelhouse (PIP_* are pip's own settings, nothing install.sh knows of)
        container.run("deploy/install.sh", "--model", "/root/robot_car.json",
                      "--deployment", "models/robot_car/deployment.yaml", "--robot", ROBOT,
                      "--driver", "mock", "--secure", cwd="/root/umlbot", timeout=600,
                      env=("PIP_NO_INDEX=1", "PIP_FIND_LINKS=/root/wheelhouse"))
        installed = time.monotonic()
        container.reboot()  # "or reboot: the car drives on boot" (Mosquitto reads its new conf.d)
        rebooted = time.monotonic()
        monitor = container.path("/etc/umlbot/auth/monitor.env").read_text(encoding="utf-8")
        url = next(line.split("=", 1)[1] for line in monitor.splitlines()
                   if line.startswith("UMLBOT_BROKER="))  # the read-only monitor user
        recorder = Recorder(container, url, topic("#"))
        log(f"root and wheels {prepared - started:.1f} s, boot {booted - prepared:.1f} s, "
            f"install.sh {installed - booted:.1f} s, reboot {rebooted - installed:.1f} s")
        yield Car(container, recorder, url)
    finally:
        ending = time.monotonic()
        if recorder is not None:
            recorder.close()
        log(f"recorder closed in {time.monotonic() - ending:.1f} s")
        container.remove()


def wait_units(car: Car, units: tuple[str, ...], timeout: float,
               check: Callable[[dict[str, str]], bool]) -> dict[str, dict[str, str]]:
    """Poll the units (systemctl returns before they have started or stopped) until `check`
    holds for each, or `timeout` passed; returns their last properties."""
    deadline = time.monotonic() + timeout
    while True:
        states = {unit: car.unit(unit) for unit in units}
        if all(check(state) for state in states.values()) or time.monotonic() > deadline:
            return states
        time.sleep(0.2)


def is_running(state: dict[str, str]) -> bool:
    return state["ActiveState"] == "active" and state["SubState"] == "running"


@pytest.fixture
def driving(car: Car) -> Car:
    """The car driving: every unit running, the orchestrator `running`, the motors turning. After
    a test that left it otherwise (a unit given up, a service frozen), umlbot.target is restarted."""
    states = {unit: car.unit(unit) for unit in UNITS}
    if all(is_running(state) for state in states.values()) and car.recorder.wait_for(
            topic("LeftActuator", "state"), running, after=time.monotonic(), timeout=5.0):
        return car
    log("the car is not driving: restarting umlbot.target")
    car.container.systemctl("reset-failed", check=False)
    since = time.monotonic()
    car.container.systemctl("restart", "umlbot.target")
    assert car.recorder.wait_for(topic("LeftActuator", "state"), running, after=since, timeout=60.0), (
        f"the car does not drive after a restart of umlbot.target:\n{car.journal()}")
    return car


def signal_while_driving(car: Car, unit: str, signum: int) -> tuple[float, int, int]:
    """Send `signum` to the unit's main process at a moment both motors turn (just after their
    state said so); returns when it was sent and the process's pid in the container and on the host."""
    inside = int(car.unit(unit)["MainPID"])
    host = car.container.host_pid(inside)
    for _ in range(20):
        left = car.recorder.wait_for(topic("LeftActuator", "state"), running, after=time.monotonic(),
                                     timeout=10.0)
        assert left is not None, f"the motors do not turn:\n{car.journal()}"
        right = car.recorder.wait_for(topic("RightActuator", "state"), lambda _: True, after=left.t,
                                      timeout=0.2)
        if right is not None and running(right.payload):
            os.kill(host, signum)  # from the host: no nsenter in between, the motors still turn
            sent = time.monotonic()
            break
    else:
        pytest.fail("never saw both motors turning at once")
    for motor in MOTORS:
        last = car.recorder.latest(topic(motor, "state"), before=sent)
        assert last is not None and running(last.payload), f"{motor} had stopped before the signal: {last}"
    return sent, inside, host


# --- the target ---------------------------------------------------------------------------------


def test_the_target_starts_every_unit_on_boot(car: Car) -> None:
    wants = car.container.path("/etc/systemd/system/umlbot.target.wants")
    assert {link.name for link in wants.iterdir()} == set(UNITS)
    assert car.container.systemctl("is-enabled", "umlbot.target").strip() == "enabled"
    states = wait_units(car, UNITS, 30.0, is_running)
    assert all(is_running(state) for state in states.values()), f"{states}\n{car.journal()}"
    assert car.container.systemctl("is-active", "umlbot.target").strip() == "active"
    for component in COMPONENTS:
        status = car.recorder.wait_for(topic(component, "status"), status_is("online"), after=0.0,
                                       timeout=10.0)
        assert status is not None, f"{component} is not online:\n{car.journal()}"
        assert status.payload["driver"] == "mock"
    assert car.recorder.wait_for(topic("orchestrator", "status"), status_is("running"), after=0.0,
                                 timeout=20.0), car.journal(ORCHESTRATOR)


# --- sandboxing ---------------------------------------------------------------------------------


def test_the_running_services_have_no_privileges(car: Car) -> None:
    """The processes systemd started: user umlbot, no_new_privs, a seccomp filter, no capabilities,
    their own mount and UTS namespaces (ProtectSystem=, PrivateTmp=, ProtectHostname=)."""
    uid = car.container.run("id", "-u", "umlbot").stdout.strip()
    init = car.container.init_pid
    for unit in UNITS:
        host = car.container.host_pid(int(car.unit(unit)["MainPID"]))
        lines = Path(f"/proc/{host}/status").read_text(encoding="ascii").splitlines()
        status = dict(line.split(":", 1) for line in lines)
        assert status["Uid"].split() == [uid] * 4, unit
        assert status["NoNewPrivs"].strip() == "1", unit
        assert status["Seccomp"].strip() == "2", unit
        for caps in ("CapInh", "CapPrm", "CapEff", "CapBnd", "CapAmb"):
            assert int(status[caps], 16) == 0, (unit, caps, status[caps])
        for namespace in ("mnt", "uts"):
            own = os.readlink(f"/proc/{host}/ns/{namespace}")
            assert own != os.readlink(f"/proc/{init}/ns/{namespace}"), (unit, namespace)


#: the keys of a unit's [Service] section that restrict what its process may do: each directive
#: given must have a check below (EXPECTED) or a reason why this test cannot tell (NOT_PROBED).
HARDENING = re.compile(r"(NoNewPrivileges|Capability|Ambient|Private|Protect|Restrict|LockPersonality|"
                       r"MemoryDeny|SystemCall|UMask|Device|IPAddress|ReadWritePaths|ReadOnlyPaths|"
                       r"InaccessiblePaths|User|Group|DynamicUser|SupplementaryGroups|ProcSubset|"
                       r"RemoveIPC|KeyringMode)\w*=")
#: directive -> what tests/systemd_probe.py sees under it. The control (a unit with only
#: User=umlbot) must see something else, except for the keys in ALLOWED_ANYWAY.
EXPECTED: dict[str, dict[str, str]] = {
    "User=umlbot": {"user": "umlbot"},
    "Group=umlbot": {},  # the probe runs as the user's own group either way: nothing to tell
    "NoNewPrivileges=yes": {"no_new_privs": "1"},
    "CapabilityBoundingSet=": {"cap_bounding": "0000000000000000"},
    "PrivateTmp=yes": {"tmp_marker": "absent"},
    "PrivateDevices=yes": {f"device:{PROBE_DEVICE}": "ENOENT", "device:/dev/null": "ok"},
    "DevicePolicy=closed": {f"device:{PROBE_DEVICE}": "EPERM", "device:/dev/null": "ok"},
    "ProtectSystem=strict": {"mount:/usr": "ro", "mount:/etc": "ro", "mount:/opt/umlbot": "ro",
                             "mount:/var": "ro", "mount:/var/lib/umlbot": "rw"},
    "ProtectHome=yes": {"list:/home": "EACCES"},
    "ProtectKernelTunables=yes": {"mount:/proc/sys/net": "ro"},
    "ProtectControlGroups=yes": {"mount:/sys/fs/cgroup": "ro"},
    "ProtectProc=invisible": {"proc:/proc/1": "absent"},
    "ProtectHostname=yes": {"ns:uts": "its own"},
    "RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX": {
        "socket:AF_NETLINK": "EAFNOSUPPORT", "socket:AF_INET": "ok", "socket:AF_UNIX": "ok"},
    "RestrictNamespaces=yes": {"syscall:unshare_user": "EPERM"},
    "RestrictSUIDSGID=yes": {"chmod:suid": "EPERM"},
    "LockPersonality=yes": {"syscall:personality": "EPERM"},
    "SystemCallFilter=@system-service": {},  # the probe (Python) runs: what it needs is allowed
    "SystemCallFilter=~@privileged @resources": {"syscall:chroot": "SIGSYS", "syscall:nice": "SIGSYS"},
    "UMask=0027": {"umask": "640"},
}
#: checks whose value is the same without the directive: they show that what must work still works.
ALLOWED_ANYWAY = {"user", "device:/dev/null", "mount:/var/lib/umlbot", "socket:AF_INET", "socket:AF_UNIX"}
NOT_PROBED = {
    "AmbientCapabilities=": "the umlbot user has no ambient capabilities without it either",
    "DeviceAllow=char-gpiochip rw": "the container has no /dev/gpiochip* (no GPIO chip in this kernel)",
    "ProtectKernelModules=yes": "loading a module needs CAP_SYS_MODULE, which umlbot never has; the "
                                "root has no /usr/lib/modules to hide",
    "ProtectKernelLogs=yes": "nspawn already hides /proc/kmsg and /dev/kmsg from the whole container",
    "ProtectClock=yes": "setting the clock needs CAP_SYS_TIME, which umlbot never has",
    "RestrictRealtime=yes": "sched_setscheduler is in @resources: SystemCallFilter= kills first",
    "SystemCallArchitectures=native": "the probe cannot make 32-bit system calls from Python",
}
#: what a probe unit drops from the installed [Service] section besides ExecStart= (a one-shot
#: probe is not restarted, not watched, and runs no safe stop).
NOT_COPIED = re.compile(r"(ExecStart|ExecStartPre|ExecStartPost|ExecStop|ExecStopPost|ExecReload|Type|"
                        r"Restart|RestartSec|WatchdogSec|NotifyAccess|StandardOutput)=")


def service_section(text: str) -> list[str]:
    lines, inside = [], False
    for raw in text.splitlines():
        line = raw.strip()
        if line.startswith("["):
            inside = line == "[Service]"
        elif inside and line and not line.startswith("#"):
            lines.append(line)
    return lines


@dataclass
class Probes:
    container: Container
    control: dict[str, str]
    init_uts: str

    def run(self, unit_file: str, instance: str = "") -> tuple[list[str], dict[str, str]]:
        """Run the probe under the installed unit's [Service] section; its directives and what
        the probe saw."""
        directives = service_section(self.container.path(f"/etc/systemd/system/{unit_file}").read_text())
        name = "umlbot-probe-" + unit_file.removeprefix("umlbot-")
        instance_name = name.replace("@.", f"@{instance}.") if instance else name
        output = f"/run/umlbot-probe/{instance_name}.json"
        text = "\n".join(["[Unit]", f"Description=probe of {unit_file}", "[Service]", "Type=oneshot",
                          f"ExecStart={VENV_PYTHON} {PROBE}", f"StandardOutput=truncate:{output}",
                          *(line for line in directives if not NOT_COPIED.match(line))]) + "\n"
        write_inside(self.container, f"/run/systemd/system/{name}", text)
        self.container.systemctl("daemon-reload")
        result = self.container.run("systemctl", "start", instance_name, check=False, timeout=60)
        assert result.returncode == 0, f"{result.stderr}\n{self.container.journal(instance_name)}"
        return directives, json.loads(self.container.run("cat", output).stdout)


def write_inside(container: Container, path: str, text: str) -> None:
    """Write a file where only the running container sees it (/run is its own tmpfs)."""
    container.run("mkdir", "-p", str(Path(path).parent))
    subprocess.run(["nsenter", "-t", str(container.init_pid), "-a", "--", "tee", path], input=text, text=True,
                   capture_output=True, check=True, timeout=30)


@pytest.fixture(scope="module")
def probes(car: Car) -> Probes:
    container = car.container
    probe = container.path(PROBE)
    probe.parent.mkdir(parents=True, exist_ok=True)
    probe.write_text((REPO / "tests" / "systemd_probe.py").read_text(encoding="utf-8"), encoding="utf-8")
    # what the probes look for: a device node anyone may open (10:200 is /dev/net/tun), a file in
    # the container's own /tmp, a user's home folder that anyone may list
    container.run("sh", "-c", f"[ -e {PROBE_DEVICE} ] || mknod -m 0666 {PROBE_DEVICE} c 10 200")
    container.run("sh", "-c", f"echo here > {TMP_MARKER} && mkdir -p /home/pi && chmod 0755 /home/pi")
    container.run("mkdir", "-p", "/run/umlbot-probe")  # where the probes write what they saw
    control = "/run/umlbot-probe/control.json"
    write_inside(container, "/run/systemd/system/umlbot-probe-control.service",
                 "\n".join(["[Service]", "Type=oneshot", "User=umlbot", "Group=umlbot",
                            f"ExecStart={VENV_PYTHON} {PROBE}", f"StandardOutput=truncate:{control}"]) + "\n")
    container.systemctl("daemon-reload")
    container.systemctl("start", "umlbot-probe-control.service")
    seen = json.loads(container.run("cat", control).stdout)
    return Probes(container, seen, container.run("readlink", "/proc/1/ns/uts").stdout.strip())


@pytest.mark.parametrize(("unit_file", "instance"), [
    ("umlbot-service@.service", "motor"),
    ("umlbot-orchestrator.service", ""),
    ("umlbot-broker.service", ""),
])
def test_the_sandboxing_directives_are_enforced(probes: Probes, unit_file: str, instance: str) -> None:
    """A probe run under each installed unit's own [Service] section is refused what each
    directive forbids, while the same probe as the same user without them is not."""
    directives, seen = probes.run(unit_file, instance)
    hardening = [line for line in directives if HARDENING.match(line)]
    unchecked = [line for line in hardening if line not in EXPECTED and line not in NOT_PROBED]
    assert not unchecked, f"no check for {unchecked}: add one to EXPECTED (or a reason to NOT_PROBED)"
    assert probes.control["ns:uts"] == probes.init_uts
    wrong, untold = {}, {}
    for line in hardening:
        for key, value in EXPECTED.get(line, {}).items():
            got = seen[key]
            if key == "ns:uts":
                got = "its own" if got != probes.init_uts else "the container's"
                control = "its own" if probes.control[key] != probes.init_uts else "the container's"
            else:
                control = probes.control[key]
            if got != value:
                wrong[f"{line}: {key}"] = f"{got} (want {value})"
            if control == value and key not in ALLOWED_ANYWAY:
                untold[f"{line}: {key}"] = f"the control sees {control} too"
    assert not wrong, f"{unit_file}: directives not enforced: {wrong}\nprobe: {seen}"
    assert not untold, f"{unit_file}: these checks cannot tell the directive at work: {untold}"


# --- faults -------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["orchestrator", "sonar", "motor"])
def test_a_killed_unit_is_restarted_and_the_motors_stop_meanwhile(driving: Car, kind: str) -> None:
    car = driving
    unit = ORCHESTRATOR if kind == "orchestrator" else SERVICE.format(kind)
    before = car.unit(unit)
    killed_at, pid, _ = signal_while_driving(car, unit, signal.SIGKILL)
    # the motors stop: the orchestrator's last will (the motor services obey it), the
    # orchestrator's fail-safe stop when a component goes offline, or, when the motor service
    # itself died, only its restart (§1 of issue 23: a safe stop outside the process comes sooner)
    bound = MQTT_STOP_S if kind != "motor" else seconds(before["RestartUSec"]) + START_S
    stops = {}
    for motor in MOTORS:
        stop = car.recorder.wait_for(topic(motor, "state"), stopped, after=killed_at, timeout=bound + 1.0)
        assert stop is not None, f"{motor} did not stop after the kill:\n{car.journal()}"
        assert stop.t - killed_at <= bound, f"{motor} stopped {stop.t - killed_at:.2f} s after the kill"
        if kind == "orchestrator":
            assert stop.payload["stop_reason"] == "orchestrator offline", stop
        stops[motor] = stop
    # systemd restarts the unit (and the orchestrator, which a lost component made fail)
    restart = seconds(before["RestartUSec"])
    after = wait_units(car, (unit,), restart + START_S + 10.0,
                       lambda s: is_running(s) and s["MainPID"] != str(pid))[unit]
    assert is_running(after) and int(after["NRestarts"]) == int(before["NRestarts"]) + 1, (
        f"{after}\n{car.journal(unit)}")
    if kind != "orchestrator":
        failed = car.recorder.wait_for(topic("orchestrator", "status"), status_is("failed"), after=killed_at,
                                       timeout=5.0)
        assert failed is not None and "went offline" in failed.payload["reason"], failed
    back = car.recorder.wait_for(topic("orchestrator", "status"), status_is("running"), after=killed_at,
                                 timeout=restart + 3 * START_S + 10.0)
    assert back is not None, f"the orchestrator did not run again:\n{car.journal()}"
    # meanwhile, until the orchestrator runs the model again, nothing turned a motor on
    for motor, stop in stops.items():
        moving = [m for m in car.recorder.select(topic(motor, "state"), after=stop.t, before=back.t)
                  if running(m.payload)]
        assert not moving, f"{motor} turned while its robot was down: {moving}"
    log(f"kill -9 {unit}: motors stopped after "
        + ", ".join(f"{stop.t - killed_at:.2f} s" for stop in stops.values())
        + f", running again after {back.t - killed_at:.1f} s")


def exec_stop_post(car: Car, unit: str) -> tuple[int, str, str] | None:
    """The last run of the unit's ExecStopPost= (pid, code, status), or None when it has none."""
    text = car.container.show(unit, "ExecStopPost").get("ExecStopPost", "")
    found = re.search(r"pid=(\d+) ; code=(\S+) ; status=(\S+)", text)
    return (int(found.group(1)), found.group(2), found.group(3)) if found else None


def test_a_frozen_motor_service_has_its_motors_stopped_from_outside(driving: Car) -> None:
    """SIGSTOP of the motor service while the motors turn: nothing in the frozen process can stop
    them, so something outside it must (issue 23 §1: systemd's WatchdogSec= ends the process, the
    unit's ExecStopPost= safe stop writes the pins low). Through systemd that shows as: the frozen
    process ended within the watchdog period and systemd's margin; the safe stop, when the unit
    has one, ran after it and succeeded; the motors' retained state says stopped once the
    service is back (a mock's pins live in its process: a safe stop in another one cannot be
    seen on MQTT)."""
    car = driving
    unit = SERVICE.format("motor")
    before = car.unit(unit)
    watchdog_s = seconds(before["WatchdogUSec"]) or MOTOR_WATCHDOG_S
    safe_stop_before = exec_stop_post(car, unit)
    frozen_at, pid, host = signal_while_driving(car, unit, signal.SIGSTOP)
    try:
        # what the process published just before it froze may still be on its way: a stop within
        # IN_FLIGHT_S is not one from outside (no deadman can act before a watchdog period)
        settled = frozen_at + IN_FLIGHT_S
        time.sleep(IN_FLIGHT_S)
        for motor in MOTORS:
            last = car.recorder.latest(topic(motor, "state"), before=settled)
            assert last is not None and running(last.payload), f"{motor} had stopped as it froze: {last}"
        # 1. systemd ends the frozen process
        bound = watchdog_s + SYSTEMD_MARGIN_S
        while Path(f"/proc/{host}").exists() and time.monotonic() < frozen_at + bound:
            time.sleep(0.05)
        assert not Path(f"/proc/{host}").exists(), (
            f"the motor service is still frozen {bound:.1f} s later (WatchdogSec="
            f"{before['WatchdogUSec']}), its motors turning: nothing outside the process stopped them\n"
            f"{car.journal(unit)}")
        log(f"kill -STOP {unit}: the process ended after {time.monotonic() - frozen_at:.2f} s")
        # 2. the unit's safe stop ran once it was gone, and succeeded
        if safe_stop_before is not None:
            deadline = time.monotonic() + START_S
            while (run := exec_stop_post(car, unit)) is not None and (
                    run[0] == safe_stop_before[0] or run[1] == "(null)") and time.monotonic() < deadline:
                time.sleep(0.05)
            assert run is not None and run[0] != safe_stop_before[0] and run[1:] == ("exited", "0"), (
                f"ExecStopPost= after the freeze: {run}\n{car.journal(unit)}")
            log(f"kill -STOP {unit}: its safe stop done after {time.monotonic() - frozen_at:.2f} s")
        # 3. the motors' state says stopped once the service is back
        bound += seconds(before["RestartUSec"]) + START_S
        for motor in MOTORS:
            stop = car.recorder.wait_for(topic(motor, "state"), stopped, after=settled,
                                         timeout=max(0.0, frozen_at + bound - time.monotonic()))
            assert stop is not None, f"{motor} not stopped {bound:.1f} s after the freeze\n{car.journal()}"
            log(f"kill -STOP {unit}: {motor} stopped on MQTT after {stop.t - frozen_at:.2f} s")
        after = wait_units(car, (unit,), START_S, is_running)[unit]
        assert is_running(after) and after["MainPID"] != str(pid), f"{after}\n{car.journal(unit)}"
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.kill(host, signal.SIGCONT)


# --- stopping -----------------------------------------------------------------------------------


def test_systemctl_stop_ends_every_unit_cleanly_with_the_status_stopped(driving: Car) -> None:
    car = driving
    timeout = max(seconds(car.unit(unit)["TimeoutStopUSec"]) for unit in UNITS)
    stopping = time.monotonic()
    car.container.systemctl("stop", "umlbot.target")  # returns before the units have stopped
    returned = time.monotonic()
    states = wait_units(car, UNITS, timeout + 5.0, lambda s: s["ActiveState"] in ("inactive", "failed"))
    log(f"systemctl stop returned after {returned - stopping:.2f} s, "
        f"every unit inactive after {time.monotonic() - stopping:.2f} s")
    for unit, state in states.items():
        assert state["ActiveState"] == "inactive" and state["Result"] == "success", (
            f"{unit}: {state}\n{car.journal(unit)}")
    snapshot = retained(car.container, car.monitor_url, topic("#"))
    status = snapshot.get(topic("orchestrator", "status"))
    assert isinstance(status, dict) and status["state"] == "stopped", (
        f"retained orchestrator status {status}\n{car.journal(ORCHESTRATOR)}")
    for component in COMPONENTS:
        assert status_is("offline")(snapshot.get(topic(component, "status"))), component
    for motor in MOTORS:
        assert stopped(snapshot.get(topic(motor, "state"))), (motor, snapshot.get(topic(motor, "state")))
