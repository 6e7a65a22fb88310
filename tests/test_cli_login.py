"""A broker that refuses the login: `umlbot call` and `umlbot monitor` stop at once and say why.

Real brokers with a password file: Mosquitto (hashed by `mosquitto_passwd -U`) and the embedded
broker (`umlbot broker --passwd`, argon2 hashes). Wrong password, unknown user and no user at all
are each refused in the broker's CONNACK ("Not authorized" / "Bad user name or password"); the
command must end with one line naming the user and the reason, long before its connect time-out.
"""

from __future__ import annotations

import os
import pwd
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import find_mosquitto, free_port, port_accepts, wait_until

from umlbot.commands.call import EXIT_REFUSED

pytestmark = pytest.mark.network

USER, PASSWORD = "alice", "right-password"
CONNECT_TIMEOUT_S = 30.0  # far longer than a refusal may take
AT_ONCE_S = 10.0  # a process start (imports) included


def _mosquitto(workdir: Path, port: int) -> list[str]:
    binary = find_mosquitto()
    assert binary, "the mosquitto binary is required (apt-get install mosquitto)"
    tool = shutil.which("mosquitto_passwd") or "/usr/bin/mosquitto_passwd"
    passwd = workdir / "mosquitto.passwd"
    passwd.write_text(f"{USER}:{PASSWORD}\n", encoding="utf-8")
    passwd.chmod(0o600)
    subprocess.run([tool, "-U", str(passwd)], check=True, capture_output=True, timeout=60)
    config = workdir / "mosquitto.conf"
    user = pwd.getpwuid(os.geteuid()).pw_name  # as root Mosquitto would drop to `mosquitto`
    config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous false\npassword_file {passwd}\n"
                      f"persistence false\nuser {user}\nlog_dest stderr\n", encoding="utf-8")
    return [binary, "-c", str(config)]


def _embedded(workdir: Path, port: int) -> list[str]:
    from pwdlib import PasswordHash
    from pwdlib.hashers.argon2 import Argon2Hasher

    passwd = workdir / "amqtt.passwd"
    passwd.write_text(f"{USER}:{PasswordHash((Argon2Hasher(),)).hash(PASSWORD)}\n", encoding="utf-8")
    return [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "WARNING",
            "broker", "--port", str(port), "--passwd", str(passwd)]


@pytest.fixture(params=["mosquitto", "amqtt"], scope="module")
def locked_broker(request: pytest.FixtureRequest,
                  tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, int]]:
    """A broker on a free port that admits only alice with her password; yields (kind, port)."""
    workdir = tmp_path_factory.mktemp(f"login-{request.param}")
    port = free_port()
    argv = _mosquitto(workdir, port) if request.param == "mosquitto" else _embedded(workdir, port)
    with (workdir / "broker.log").open("wb") as log:
        proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, cwd=workdir)
    try:
        started = wait_until(lambda: port_accepts(port) or proc.poll() is not None, timeout=20)
        assert started and proc.poll() is None, (workdir / "broker.log").read_text(errors="replace")
        yield request.param, port
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(10)


def umlbot(*args: str) -> tuple[subprocess.CompletedProcess[str], float]:
    environment = {k: v for k, v in os.environ.items() if k not in ("UMLBOT_BROKER", "UMLBOT_LOG_LEVEL")}
    began = time.monotonic()
    result = subprocess.run([sys.executable, "-c", "from umlbot.cli import main; main()", *args],
                            capture_output=True, text=True, timeout=90, env=environment, check=False)
    return result, time.monotonic() - began


LOGINS = {
    "wrong password": (f"{USER}:wrong@", f"of user '{USER}'"),
    "unknown user": ("mallory:right-password@", "of user 'mallory'"),
    "no user": ("", "without a user (anonymous)"),
}


def _assert_refused(result: subprocess.CompletedProcess[str], elapsed: float, who: str) -> None:
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr  # one line: no log lines, no retries, no traceback
    assert f"refused the login {who}: " in lines[0], result.stderr
    reason = lines[0].split(f"refused the login {who}: ", 1)[1]
    assert reason.startswith(("Not authorized", "Bad user name or password")), reason
    assert "wrong" not in lines[0] and "right-password" not in lines[0]  # no password shown
    assert elapsed < AT_ONCE_S, f"took {elapsed:.1f} s: waited for the time-out"


@pytest.mark.parametrize("login", LOGINS)
def test_call_stops_at_once_when_the_login_is_refused(locked_broker: tuple[str, int], login: str) -> None:
    kind, port = locked_broker
    credentials, who = LOGINS[login]
    # MQTT 5 names its reason code in the CONNACK; the embedded broker speaks only 3.1.1
    for query in ("", "?protocol=5") if kind == "mosquitto" else ("",):
        result, elapsed = umlbot("call", "--broker", f"mqtt://{credentials}127.0.0.1:{port}{query}",
                                 "--connect-timeout", str(CONNECT_TIMEOUT_S), "LeftActuator.dutycycle", "10")
        assert result.returncode == EXIT_REFUSED, result.stderr
        assert result.stdout == ""
        assert result.stderr.startswith("refused: the MQTT broker at ")
        _assert_refused(result, elapsed, who)


@pytest.mark.parametrize("view", [[], ["--json"]])
def test_monitor_stops_at_once_when_the_login_is_refused(locked_broker: tuple[str, int],
                                                         view: list[str]) -> None:
    result, elapsed = umlbot("monitor", *view, "--broker", f"mqtt://{USER}:wrong@127.0.0.1:{locked_broker[1]}",
                             "--connect-timeout", str(CONNECT_TIMEOUT_S))
    assert result.returncode == 1, result.stderr
    assert result.stdout == ""
    _assert_refused(result, elapsed, f"of user '{USER}'")


def test_the_right_password_is_let_in(locked_broker: tuple[str, int]) -> None:
    """The refusal above is the password's doing: with it the monitor connects and runs."""
    result, _ = umlbot("monitor", "--json", "--duration", "0.5", "--broker",
                       f"mqtt://{USER}:{PASSWORD}@127.0.0.1:{locked_broker[1]}")
    assert result.returncode == 0, result.stderr
    assert "refused" not in result.stderr
