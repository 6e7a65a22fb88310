"""The topic scheme of SPEC §3: everything of one robot lives under `umlbot/<robot>/`."""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Final

from umlbot.base.errors import ConfigError

ROOT: Final = "umlbot"
#: robot, component, feature and signal names: one topic level, no wildcards, no spaces.
_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.\-]*$")


def check_name(what: str, name: str) -> str:
    """Return `name` if it can be one topic level; raise ConfigError otherwise."""
    if not _NAME.match(name):
        raise ConfigError(
            f"{what} {name!r} cannot be used in an MQTT topic "
            "(letters, digits, '_', '-', '.'; no '/', '+', '#' or spaces)"
        )
    return name


def is_valid_publish_topic(topic: str) -> bool:
    """True for a topic one may publish to: non-empty, no wildcards, no NUL, at most 65535 bytes."""
    return (
        bool(topic)
        and "+" not in topic
        and "#" not in topic
        and "\x00" not in topic
        and len(topic.encode("utf-8")) <= 65535
    )


@dataclass(frozen=True)
class Topics:
    """The topics of one robot, e.g. `Topics("car").call("LeftActuator", "dutycycle")`."""

    robot: str

    def __post_init__(self) -> None:
        check_name("robot id", self.robot)

    @property
    def base(self) -> str:
        return f"{ROOT}/{self.robot}"

    def status(self, component: str) -> str:
        """Retained availability of a component."""
        return f"{self.base}/{component}/status"

    def call(self, component: str, feature: str) -> str:
        """Requests to one feature of a component."""
        return f"{self.base}/{component}/call/{feature}"

    def calls(self, component: str) -> str:
        """Filter matching every feature's request topic of a component."""
        return f"{self.base}/{component}/call/+"

    def state(self, component: str) -> str:
        """Retained current state of a component."""
        return f"{self.base}/{component}/state"

    def signal(self, name: str) -> str:
        """Signal-slot traffic of one signal."""
        return f"{self.base}/signal/{name}"

    @property
    def signals(self) -> str:
        """Filter matching every signal."""
        return f"{self.base}/signal/+"

    def reply(self, user: str | None, token: str) -> str:
        """Where a BusClient receives its replies: `_reply/<user>/<token>` for a client with a user
        name (a user reads only its own replies: Mosquitto's ACL pattern `_reply/%u/#`), else
        `_reply/<token>`. The token is random: the topic does not tell the client id."""
        if user and not any(c in user for c in "/+#\0"):
            return f"{self.base}/_reply/{user}/{token}"
        return f"{self.base}/_reply/{token}"

    @property
    def orchestrator_status(self) -> str:
        return f"{self.base}/orchestrator/status"

    @property
    def orchestrator_trace(self) -> str:
        return f"{self.base}/orchestrator/trace"

    @property
    def orchestrator_exit(self) -> str:
        return f"{self.base}/orchestrator/exit"

    @property
    def orchestrator_heartbeat(self) -> str:
        """The running orchestrator's lease on the motors it drives (`Heartbeat`)."""
        return f"{self.base}/orchestrator/heartbeat"

    @property
    def everything(self) -> str:
        """Filter matching all of this robot's traffic."""
        return f"{self.base}/#"

    def parse_call(self, topic: str) -> tuple[str, str] | None:
        """`(component, feature)` of a request topic of this robot, else None."""
        prefix = self.base + "/"
        if not topic.startswith(prefix):
            return None
        parts = topic[len(prefix):].split("/")
        if len(parts) == 3 and parts[1] == "call" and parts[0] and parts[2]:
            return parts[0], parts[2]
        return None
