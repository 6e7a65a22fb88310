#!/usr/bin/env python3
"""Broker users, passwords and ACLs for one robot, written from its deployment.

One MQTT user per service kind the deployment uses (`umlbot-motor`, `umlbot-sonar`,
`umlbot-servo`, `umlbot-gpio`, and a plugin's kinds alike, e.g. `umlbot-buzzer`), `umlbot-all` for
`umlbot service all` (every kind's rights together), one for
the orchestrator, a read-only `umlbot-monitor` and a write-only `umlbot-operator` (for
`umlbot call`, `mosquitto_pub`: calls, signals and exit requests; it reads only its own replies).
Each service user may only serve the topics of the components the deployment gives its kind.
Run it with the venv's Python:

    /opt/umlbot/venv/bin/python /opt/umlbot/share/broker_auth.py \\
        --deployment /opt/umlbot/robot/deployment.yaml --robot car --out /etc/umlbot/auth

It writes into `--out`:
  mosquitto.acl      Mosquitto `acl_file`
  mosquitto.passwd   Mosquitto `password_file` (hashed by `mosquitto_passwd -U`, when installed)
  amqtt-acl.yaml     `umlbot broker --acl` (amqtt's `acl` = subscribe and `publish_acl` tables)
  amqtt.passwd       `umlbot broker --passwd` (argon2 hashes, as amqtt's FileAuthPlugin reads)
  <role>.env         `UMLBOT_BROKER=mqtt://<user>:<password>@host:port` for each role, mode 0600

Passwords are random; re-running keeps those already in the `<role>.env` files. No password is
ever printed or passed on a command line.
"""

from __future__ import annotations

import argparse
import os
import secrets
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import urlsplit


def service_kinds() -> tuple[str, ...]:
    """Every installed service kind: the built-ins and those plugins add (`umlbot plugins`)."""
    from umlbot.base.catalog import service_kinds as installed

    return installed()


def user_of(role: str) -> str:
    """The MQTT user name of a role."""
    return f"umlbot-{role}"


@dataclass
class Grants:
    """What one user may do: topic filters it may read (subscribe) and write (publish)."""

    read: list[str] = field(default_factory=list)
    write: list[str] = field(default_factory=list)


def grants(components: dict[str, str], robot: str) -> dict[str, Grants]:
    """The rights of every role; `components` maps component name -> service kind.

    One role per service kind that `components` uses (in the order of `service_kinds()`: no user
    without a purpose), then `all`, `orchestrator`, `monitor` and `operator`.

    A service serves `<Component>/call/#` and owns `<Component>/status` (its last will) and
    `<Component>/state`; it answers on the callers' reply topics under `_reply/`, and watches the
    orchestrator's status (a motor stops when the orchestrator goes offline) and heartbeat (the
    lease that keeps the motors it commanded running). The orchestrator
    calls the deployed components, reads their status and state, owns `orchestrator/#` and the
    signals. `all` (`umlbot service all`) has the rights of every service kind together.
    `monitor` reads everything and publishes nothing. `operator` (people, tools) publishes calls to
    the deployed components, signals and exit requests, and reads nothing but its own replies: it
    cannot pose as a component (`status`, `state`, replies) nor as the orchestrator (`status`).
    Every user reads its own replies: on Mosquitto through the `%u` pattern (reply topics are
    `_reply/<user>/<token>`, so that no topic tells a client id), on amqtt (no patterns) through
    `_reply/#`.
    """
    base = f"umlbot/{robot}"
    table: dict[str, Grants] = {}
    used = set(components.values())
    for kind in (k for k in service_kinds() if k in used):
        owned = [f"{base}/{name}/#" for name, k in sorted(components.items()) if k == kind]
        table[kind] = Grants(
            read=[*owned, f"{base}/orchestrator/status", f"{base}/orchestrator/heartbeat"],
            write=[*owned, f"{base}/_reply/#"],
        )
    table["all"] = Grants(  # `umlbot service all`: every kind in one process
        read=[*(f"{base}/{name}/#" for name in sorted(components)), f"{base}/orchestrator/status",
              f"{base}/orchestrator/heartbeat"],
        write=[*(f"{base}/{name}/#" for name in sorted(components)), f"{base}/_reply/#"],
    )
    names = sorted(components)
    table["orchestrator"] = Grants(
        # status and state of every component: amqtt cannot grant a `+/status` subscription
        # through per-component entries, and availability is not a secret.
        read=[f"{base}/+/status", f"{base}/+/state", f"{base}/signal/#", f"{base}/orchestrator/#"],
        write=[*(f"{base}/{name}/call/#" for name in names), f"{base}/signal/#", f"{base}/orchestrator/#"],
    )
    table["monitor"] = Grants(read=[f"{base}/#"])
    table["operator"] = Grants(
        write=[*(f"{base}/{name}/call/#" for name in names), f"{base}/signal/#", f"{base}/orchestrator/exit"],
    )
    return table


def mosquitto_acl(table: dict[str, Grants], robot: str, source: str) -> str:
    """The Mosquitto ACL file text for the table."""
    lines = [
        f"# umlbot broker ACL for robot '{robot}', generated by deploy/broker_auth.py from {source}.",
        "# Anonymous clients have no rights (and allow_anonymous is false anyway).",
        "",
        "# Every user reads its own reply topics, umlbot/<robot>/_reply/<its user name>/<token>.",
        "pattern read umlbot/+/_reply/%u/#",
    ]
    for role, grant in table.items():
        lines += ["", f"user {user_of(role)}"]
        both = [t for t in grant.read if t in grant.write]
        lines += [f"topic readwrite {t}" for t in both]
        lines += [f"topic read {t}" for t in grant.read if t not in both]
        lines += [f"topic write {t}" for t in grant.write if t not in both]
    return "\n".join(lines) + "\n"


