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
    assert enabled == {  # the deployment has motors only: only the motor service is enabled
        "umlbot-service@motor.service": "/etc/systemd/system/umlbot-service@.service",
        "umlbot-orchestrator.service": "/etc/systemd/system/umlbot-orchestrator.service",
    }
    on_boot = units / "multi-user.target.wants" / "umlbot.target"
    assert os.readlink(on_boot) == "/etc/systemd/system/umlbot.target"
    assert (root / "etc" / "sysusers.d" / "umlbot.conf").read_text(encoding="utf-8").startswith("#")
    # The directories the units write are systemd's StateDirectory= (owned by User=umlbot when
    # made); install.sh makes none of them, so none is left owned by root.
    assert not (root / "var").exists()


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


def env_of(env_file: Path) -> dict[str, str]:
    return dict(line.split("=", 1) for line in env_file.read_text(encoding="utf-8").splitlines()
                if line and not line.startswith("#"))


def test_existing_env_file_keeps_its_values_and_gets_the_keys_it_lacks(tmp_path: Path) -> None:
    root = tmp_path / "root"
    (root / "etc" / "umlbot").mkdir(parents=True)
    env_file = root / "etc" / "umlbot" / "umlbot.env"
    env_file.write_text("UMLBOT_BROKER=mqtt://orchestrator:secret@broker:1883\n", encoding="utf-8")
    result = run_install("--root", str(root), "--no-venv", "--no-enable")
    assert result.returncode == 0, result.stderr
    lines = env_file.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "UMLBOT_BROKER=mqtt://orchestrator:secret@broker:1883"  # kept as it was
    assert env_of(env_file) == {
        "UMLBOT_BROKER": "mqtt://orchestrator:secret@broker:1883", "UMLBOT_ROBOT": "car",
        "UMLBOT_DEPLOYMENT": "/opt/umlbot/robot/deployment.yaml",
        "UMLBOT_COMPILED": "/opt/umlbot/robot/model.json", "UMLBOT_SERVICE_ARGS": "--driver auto",
        "UMLBOT_RUN_ARGS": "", "UMLBOT_BROKER_ARGS": "--bind 127.0.0.1 --port 1883",
        "UMLBOT_LOG_LEVEL": "INFO",
    }
    assert "secret" not in result.stdout + result.stderr
    assert not (root / "etc/systemd/system/umlbot.target.wants").exists()


def test_a_rerun_updates_the_keys_of_the_options_given_and_keeps_the_rest(
    tmp_path: Path, robot_files: tuple[Path, Path]
) -> None:
    """An update with a new --robot, --broker, --driver and model changes those keys only: the
    user's own lines, comments and extra arguments stay."""
    model, deployment = robot_files
    root = tmp_path / "root"
    first = run_install("--root", str(root), "--model", str(model), "--deployment", str(deployment),
                        "--robot", "car", "--broker", "mqtt://127.0.0.1:1883")
    assert first.returncode == 0, first.stderr
    env_file = root / "etc" / "umlbot" / "umlbot.env"
    text = env_file.read_text(encoding="utf-8")
    text = text.replace("UMLBOT_SERVICE_ARGS=--driver auto", "UMLBOT_SERVICE_ARGS=--driver auto --log-json")
    text = text.replace("UMLBOT_RUN_ARGS=", "UMLBOT_RUN_ARGS=--trace /var/lib/umlbot/trace.jsonl")
    text = text.replace("UMLBOT_BROKER_ARGS=--bind 127.0.0.1", "UMLBOT_BROKER_ARGS=--bind 0.0.0.0")
    text += "# my own setting\nPIGPIO_ADDR=10.0.0.9\n"
    env_file.write_text(text, encoding="utf-8")
    again = run_install("--root", str(root), "--no-venv", "--robot", "rover", "--broker",
                        "mqtt://127.0.0.1:1884", "--driver", "mock")
    assert again.returncode == 0, again.stderr
    assert ("updated UMLBOT_ROBOT UMLBOT_BROKER UMLBOT_SERVICE_ARGS UMLBOT_BROKER_ARGS in "
            "/etc/umlbot/umlbot.env") in again.stdout
    updated = env_file.read_text(encoding="utf-8")
    assert updated.endswith("# my own setting\nPIGPIO_ADDR=10.0.0.9\n")
    assert env_of(env_file) == {
        "UMLBOT_ROBOT": "rover", "UMLBOT_BROKER": "mqtt://127.0.0.1:1884",
        "UMLBOT_DEPLOYMENT": "/opt/umlbot/robot/deployment.txt",
        "UMLBOT_COMPILED": "/opt/umlbot/robot/robot_car.json",
        "UMLBOT_SERVICE_ARGS": "--driver mock --log-json",
        "UMLBOT_RUN_ARGS": "--trace /var/lib/umlbot/trace.jsonl",
        "UMLBOT_BROKER_ARGS": "--bind 0.0.0.0 --port 1884", "UMLBOT_LOG_LEVEL": "INFO",
        "PIGPIO_ADDR": "10.0.0.9",
    }
    assert stat.S_IMODE(env_file.stat().st_mode) == 0o640
    assert not (env_file.parent / "umlbot.env.new").exists()

    # A new model: only UMLBOT_COMPILED changes. Nothing given: nothing changes.
    newer = tmp_path / "newer.json"
    newer.write_text('{"format": 1}\n', encoding="utf-8")
    assert run_install("--root", str(root), "--model", str(newer)).returncode == 0
    assert env_of(env_file)["UMLBOT_COMPILED"] == "/opt/umlbot/robot/newer.json"
    before = env_file.read_bytes()
    same = run_install("--root", str(root))
    assert same.returncode == 0, same.stderr
    assert "umlbot.env is up to date" in same.stdout
    assert env_file.read_bytes() == before


