"""The systemd units in deploy/systemd pass `systemd-analyze verify` once their paths are filled
in, and the hardware services' watchdog and safe stop work as the unit says (run by hand)."""

from __future__ import annotations

import contextlib
import itertools
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parent.parent
UNITS = REPO / "deploy" / "systemd"
VENV = Path(sys.prefix)  # the venv running the tests holds a real `bin/umlbot`

KINDS = ("motor", "sonar", "servo", "gpio")
SERVICE_UNITS = ["umlbot-service@.service", "umlbot-orchestrator.service", "umlbot-broker.service"]

#: unit file -> the name verified (the template is verified through one instance per kind).
VERIFIED = {
    "umlbot-orchestrator.service": ["umlbot-orchestrator.service"],
    "umlbot-broker.service": ["umlbot-broker.service"],
    "umlbot.target": ["umlbot.target"],
    "umlbot-service@.service": [f"umlbot-service@{kind}.service" for kind in KINDS],
    "umlbot-ros2-bridge.service": ["umlbot-ros2-bridge.service"],
}


def _systemd_analyze() -> str:
    exe = shutil.which("systemd-analyze")
    assert exe, "systemd-analyze is missing: install Debian's systemd package (.ci/run does)"
    return exe


def fill_in(unit_text: str) -> str:
    """The unit with /opt/umlbot/venv pointing at the venv that runs the tests."""
    return unit_text.replace("/opt/umlbot/venv", str(VENV))


def verify(paths: list[Path]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [_systemd_analyze(), "verify", *[str(p) for p in paths]],
        capture_output=True, text=True, timeout=60, cwd=paths[0].parent, check=False,
    )


def test_every_unit_is_listed() -> None:
    shipped = {p.name for p in UNITS.iterdir() if p.suffix in (".service", ".target")}
    assert shipped == set(VERIFIED)


@pytest.mark.parametrize("unit", sorted(VERIFIED))
def test_unit_verifies_cleanly(unit: str, tmp_path: Path) -> None:
    text = fill_in((UNITS / unit).read_text(encoding="utf-8"))
    (tmp_path / unit).write_text(text, encoding="utf-8")  # instances find their template beside them
    targets = []
    for name in VERIFIED[unit]:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        targets.append(path)
    result = verify(targets)
    # verify exits 0 on unknown keys but prints them: any output is a defect in the unit.
    assert result.returncode == 0, result.stderr
    assert result.stderr.strip() == "", result.stderr


def test_verify_catches_a_broken_unit(tmp_path: Path) -> None:
    """The check above can fail: a unit whose binary is missing does not verify."""
    text = fill_in((UNITS / "umlbot-orchestrator.service").read_text(encoding="utf-8"))
    broken = tmp_path / "umlbot-orchestrator.service"
    broken.write_text(text.replace(str(VENV), str(tmp_path / "nowhere")), encoding="utf-8")
    assert verify([broken]).returncode != 0


def _unit(name: str) -> dict[str, dict[str, str]]:
    """The unit's sections; a key given several times (After=, EnvironmentFile=) joins its values."""
    sections: dict[str, dict[str, str]] = {}
    current: dict[str, str] = {}
    for raw in (UNITS / name).read_text(encoding="utf-8").splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("["):
            current = sections.setdefault(line.strip("[]"), {})
            continue
        key, _, value = line.partition("=")
        current[key] = f"{current[key]} {value}" if key in current else value
    return sections


@pytest.mark.parametrize("name", SERVICE_UNITS)
def test_units_run_unprivileged_restart_on_failure_and_read_the_env_file(name: str) -> None:
    unit = _unit(name)
    service = unit["Service"]
    assert service["User"] == "umlbot"
    assert service["Restart"] == "on-failure"
    assert service["EnvironmentFile"].split()[0] == "/etc/umlbot/umlbot.env"
    assert service["NoNewPrivileges"] == "yes"
    assert service["ProtectSystem"] == "strict"
    # TCP must stay possible: pigpiod on localhost:8888 and the broker.
    families = service["RestrictAddressFamilies"].split()
    assert "AF_INET" in families and "AF_INET6" in families
    assert "PrivateNetwork" not in service
    assert "network-online.target" in unit["Unit"]["After"].split()
    assert "network-online.target" in unit["Unit"]["Wants"].split()


def test_hardware_services_wait_for_pigpiod_and_the_broker() -> None:
    unit = _unit("umlbot-service@.service")["Unit"]
    assert "pigpiod.service" in unit["After"].split() and "pigpiod.service" in unit["Wants"].split()
    assert {"mosquitto.service", "umlbot-broker.service"} <= set(unit["After"].split())
    assert "mosquitto.service" in _unit("umlbot-orchestrator.service")["Unit"]["After"].split()


def test_hardware_services_reach_the_gpiochips_for_lgpio_and_nothing_else() -> None:
    service = _unit("umlbot-service@.service")["Service"]
    assert "PrivateDevices" not in service, "it would hide /dev/gpiochip* (the Pi 5 has no pigpiod)"
    assert service["DevicePolicy"] == "closed" and service["DeviceAllow"] == "char-gpiochip rw"
    assert service["WorkingDirectory"] == "/var/lib/umlbot", "lgpio's notification pipe goes there"
    sysusers = (REPO / "deploy" / "sysusers.d" / "umlbot.conf").read_text(encoding="utf-8").splitlines()
    assert "m umlbot gpio" in sysusers, "the group that owns /dev/gpiochip*"
    for other in ("umlbot-orchestrator.service", "umlbot-broker.service"):
        assert _unit(other)["Service"]["PrivateDevices"] == "yes"


