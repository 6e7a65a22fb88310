#!/usr/bin/env python3
"""Fleet set-up: the hub's users and ACL, and a robot's bridge to the hub.

On the hub (once, and again whenever a robot joins; passwords already made are kept):

    python deploy/fleet.py hub --robots car1 car2 car3 --host hub.example --out /etc/umlbot/hub

writes into `--out`:
  mosquitto.acl       the hub's `acl_file`: robot <id> reads and writes only umlbot/<id>/#
  mosquitto.passwd    the hub's `password_file` (hashed by `mosquitto_passwd -U`)
  umlbot-hub.conf     a conf.d file: TLS listener for the robots, loopback listener, users, ACL
  robot-<id>.hub      `UMLBOT_HUB=mqtts://umlbot-robot-<id>:<password>@host:8883`: copy it to
                      that robot (install.sh --hub-credentials), mode 0600
  viewer.env          `UMLBOT_BROKER=…` of umlbot-fleet-viewer (studio, monitor: reads every robot)
  operator.env        `UMLBOT_BROKER=…` of umlbot-fleet-operator (calls, signals, exit to any robot)

On a robot (deploy/install.sh --hub … calls it):

    python deploy/fleet.py bridge --robot car1 --hub mqtts://hub.example:8883 \\
        --hub-credentials robot-car1.hub --hub-ca ca.crt --out /etc/mosquitto/conf.d/umlbot-bridge.conf

No password is printed or passed on a command line.
"""

from __future__ import annotations

import argparse
import secrets
import subprocess
import sys
from pathlib import Path
from urllib.parse import quote, urlsplit

sys.path.insert(0, str(Path(__file__).resolve().parent))
from broker_auth import find_mosquitto_passwd, write_private

from umlbot.base.errors import ConfigError
from umlbot.fleet import OPERATOR, VIEWER, Hub, bridge_conf, hub_acl, hub_conf, robot_user

CERTS = Path("/etc/mosquitto/certs")


def credentials_line(key: str, scheme: str, user: str, password: str, host: str, port: int) -> str:
    return f"{key}={scheme}://{quote(user, safe='')}:{quote(password, safe='')}@{host}:{port}\n"


def hub_command(args: argparse.Namespace) -> int:
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    users = {robot_user(robot): f"robot-{robot}.hub" for robot in args.robots}
    users[VIEWER] = "viewer.env"
    users[OPERATOR] = "operator.env"
    (out / "mosquitto.acl").write_text(hub_acl(args.robots), encoding="utf-8")
    (out / "umlbot-hub.conf").write_text(
        hub_conf(Path("/etc/mosquitto/umlbot-hub.passwd"), Path("/etc/mosquitto/umlbot-hub.acl"),
                 args.tls_port, 1883,
                 {name: CERTS / name for name in ("ca.crt", "server.crt", "server.key")}),
        encoding="utf-8",
    )
    passwords: dict[str, str] = {}
    for user, name in users.items():
        file = out / name
        key = "UMLBOT_HUB" if name.endswith(".hub") else "UMLBOT_BROKER"
        passwords[user] = _existing(file, key) or secrets.token_urlsafe(24)
        write_private(file, f"# umlbot fleet hub credentials of {user}; keep it secret.\n"
                      + credentials_line(key, "mqtts", user, passwords[user], args.host, args.tls_port))
    tool = find_mosquitto_passwd()
    if tool is None:
        print("fleet.py: mosquitto_passwd not found; mosquitto.passwd not written", file=sys.stderr)
        return 1
    passwd = out / "mosquitto.passwd"
    write_private(passwd, "".join(f"{user}:{pw}\n" for user, pw in passwords.items()))
    result = subprocess.run([tool, "-U", str(passwd)], capture_output=True, text=True, timeout=120,
                            check=False)
    if result.returncode != 0:
        passwd.unlink()
        print(f"fleet.py: mosquitto_passwd -U failed: {result.stderr.strip()}", file=sys.stderr)
        return 1
    return 0


def _existing(file: Path, key: str) -> str | None:
    if not file.is_file():
        return None
    for line in file.read_text(encoding="utf-8").splitlines():
        if line.startswith(f"{key}="):
            return urlsplit(line.partition("=")[2]).password
    return None


def read_credentials(file: Path) -> tuple[str, str]:
    """User and password from a `robot-<id>.hub` file."""
    for line in file.read_text(encoding="utf-8").splitlines():
        if line.startswith("UMLBOT_HUB="):
            parts = urlsplit(line.partition("=")[2])
            if parts.username and parts.password:
                from urllib.parse import unquote

                return unquote(parts.username), unquote(parts.password)
    raise ConfigError(f"{file}: no UMLBOT_HUB=mqtts://user:password@host:port line")


def bridge_command(args: argparse.Namespace) -> int:
    hub = Hub.from_url(args.hub, args.hub_ca)
    if args.hub_credentials is not None:
        user, password = read_credentials(args.hub_credentials)
        hub = Hub(hub.host, hub.port, hub.tls, user, password, hub.ca_file)
    if hub.username is not None and hub.username != robot_user(args.robot):
        print(f"fleet.py: warning: the hub user {hub.username} is not {robot_user(args.robot)}, the user "
              "deploy/fleet.py hub makes for this robot", file=sys.stderr)
    write_private(args.out, bridge_conf(args.robot, hub))
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    sub = parser.add_subparsers(dest="command", required=True)
    hub = sub.add_parser("hub", help="the hub's users, ACL and configuration")
    hub.add_argument("--robots", nargs="+", required=True, metavar="ID", help="every robot's id")
    hub.add_argument("--host", required=True, help="the hub's name as robots reach it (in the URLs)")
    hub.add_argument("--tls-port", type=int, default=8883, help="the hub's TLS port (default 8883)")
    hub.add_argument("--out", type=Path, required=True, help="directory for the generated files")
    bridge = sub.add_parser("bridge", help="a robot's bridge configuration (a Mosquitto conf.d file)")
    bridge.add_argument("--robot", required=True, help="this robot's id")
    bridge.add_argument("--hub", required=True, help="mqtts://hub:8883 (mqtt:// only on a trusted network)")
    bridge.add_argument("--hub-credentials", type=Path, help="the robot-<id>.hub file made on the hub")
    bridge.add_argument("--hub-ca", type=Path, help="the CA certificate of the hub's TLS certificate")
    bridge.add_argument("--out", type=Path, required=True, help="the bridge configuration file to write")
    args = parser.parse_args(argv)
    try:
        return hub_command(args) if args.command == "hub" else bridge_command(args)
    except (ConfigError, OSError) as exc:
        print(f"fleet.py: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
