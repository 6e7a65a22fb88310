"""ROS 2 message and service types: definitions, field paths and the values a field takes.

Definitions come from rosbags' ROS 2 Humble store (`std_msgs`, `geometry_msgs`, `sensor_msgs`,
`builtin_interfaces` …), umlbot's own messages (`umlbot.base.rosmsg`), the services bundled
here as `.srv` text (`std_srvs`, `umlbot_msgs/srv/CallFeature`: rosbags has no services) and
the user's `.msg`/`.srv` files (`msg_paths`: folders laid out as `<package>/msg/<Name>.msg` and
`<package>/srv/<Name>.srv`). A service `pkg/srv/Name` is the two messages
`pkg/srv/Name_Request` and `pkg/srv/Name_Response`, as ROS 2 names them.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from umlbot.base.library import ArgType
from umlbot.services.ros2 import missing_extra

#: ROS base type -> (umlbot value type, minimum, maximum)
BASE_TYPES: dict[str, tuple[ArgType, float | None, float | None]] = {
    "bool": ("bool", None, None),
    "byte": ("int", 0, 255), "char": ("int", 0, 255), "octet": ("int", 0, 255),
    "uint8": ("int", 0, 255), "int8": ("int", -128, 127),
    "uint16": ("int", 0, 65535), "int16": ("int", -32768, 32767),
    "uint32": ("int", 0, 2**32 - 1), "int32": ("int", -(2**31), 2**31 - 1),
    "uint64": ("int", 0, 2**64 - 1), "int64": ("int", -(2**63), 2**63 - 1),
    "float32": ("float", -3.4028234663852886e38, 3.4028234663852886e38),
    "float64": ("float", None, None),
    "string": ("str", None, None),
}

# rosbags' node kinds (rosbags.interfaces.Nodetype), by value
BASE, NAME, ARRAY, SEQUENCE = 1, 2, 3, 4


@dataclass(frozen=True)
class Field:
    """What a field path reaches: a base type (`base`, e.g. `float32`) or a message (`message`)."""

    path: str
    base: str | None = None
    message: str | None = None

    @property
    def value_type(self) -> ArgType | None:
        return BASE_TYPES[self.base][0] if self.base in BASE_TYPES else None


def split_service(text: str) -> tuple[str, str]:
    """A `.srv` file's request and response parts."""
    lines = text.splitlines()
    for index, line in enumerate(lines):
        if line.strip() == "---":
            return "\n".join(lines[:index]), "\n".join(lines[index + 1:])
    raise ValueError("a .srv definition needs a '---' line between request and response")


