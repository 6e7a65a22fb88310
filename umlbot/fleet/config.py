"""Mosquitto configuration for a fleet: each robot's broker bridged to a hub.

A robot's local Mosquitto (the *leaf*) keeps the robot driving on its own; its bridge carries
`umlbot/<robot>/#` to the hub, out of the robot, and only requests into it: calls, signals and
exit requests (`bridge_conf`). Status, state and trace never flow back from the hub, so a stale
retained copy on the hub cannot replace the robot's own (a retained `offline` would stop its
motors). The hub (`hub_conf`, `hub_acl`) gives every robot one user, `umlbot-robot-<id>`, that
may read and write `umlbot/<id>/#` and nothing else; `umlbot-fleet-viewer` reads every robot
(the studio, `umlbot monitor`); `umlbot-fleet-operator` sends requests to every robot and reads
only its own replies.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlsplit

from umlbot.base.errors import ConfigError

#: A robot id as it appears in topics and user names (the same rule as deploy/install.sh).
ROBOT_ID = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$")
VIEWER = "umlbot-fleet-viewer"
OPERATOR = "umlbot-fleet-operator"
#: The topics a bridge carries from the hub into the robot (relative to `umlbot/<robot>/`):
#: requests only. A retained request is ignored by the services and the orchestrator.
INBOUND = ("+/call/#", "signal/#", "orchestrator/exit")
#: Where the leaf broker says whether its bridge is up: `1` (retained), `0` by its last will.
LINK_TOPIC = "_bridge/connected"


def check_robot_id(robot: str) -> str:
    """The robot id, or a ConfigError saying why it cannot be one."""
    if not ROBOT_ID.match(robot) or len(robot) > 64:
        raise ConfigError(f"bad robot id {robot!r}: letters, digits, '_', '.' and '-' (at most 64), "
                          "not starting with '.' or '-'")
    return robot


def robot_user(robot: str) -> str:
    """The hub user of a robot's bridge."""
    return f"umlbot-robot-{check_robot_id(robot)}"


@dataclass(frozen=True)
class Hub:
    """Where a leaf's bridge connects: host, port, TLS and the robot's hub credentials."""

    host: str
    port: int
    tls: bool
    username: str | None = None
    password: str | None = None
    ca_file: Path | None = None

    @classmethod
    def from_url(cls, url: str, ca_file: Path | None = None) -> Hub:
        """`mqtts://user:password@hub:8883` (or `mqtt://` on a trusted network, such as loopback)."""
        try:
            parts = urlsplit(url)
            port = parts.port
        except ValueError as exc:
            raise ConfigError(f"bad hub URL: {exc}") from exc
        if parts.scheme not in ("mqtt", "mqtts") or not parts.hostname:
            raise ConfigError("bad hub URL: give mqtts://[user:password@]host[:port] (or mqtt://)")
        tls = parts.scheme == "mqtts"
        if tls and ca_file is None:
            raise ConfigError("a mqtts:// hub needs the CA certificate that signed the hub's certificate "
                              "(--hub-ca FILE)")
        return cls(parts.hostname, port or (8883 if tls else 1883), tls,
                   unquote(parts.username) if parts.username else None,
                   unquote(parts.password) if parts.password else None, ca_file)


def _no_newline(name: str, value: str) -> str:
    if "\n" in value or "\r" in value or not value.strip() or value != value.strip():
        raise ConfigError(f"bad {name} for the bridge configuration: {value!r}")
    return value


def bridge_conf(robot: str, hub: Hub) -> str:
    """The leaf broker's bridge section (a Mosquitto conf.d file) for `robot` to `hub`."""
    check_robot_id(robot)
    prefix = f"umlbot/{robot}/"
    host = f"[{hub.host}]" if ":" in hub.host else hub.host
    lines = [
        f"# umlbot fleet: bridge umlbot/{robot}/# to the hub {host}:{hub.port}",
        "# (written by umlbot.fleet.bridge_conf). Everything of this robot goes out; only requests",
        "# (calls, signals, exit) come in, so a stale retained status on the hub never reaches it.",
        f"connection umlbot-{robot}",
        f"address {host}:{hub.port}",
        f"remote_clientid umlbot-bridge-{robot}",
        f"topic # out 1 {prefix} {prefix}",
        *(f"topic {t} in 1 {prefix} {prefix}" for t in INBOUND),
        # a new session on every connection: nothing queued on the hub is delivered late
        "cleansession true",
        "try_private true",
        "bridge_protocol_version mqttv311",
        "notifications true",
        f"notification_topic {prefix}{LINK_TOPIC}",
        # back-off between attempts capped at 3 s: the hub sees a robot again within 3 s of its return
        "restart_timeout 1 3",
        "keepalive_interval 10",
        "start_type automatic",
    ]
    if hub.username is not None:
        lines.append(f"remote_username {_no_newline('hub user', hub.username)}")
    if hub.password is not None:
        lines.append(f"remote_password {_no_newline('hub password', hub.password)}")
    if hub.tls:
        assert hub.ca_file is not None
        lines += [f"bridge_cafile {_no_newline('CA file', str(hub.ca_file))}", "bridge_insecure false",
                  "bridge_tls_version tlsv1.2"]
    return "\n".join(lines) + "\n"


def hub_acl(robots: list[str]) -> str:
    """The hub's Mosquitto ACL: each robot only under its own `umlbot/<id>/`."""
    out = [
        "# umlbot fleet hub ACL, written by deploy/fleet.py: each robot's bridge user reads and",
        "# writes only umlbot/<its id>/#; the viewer reads every robot; the operator sends requests.",
        "",
        "# Every user reads its own reply topics, umlbot/<robot>/_reply/<its user name>/<token>.",
        "pattern read umlbot/+/_reply/%u/#",
    ]
    for robot in sorted(set(robots)):
        out += ["", f"user {robot_user(robot)}", f"topic readwrite umlbot/{robot}/#"]
    out += ["", f"user {VIEWER}", "topic read umlbot/#"]
    out += ["", f"user {OPERATOR}", "topic write umlbot/+/+/call/#", "topic write umlbot/+/signal/#",
            "topic write umlbot/+/orchestrator/exit"]
    return "\n".join(out) + "\n"


def hub_conf(password_file: Path, acl_file: Path, tls_port: int = 8883, local_port: int | None = 1883,
             certs: dict[str, Path] | None = None, tls_bind: str | None = None) -> str:
    """The hub's Mosquitto configuration: users and ACL for every listener, TLS for the robots
    (`certs`: ca.crt, server.crt, server.key; on every interface unless `tls_bind`) and a plain
    listener on loopback for the hub itself (users and ACL are the same on both)."""
    lines = [
        "# umlbot fleet hub, written by deploy/fleet.py.",
        "allow_anonymous false",
        f"password_file {password_file}",
        f"acl_file {acl_file}",
        "set_tcp_nodelay true",
        # a robot's state must be the robot's: the bridge re-sends it on every connection
        "persistence false",
    ]
    if local_port is not None:
        lines.append(f"listener {local_port} 127.0.0.1")
    if certs is not None:
        lines += [f"listener {tls_port}" + (f" {tls_bind}" if tls_bind else ""),
                  f"certfile {certs['server.crt']}", f"keyfile {certs['server.key']}",
                  f"cafile {certs['ca.crt']}", "tls_version tlsv1.2", "require_certificate false"]
    return "\n".join(lines) + "\n"
