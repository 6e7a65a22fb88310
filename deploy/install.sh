#!/usr/bin/env bash
# Install umlbot on a robot: a virtual environment under /opt, the compiled model and the
# deployment, /etc/umlbot/umlbot.env, the unprivileged `umlbot` user, the systemd units, enabled so
# the car drives on boot, and Mosquitto's conf.d/umlbot-nodelay.conf (set_tcp_nodelay true).
# Run as root on the Raspberry Pi:
#
#   sudo deploy/install.sh --model out/robot_car.json --deployment models/robot_car/deployment.yaml
#
# With --root DIR everything goes under DIR (an SD-card image, a test tree): the host's systemd is
# not touched, units are enabled by creating the same symlinks `systemctl enable` would, and no
# venv is made (a venv only works at the path it was made at: make it on the robot).
#
# Run it again to update: /etc/umlbot/umlbot.env keeps the lines it does not manage and the values
# of the options not given this time; the options given replace their keys.
set -euo pipefail

usage() {
    cat <<'EOF'
usage: install.sh [options]
  --root DIR          install under DIR instead of / (no systemctl, no user creation on the host);
                      implies --no-venv: a venv works only at the path it was made at, so make
                      it on the robot (run install.sh there, or python3 -m venv PREFIX/venv)
  --prefix DIR        installation directory (default /opt/umlbot)
  --source DIR        umlbot source checkout to install (default: the one holding this script)
  --model FILE        compiled model (`umlbot compile MODEL -o FILE`); enables the orchestrator
  --program FILE      a generated orchestrator (`umlbot generate cpp MODEL -o DIR --build`,
                      built for the robot): installed as PREFIX/bin/umlbot-orchestrator-program
                      and run by umlbot-orchestrator.service instead of `umlbot run` (a drop-in,
                      rewritten on every run: a re-run without --program goes back to Python)
  --deployment FILE   deployment file (plain or YAML)
  --robot ID          robot id written to umlbot.env (default: car)
  --broker URL        default broker URL written to umlbot.env (default: mqtt://127.0.0.1:1883)
  --driver NAME       driver for the services: auto (default: lgpio on a Pi 5, pigpio where
                      pigpiod runs), pigpio, lgpio, mock or sim
                      (on a re-run, --robot, --broker, --driver, --model and --deployment update
                      their keys in an existing umlbot.env; its other lines are kept)
  --services "K..."   service kinds to enable: motor, sonar, servo, gpio and the kinds of the
                      plugins in the venv (--plugin; `umlbot plugins` lists them), or "all"
                      for every kind in one process (small boards). Default: the kinds the
                      deployment uses, or "motor sonar servo gpio" without one. A kind the
                      deployment does not use is refused (its service would fail at start)
  --plugin SPEC       also pip-install SPEC (a plugin's folder, wheel or requirement) into the
                      venv; repeatable. Its service kinds can then be named in --services
  --embedded-broker   also enable umlbot-broker.service (the embedded amqtt broker)
  --secure            one MQTT user per service and for the orchestrator (deploy/broker_auth.py):
                      /etc/umlbot/<role>.env, Mosquitto's conf.d/umlbot.conf, umlbot.passwd and
                      umlbot.acl, and the embedded broker's password and ACL files (needs
                      --deployment)
  --hub URL           bridge this robot's Mosquitto to a fleet hub (mqtts://hub:8883): writes
                      Mosquitto's conf.d/umlbot-bridge.conf (deploy/fleet.py bridge; docs/fleet.md)
  --hub-credentials F the robot-<id>.hub file `deploy/fleet.py hub` made for this robot
  --hub-ca FILE       the CA certificate of the hub's TLS certificate (needed for mqtts://)
  --no-venv           do not create the virtual environment (one exists, or a test); implied
                      by --root
  --no-enable         install the units but do not enable them
  --start             start umlbot.target at the end (not with --root)
  --python EXE        Python 3.11+ used to create the venv (default: python3)
  -h, --help          this help
EOF
}

ROOT=""
PREFIX=/opt/umlbot
GIVEN=" "  # the options given on this command line (they update an existing umlbot.env)
SOURCE="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
MODEL=""
PROGRAM=""
DEPLOYMENT=""
ROBOT=car
BROKER=mqtt://127.0.0.1:1883
DRIVER=auto
SERVICES="motor sonar servo gpio"
EMBEDDED_BROKER=0
SECURE=0
VENV=1
ENABLE=1
START=0
PYTHON=python3
PLUGINS=()
HUB=""
HUB_CREDENTIALS=""
HUB_CA=""

while [ $# -gt 0 ]; do
    case "$1" in
        --root) ROOT="${2%/}"; shift 2 ;;
        --prefix) PREFIX="${2%/}"; shift 2 ;;
        --source) SOURCE="$2"; shift 2 ;;
        --model) MODEL="$2"; shift 2 ;;
        --program) PROGRAM="$2"; shift 2 ;;
        --deployment) DEPLOYMENT="$2"; shift 2 ;;
        --robot) ROBOT="$2"; GIVEN+="robot "; shift 2 ;;
        --broker) BROKER="$2"; GIVEN+="broker "; shift 2 ;;
        --driver) DRIVER="$2"; GIVEN+="driver "; shift 2 ;;
        --services) SERVICES="$2"; GIVEN+="services "; shift 2 ;;
        --plugin) PLUGINS+=("$2"); shift 2 ;;
        --embedded-broker) EMBEDDED_BROKER=1; shift ;;
        --hub) HUB="$2"; shift 2 ;;
        --hub-credentials) HUB_CREDENTIALS="$2"; shift 2 ;;
        --hub-ca) HUB_CA="$2"; shift 2 ;;
        --secure) SECURE=1; shift ;;
        --no-venv) VENV=0; shift ;;
        --no-enable) ENABLE=0; shift ;;
        --start) START=1; shift ;;
        --python) PYTHON="$2"; shift 2 ;;
        -h|--help) usage; exit 0 ;;
        *) echo "install.sh: unknown option $1" >&2; usage >&2; exit 2 ;;
    esac