class Types:
    """A set of message definitions (a rosbags `Typestore`); `Types.load(paths)` is cached."""

    _cache: dict[tuple[str, ...], Types] = {}
    _lock = threading.Lock()

    def __init__(self, store: Any) -> None:
        self.store = store

    @classmethod
    def load(cls, msg_paths: tuple[str, ...] = ()) -> Types:
        with cls._lock:
            cached = cls._cache.get(msg_paths)
            if cached is None:
                cached = cls._cache[msg_paths] = cls._build(msg_paths)
            return cached

    @classmethod
    def _build(cls, msg_paths: tuple[str, ...]) -> Types:
        try:
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore
        except ImportError as exc:
            raise missing_extra("rosbags") from exc
        store = get_typestore(Stores.ROS2_HUMBLE)
        typs: dict[str, Any] = {}
        from umlbot.base.rosmsg import message_definitions

        for name, text in message_definitions().items():  # umlbot_msgs/msg/*
            typs |= get_types_from_msg(text, name)
        bundled = resources.files("umlbot.services.ros2") / "srv"  # srv/<package>/<Name>.srv
        for package in sorted(bundled.iterdir(), key=lambda e: e.name):
            if not package.is_dir():
                continue
            for entry in sorted(package.iterdir(), key=lambda e: e.name):
                if entry.name.endswith(".srv"):
                    typs |= _service_types(f"{package.name}/srv/{entry.name[:-4]}",
                                           entry.read_text("utf-8"), get_types_from_msg)
        for folder in msg_paths:
            root = Path(folder)
            if not root.is_dir():
                raise ValueError(f"msg_paths: {folder!r} is not a folder")
            for file in sorted(root.glob("*/msg/*.msg")):
                name = f"{file.parent.parent.name}/msg/{file.stem}"
                typs |= get_types_from_msg(file.read_text("utf-8"), name)
            for file in sorted(root.glob("*/srv/*.srv")):
                typs |= _service_types(f"{file.parent.parent.name}/srv/{file.stem}",
                                       file.read_text("utf-8"), get_types_from_msg)
        store.register({k: v for k, v in typs.items() if k not in store.fielddefs})
        return cls(store)

    def has(self, typename: str) -> bool:
        return typename in self.store.fielddefs

    def check_message(self, typename: str) -> None:
        """Raises ValueError with a clear message for an unknown or misspelt message type."""
        if self.has(typename):
            return
        if typename.count("/") == 1:  # ROS 1 style `pkg/Name`
            pkg, name = typename.split("/")
            hint = f" (ROS 2 names it '{pkg}/msg/{name}')" if self.has(f"{pkg}/msg/{name}") else ""
            raise ValueError(f"unknown message type '{typename}'{hint}")
        raise ValueError(f"unknown message type '{typename}' (a ROS 2 name such as "
                         "'sensor_msgs/msg/Range'; your own types through msg_paths)")

    def check_service(self, typename: str) -> None:
        if "/srv/" not in typename or not self.has(f"{typename}_Request"):
            known = sorted({k.removesuffix("_Request") for k in self.store.fielddefs
                            if k.endswith("_Request")})
            raise ValueError(f"unknown service type '{typename}' (known: {', '.join(known)}; your own "
                             "through msg_paths)")

    def fields(self, typename: str) -> list[tuple[str, Any]]:
        """The fields of a message type: (name, rosbags node)."""
        return list(self.store.fielddefs[typename][1])

    def field(self, typename: str, path: str) -> Field:
        """What `path` (`linear.x`, `header.frame_id`) of a message reaches; ValueError when it
        names no field."""
        current = typename
        parts = path.split(".")
        for depth, part in enumerate(parts):
            node = dict(self.fields(current)).get(part)
            if node is None:
                names = ", ".join(name for name, _ in self.fields(current)) or "none"
                where = f"'{current}'" if depth == 0 else f"'{'.'.join(parts[:depth])}' ({current})"
                raise ValueError(f"no field '{part}' in {where} of path '{path}' (fields: {names})")
            kind, detail = node
            last = depth == len(parts) - 1
            if kind == BASE:
                if not last:
                    raise ValueError(f"'{'.'.join(parts[:depth + 1])}' of path '{path}' is a "
                                     f"{detail[0]}, it has no fields")
                if detail[0] not in BASE_TYPES:
                    raise ValueError(f"field '{path}' is a {detail[0]}, which umlbot does not map")
                return Field(path, base=detail[0])
            if kind == NAME:
                if last:
                    return Field(path, message=detail)
                current = detail
                continue
            raise ValueError(f"field '{'.'.join(parts[:depth + 1])}' of path '{path}' is an array or "
                             "sequence, which a feature cannot read or write")
        raise ValueError(f"empty field path in '{typename}'")

    def scalar_field(self, typename: str, path: str) -> Field:
        """A field path that must reach a number, bool or string."""
        found = self.field(typename, path)
        if found.base is None:
            raise ValueError(f"field '{path}' of '{typename}' is a {found.message}, not a number, "
                             "bool or string: name one of its fields")
        return found


def _service_types(name: str, text: str, parse: Any) -> dict[str, Any]:
    request, response = split_service(text)
    parsed = {**parse(request, f"{name}_Request"), **parse(response, f"{name}_Response")}
    # rosbags files every definition under `<pkg>/<sub>/msg/`: a service's parts are `<pkg>/srv/…`
    return {key.replace("/srv/msg/", "/srv/"): value for key, value in parsed.items()}


def dds_type_name(typename: str) -> str:
    """ROS 2's DDS name of a type: `geometry_msgs/msg/Twist` -> `geometry_msgs::msg::dds_::Twist_`."""
    pkg, sub, name = typename.split("/")
    return f"{pkg}::{sub}::dds_::{name}_"


def dds_topic_name(topic: str) -> str:
    """ROS 2's DDS topic of a topic name: `/cmd_vel` -> `rt/cmd_vel`."""
    return "rt/" + topic.lstrip("/")


def check_value(value: Any, field: Field) -> None:
    """ValueError when a constant does not fit a field (type and range)."""
    arg, low, high = BASE_TYPES[field.base or "string"]
    ok = {"bool": isinstance(value, bool), "str": isinstance(value, str),
          "int": isinstance(value, int) and not isinstance(value, bool),
          "float": isinstance(value, int | float) and not isinstance(value, bool)}[arg]
    if not ok:
        raise ValueError(f"field '{field.path}' is a {field.base}, got {value!r}")
    if (low is not None and value < low) or (high is not None and value > high):
        raise ValueError(f"field '{field.path}' is a {field.base} ({low:g}..{high:g}), got {value!r}")