def test_root_implies_no_venv(tmp_path: Path) -> None:
    """A venv made under --root would name the staging path: --root makes none, and says why."""
    calls = tmp_path / "calls"
    python = tmp_path / "python"
    python.write_text(f'#!/bin/sh\necho "$*" >>{calls}\n'
                      f'case "$*" in *"-m venv"*|*"-m pip"*) exit 3 ;; esac\nexec {sys.executable} "$@"\n',
                      encoding="utf-8")
    python.chmod(0o755)
    root = tmp_path / "root"
    result = run_install("--root", str(root), "--python", str(python))
    assert result.returncode == 0, result.stderr
    assert "--root: no venv is made" in result.stdout
    assert not (root / "opt" / "umlbot" / "venv").exists()
    assert "venv" not in calls.read_text(encoding="utf-8") and "pip" not in calls.read_text(encoding="utf-8")
    refused = run_install("--root", str(tmp_path / "r2"), "--plugin", "umlbot-buzzer")
    assert refused.returncode != 0
    assert "--plugin needs the venv, which --root does not make" in refused.stderr
    help_text = run_install("--help").stdout
    assert "implies --no-venv" in help_text


def test_a_kind_the_deployment_does_not_use_is_refused(
    tmp_path: Path, robot_files: tuple[Path, Path]
) -> None:
    """Its service would exit at once ("no component served by the sonar service"): refused, with
    the kinds the deployment uses; also on an update that names no deployment (the installed one)."""
    model, deployment = robot_files  # motors only
    root = tmp_path / "root"
    result = run_install("--root", str(root), "--deployment", str(deployment), "--services", "motor sonar")
    assert result.returncode != 0
    assert (f"service kind 'sonar' is not used by the deployment {deployment}: its service would have "
            "nothing to serve and fail at start (the deployment uses: motor; or all)") in result.stderr
    assert not root.exists()
    first = run_install("--root", str(root), "--deployment", str(deployment), "--model", str(model))
    assert first.returncode == 0, first.stderr
    update = run_install("--root", str(root), "--services", "servo")
    assert update.returncode != 0
    assert "service kind 'servo' is not used by the deployment" in update.stderr
    assert "(the deployment uses: motor; or all)" in update.stderr
    together = run_install("--root", str(root), "--services", "motor all")
    assert together.returncode != 0 and "--services all already serves every kind" in together.stderr
    # `all` alone is fine, and an update to it disables the single kinds
    one = run_install("--root", str(root), "--services", "all")
    assert one.returncode == 0, one.stderr
    wants = root / "etc" / "systemd" / "system" / "umlbot.target.wants"
    assert sorted(p.name for p in wants.iterdir()) == ["umlbot-orchestrator.service",
                                                       "umlbot-service@all.service"]