@pytest.mark.parametrize("name", SERVICE_UNITS)
def test_the_directories_the_units_write_belong_to_the_service_user(name: str) -> None:
    """The one writable place, /var/lib/umlbot (traces, lgpio's pipe), is the units' StateDirectory=:
    systemd makes it (and chowns it on every start) for User=/Group=umlbot. No tmpfiles.d entry may
    make an umlbot directory for another owner (systemd-tmpfiles runs as root: root would own it)."""
    unit = _unit(name)
    service = unit["Service"]
    assert service["User"] == "umlbot" and service["Group"] == "umlbot"
    assert service["StateDirectory"] == "umlbot"
    assert service["WorkingDirectory"] == "/var/lib/umlbot"
    assert "ReadWritePaths" not in service, "a writable path systemd does not make for the service user"
    for key in ("RuntimeDirectory", "LogsDirectory", "CacheDirectory"):  # systemd-made, user-owned too
        assert service.get(key, "umlbot").split()[0].startswith("umlbot")
    for conf in sorted((REPO / "deploy").glob("tmpfiles.d/*.conf")):
        for line in conf.read_text(encoding="utf-8").splitlines():
            fields = line.split()
            if fields and not line.startswith("#") and "umlbot" in fields[1]:
                assert fields[0][0] in "dDv" and fields[3:5] == ["umlbot", "umlbot"], (conf.name, line)


# --- the deadman in systemd: WatchdogSec= and ExecStopPost=, run as systemd would -------------


def _command_line(line: str, env: dict[str, str], instance: str) -> list[str]:
    """An Exec*= line as systemd runs it: `%i`, `${VAR}` (one word) and `$VAR` (split into words)."""
    words: list[str] = []
    for word in line.replace("%i", instance).replace("/opt/umlbot/venv", str(VENV)).split():
        if word.startswith("$") and not word.startswith("${"):
            words += env.get(word[1:], "").split()
        else:
            words.append(re.sub(r"\$\{(\w+)\}", lambda m: env.get(m.group(1), ""), word))
    return words


@pytest.mark.network
def test_a_frozen_service_stops_its_watchdog_pings_and_the_safe_stop_writes_the_pins_low(
    mosquitto_broker: Any, tmp_path: Path,
) -> None:
    """What systemd does with the unit, done by hand: it starts ExecStart with NOTIFY_SOCKET and
    WATCHDOG_USEC, gets READY=1 and WATCHDOG=1 pings while the service runs, sees them stop when
    the service is frozen, kills it with WatchdogSignal= and runs ExecStopPost=, which writes the
    pins low (the fake pigpio's pins: its state file, shared by every process of the test)."""
    from services_support import client, deployment

    service = _unit("umlbot-service@.service")["Service"]
    kind = (service["Type"], service["NotifyAccess"], service["WatchdogSignal"])
    assert kind == ("notify", "main", "SIGKILL")
    watchdog_s = float(service["WatchdogSec"])
    deploy = tmp_path / "deployment.json"
    deploy.write_text(deployment("pigpio").model_dump_json(), encoding="utf-8")
    pins = tmp_path / "pins.json"
    notify = tmp_path / "notify.sock"
    env = {**os.environ, "UMLBOT_DEPLOYMENT": str(deploy), "UMLBOT_LOG_LEVEL": "WARNING",
           "UMLBOT_SERVICE_ARGS": f"--broker {mosquitto_broker.url} --robot car",
           "UMLBOT_FAKE_PIGPIO": "1", "UMLBOT_FAKE_PIGPIO_STATE": str(pins)}
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sd:
        sd.bind(str(notify))
        proc = subprocess.Popen(_command_line(service["ExecStart"], env, "motor"),
                                env={**env, "NOTIFY_SOCKET": str(notify),
                                     "WATCHDOG_USEC": str(int(watchdog_s * 1e6))})
        try:
            sd.settimeout(20.0)
            assert sd.recv(512) == b"READY=1"
            with client(mosquitto_broker.url) as bus:
                for name in ("LeftActuator", "RightActuator"):
                    bus.call(name, "dutycycle", 60, timeout=5.0)
                    bus.call(name, "enabled", True, timeout=5.0)
            assert json.loads(pins.read_text())["pins"]["22"]["duty_fraction"] == 0.6
            sd.settimeout(watchdog_s)
            pings = [time.monotonic()]
            while len(pings) < 6:
                assert sd.recv(512) == b"WATCHDOG=1"
                pings.append(time.monotonic())
            gaps = [b - a for a, b in itertools.pairwise(pings[1:])]
            assert max(gaps) <= watchdog_s / 2, gaps
            os.kill(proc.pid, signal.SIGSTOP)
            with contextlib.suppress(TimeoutError):  # a ping on its way before the signal
                sd.settimeout(0.3)
                sd.recv(512)
            sd.settimeout(watchdog_s)
            with pytest.raises(TimeoutError):
                sd.recv(512)  # no ping for WatchdogSec: systemd kills it now
            assert json.loads(pins.read_text())["pins"]["22"]["duty_fraction"] == 0.6, "still driving"
            os.kill(proc.pid, signal.SIGKILL)  # WatchdogSignal=SIGKILL ends a stopped process too
            proc.wait(5)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(5)
    stop_post = subprocess.run(_command_line(service["ExecStopPost"], env, "motor"), env=env,
                               capture_output=True, text=True, timeout=60, check=False)
    assert stop_post.returncode == 0, stop_post.stderr
    duties = {gpio: pin["duty_fraction"] for gpio, pin in json.loads(pins.read_text())["pins"].items()}
    assert duties and set(duties.values()) == {0.0}, duties
