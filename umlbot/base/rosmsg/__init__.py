"""umlbot's own ROS 2 message definitions (`umlbot_msgs/msg/*.msg`), shipped as package data.

The same types serve the MCAP recordings (umlbot.record) and the ROS 2 bridge: one `.msg` file per
payload of SPEC §3 (trace event, feature call, component status and state, orchestrator status,
signal). A value without a fixed type travels as JSON text in a `*_json` string field.

`message_definitions()` reads the texts (no extra needed); `typestore()` builds a `rosbags`
Typestore with the standard ROS 2 types plus these, importing rosbags only then and raising
`MissingExtra` (naming the extra to install) when it is not installed.
"""

from __future__ import annotations

import importlib
from functools import cache
from importlib import resources
from typing import TYPE_CHECKING, Any, Final

from umlbot.base.errors import MissingExtra

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = ["PACKAGE", "TYPE_NAMES", "message_definitions", "require", "typestore"]

#: the ROS 2 package name of umlbot's messages.
PACKAGE: Final = "umlbot_msgs"
#: the message types umlbot defines, as ROS 2 names (`umlbot_msgs/msg/TraceEvent`).
TYPE_NAMES: Final[tuple[str, ...]] = tuple(
    f"{PACKAGE}/msg/{name}"
    for name in ("TraceEvent", "FeatureCall", "ComponentStatus", "ComponentState",
                 "OrchestratorStatus", "Signal")
)


def require(module: str, extra: str, what: str) -> Any:
    """Import `module`, or raise `MissingExtra` saying which extra of umlbot brings it."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise MissingExtra(module, extra, what) from exc


@cache
def message_definitions() -> dict[str, str]:
    """The `.msg` text of each of umlbot's types, by ROS 2 name (`umlbot_msgs/msg/TraceEvent`)."""
    folder = resources.files(__package__).joinpath(PACKAGE, "msg")
    texts: dict[str, str] = {}
    for name in TYPE_NAMES:
        stem = name.rsplit("/", 1)[1]
        texts[name] = folder.joinpath(f"{stem}.msg").read_text(encoding="utf-8")
    return texts


@cache
def typestore(extra: str = "record") -> Typestore:
    """A rosbags Typestore of ROS 2 Humble's standard types plus umlbot's own (cached).

    `extra` names the extra in the error when rosbags is missing (`record` or `ros2`).
    """
    typesys = require("rosbags.typesys", extra, "ROS 2 message types")
    store: Typestore = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    types: dict[str, Any] = {}
    for name, text in message_definitions().items():
        types.update(typesys.get_types_from_msg(text, name))
    store.register(types)
    return store
