"""Entry points of the installed packages, read without `importlib.metadata` where it can be.

`importlib.metadata` imports email, zipfile, csv and (through importlib.abc) tempfile: 1.7 MB
resident in a service process, which only needs the two `umlbot.*` groups of the plugin catalog
(and pydantic's look for its plugins; docs/performance.md, "Memory"). For the usual layout —
folders on `sys.path` holding pip's `*.dist-info` (or setuptools' `*.egg-info`) folders, editable
installs included — this module reads the same files the same way: the distributions in
`sys.path` order, the first of each normalized name only, their `entry_points.txt`, and Name and
Version from their `METADATA`. Anything else — a zip archive or an `.egg` on `sys.path`, a meta
path finder with distributions of its own — goes to `importlib.metadata` itself, so the answer is
the same either way.
"""

from __future__ import annotations

import functools
import importlib
import importlib.machinery
import os
import re
import sys
from collections.abc import Collection
from typing import Any, Protocol


class Metadata(Protocol):
    """The part of a distribution's metadata that umlbot reads (`metadata["Name"]`)."""

    def __getitem__(self, key: str) -> str | None: ...


class DistributionLike(Protocol):
    """The part of `importlib.metadata.Distribution` that umlbot reads."""

    @property
    def metadata(self) -> Metadata: ...

    @property
    def version(self) -> str: ...


class EntryPointLike(Protocol):
    """The part of `importlib.metadata.EntryPoint` that umlbot (and pydantic) read."""

    @property
    def name(self) -> str: ...

    @property
    def value(self) -> str: ...

    @property
    def group(self) -> str: ...

    @property
    def dist(self) -> DistributionLike | None: ...

    def load(self) -> Any: ...


#: importlib.metadata's pattern of an entry point's value: `module[:attr[.attr]] [extras]`
_VALUE = re.compile(r"(?P<module>[\w.]+)\s*(:\s*(?P<attr>[\w.]+)\s*)?((?P<extras>\[.*\])\s*)?$")
_INFO_SUFFIXES = (".dist-info", ".egg-info")


class _Headers:
    """The header block of a METADATA file (RFC 822 style): the first value of each name."""

    def __init__(self, text: str) -> None:
        self._values: dict[str, str] = {}
        for line in text.splitlines():
            if not line.strip():
                break  # the headers end at the first empty line; the description follows
            if line[0] in " \t":
                continue  # a folded continuation: Name and Version are never folded
            key, sep, value = line.partition(":")
            if sep:
                self._values.setdefault(key.strip().lower(), value.strip())

    def __getitem__(self, key: str) -> str | None:
        return self._values.get(key.lower())


class _Distribution:
    """One installed distribution: its `*.dist-info` (or `*.egg-info`) folder."""

    def __init__(self, path: str) -> None:
        self._path = path

    def read_text(self, name: str) -> str | None:
        try:
            with open(os.path.join(self._path, name), encoding="utf-8") as file:
                return file.read()
        except (OSError, UnicodeDecodeError):
            return None

    @functools.cached_property
    def metadata(self) -> _Headers:
        return _Headers(self.read_text("METADATA") or self.read_text("PKG-INFO") or "")

    @property
    def version(self) -> str:
        return self.metadata["Version"] or ""


class _EntryPoint:
    """One entry point, as `importlib.metadata.EntryPoint` has it (name, value, group, dist, load)."""

    __slots__ = ("dist", "group", "name", "value")

    def __init__(self, name: str, value: str, group: str, dist: _Distribution) -> None:
        self.name = name
        self.value = value
        self.group = group
        self.dist = dist

    def load(self) -> Any:
        """Import the module the value names and return its attribute (as importlib.metadata)."""
        match = _VALUE.match(self.value)
        if match is None:
            raise ValueError(f"malformed entry point value {self.value!r}")
        module = importlib.import_module(match.group("module"))
        attrs = filter(None, (match.group("attr") or "").split("."))
        return functools.reduce(getattr, attrs, module)

    def __repr__(self) -> str:
        return f"EntryPoint(name={self.name!r}, value={self.value!r}, group={self.group!r})"


def _normalize(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower().replace("-", "_")


def _distributions() -> list[_Distribution] | None:
    """The distributions on `sys.path` as importlib.metadata finds them; None when the layout has
    something only importlib.metadata reads."""
    for finder in sys.meta_path:
        own = getattr(finder, "find_distributions", None) is not None
        if own and finder is not importlib.machinery.PathFinder:
            return None
    found: list[_Distribution] = []
    seen: set[str] = set()
    for entry in sys.path:
        root = entry or "."
        if os.path.basename(root).lower().endswith(".egg"):
            return None
        try:
            children = os.listdir(root)
        except NotADirectoryError:
            return None  # a zip archive on sys.path
        except OSError:
            continue  # missing or unreadable: importlib.metadata finds nothing there either
        for child in children:
            if not child.lower().endswith(_INFO_SUFFIXES):
                continue
            name = _normalize(os.path.splitext(child)[0].partition("-")[0])
            if name in seen:
                continue
            seen.add(name)
            found.append(_Distribution(os.path.join(root, child)))
    return found


def _parse(text: str, dist: _Distribution, groups: Collection[str]) -> list[_EntryPoint]:
    """The entry points of one `entry_points.txt` in `groups` (importlib.metadata's reading)."""
    found: list[_EntryPoint] = []
    group: str | None = None
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("[") and line.endswith("]"):
            group = line.strip("[]")
            continue
        if group is None or group not in groups:
            continue
        name, sep, value = line.partition("=")
        if sep:
            found.append(_EntryPoint(name.strip(), value.strip(), group, dist))
    return found


def entry_points(*groups: str) -> list[EntryPointLike]:
    """The installed entry points of `groups`, in the order importlib.metadata gives them."""
    dists = _distributions()
    if dists is None:
        from importlib.metadata import entry_points as read

        return [ep for group in groups for ep in read(group=group)]
    found: list[EntryPointLike] = []
    for dist in dists:
        text = dist.read_text("entry_points.txt")
        if text:
            found.extend(_parse(text, dist, groups))
    return found


def select(group: str) -> list[EntryPointLike]:
    """`importlib.metadata.entry_points(group=…)`'s signature, for a library that calls it."""
    return entry_points(group)