def amqtt_acl(table: dict[str, Grants], robot: str, source: str) -> str:
    """The `umlbot broker --acl` YAML text (amqtt keys: `acl` = subscribe, `publish_acl`)."""
    reply = f"umlbot/{robot}/_reply/#"
    everything = f"umlbot/{robot}/#"
    out = [
        f"# umlbot broker ACL for robot '{robot}', generated by deploy/broker_auth.py from {source}.",
        "# amqtt has no %c patterns: every user may subscribe to the reply topics (_reply/#).",
        "acl:",
    ]
    for role, grant in table.items():
        topics = grant.read if everything in grant.read else [*grant.read, reply]
        out.append(f"  {user_of(role)}:")
        out += [f"    - '{t}'" for t in topics]
    out.append("publish_acl:")
    for role, grant in table.items():
        if grant.write:
            out.append(f"  {user_of(role)}:")
            out += [f"    - '{t}'" for t in grant.write]
    return "\n".join(out) + "\n"


def load_components(deployment_path: Path) -> dict[str, str]:
    """Component name -> service kind, from a deployment file (plain or YAML)."""
    from umlbot.base.deployment import load_deployment

    deployment = load_deployment(deployment_path)
    return {name: comp.implementation.service for name, comp in deployment.components.items()}


def existing_password(env_file: Path) -> str | None:
    """The password in an earlier `<role>.env`, so that re-running keeps credentials."""
    if not env_file.is_file():
        return None
    for line in env_file.read_text(encoding="utf-8").splitlines():
        if line.startswith("UMLBOT_BROKER="):
            return urlsplit(line.partition("=")[2]).password
    return None


def write_private(path: Path, text: str) -> None:
    """Write a file only its owner can read (it holds a secret)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w", encoding="utf-8") as handle:
        handle.write(text)
    os.chmod(path, 0o600)


def hash_argon2(password: str) -> str:
    """An argon2 hash as amqtt's FileAuthPlugin verifies it (pwdlib)."""
    from pwdlib import PasswordHash
    from pwdlib.hashers.argon2 import Argon2Hasher

    return str(PasswordHash((Argon2Hasher(),)).hash(password))


def find_mosquitto_passwd() -> str | None:
    """Mosquitto's password tool on PATH or in the Debian locations, or None."""
    candidates = ("/usr/bin/mosquitto_passwd", "/usr/sbin/mosquitto_passwd")
    return shutil.which("mosquitto_passwd") or next((p for p in candidates if os.access(p, os.X_OK)), None)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--deployment", type=Path, required=True, help="the robot's deployment file")
    parser.add_argument("--robot", default="+", help="robot id (default '+': any robot)")
    parser.add_argument("--out", type=Path, required=True, help="directory for the generated files")
    parser.add_argument("--host", default="127.0.0.1", help="broker host written into the URLs")
    parser.add_argument("--port", type=int, default=1883, help="broker port written into the URLs")
    parser.add_argument("--tls", action="store_true", help="mqtts:// URLs (a TLS listener)")
    parser.add_argument("--no-passwords", action="store_true", help="write only the ACL files")
    args = parser.parse_args(argv)

    if any(c in args.robot for c in "/#") or (("+" in args.robot) and args.robot != "+"):
        parser.error(f"robot id {args.robot!r} may not contain '/', '#' or '+'")
    components = load_components(args.deployment)
    table = grants(components, args.robot)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    source = args.deployment.name
    (out / "mosquitto.acl").write_text(mosquitto_acl(table, args.robot, source), encoding="utf-8")
    (out / "amqtt-acl.yaml").write_text(amqtt_acl(table, args.robot, source), encoding="utf-8")
    if args.no_passwords:
        return 0

    scheme = "mqtts" if args.tls else "mqtt"
    passwords: dict[str, str] = {}
    for role in table:
        env_file = out / f"{role}.env"
        passwords[role] = existing_password(env_file) or secrets.token_urlsafe(24)
        write_private(
            env_file,
            f"# MQTT credentials of the umlbot {role} (user {user_of(role)}); keep it secret.\n"
            f"UMLBOT_BROKER={scheme}://{user_of(role)}:{passwords[role]}@{args.host}:{args.port}\n",
        )
    write_private(
        out / "amqtt.passwd",
        "".join(f"{user_of(role)}:{hash_argon2(pw)}\n" for role, pw in passwords.items()),
    )
    mosquitto_passwd = find_mosquitto_passwd()
    if mosquitto_passwd is None:
        print("broker_auth: mosquitto_passwd not found; mosquitto.passwd not written", file=sys.stderr)
        return 0
    # Plain `user:password` lines hashed in place: no password on a command line.
    passwd = out / "mosquitto.passwd"
    write_private(passwd, "".join(f"{user_of(role)}:{pw}\n" for role, pw in passwords.items()))
    result = subprocess.run(
        [mosquitto_passwd, "-U", str(passwd)], capture_output=True, text=True, timeout=60, check=False
    )
    if result.returncode != 0:
        passwd.unlink()
        print(f"broker_auth: mosquitto_passwd -U failed: {result.stderr.strip()}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
