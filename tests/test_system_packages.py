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
            "systemd": "systemd-analyze", "systemd-container": "systemd-nspawn", "debootstrap": "debootstrap",
            "chromium": "chromium", "chromium-driver": "chromedriver",
            "nodejs": "node", "npm": "npm", "g++": "g++", "cmake": "cmake", "ninja-build": "ninja"}


def run(path: str, *args: str, python: str | None = None) -> subprocess.CompletedProcess[str]:
    bash = shutil.which("bash")
    assert bash is not None
    env = {"PATH": path} if python is None else {"PATH": path, "PYTHON": python}
    return subprocess.run([bash, str(SCRIPT), *args], capture_output=True, text=True, timeout=30,
                          check=False, env=env)


DEBIAN_PYTHON = "/usr/bin/python3"


def without_ensurepip(folder: Path, python: str) -> str:
    """A `python3` that runs `python` as a machine without Debian's python3-venv has it: its
    ensurepip cannot be imported, so `python3 -m venv` fails."""
    folder.mkdir()
    (folder / "ensurepip.py").write_text(
        'raise ModuleNotFoundError("No module named \'ensurepip\'", name="ensurepip")\n', encoding="utf-8")
    wrapper = folder / "python3"
    wrapper.write_text(f'#!/bin/sh\nPYTHONPATH={folder} exec {python} "$@"\n', encoding="utf-8")
    wrapper.chmod(0o755)
    return str(wrapper)


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
    assert dict(re.findall(r"have ([\w+-]+) .*\|\| missing\+=\(([\w+-]+)\)", text)) == {
        program: package for package, program in PROGRAMS.items()}
    readme = (ROOT / "README.md").read_text(encoding="utf-8").split("## Set-up", 1)[1].split("\n## ")[0]
    for package in [*PROGRAMS, "python3-venv"]:
        assert f"`{package}`" in readme


def test_make_test_runs_it_first_and_make_sim_does_not() -> None:
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    assert re.search(r"^test: system-packages ", makefile, re.M)
    assert re.search(r"^pytest: system-packages ", makefile, re.M)
    assert re.search(r"^system-packages:\n\t@PYTHON='\$\(PYTHON\)' scripts/system-packages.sh\n",
                     makefile, re.M)
    # before `python -m venv`, which fails on Debian without python3-venv (make sim, make install)
    stamp = makefile.split("$(STAMP):", 1)[1]
    assert stamp.index("scripts/system-packages.sh --venv") < stamp.index("$(PYTHON) -m venv")
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
    # the script finds these two in /usr/sbin, which is not on this PATH
    missing = [p for p in PROGRAMS
               if not (p in ("mosquitto", "debootstrap") and Path("/usr/sbin", p).exists())]
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


def test_sudo_that_wants_a_password_without_a_terminal_is_named(tmp_path: Path) -> None:
    marker = tmp_path / "apt-get-ran"
    # `sudo -n` fails as sudo does when it would have to ask for a password
    path = tools(tmp_path / "bin", id="echo 1000", sudo='[ "$1" = -n ] && exit 1; "$@"',
                 **{"apt-get": f": >{marker}"})
    result = subprocess.run([shutil.which("bash") or "bash", str(SCRIPT)], capture_output=True, text=True,
                            timeout=30, check=False, env={"PATH": path}, stdin=subprocess.DEVNULL)
    assert result.returncode == 1
    assert "(not root, and sudo wants a password but there is no terminal to ask on)" in result.stderr
    assert not marker.exists()


def test_passwordless_sudo_runs_apt_get_without_asking(tmp_path: Path) -> None:
    log = tmp_path / "apt.log"
    sudo = f'echo "sudo $*" >>{log}; [ "$1" = -n ] && shift; "$@"'
    path = tools(tmp_path / "bin", id="echo 1000", sudo=sudo, **{"apt-get": "exit 0"})
    result = run(path)
    assert result.returncode == 1 and "(still missing after apt-get install)" in result.stderr
    calls = log.read_text(encoding="utf-8").splitlines()
    assert calls[0] == "sudo -n true"
    assert calls[1].startswith("sudo -n env DEBIAN_FRONTEND=noninteractive apt-get update")


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


