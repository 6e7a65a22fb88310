#!/usr/bin/env bash
# Install umlbot on a robot: a virtual environment under /opt, the compiled model and the
# deployment, /etc/umlbot/umlbot.env, the unprivileged `umlbot` user, the systemd units, enabled so
# the car drives on boot, and Mosquitto's conf.d/umlbot-nodelay.conf (set_tcp_nodelay true).
# Run as root on the Raspberry Pi:
#
#   sudo deploy/install.sh --model out/robot_car.json --deployment models/robot_car/deployment.yaml
#
# With --root DIR everything goes under DIR (an SD-card image, a test tree): the host's systemd is
# not touched, units are enabled by creating the same symlinks `systemctl enable` would.
set -euo pipefail

usage() {
    cat <<'EOF'
usage: install.sh [options]
  --root DIR          install under DIR instead of / (no systemctl, no user creation on the host)
  --prefix DIR        installation directory (default /opt/umlbot)
  --source DIR        umlbot source checkout to install (default: the one holding this script)
  --model FILE        compiled model (`umlbot compile MODEL -o FILE`); enables the orchestrator
  --deployment FILE   deployment file (plain or YAML)
  --robot ID          robot id written to umlbot.env (default: car)
  --broker URL        default broker URL written to umlbot.env (default: mqtt://127.0.0.1:1883)
  --driver NAME       driver for the services: auto (default: lgpio on a Pi 5, pigpio where
                      pigpiod runs), pigpio, lgpio, mock or sim
  --services "K..."   service kinds to enable (default: "motor sonar servo gpio"; "all" is
                      every kind in one process, for small boards); a plugin's kinds too
  --plugin SPEC       also pip-install SPEC (a plugin's folder, wheel or requirement) into the
                      venv; repeatable. Its service kinds can then be named in --services
  --embedded-broker   also enable umlbot-broker.service (the embedded amqtt broker)
  --secure            one MQTT user per service and for the orchestrator (deploy/broker_auth.py):
                      /etc/umlbot/<role>.env, Mosquitto's conf.d/umlbot.conf, umlbot.passwd and
                      umlbot.acl, and the embedded broker's password and ACL files (needs
                      --deployment)
  --no-venv           do not create the virtual environment (one exists, or a test)
  --no-enable         install the units but do not enable them
  --start             start umlbot.target at the end (not with --root)
  --python EXE        Python 3.11+ used to create the venv (default: python3)
  -h, --help          this help
EOF
}

ROOT=""
PREFIX=/opt/umlbot
SOURCE="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
MODEL=""
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

while [ $# -gt 0 ]; do
    case "$1" in
        --root) ROOT="${2%/}"; shift 2 ;;
        --prefix) PREFIX="${2%/}"; shift 2 ;;
        --source) SOURCE="$2"; shift 2 ;;
        --model) MODEL="$2"; shift 2 ;;
        --deployment) DEPLOYMENT="$2"; shift 2 ;;
        --robot) ROBOT="$2"; shift 2 ;;
        --broker) BROKER="$2"; shift 2 ;;
        --driver) DRIVER="$2"; shift 2 ;;
        --services) SERVICES="$2"; shift 2 ;;
        --plugin) PLUGINS+=("$2"); shift 2 ;;
        --embedded-broker) EMBEDDED_BROKER=1; shift ;;
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

