#!/usr/bin/env bash
# The Debian packages `make test` needs besides Python: Mosquitto (the tests start their own),
# Graphviz's `dot` (SVG diagrams), openssl (test certificates), systemd-analyze (unit checks),
# chromium and chromium-driver (the studio's browser tests drive /usr/bin/chromium).
#
# Installs the missing ones with apt-get (through sudo when not root). When it cannot (no apt-get,
# neither root nor sudo, or apt-get fails), it names the missing packages and the command that
# installs them, and exits 1. With --check it only reports, installing nothing. `make sim` needs
# none of these.
set -euo pipefail

CHECK_ONLY=0
case "${1:-}" in
    "") ;;
    --check) CHECK_ONLY=1 ;;
    -h|--help) sed -n '2,9p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "system-packages.sh: unknown option $1 (--check, --help)" >&2; exit 2 ;;
esac

have() { command -v "$1" >/dev/null 2>&1; }

# The Debian packages whose program is not there (Mosquitto lives in /usr/sbin, often not on
# a user's PATH).
find_missing() {
    missing=()
    have mosquitto || [ -x /usr/sbin/mosquitto ] || missing+=(mosquitto)
    have dot || missing+=(graphviz)
    have openssl || missing+=(openssl)
    have systemd-analyze || missing+=(systemd)
    have chromium || missing+=(chromium)
    have chromedriver || missing+=(chromium-driver)
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
    SUDO=(sudo)
fi
echo "system-packages.sh: installing from Debian's packages: ${missing[*]}"
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq \
    || cannot "apt-get update failed"
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" || cannot "apt-get install failed"
find_missing
[ ${#missing[@]} -eq 0 ] || cannot "still missing after apt-get install"
