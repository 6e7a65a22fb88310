#!/usr/bin/env bash
# The Debian packages `make test` needs besides Python: Mosquitto (the tests start their own),
# Graphviz's `dot` (SVG diagrams), openssl (test certificates), systemd-analyze (unit checks),
# systemd-nspawn and debootstrap (the units under a real systemd: `make test-systemd`),
# chromium and chromium-driver (the studio's browser tests drive /usr/bin/chromium), nodejs and
# npm (the studio page's TypeScript checks and unit tests), eProsima Fast DDS with cmake, ninja
# and g++ (the ROS 2 tests build a Fast DDS peer: libfastrtps-dev, libfastcdr-dev), and
# python3-venv when $PYTHON (default python3) is Debian's own Python without it: there
# `python3 -m venv` fails (no ensurepip). A pyenv or other Python has its own venv.
#
# Installs the missing ones with apt-get (through sudo when not root). When it cannot (no apt-get,
# neither root nor sudo, or apt-get fails), it names the missing packages and the command that
# installs them, and exits 1. With --check it only reports, installing nothing. With --venv it
# only checks that $PYTHON can create a virtual environment (all `make sim` needs) and, when it
# cannot, says in one line what to install and exits 1.
set -euo pipefail

CHECK_ONLY=0
VENV_ONLY=0
case "${1:-}" in
    "") ;;
    --check) CHECK_ONLY=1 ;;
    --venv) VENV_ONLY=1 ;;
    -h|--help) sed -n '2,/^[^#]/p' "$0" | sed -e '$d' -e 's/^# \{0,1\}//'; exit 0 ;;  # the header
    *) echo "system-packages.sh: unknown option $1 (--check, --venv, --help)" >&2; exit 2 ;;
esac
PYTHON="${PYTHON:-python3}"

have() { command -v "$1" >/dev/null 2>&1; }

# The Debian package that gives $PYTHON its venv (python3-venv; python3.X-venv for a Debian Python
# that is not the default python3), printed only when $PYTHON is Debian's own (its prefix is /usr,
# not a virtual environment's or pyenv's) and lacks ensurepip. Nothing when $PYTHON does not run:
# the Makefile's version check names that.
venv_package() {
    "$PYTHON" - 2>/dev/null <<'PY' || true
import os, sys
if sys.prefix == "/usr":
    try:
        import ensurepip  # Debian ships it in python3.X-venv
    except ImportError:
        version = f"{sys.version_info[0]}.{sys.version_info[1]}"
        default = os.path.realpath("/usr/bin/python3")
        print("python3-venv" if default == f"/usr/bin/python{version}" else f"python{version}-venv")
PY
}

if [ "$VENV_ONLY" -eq 1 ]; then
    package="$(venv_package)"
    [ -z "$package" ] && exit 0
    echo "system-packages.sh: $PYTHON cannot create a virtual environment (no ensurepip):" \
        "install Debian's $package as root: apt-get install $package" >&2
    exit 1
fi

# The Debian packages whose program is not there (Mosquitto lives in /usr/sbin, often not on
# a user's PATH).
find_missing() {
    missing=()
    have mosquitto || [ -x /usr/sbin/mosquitto ] || missing+=(mosquitto)
    have dot || missing+=(graphviz)
    have openssl || missing+=(openssl)
    have systemd-analyze || missing+=(systemd)
    have systemd-nspawn || missing+=(systemd-container)
    have debootstrap || [ -x /usr/sbin/debootstrap ] || missing+=(debootstrap)
    have chromium || missing+=(chromium)
    have chromedriver || missing+=(chromium-driver)
    have node || missing+=(nodejs)
    have npm || missing+=(npm)
    # C++ builds: `umlbot generate cpp` (a C++17 compiler, CMake, Ninja, libmosquitto, nlohmann-json)
    # and the ROS 2 tests' Fast DDS peer (libfastrtps-dev, libfastcdr-dev)
    have g++ || missing+=(g++)
    have cmake || missing+=(cmake)
    have ninja || missing+=(ninja-build)
    [ -f /usr/include/mosquitto.h ] || missing+=(libmosquitto-dev)
    [ -f /usr/include/nlohmann/json.hpp ] || missing+=(nlohmann-json3-dev)
    [ -f /usr/include/fastdds/dds/domain/DomainParticipant.hpp ] || missing+=(libfastrtps-dev)
    [ -f /usr/include/fastcdr/Cdr.h ] || missing+=(libfastcdr-dev)
    local venv
    venv="$(venv_package)"
    [ -z "$venv" ] || missing+=("$venv")
}
find_missing
[ ${#missing[@]} -eq 0 ] && exit 0

command_line="apt-get install --no-install-recommends ${missing[*]}"
cannot() {
    echo "system-packages.sh: missing Debian packages: ${missing[*]} ($1)" >&2
    echo "system-packages.sh: install them as root: $command_line" >&2
    exit 1
}

[ "$CHECK_ONLY" -eq 0 ] || cannot "--check installs nothing"
have apt-get || cannot "no apt-get on this machine"
SUDO=()
if [ "$(id -u)" -ne 0 ]; then
    have sudo || cannot "not root and no sudo"
    # sudo that would ask for a password with no terminal to ask on fails; say that, not "apt-get
    # update failed"
    if sudo -n true 2>/dev/null; then
        SUDO=(sudo -n)
    elif [ -t 0 ]; then
        SUDO=(sudo)
    else
        cannot "not root, and sudo wants a password but there is no terminal to ask on"
    fi
fi
echo "system-packages.sh: installing from Debian's packages: ${missing[*]}"
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq \
    || cannot "apt-get update failed"
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" || cannot "apt-get install failed"
find_missing
[ ${#missing[@]} -eq 0 ] || cannot "still missing after apt-get install"