done

die() { echo "install.sh: $*" >&2; exit 1; }
say() { echo "install.sh: $*"; }
given() { case "$GIVEN" in *" $1 "*) return 0 ;; esac; return 1; }

# umlbot.env is read by systemd as KEY=VALUE lines. env_get FILE KEY prints KEY's value (the first
# line that sets it) and fails when the file or the key is missing.
env_get() {
    local line
    [ -f "$1" ] || return 1
    while IFS= read -r line || [ -n "$line" ]; do
        case "$line" in "$2="*) printf '%s\n' "${line#*=}"; return 0 ;; esac
    done <"$1"
    return 1
}
# set_arg "ARGS" --opt VALUE: ARGS with --opt's value replaced (or --opt VALUE added); others kept.
set_arg() {
    local words out=() found=0 i=0
    read -ra words <<<"$1"
    while [ "$i" -lt "${#words[@]}" ]; do
        case "${words[$i]}" in
            "$2") out+=("$2" "$3"); found=1; i=$((i + 2)) ;;
            "$2="*) out+=("$2" "$3"); found=1; i=$((i + 1)) ;;
            *) out+=("${words[$i]}"); i=$((i + 1)) ;;
        esac
    done
    [ "$found" -eq 1 ] || out+=("$2" "$3")
    printf '%s\n' "${out[*]}"
}