# --- python3-venv: Debian's Python cannot create .venv without it ----------------------------------


def test_debian_ships_ensurepip_in_the_venv_package() -> None:
    # the premise of the check: without python3.X-venv, Debian's Python has no ensurepip, and
    # `python3 -m venv` stops ("ensurepip is not available")
    where = subprocess.run([DEBIAN_PYTHON, "-c", "import ensurepip, sys; print(ensurepip.__file__); "
                            "print(*sys.version_info[:2], sep='.')"],
                           capture_output=True, text=True, timeout=30, check=True).stdout.split()
    owner = subprocess.run(["dpkg-query", "-S", where[0]], capture_output=True, text=True, timeout=30,
                           check=True).stdout
    assert owner.startswith(f"python{where[1]}-venv: ")


def test_venv_check_names_the_package_in_one_line(tmp_path: Path) -> None:
    python = without_ensurepip(tmp_path / "nopip", DEBIAN_PYTHON)
    result = run("/usr/bin:/bin", "--venv", python=python)
    assert (result.returncode, result.stdout) == (1, "")
    assert result.stderr.splitlines() == [
        f"system-packages.sh: {python} cannot create a virtual environment (no ensurepip): "
        "install Debian's python3-venv as root: apt-get install python3-venv"]


def test_venv_check_passes_for_a_python_with_ensurepip() -> None:
    assert run("/usr/bin:/bin", "--venv", python=DEBIAN_PYTHON).returncode == 0


def test_another_python_without_ensurepip_is_left_alone(tmp_path: Path) -> None:
    # a virtual environment's Python (or pyenv's) is not under /usr: Debian's package is no help
    subprocess.run([DEBIAN_PYTHON, "-m", "venv", "--without-pip", str(tmp_path / "other")], check=True,
                   timeout=60)
    python = without_ensurepip(tmp_path / "nopip", str(tmp_path / "other" / "bin" / "python3"))
    assert run("/usr/bin:/bin", "--venv", python=python).returncode == 0
    result = run(tools(tmp_path / "bin", id="echo 0"), python=python)
    assert "python3-venv" not in result.stderr


def test_make_test_installs_python3_venv_with_the_others(tmp_path: Path) -> None:
    log = tmp_path / "apt.log"
    python = without_ensurepip(tmp_path / "nopip", DEBIAN_PYTHON)
    path = tools(tmp_path / "bin", id="echo 0", **{"apt-get": f'echo "$*" >>{log}'})
    result = run(path, python=python)
    assert result.returncode == 1 and "(still missing after apt-get install)" in result.stderr
    install = log.read_text(encoding="utf-8").splitlines()[1].split()
    assert install[:5] == ["install", "-y", "-qq", "--no-install-recommends", "graphviz"]
    assert install[-1] == "python3-venv"
    checked = run(path, "--check", python=python)
    assert "install them as root: apt-get install --no-install-recommends" in checked.stderr
    assert checked.stderr.rstrip().endswith(" python3-venv")


def test_make_sim_stops_before_creating_the_venv(tmp_path: Path) -> None:
    make = shutil.which("make")
    assert make is not None
    python = without_ensurepip(tmp_path / "nopip", DEBIAN_PYTHON)
    venv = tmp_path / "venv"
    result = subprocess.run([make, "-s", "-C", str(ROOT), "sim", f"PYTHON={python}", f"VENV={venv}",
                             f"OUT={tmp_path / 'out'}"], capture_output=True, text=True, timeout=60,
                            check=False)
    assert result.returncode != 0
    assert result.stderr.splitlines()[0] == (
        f"system-packages.sh: {python} cannot create a virtual environment (no ensurepip): "
        "install Debian's python3-venv as root: apt-get install python3-venv")
    assert not venv.exists() and not (tmp_path / "out").exists()


def test_help_prints_the_whole_header() -> None:
    lines = SCRIPT.read_text(encoding="utf-8").splitlines()[1:]
    header = [line.removeprefix("#").removeprefix(" ") for line in lines[:next(
        i for i, line in enumerate(lines) if not line.startswith("#"))]]
    result = run("/usr/bin:/bin", "--help")
    assert result.returncode == 0
    assert result.stdout.splitlines() == header
    assert header[-1].endswith("exits 1.")