case "$PREFIX" in /*) ;; *) die "--prefix must be an absolute path" ;; esac
for kind in $SERVICES; do  # the name goes into a unit name: checked against the installed kinds below
    [[ "$kind" =~ ^[a-z][a-z0-9_]*$ ]] || die "bad service kind name '$kind' (lower-case letters, digits, _)"
done
case "$DRIVER" in auto|pigpio|lgpio|mock|sim) ;; *) die "unknown driver '$DRIVER' (auto, pigpio, lgpio, mock or sim)" ;; esac
[ -z "$MODEL" ] || [ -f "$MODEL" ] || die "compiled model $MODEL not found"
[ -z "$DEPLOYMENT" ] || [ -f "$DEPLOYMENT" ] || die "deployment $DEPLOYMENT not found"
[ -f "$SOURCE/pyproject.toml" ] || die "$SOURCE is not an umlbot checkout (no pyproject.toml)"
if [ "$VENV" -eq 0 ] && [ "${#PLUGINS[@]}" -gt 0 ]; then die "--plugin needs the venv (drop --no-venv)"; fi
if [ "$SECURE" -eq 1 ] && [ -z "$DEPLOYMENT" ]; then die "--secure needs --deployment"; fi
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
KINDS="$(cd "$SOURCE" && "$PY" -c 'from umlbot.library import service_kinds; print(" ".join(service_kinds()))')" \
    || die "cannot list the service kinds with $PY (is umlbot installed for it?)"
for kind in $SERVICES; do
    case " $KINDS all " in *" $kind "*) ;; *) die "unknown service kind '$kind' (installed: $KINDS, all)" ;; esac
done

UNITDIR="$ROOT/etc/systemd/system"
ETC_PATH=/etc/umlbot
ETC="$ROOT$ETC_PATH"

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
MODEL_PATH="$PREFIX/robot/model.json"
DEPLOYMENT_PATH="$PREFIX/robot/deployment.yaml"
if [ -n "$MODEL" ]; then
    MODEL_PATH="$PREFIX/robot/$(basename "$MODEL")"
    install -m 0644 "$MODEL" "$ROOT$MODEL_PATH"
fi
if [ -n "$DEPLOYMENT" ]; then
    DEPLOYMENT_PATH="$PREFIX/robot/$(basename "$DEPLOYMENT")"
    install -m 0644 "$DEPLOYMENT" "$ROOT$DEPLOYMENT_PATH"
fi

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
if [ -f "$SOURCE/deploy/broker_auth.py" ]; then install -m 0755 "$SOURCE/deploy/broker_auth.py" "$DEST/share/broker_auth.py"; fi

# 4. Mosquitto, always: send small packets at once (see umlbot-nodelay.conf). Then broker users
#    and ACLs (--secure): per-role env files with each role's own MQTT user.
install -d -m 0755 "$ROOT/etc/mosquitto/conf.d"
install -m 0644 "$SOURCE/deploy/mosquitto/umlbot-nodelay.conf" "$ROOT/etc/mosquitto/conf.d/umlbot-nodelay.conf"
BROKER_ARGS="--bind 127.0.0.1 --port 1883"
if [ "$SECURE" -eq 1 ]; then
    AUTH="$ETC/auth"
    hostport="${BROKER#*://}"; hostport="${hostport%%/*}"
    host="${hostport%:*}"; port="${hostport##*:}"
    if [ "$port" = "$hostport" ]; then port=1883; fi
    tls=(); case "$BROKER" in mqtts://*) tls=(--tls) ;; esac
    install -d -m 0750 "$AUTH"
    "$PY" "$SOURCE/deploy/broker_auth.py" --deployment "$DEPLOYMENT" --robot "$ROBOT" --out "$AUTH" \
        --host "$host" --port "$port" "${tls[@]}"
    for kind in $SERVICES; do
        if [ "$kind" != all ] && [ ! -f "$AUTH/$kind.env" ]; then
            say "warning: the deployment has no component of service kind '$kind': its service serves nothing"
        fi
    done
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
    BROKER_ARGS="--bind 127.0.0.1 --port $port --passwd $ETC_PATH/auth/amqtt.passwd --acl $ETC_PATH/auth/amqtt-acl.yaml"
    say "broker users written to /etc/umlbot/auth (operator.env and monitor.env are for people)"
fi

# 5. /etc/umlbot/umlbot.env: written once, never overwritten (it may hold credentials).
ENVFILE="$ETC/umlbot.env"
if [ -e "$ENVFILE" ]; then
    say "keeping existing $ENVFILE"
else
    umask 027
    cat >"$ENVFILE" <<EOF
# /etc/umlbot/umlbot.env — read by every umlbot unit. Keep it root:umlbot 0640: the broker URL
# may carry a password. /etc/umlbot/<role>.env (a service kind, all, orchestrator) may override
# UMLBOT_BROKER with that role's own MQTT user (see docs/security.md).
UMLBOT_ROBOT=$ROBOT
UMLBOT_BROKER=$BROKER
UMLBOT_DEPLOYMENT=$DEPLOYMENT_PATH
UMLBOT_COMPILED=$MODEL_PATH
UMLBOT_SERVICE_ARGS=--driver $DRIVER
UMLBOT_RUN_ARGS=
UMLBOT_BROKER_ARGS=$BROKER_ARGS
UMLBOT_LOG_LEVEL=INFO
EOF
    umask 022
    chmod 0640 "$ENVFILE"
fi
if [ -z "$ROOT" ] && id umlbot >/dev/null 2>&1; then
    chgrp -R umlbot "$ETC"
fi

# 6. The units, with the prefix filled in.
for unit in "$SOURCE"/deploy/systemd/*.service "$SOURCE"/deploy/systemd/*.target; do
    sed "s#/opt/umlbot#$PREFIX#g" "$unit" >"$UNITDIR/$(basename "$unit")"
    chmod 0644 "$UNITDIR/$(basename "$unit")"
done

# 7. Enable: umlbot.target on boot, and under it every service kind and the orchestrator.
WANTED=()
for kind in $SERVICES; do WANTED+=("umlbot-service@$kind.service"); done
if [ -n "$MODEL" ]; then WANTED+=(umlbot-orchestrator.service); fi
if [ "$EMBEDDED_BROKER" -eq 1 ]; then WANTED+=(umlbot-broker.service); fi

if [ "$ENABLE" -eq 1 ]; then
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
