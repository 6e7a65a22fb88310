"""The installed units really run the car: their ExecStart lines, expanded the way systemd does
with the installed environment files, start the broker, the services and the orchestrator.

systemd itself is not running here, so the test expands each unit's `ExecStart=` (`%i`, `${VAR}`
as one word, `$VAR` split on white space) with `/etc/umlbot/umlbot.env` and the role's own
`/etc/umlbot/<role>.env` from a `deploy/install.sh --secure --root` tree, and starts the commands.
"""

from __future__ import annotations

import json
import os
import pwd
import re
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

import pytest
from conftest import find_mosquitto, free_port, port_accepts
from robot_run import CAR_COMPONENTS, CAR_DEPLOYMENT, Proc, compile_car, processes, umlbot_argv
from secured_brokers import connect_client

REPO = Path(__file__).resolve().parent.parent
KINDS = ("motor", "sonar", "servo", "gpio")


def run_install(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", str(REPO / "deploy" / "install.sh"), *args],
                          capture_output=True, text=True, timeout=120, check=False)


def read_env(path: Path) -> dict[str, str]:
    """An EnvironmentFile= as systemd reads it (KEY=VALUE lines, # comments)."""
    env: dict[str, str] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        line = line.strip()
        if line and not line.startswith("#"):
            key, _, value = line.partition("=")
            env[key.strip()] = value.strip()
    return env


def exec_start(unit: Path, env: dict[str, str], instance: str = "") -> list[str]:
    """The unit's ExecStart= as argv, expanded like systemd does."""
    [line] = [ln for ln in unit.read_text(encoding="utf-8").splitlines() if ln.startswith("ExecStart=")]
    argv: list[str] = []
    for word in line.removeprefix("ExecStart=").replace("%i", instance).split():
        if match := re.fullmatch(r"\$\{(\w+)\}", word):
            argv.append(env.get(match.group(1), ""))
        elif match := re.fullmatch(r"\$(\w+)", word):
            argv.extend(env.get(match.group(1), "").split())
        else:
            argv.append(word)
    return argv


def in_root(root: Path, value: str) -> str:
    """A path as installed (/opt/umlbot, /etc/…) moved under the test's root; the venv is ours."""
    value = value.replace("/opt/umlbot/venv/bin/umlbot", f"{sys.prefix}/bin/umlbot")
    installed = r"(?<![\w/])/(opt/umlbot|etc/umlbot|etc/mosquitto)"
    return re.sub(installed, lambda m: f"{root}/{m.group(1)}", value)


def unit_process(name: str, root: Path, unit: str, role: str | None, workdir: Path,
                 instance: str = "") -> Proc:
    etc = root / "etc" / "umlbot"
    env = read_env(etc / "umlbot.env")
    if role is not None and (etc / f"{role}.env").exists():
        env.update(read_env(etc / f"{role}.env"))
    env = {k: in_root(root, v) for k, v in env.items()}
    argv = [in_root(root, a) for a in exec_start(root / "etc/systemd/system" / unit, env, instance)]
    assert argv[0] == f"{sys.prefix}/bin/umlbot", argv
    return Proc(name, [sys.executable, "-c", "from umlbot.cli import main; main()", *argv[1:]], workdir,
                env["UMLBOT_BROKER"], env)


@pytest.mark.parametrize("broker_kind", ["mosquitto", "embedded"])
def test_installed_units_run_the_car(tmp_path: Path, broker_kind: str) -> None:
    compiled = compile_car(tmp_path)
    root = tmp_path / "root"
    port = free_port()
    extra = ["--embedded-broker"] if broker_kind == "embedded" else []
    result = run_install(
        "--root", str(root), "--no-venv", "--python", sys.executable, "--model", str(compiled),
        "--deployment", str(CAR_DEPLOYMENT), "--robot", "car", "--driver", "mock",
        "--broker", f"mqtt://127.0.0.1:{port}", "--secure", *extra,
    )
    assert result.returncode == 0, result.stderr
    auth = root / "etc" / "umlbot" / "auth"

    with processes() as made:
        if broker_kind == "mosquitto":
            binary = find_mosquitto()
            assert binary, "the mosquitto binary is required"
            conf = in_root(root, (root / "etc/mosquitto/conf.d/umlbot.conf").read_text(encoding="utf-8"))
            user = pwd.getpwuid(os.geteuid()).pw_name  # as root, mosquitto would drop to `mosquitto`
            (tmp_path / "mosquitto.conf").write_text(
                conf + f"\nuser {user}\npersistence false\nlog_dest stderr\n", encoding="utf-8")
            made.append(Proc("mosquitto", [binary, "-c", str(tmp_path / "mosquitto.conf")], tmp_path, ""))
        else:
            made.append(unit_process("broker", root, "umlbot-broker.service", None, tmp_path))
        deadline = time.monotonic() + 15
        while not port_accepts(port):
            assert time.monotonic() < deadline, made[0].log_text()
            time.sleep(0.05)

        monitor_env = {k: in_root(root, v) for k, v in read_env(auth / "monitor.env").items()}
        mon = Proc("monitor", umlbot_argv("monitor", "--json", "--robot", "car", "--duration", "120"),
                   tmp_path, monitor_env["UMLBOT_BROKER"])
        made.append(mon)
        services = [unit_process(kind, root, "umlbot-service@.service", kind, tmp_path, instance=kind)
                    for kind in KINDS]
        made.extend(services)
        online: set[str] = set()
        while online != CAR_COMPONENTS:
            event = mon.wait_line(lambda e: e["type"] == "availability" and e["state"] == "online", 30)
            online.add(event["component"])
        run = unit_process("orchestrator", root, "umlbot-orchestrator.service", "orchestrator", tmp_path)
        made.append(run)
        mon.wait_line(lambda e: e["type"] == "call" and e["component"] == "DistanceRead" and e["ok"], 30)
        assert run.stop() == 0, run.log_text()[-3000:]  # SIGTERM, as `systemctl stop` sends
        for service in services:
            assert service.stop() == 0, service.log_text()[-2000:]
        # The orchestrator's retained status says how it ended.
        watcher = connect_client(port, "umlbot-monitor", urlsplit(monitor_env["UMLBOT_BROKER"]).password)
        try:
            assert watcher.subscribe("umlbot/car/orchestrator/status")
            messages = watcher.received("umlbot/car/orchestrator/status", 1.0)
            retained = [json.loads(m.payload) for m in messages]
        finally:
            watcher.client.disconnect()
            watcher.client.loop_stop()
        seen = [e.get("state") for e in mon.events() + mon.drain(1.0) if e["type"] == "orchestrator"]
        assert retained and retained[-1]["state"] == "stopped", (retained, seen)
        assert "stopped" in seen, (retained, seen)
