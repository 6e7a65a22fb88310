"""deploy/install.sh run into a temporary root produces the expected tree, and its units verify."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import find_mosquitto, free_port, port_accepts

REPO = Path(__file__).resolve().parent.parent
INSTALL = REPO / "deploy" / "install.sh"
KINDS = ("motor", "sonar", "servo", "gpio")


def run_install(*args: str) -> subprocess.CompletedProcess[str]:
    """install.sh with this Python (umlbot and the example plugin installed) unless told otherwise."""
    python = () if "--python" in args else ("--python", sys.executable)
    return subprocess.run(
        ["bash", str(INSTALL), *python, *args], capture_output=True, text=True, timeout=60, check=False,
    )


@pytest.fixture
def robot_files(tmp_path: Path) -> tuple[Path, Path]:
    model = tmp_path / "robot_car.json"
    model.write_text('{"format": 1}\n', encoding="utf-8")
    deployment = tmp_path / "deployment.txt"
    deployment.write_text("LeftActuator=l298n\nRightActuator=l298n\n", encoding="utf-8")
    return model, deployment


def test_install_into_a_root_produces_the_tree(tmp_path: Path, robot_files: tuple[Path, Path]) -> None:
    model, deployment = robot_files
    root = tmp_path / "root"
    result = run_install(
        "--root", str(root), "--no-venv", "--model", str(model), "--deployment", str(deployment),
        "--robot", "rover", "--broker", "mqtt://10.0.0.2:1883", "--driver", "mock",
    )
    assert result.returncode == 0, result.stderr

    prefix = root / "opt" / "umlbot"
    assert (prefix / "robot" / "robot_car.json").read_bytes() == model.read_bytes()
    assert (prefix / "robot" / "deployment.txt").read_bytes() == deployment.read_bytes()
    assert (prefix / "share" / "docs").is_dir()
    assert not (prefix / "venv").exists()  # --no-venv

    env_file = root / "etc" / "umlbot" / "umlbot.env"
    env = dict(
        line.split("=", 1) for line in env_file.read_text(encoding="utf-8").splitlines()
        if line and not line.startswith("#")
    )
    assert env["UMLBOT_ROBOT"] == "rover"
    assert env["UMLBOT_BROKER"] == "mqtt://10.0.0.2:1883"
    assert env["UMLBOT_COMPILED"] == "/opt/umlbot/robot/robot_car.json"
    assert env["UMLBOT_DEPLOYMENT"] == "/opt/umlbot/robot/deployment.txt"
    assert env["UMLBOT_SERVICE_ARGS"] == "--driver mock"
    # It may carry credentials: not readable by others.
    assert stat.S_IMODE(env_file.stat().st_mode) & 0o007 == 0

    units = root / "etc" / "systemd" / "system"
    for name in ("umlbot-service@.service", "umlbot-orchestrator.service", "umlbot-broker.service",
                 "umlbot.target"):
        assert (units / name).read_text(encoding="utf-8") == (
            REPO / "deploy" / "systemd" / name
        ).read_text(encoding="utf-8")
    wants = units / "umlbot.target.wants"
    enabled = {p.name: os.readlink(p) for p in wants.iterdir()}
    assert enabled == {
        **{f"umlbot-service@{k}.service": "/etc/systemd/system/umlbot-service@.service" for k in KINDS},
        "umlbot-orchestrator.service": "/etc/systemd/system/umlbot-orchestrator.service",
    }
    on_boot = units / "multi-user.target.wants" / "umlbot.target"
    assert os.readlink(on_boot) == "/etc/systemd/system/umlbot.target"
    assert (root / "etc" / "sysusers.d" / "umlbot.conf").read_text(encoding="utf-8").startswith("#")


def test_installed_units_verify(tmp_path: Path, robot_files: tuple[Path, Path]) -> None:
    model, deployment = robot_files
    root = tmp_path / "root"
    result = run_install(
        "--root", str(root), "--no-venv", "--model", str(model), "--deployment", str(deployment)
    )
    assert result.returncode == 0, result.stderr
    analyze = shutil.which("systemd-analyze")
    assert analyze, "systemd-analyze is missing (Debian package systemd)"
    units = root / "etc" / "systemd" / "system"
    checked = tmp_path / "checked"
    checked.mkdir()
    names = [f"umlbot-service@{k}.service" for k in KINDS] + ["umlbot-orchestrator.service"]
    for name in names:
        source = units / ("umlbot-service@.service" if "@" in name else name)
        text = source.read_text(encoding="utf-8").replace("/opt/umlbot/venv", sys.prefix)
        (checked / name).write_text(text, encoding="utf-8")
    verified = subprocess.run(
        [analyze, "verify", *names], cwd=checked, capture_output=True, text=True, timeout=60, check=False,
    )
    assert verified.returncode == 0 and verified.stderr.strip() == "", verified.stderr


def test_prefix_is_filled_into_the_units_and_env(tmp_path: Path, robot_files: tuple[Path, Path]) -> None:
    model, _ = robot_files
    root = tmp_path / "root"
    result = run_install(
        "--root", str(root), "--prefix", "/srv/bot", "--no-venv", "--model", str(model),
        "--services", "motor sonar", "--embedded-broker",
    )
    assert result.returncode == 0, result.stderr
    unit = (root / "etc/systemd/system/umlbot-orchestrator.service").read_text(encoding="utf-8")
    assert "ExecStart=/srv/bot/venv/bin/umlbot run" in unit and "/opt/umlbot" not in unit
    assert (root / "srv/bot/robot/robot_car.json").is_file()
    enabled = {p.name for p in (root / "etc/systemd/system/umlbot.target.wants").iterdir()}
    assert enabled == {"umlbot-service@motor.service", "umlbot-service@sonar.service",
                       "umlbot-orchestrator.service", "umlbot-broker.service"}


def test_existing_env_file_is_kept(tmp_path: Path) -> None:
    root = tmp_path / "root"
    (root / "etc" / "umlbot").mkdir(parents=True)
    env_file = root / "etc" / "umlbot" / "umlbot.env"
    env_file.write_text("UMLBOT_BROKER=mqtt://orchestrator:secret@broker:1883\n", encoding="utf-8")
    result = run_install("--root", str(root), "--no-venv", "--no-enable")
    assert result.returncode == 0, result.stderr
    assert env_file.read_text(encoding="utf-8") == "UMLBOT_BROKER=mqtt://orchestrator:secret@broker:1883\n"
    assert not (root / "etc/systemd/system/umlbot.target.wants").exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--services", "motor laser"], "unknown service kind 'laser'"),
        (["--driver", "gpiozero"], "unknown driver 'gpiozero'"),
        (["--model", "/nonexistent/model.json"], "not found"),
        (["--prefix", "relative/dir"], "absolute"),
        (["--bogus"], "unknown option --bogus"),
        (["--plugin", "umlbot-buzzer"], "--plugin needs the venv"),
    ],
)
def test_bad_arguments_are_refused(tmp_path: Path, args: list[str], message: str) -> None:
    result = run_install("--root", str(tmp_path / "root"), "--no-venv", *args)
    assert result.returncode != 0
    assert message in result.stderr
    assert not (tmp_path / "root").exists()  # refused before anything is written


def test_secure_install_writes_one_user_per_role(tmp_path: Path) -> None:
    root = tmp_path / "root"
    deployment = REPO / "models" / "robot_car" / "deployment.yaml"
    result = run_install(
        "--root", str(root), "--no-venv", "--python", sys.executable, "--deployment", str(deployment),
        "--robot", "car", "--broker", "mqtt://127.0.0.1:1884", "--secure", "--embedded-broker",
    )
    assert result.returncode == 0, result.stderr
    etc = root / "etc" / "umlbot"
    passwords = set()
    for role in (*KINDS, "all", "orchestrator"):
        text = (etc / f"{role}.env").read_text(encoding="utf-8")
        assert f"UMLBOT_BROKER=mqtt://umlbot-{role}:" in text and "@127.0.0.1:1884" in text
        assert stat.S_IMODE((etc / f"{role}.env").stat().st_mode) & 0o007 == 0
        passwords.add(text.split(":")[2].split("@")[0])
    assert len(passwords) == 6
    for password in passwords:  # nothing printed them
        assert password not in result.stdout + result.stderr
    mosquitto = root / "etc" / "mosquitto"
    conf = (mosquitto / "conf.d" / "umlbot.conf").read_text(encoding="utf-8")
    assert "listener 1884 127.0.0.1" in conf and "allow_anonymous false" in conf
    assert "user umlbot-motor" in (mosquitto / "umlbot.acl").read_text(encoding="utf-8")
    assert "umlbot/car/LeftActuator/#" in (mosquitto / "umlbot.acl").read_text(encoding="utf-8")
    assert (mosquitto / "umlbot.passwd").read_text(encoding="utf-8").startswith("umlbot-motor:$7$")
    env = (etc / "umlbot.env").read_text(encoding="utf-8")
    assert ("UMLBOT_BROKER_ARGS=--bind 127.0.0.1 --port 1884 --passwd /etc/umlbot/auth/amqtt.passwd "
            "--acl /etc/umlbot/auth/amqtt-acl.yaml") in env
    assert (etc / "auth" / "amqtt.passwd").read_text(encoding="utf-8").startswith("umlbot-motor:$argon2")


def test_secure_needs_a_deployment_and_no_password_in_the_url(tmp_path: Path) -> None:
    result = run_install("--root", str(tmp_path / "r1"), "--no-venv", "--secure")
    assert result.returncode != 0 and "--secure needs --deployment" in result.stderr
    deployment = REPO / "models" / "robot_car" / "deployment.yaml"
    result = run_install("--root", str(tmp_path / "r2"), "--no-venv", "--secure", "--deployment",
                         str(deployment), "--broker", "mqtt://me:secret@host:1883")
    assert result.returncode != 0 and "without user:password" in result.stderr


def test_mosquitto_gets_tcp_nodelay_without_secure(tmp_path: Path, robot_files: tuple[Path, Path]) -> None:
    model, deployment = robot_files
    root = tmp_path / "root"
    result = run_install("--root", str(root), "--no-venv", "--model", str(model), "--deployment",
                         str(deployment))
    assert result.returncode == 0, result.stderr
    conf_d = root / "etc" / "mosquitto" / "conf.d"
    assert sorted(p.name for p in conf_d.iterdir()) == ["umlbot-nodelay.conf"]  # no users, no ACL
    settings = [line for line in (conf_d / "umlbot-nodelay.conf").read_text(encoding="utf-8").splitlines()
                if line and not line.startswith("#")]
    assert settings == ["set_tcp_nodelay true"]
    # Mosquitto takes the file as it is (it refuses a setting it does not know).
    binary = find_mosquitto()
    assert binary, "the mosquitto binary is required"
    port = free_port()
    main_conf = tmp_path / "mosquitto.conf"
    main_conf.write_text(f"include_dir {conf_d}\nlistener {port} 127.0.0.1\nallow_anonymous true\n"
                         "persistence false\n", encoding="utf-8")
    broker = subprocess.Popen([binary, "-c", str(main_conf), "-v"], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 10
        while not port_accepts(port):
            assert broker.poll() is None, broker.communicate()[0]
            assert time.monotonic() < deadline, "mosquitto did not start"
            time.sleep(0.05)
    finally:
        broker.terminate()
        log = broker.communicate(timeout=10)[0]
    assert "umlbot-nodelay.conf" in log


def test_secure_adds_users_beside_tcp_nodelay(tmp_path: Path) -> None:
    root = tmp_path / "root"
    result = run_install("--root", str(root), "--no-venv", "--python", sys.executable, "--deployment",
                         str(REPO / "models" / "robot_car" / "deployment.yaml"), "--secure")
    assert result.returncode == 0, result.stderr
    conf_d = root / "etc" / "mosquitto" / "conf.d"
    assert sorted(p.name for p in conf_d.iterdir()) == ["umlbot-nodelay.conf", "umlbot.conf"]


def test_a_plugins_service_kind_is_installed_and_secured_like_a_built_in(tmp_path: Path) -> None:
    """The example plugin (installed for this Python) adds the service kind `buzzer`."""
    deployment = tmp_path / "deployment.txt"
    deployment.write_text("LeftActuator=l298n\nBell=passive_buzzer\n", encoding="utf-8")
    root = tmp_path / "root"
    result = run_install("--root", str(root), "--no-venv", "--deployment", str(deployment), "--robot", "car",
                         "--services", "motor buzzer", "--secure")
    assert result.returncode == 0, result.stderr
    wants = root / "etc" / "systemd" / "system" / "umlbot.target.wants"
    assert sorted(p.name for p in wants.iterdir()) == ["umlbot-service@buzzer.service",
                                                       "umlbot-service@motor.service"]
    etc = root / "etc" / "umlbot"
    assert "UMLBOT_BROKER=mqtt://umlbot-buzzer:" in (etc / "buzzer.env").read_text(encoding="utf-8")
    assert not (etc / "sonar.env").exists()  # no sonar in this deployment: no user for one
    acl = (root / "etc" / "mosquitto" / "umlbot.acl").read_text(encoding="utf-8")
    buzzer = acl.split("user umlbot-buzzer\n", 1)[1].split("\n\n", 1)[0].splitlines()
    assert buzzer == ["topic readwrite umlbot/car/Bell/#", "topic read umlbot/car/orchestrator/status",
                      "topic write umlbot/car/_reply/#"]
    motor = acl.split("user umlbot-motor\n", 1)[1].split("\n\n", 1)[0]
    assert "Bell" not in motor


def test_an_unknown_kind_is_refused_with_the_installed_ones(tmp_path: Path) -> None:
    result = run_install("--root", str(tmp_path / "root"), "--no-venv", "--services", "motor laser")
    assert result.returncode != 0
    assert "unknown service kind 'laser' (installed: motor sonar servo gpio buzzer, all)" in result.stderr
    result = run_install("--root", str(tmp_path / "root"), "--no-venv", "--services", "motor ../x")
    assert result.returncode != 0 and "bad service kind name '../x'" in result.stderr
    assert not (tmp_path / "root").exists()