case "$PREFIX" in /*) ;; *) die "--prefix must be an absolute path" ;; esac
for kind in $SERVICES; do  # the name goes into a unit name: checked against the installed kinds below
    [[ "$kind" =~ ^[a-z][a-z0-9_]*$ ]] || die "bad service kind name '$kind' (lower-case letters, digits, _)"
done
case " $SERVICES " in
    *" all "*) [ "$(echo $SERVICES)" = all ] || die "--services all already serves every kind: give it alone (not '$SERVICES')" ;;
esac
case "$DRIVER" in auto|pigpio|lgpio|mock|sim) ;; *) die "unknown driver '$DRIVER' (auto, pigpio, lgpio, mock or sim)" ;; esac
[ -z "$MODEL" ] || [ -f "$MODEL" ] || die "compiled model $MODEL not found"
[ -z "$PROGRAM" ] || [ -f "$PROGRAM" ] || die "generated program $PROGRAM not found"
[ -z "$PROGRAM" ] || [ -x "$PROGRAM" ] || die "generated program $PROGRAM is not executable"
[ -z "$DEPLOYMENT" ] || [ -f "$DEPLOYMENT" ] || die "deployment $DEPLOYMENT not found"
[ -f "$SOURCE/pyproject.toml" ] || die "$SOURCE is not an umlbot checkout (no pyproject.toml)"
[[ "$ROBOT" =~ ^[A-Za-z0-9_][A-Za-z0-9_.-]*$ ]] || die "bad robot id '$ROBOT' (letters, digits, _ . -)"
case "$BROKER" in *[[:space:]]*|"") die "bad broker URL '$BROKER'" ;; esac
if [ -n "$ROOT" ] && [ "${#PLUGINS[@]}" -gt 0 ]; then
    die "--plugin needs the venv, which --root does not make (install the plugin on the robot)"
fi
if [ "$VENV" -eq 0 ] && [ "${#PLUGINS[@]}" -gt 0 ]; then die "--plugin needs the venv (drop --no-venv)"; fi
if [ -n "$ROOT" ] && [ "$VENV" -eq 1 ]; then
    # A venv's scripts name the path it was made at: one made under DIR would not run on the robot.
    say "--root: no venv is made (it would not work at $PREFIX/venv on the robot; make it there)"
    VENV=0
fi
if [ "$SECURE" -eq 1 ] && [ -z "$DEPLOYMENT" ]; then die "--secure needs --deployment"; fi
if [ -n "$HUB" ]; then
    case "$HUB" in
        mqtts://*@*|mqtt://*@*) die "--hub takes no user:password (it would show in the process list): give --hub-credentials FILE" ;;
        mqtts://?*) [ -n "$HUB_CA" ] || die "--hub mqtts://… needs --hub-ca FILE (the CA of the hub's certificate)" ;;
        mqtt://?*) ;;
        *) die "bad hub URL '$HUB' (mqtts://host[:port])" ;;
    esac
    [ -z "$HUB_CREDENTIALS" ] || [ -f "$HUB_CREDENTIALS" ] || die "hub credentials $HUB_CREDENTIALS not found"
    [ -z "$HUB_CA" ] || [ -f "$HUB_CA" ] || die "hub CA certificate $HUB_CA not found"
elif [ -n "$HUB_CREDENTIALS$HUB_CA" ]; then
    die "--hub-credentials and --hub-ca go with --hub URL"
fi
case "$BROKER" in
    *@*) if [ "$SECURE" -eq 1 ]; then die "--secure makes the credentials: give --broker without user:password"; fi ;;
esac

LIVE=0
if [ -z "$ROOT" ] && [ -d /run/systemd/system ]; then LIVE=1; fi
if [ -z "$ROOT" ] && [ "$(id -u)" -ne 0 ]; then die "run as root (or give --root DIR)"; fi

DEST="$ROOT$PREFIX"

# The virtual environment first, with umlbot from the source checkout and the plugins: the service
# kinds are those it has (built-ins and plugins), checked before anything else is written.
if [ "$VENV" -eq 1 ]; then
    "$PYTHON" -c 'import sys; assert sys.version_info >= (3, 11), "umlbot needs Python 3.11+"'
    say "creating $DEST/venv and installing umlbot from $SOURCE"
    install -d -m 0755 "$DEST"
    "$PYTHON" -m venv "$DEST/venv"
    "$DEST/venv/bin/python" -m pip install --quiet --upgrade pip
    # the `pi` extra brings the pigpio and lgpio libraries the hardware drivers use
    "$DEST/venv/bin/python" -m pip install --quiet "$SOURCE[pi]"
    for plugin in "${PLUGINS[@]}"; do
        say "installing the plugin $plugin"
        "$DEST/venv/bin/python" -m pip install --quiet "$plugin"
    done
    PY="$DEST/venv/bin/python"
else
    PY="$PYTHON"  # --no-venv: umlbot is installed for this Python (or checked from the source)
fi
KINDS="$(cd "$SOURCE" && "$PY" -c 'from umlbot.base.catalog import service_kinds; print(" ".join(service_kinds()))')" \
    || die "cannot list the service kinds with $PY (is umlbot installed for it?)"
for kind in $SERVICES; do
    case " $KINDS all " in *" $kind "*) ;; *) die "unknown service kind '$kind' (installed: $KINDS, all)" ;; esac
done

UNITDIR="$ROOT/etc/systemd/system"
ETC_PATH=/etc/umlbot
ETC="$ROOT$ETC_PATH"
ENVFILE="$ETC/umlbot.env"

# An update keeps what the existing umlbot.env says for the options not given this time.
MODEL_PATH="$PREFIX/robot/model.json"
DEPLOYMENT_PATH="$PREFIX/robot/deployment.yaml"
if [ -n "$MODEL" ]; then MODEL_PATH="$PREFIX/robot/$(basename "$MODEL")"; fi
if [ -n "$DEPLOYMENT" ]; then DEPLOYMENT_PATH="$PREFIX/robot/$(basename "$DEPLOYMENT")"; fi
if [ -f "$ENVFILE" ]; then
    if ! given robot && value="$(env_get "$ENVFILE" UMLBOT_ROBOT)"; then ROBOT="$value"; fi
    if ! given broker && value="$(env_get "$ENVFILE" UMLBOT_BROKER)"; then BROKER="$value"; fi
    if [ -z "$MODEL" ] && value="$(env_get "$ENVFILE" UMLBOT_COMPILED)"; then MODEL_PATH="$value"; fi
    if [ -z "$DEPLOYMENT" ] && value="$(env_get "$ENVFILE" UMLBOT_DEPLOYMENT)"; then DEPLOYMENT_PATH="$value"; fi
fi

# The service kinds to enable are those the deployment uses: a service with no component to serve
# exits at once ("the deployment has no component served by …"), so such a kind is refused here.
CHECKED_DEPLOYMENT="$DEPLOYMENT"
if [ -z "$CHECKED_DEPLOYMENT" ] && [ -n "$DEPLOYMENT_PATH" ] && [ -f "$ROOT$DEPLOYMENT_PATH" ]; then
    CHECKED_DEPLOYMENT="$ROOT$DEPLOYMENT_PATH"  # an update: the installed deployment
fi
CHECKED_DEPLOYMENT="${CHECKED_DEPLOYMENT:+$(realpath "$CHECKED_DEPLOYMENT")}"  # read from $SOURCE
if [ -n "$CHECKED_DEPLOYMENT" ]; then
    USED="$(cd "$SOURCE" && "$PY" - "$CHECKED_DEPLOYMENT" <<'PYEOF'
import sys
from umlbot.base.deployment import load_deployment
from umlbot.base.errors import UmlbotError
from umlbot.base.catalog import service_kinds
try:
    used = {c.implementation.service for c in load_deployment(sys.argv[1]).components.values()}
except (UmlbotError, OSError) as exc:
    sys.exit(f"install.sh: {exc}")
print(" ".join(k for k in service_kinds() if k in used))
PYEOF
)" || exit 1
    [ -n "$USED" ] || die "the deployment $CHECKED_DEPLOYMENT has no component"
    if given services; then
        for kind in $SERVICES; do
            case " $USED all " in
                *" $kind "*) ;;
                *) die "service kind '$kind' is not used by the deployment $CHECKED_DEPLOYMENT: its service would have nothing to serve and fail at start (the deployment uses: $USED; or all)" ;;
            esac
        done
    elif [ -L "$UNITDIR/umlbot.target.wants/umlbot-service@all.service" ]; then
        SERVICES=all  # an update of a one-process install stays one process
    else
        SERVICES="$USED"
    fi
fi

install -d -m 0755 "$DEST" "$DEST/robot" "$DEST/share/docs" "$DEST/share/mosquitto" \
    "$DEST/share/amqtt" "$UNITDIR" "$ROOT/etc/sysusers.d"
install -d -m 0750 "$ETC"

# 1. The unprivileged user (systemd-sysusers reads the same file at boot).
install -m 0644 "$SOURCE/deploy/sysusers.d/umlbot.conf" "$ROOT/etc/sysusers.d/umlbot.conf"
# The user is in group gpio for lgpio's /dev/gpiochip* (sysusers' `m` line; both steps idempotent).
if [ -z "$ROOT" ]; then
    if command -v systemd-sysusers >/dev/null 2>&1; then
        systemd-sysusers /etc/sysusers.d/umlbot.conf
    elif ! id umlbot >/dev/null 2>&1; then
        useradd --system --home-dir /var/lib/umlbot --shell /usr/sbin/nologin umlbot
    fi
    if getent group gpio >/dev/null 2>&1; then usermod -aG gpio umlbot; fi
fi

# 2. The robot: compiled model and deployment (the robot needs no model sources).
if [ -n "$MODEL" ]; then install -m 0644 "$MODEL" "$ROOT$MODEL_PATH"; fi
if [ -n "$PROGRAM" ]; then
    install -d -m 0755 "$DEST/bin"
    install -m 0755 "$PROGRAM" "$DEST/bin/umlbot-orchestrator-program"
fi
if [ -n "$DEPLOYMENT" ]; then install -m 0644 "$DEPLOYMENT" "$ROOT$DEPLOYMENT_PATH"; fi

# 3. Documentation and the broker security files, for reference on the robot.
for doc in deploy-pi.md security.md; do
    if [ -f "$SOURCE/docs/$doc" ]; then install -m 0644 "$SOURCE/docs/$doc" "$DEST/share/docs/$doc"; fi
done
for f in "$SOURCE"/deploy/mosquitto/*; do
    if [ -f "$f" ]; then install -m 0644 "$f" "$DEST/share/mosquitto/$(basename "$f")"; fi
done
for f in "$SOURCE"/deploy/amqtt/*; do
    if [ -f "$f" ]; then install -m 0644 "$f" "$DEST/share/amqtt/$(basename "$f")"; fi
done
for script in broker_auth.py fleet.py; do
    if [ -f "$SOURCE/deploy/$script" ]; then install -m 0755 "$SOURCE/deploy/$script" "$DEST/share/$script"; fi
done

# 4. Mosquitto, always: send small packets at once (see umlbot-nodelay.conf). Then broker users
#    and ACLs (--secure): per-role env files with each role's own MQTT user.
install -d -m 0755 "$ROOT/etc/mosquitto/conf.d"
install -m 0644 "$SOURCE/deploy/mosquitto/umlbot-nodelay.conf" "$ROOT/etc/mosquitto/conf.d/umlbot-nodelay.conf"
# Host and port of the broker URL (scheme://[user:password@]host[:port][/…][?…]).
hostport="${BROKER#*://}"; hostport="${hostport%%/*}"; hostport="${hostport%%\?*}"; hostport="${hostport##*@}"
case "$hostport" in
    *:[0-9]*) host="${hostport%:*}"; port="${hostport##*:}" ;;
    *) host="$hostport"; case "$BROKER" in mqtts://*) port=8883 ;; *) port=1883 ;; esac ;;
esac
BROKER_ARGS="--bind 127.0.0.1 --port $port"
if [ "$SECURE" -eq 1 ]; then
    AUTH="$ETC/auth"
    tls=(); case "$BROKER" in mqtts://*) tls=(--tls) ;; esac
    install -d -m 0750 "$AUTH"
    "$PY" "$SOURCE/deploy/broker_auth.py" --deployment "$DEPLOYMENT" --robot "$ROBOT" --out "$AUTH" \
        --host "$host" --port "$port" "${tls[@]}"
    for role in $KINDS all orchestrator; do  # monitor.env and operator.env stay in auth/ (for people)
        if [ -f "$AUTH/$role.env" ]; then install -m 0640 "$AUTH/$role.env" "$ETC/$role.env"; fi
    done
    sed "s#^listener 1883 127.0.0.1#listener $port 127.0.0.1#" "$SOURCE/deploy/mosquitto/umlbot.conf" \
        >"$ROOT/etc/mosquitto/conf.d/umlbot.conf"
    install -m 0644 "$AUTH/mosquitto.acl" "$ROOT/etc/mosquitto/umlbot.acl"
    if [ -f "$AUTH/mosquitto.passwd" ]; then
        install -m 0640 "$AUTH/mosquitto.passwd" "$ROOT/etc/mosquitto/umlbot.passwd"
        if [ -z "$ROOT" ] && getent group mosquitto >/dev/null 2>&1; then
            chgrp mosquitto "$ROOT/etc/mosquitto/umlbot.passwd"
        fi
    fi
    chmod 0640 "$AUTH/amqtt.passwd"
    BROKER_ARGS="$BROKER_ARGS --passwd $ETC_PATH/auth/amqtt.passwd --acl $ETC_PATH/auth/amqtt-acl.yaml"
    say "broker users written to /etc/umlbot/auth (operator.env and monitor.env are for people)"
fi

# 4b. The bridge to a fleet hub (--hub): umlbot/<robot>/# goes out, requests come in (docs/fleet.md).
#     The file holds the robot's hub password: 0640, group mosquitto.
if [ -n "$HUB" ]; then
    bridge_args=(--robot "$ROBOT" --hub "$HUB" --out "$ROOT/etc/mosquitto/conf.d/umlbot-bridge.conf")
    if [ -n "$HUB_CA" ]; then
        install -d -m 0755 "$ROOT/etc/mosquitto/certs"
        install -m 0644 "$HUB_CA" "$ROOT/etc/mosquitto/certs/umlbot-hub-ca.crt"
        bridge_args+=(--hub-ca /etc/mosquitto/certs/umlbot-hub-ca.crt)
    fi
    if [ -n "$HUB_CREDENTIALS" ]; then bridge_args+=(--hub-credentials "$HUB_CREDENTIALS"); fi
    (cd "$SOURCE" && "$PY" "$SOURCE/deploy/fleet.py" bridge "${bridge_args[@]}") || die "cannot write the bridge configuration"
    chmod 0640 "$ROOT/etc/mosquitto/conf.d/umlbot-bridge.conf"
    if [ -z "$ROOT" ] && getent group mosquitto >/dev/null 2>&1; then
        chgrp mosquitto "$ROOT/etc/mosquitto/conf.d/umlbot-bridge.conf"
    fi
    say "bridge to the hub $HUB written to /etc/mosquitto/conf.d/umlbot-bridge.conf (robot $ROBOT)"
fi

# 5. /etc/umlbot/umlbot.env (it may hold credentials: root:umlbot 0640). Made on the first run; an
#    update sets the keys of the options given (and adds keys it lacks) and keeps every other line.
SERVICE_ARGS="--driver $DRIVER"
RUN_ARGS=""
LOG_LEVEL=INFO
if [ -f "$ENVFILE" ]; then
    if old="$(env_get "$ENVFILE" UMLBOT_SERVICE_ARGS)"; then
        SERVICE_ARGS="$old"
        if given driver; then SERVICE_ARGS="$(set_arg "$old" --driver "$DRIVER")"; fi
    fi
    if old="$(env_get "$ENVFILE" UMLBOT_BROKER_ARGS)"; then
        new="$old"
        if given broker || [ "$SECURE" -eq 1 ]; then new="$(set_arg "$new" --port "$port")"; fi
        if [ "$SECURE" -eq 1 ]; then
            new="$(set_arg "$new" --passwd "$ETC_PATH/auth/amqtt.passwd")"
            new="$(set_arg "$new" --acl "$ETC_PATH/auth/amqtt-acl.yaml")"
        fi
        BROKER_ARGS="$new"
    fi
    if value="$(env_get "$ENVFILE" UMLBOT_RUN_ARGS)"; then RUN_ARGS="$value"; fi
    if value="$(env_get "$ENVFILE" UMLBOT_LOG_LEVEL)"; then LOG_LEVEL="$value"; fi
fi
declare -A SETTING=(
    [UMLBOT_ROBOT]="$ROBOT" [UMLBOT_BROKER]="$BROKER" [UMLBOT_DEPLOYMENT]="$DEPLOYMENT_PATH"
    [UMLBOT_COMPILED]="$MODEL_PATH" [UMLBOT_SERVICE_ARGS]="$SERVICE_ARGS" [UMLBOT_RUN_ARGS]="$RUN_ARGS"
    [UMLBOT_BROKER_ARGS]="$BROKER_ARGS" [UMLBOT_LOG_LEVEL]="$LOG_LEVEL"
)
SETTING_ORDER=(UMLBOT_ROBOT UMLBOT_BROKER UMLBOT_DEPLOYMENT UMLBOT_COMPILED UMLBOT_SERVICE_ARGS
               UMLBOT_RUN_ARGS UMLBOT_BROKER_ARGS UMLBOT_LOG_LEVEL)
declare -A DONE=()
CHANGED=()
NEWENV="$ENVFILE.new"
umask 027
if [ -f "$ENVFILE" ]; then
    while IFS= read -r line || [ -n "$line" ]; do
        key="${line%%=*}"
        if [[ "$key" =~ ^[A-Z_][A-Z0-9_]*$ ]] && [ -n "${SETTING[$key]+set}" ]; then
            if [ -n "${DONE[$key]+set}" ]; then continue; fi  # said twice: keep one line, the new value
            DONE[$key]=1
            if [ "${line#*=}" != "${SETTING[$key]}" ]; then CHANGED+=("$key"); fi
            printf '%s=%s\n' "$key" "${SETTING[$key]}"
        else
            printf '%s\n' "$line"
        fi
    done <"$ENVFILE" >"$NEWENV"
else
    cat >"$NEWENV" <<'EOF'
# /etc/umlbot/umlbot.env — read by every umlbot unit. Keep it root:umlbot 0640: the broker URL
# may carry a password. /etc/umlbot/<role>.env (a service kind, all, orchestrator) may override
# UMLBOT_BROKER with that role's own MQTT user (see docs/security.md). install.sh run again sets
# the keys of the options it is given and keeps every other line.
EOF
fi
for key in "${SETTING_ORDER[@]}"; do  # new keys (first run, or an update that brings a new one)
    if [ -z "${DONE[$key]+set}" ]; then
        if [ -f "$ENVFILE" ]; then CHANGED+=("$key"); fi
        printf '%s=%s\n' "$key" "${SETTING[$key]}" >>"$NEWENV"
    fi
done
umask 022
chmod 0640 "$NEWENV"
if [ -f "$ENVFILE" ]; then
    if [ "${#CHANGED[@]}" -gt 0 ]; then say "updated ${CHANGED[*]} in $ETC_PATH/umlbot.env (its other lines kept)"
    else say "$ETC_PATH/umlbot.env is up to date"; fi
fi
mv -f "$NEWENV" "$ENVFILE"
if [ -z "$ROOT" ] && id umlbot >/dev/null 2>&1; then
    chgrp -R umlbot "$ETC"
fi

# 6. The units, with the prefix filled in.
for unit in "$SOURCE"/deploy/systemd/*.service "$SOURCE"/deploy/systemd/*.target; do
    sed "s#/opt/umlbot#$PREFIX#g" "$unit" >"$UNITDIR/$(basename "$unit")"
    chmod 0644 "$UNITDIR/$(basename "$unit")"
done

# 7. Start order, in drop-ins (rewritten on every run): the services and the orchestrator want the
#    broker they use (Mosquitto, or the embedded broker, when on this machine) and start after it;
#    the orchestrator also wants the service units of this install and starts after them.
SERVICE_UNITS=()
for kind in $SERVICES; do SERVICE_UNITS+=("umlbot-service@$kind.service"); done
BROKER_UNIT=""
if [ "$EMBEDDED_BROKER" -eq 1 ]; then
    BROKER_UNIT=umlbot-broker.service
else
    case "$host" in 127.0.0.1|localhost|"[::1]") BROKER_UNIT=mosquitto.service ;; esac
fi
for unit in umlbot-service@.service umlbot-orchestrator.service; do
    dropin="$UNITDIR/$unit.d"
    install -d -m 0755 "$dropin"
    {
        echo "# Written by deploy/install.sh on every run: the broker this robot uses."
        echo "[Unit]"
        if [ -n "$BROKER_UNIT" ]; then
            echo "Wants=$BROKER_UNIT"
            echo "After=$BROKER_UNIT"
        fi
    } >"$dropin/10-umlbot-broker.conf"
    chmod 0644 "$dropin/10-umlbot-broker.conf"
done
{
    echo "# Written by deploy/install.sh on every run: the orchestrator calls these services, so it"
    echo "# pulls them in and starts after them (and then waits until their components are online)."
    echo "[Unit]"
    echo "Wants=${SERVICE_UNITS[*]}"
    echo "After=${SERVICE_UNITS[*]}"
} >"$UNITDIR/umlbot-orchestrator.service.d/20-umlbot-services.conf"
chmod 0644 "$UNITDIR/umlbot-orchestrator.service.d/20-umlbot-services.conf"
# the generated program instead of `umlbot run` (docs/codegen.md): the same options and exit codes
GENERATED="$UNITDIR/umlbot-orchestrator.service.d/30-generated-program.conf"
if [ -n "$PROGRAM" ]; then
    {
        echo "# Written by deploy/install.sh --program: the generated C++ orchestrator runs the model."
        echo "[Service]"
        echo "ExecStart="
        echo "ExecStart=$PREFIX/bin/umlbot-orchestrator-program \$UMLBOT_RUN_ARGS"
    } >"$GENERATED"
    chmod 0644 "$GENERATED"
else
    rm -f "$GENERATED"
fi

# 8. Enable: umlbot.target on boot, and under it every service kind and the orchestrator.
WANTED=("${SERVICE_UNITS[@]}")
if [ -n "$MODEL$PROGRAM" ]; then WANTED+=(umlbot-orchestrator.service); fi
if [ "$EMBEDDED_BROKER" -eq 1 ]; then WANTED+=(umlbot-broker.service); fi

if [ "$ENABLE" -eq 1 ]; then
    # An update that enables fewer kinds disables the others (they would fail or serve twice).
    for link in "$UNITDIR"/umlbot.target.wants/umlbot-service@*.service; do
        [ -L "$link" ] || continue
        case " ${WANTED[*]} " in *" $(basename "$link") "*) continue ;; esac
        say "disabling $(basename "$link") (not in --services)"
        if [ "$LIVE" -eq 1 ]; then systemctl disable "$(basename "$link")"; else rm -f "$link"; fi
    done
    if [ "$LIVE" -eq 1 ]; then
        systemctl daemon-reload
        systemctl enable umlbot.target "${WANTED[@]}"
    else
        # Offline: the symlinks `systemctl enable` makes, from each unit's WantedBy=.
        install -d -m 0755 "$UNITDIR/multi-user.target.wants" "$UNITDIR/umlbot.target.wants"
        ln -sfn /etc/systemd/system/umlbot.target "$UNITDIR/multi-user.target.wants/umlbot.target"
        for unit in "${WANTED[@]}"; do
            file="$unit"
            case "$unit" in *@*.service) file="${unit%%@*}@.service" ;; esac
            ln -sfn "/etc/systemd/system/$file" "$UNITDIR/umlbot.target.wants/$unit"
        done
        if [ -z "$ROOT" ]; then say "systemd is not running: units enabled by symlink, run 'systemctl daemon-reload' later"; fi
    fi
fi

if [ "$START" -eq 1 ]; then
    [ "$LIVE" -eq 1 ] || die "--start needs a running systemd and no --root"
    systemctl restart umlbot.target
fi

say "installed into ${ROOT:-/}: $PREFIX, /etc/umlbot, /etc/systemd/system (${WANTED[*]})"