def _dropin(root: Path, unit: str, name: str) -> dict[str, list[str]]:
    text = (root / "etc/systemd/system" / f"{unit}.d" / name).read_text(encoding="utf-8")
    keys: dict[str, list[str]] = {}
    for line in text.splitlines():
        if "=" in line and not line.startswith("#"):
            key, _, value = line.partition("=")
            keys.setdefault(key, []).extend(value.split())
    return keys


@pytest.mark.parametrize(
    ("args", "services", "broker"),
    [
        ([], [f"umlbot-service@{k}.service" for k in KINDS], ["mosquitto.service"]),
        (["--embedded-broker", "--services", "all"], ["umlbot-service@all.service"],
         ["umlbot-broker.service"]),
        (["--broker", "mqtt://10.0.0.2:1883", "--services", "motor"], ["umlbot-service@motor.service"], []),
    ],
)
def test_drop_ins_order_the_orchestrator_after_the_broker_and_its_services(
    tmp_path: Path, args: list[str], services: list[str], broker: list[str]
) -> None:
    root = tmp_path / "root"
    model = tmp_path / "robot_car.json"
    model.write_text('{"format": 1}\n', encoding="utf-8")
    result = run_install("--root", str(root), "--model", str(model), "--deployment",
                         str(REPO / "models" / "robot_car" / "deployment.yaml"), *args)
    assert result.returncode == 0, result.stderr
    ordered = _dropin(root, "umlbot-orchestrator.service", "20-umlbot-services.conf")
    assert ordered == {"Wants": services, "After": services}
    for unit in ("umlbot-orchestrator.service", "umlbot-service@.service"):
        on_broker = _dropin(root, unit, "10-umlbot-broker.conf")
        assert on_broker == ({"Wants": broker, "After": broker} if broker else {})


def test_installed_units_with_their_drop_ins_verify_and_order_the_orchestrator_last(tmp_path: Path) -> None:
    """systemd-analyze reads the drop-ins: clean; and a service ordered after the orchestrator
    (a cycle only the drop-in's After= on the services can close) is reported."""
    root = tmp_path / "root"
    model = tmp_path / "robot_car.json"
    model.write_text('{"format": 1}\n', encoding="utf-8")
    result = run_install("--root", str(root), "--model", str(model), "--deployment",
                         str(REPO / "models" / "robot_car" / "deployment.yaml"), "--embedded-broker")
    assert result.returncode == 0, result.stderr
    analyze = shutil.which("systemd-analyze")
    assert analyze, "systemd-analyze is missing (Debian package systemd)"
    units = root / "etc" / "systemd" / "system"
    checked = tmp_path / "checked"
    checked.mkdir()
    for unit in units.glob("umlbot*"):
        if unit.name.endswith(".d"):
            shutil.copytree(unit, checked / unit.name)  # the drop-ins
        elif unit.is_file():
            text = unit.read_text(encoding="utf-8").replace("/opt/umlbot/venv", sys.prefix)
            (checked / unit.name).write_text(text, encoding="utf-8")

    def verify() -> str:
        done = subprocess.run([analyze, "verify", "umlbot-orchestrator.service"], cwd=checked,
                              capture_output=True, text=True, timeout=60, check=False)
        assert done.returncode == 0, done.stderr
        return done.stderr.strip()

    assert verify() == ""
    (checked / "umlbot-service@.service.d" / "99-cycle.conf").write_text(
        "[Unit]\nAfter=umlbot-orchestrator.service\n", encoding="utf-8")
    cycle = verify()
    assert "ordering cycle" in cycle and "umlbot-service@motor.service" in cycle, cycle


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
                      "topic read umlbot/car/orchestrator/heartbeat", "topic write umlbot/car/_reply/#"]
    motor = acl.split("user umlbot-motor\n", 1)[1].split("\n\n", 1)[0]
    assert "Bell" not in motor


def test_an_unknown_kind_is_refused_with_the_installed_ones(tmp_path: Path) -> None:
    result = run_install("--root", str(tmp_path / "root"), "--no-venv", "--services", "motor laser")
    assert result.returncode != 0
    installed = "motor sonar servo gpio stereo ros2 buzzer, all"
    assert f"unknown service kind 'laser' (installed: {installed})" in result.stderr
    result = run_install("--root", str(tmp_path / "root"), "--no-venv", "--services", "motor ../x")
    assert result.returncode != 0 and "bad service kind name '../x'" in result.stderr
    assert not (tmp_path / "root").exists()
