"""scripts/system-packages.sh: what `make test` installs first, and how it stops when it cannot."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "system-packages.sh"
#: Debian package -> the program the script looks for.
PROGRAMS = {"mosquitto": "mosquitto", "graphviz": "dot", "openssl": "openssl",
            "systemd": "systemd-analyze", "chromium": "chromium", "chromium-driver": "chromedriver"}


def run(path: str, *args: str) -> subprocess.CompletedProcess[str]:
    bash = shutil.which("bash")
    assert bash is not None
    return subprocess.run([bash, str(SCRIPT), *args], capture_output=True, text=True, timeout=30,
                          check=False, env={"PATH": path})


def tools(folder: Path, **scripts: str) -> str:
    """A PATH of one folder holding only `env` and the given shell scripts."""
    folder.mkdir()
    env = shutil.which("env")
    assert env is not None
    (folder / "env").symlink_to(env)
    for name, body in scripts.items():
        (folder / name).write_text(f"#!/bin/sh\n{body}\n", encoding="utf-8")
        (folder / name).chmod(0o755)
    return str(folder)


def test_the_script_looks_for_the_documented_packages() -> None:
    text = SCRIPT.read_text(encoding="utf-8")
    assert dict(re.findall(r"have ([\w-]+) .*\|\| missing\+=\(([\w-]+)\)", text)) == {
        program: package for package, program in PROGRAMS.items()}
    readme = (ROOT / "README.md").read_text(encoding="utf-8").split("## Set-up", 1)[1].split("\n## ")[0]
    for package in PROGRAMS:
        assert f"`{package}`" in readme


def test_make_test_runs_it_first_and_make_sim_does_not() -> None:
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    assert re.search(r"^test: system-packages ", makefile, re.M)
    assert re.search(r"^pytest: system-packages ", makefile, re.M)
    assert re.search(r"^system-packages:\n\t@scripts/system-packages.sh\n", makefile, re.M)
    sim = re.search(r"^sim:(.*)", makefile, re.M)
    assert sim is not None and "system-packages" not in sim.group(1)
    assert "make test" in (ROOT / ".ci" / "run").read_text(encoding="utf-8")


def test_check_agrees_with_what_is_installed() -> None:
    path = "/usr/local/bin:/usr/bin:/bin:/usr/sbin:/sbin"
    result = run(path, "--check")
    missing = [package for package, program in PROGRAMS.items() if shutil.which(program, path=path) is None]
    if missing:
        assert result.returncode == 1
        assert f"missing Debian packages: {' '.join(missing)} (--check installs nothing)" in result.stderr
    else:
        assert (result.returncode, result.stdout, result.stderr) == (0, "", "")


def test_without_apt_get_it_names_the_packages_and_stops(tmp_path: Path) -> None:
    result = run(tools(tmp_path / "bin", id="echo 0"))
    assert result.returncode == 1
    missing = [p for p in PROGRAMS if not (p == "mosquitto" and Path("/usr/sbin/mosquitto").exists())]
    names = " ".join(missing)
    assert result.stderr.splitlines() == [
        f"system-packages.sh: missing Debian packages: {names} (no apt-get on this machine)",
        f"system-packages.sh: install them as root: apt-get install --no-install-recommends {names}",
    ]


def test_not_root_and_no_sudo_stops_before_apt_get(tmp_path: Path) -> None:
    marker = tmp_path / "apt-get-ran"
    path = tools(tmp_path / "bin", id="echo 1000", **{"apt-get": f": >{marker}"})
    result = run(path)
    assert result.returncode == 1
    assert "(not root and no sudo)" in result.stderr
    assert "install them as root: apt-get install --no-install-recommends" in result.stderr
    assert not marker.exists()


def test_a_failing_apt_get_is_reported(tmp_path: Path) -> None:
    path = tools(tmp_path / "bin", id="echo 0", **{"apt-get": "exit 100"})
    result = run(path)
    assert result.returncode == 1
    assert "(apt-get update failed)" in result.stderr


def test_apt_get_is_called_noninteractively_with_the_missing_packages(tmp_path: Path) -> None:
    log = tmp_path / "apt.log"
    path = tools(tmp_path / "bin", id="echo 0", **{"apt-get": f'echo "$DEBIAN_FRONTEND $*" >>{log}'})
    result = run(path)
    # the fake apt-get installs nothing, so the script says they are still missing
    assert result.returncode == 1 and "(still missing after apt-get install)" in result.stderr
    calls = log.read_text(encoding="utf-8").splitlines()
    assert calls[0] == "noninteractive update -qq"
    assert calls[1].startswith("noninteractive install -y -qq --no-install-recommends graphviz openssl")
