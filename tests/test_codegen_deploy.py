"""deploy/install.sh --program: the generated orchestrator installed as the orchestrator unit."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).parent.parent
INSTALL = REPO / "deploy" / "install.sh"


def _install(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", str(INSTALL), "--python", sys.executable, "--no-venv", *args],
                          capture_output=True, text=True, timeout=60, check=False)


def test_install_program_runs_it_instead_of_umlbot_run(tmp_path: Path) -> None:
    program = tmp_path / "car-orchestrator"
    program.write_text("#!/bin/sh\nexit 0\n", encoding="utf-8")
    program.chmod(0o755)
    deployment = tmp_path / "deployment.txt"
    deployment.write_text("LeftActuator=l298n\nRightActuator=l298n\n", encoding="utf-8")
    root = tmp_path / "root"
    result = _install("--root", str(root), "--program", str(program), "--deployment", str(deployment))
    assert result.returncode == 0, result.stderr
    installed = root / "opt" / "umlbot" / "bin" / "umlbot-orchestrator-program"
    assert installed.read_bytes() == program.read_bytes()
    assert stat.S_IMODE(installed.stat().st_mode) == 0o755
    units = root / "etc" / "systemd" / "system"
    dropin = units / "umlbot-orchestrator.service.d" / "30-generated-program.conf"
    lines = dropin.read_text(encoding="utf-8").splitlines()
    assert lines[1:] == ["[Service]", "ExecStart=",
                         "ExecStart=/opt/umlbot/bin/umlbot-orchestrator-program $UMLBOT_RUN_ARGS"]
    enabled = {p.name: os.readlink(p) for p in (units / "umlbot.target.wants").iterdir()}
    assert enabled["umlbot-orchestrator.service"] == "/etc/systemd/system/umlbot-orchestrator.service"
    # a re-run without --program goes back to `umlbot run`
    model = tmp_path / "car.json"
    model.write_text('{"format": 1}\n', encoding="utf-8")
    result = _install("--root", str(root), "--model", str(model), "--deployment", str(deployment))
    assert result.returncode == 0, result.stderr
    assert not dropin.exists()


def test_a_missing_or_not_executable_program_is_refused(tmp_path: Path) -> None:
    result = _install("--root", str(tmp_path / "root"), "--program", str(tmp_path / "nothing"))
    assert result.returncode != 0 and "generated program" in result.stderr and "not found" in result.stderr
    plain = tmp_path / "plain"
    plain.write_text("x", encoding="utf-8")
    result = _install("--root", str(tmp_path / "root"), "--program", str(plain))
    assert result.returncode != 0 and "is not executable" in result.stderr
