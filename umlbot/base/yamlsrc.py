"""YAML read with the position of every value, for error messages that point at the exact spot.

`parse_yaml` reads the parser's events (libyaml through PyYAML when available: about twenty times
faster than a pure-Python parser, which matters for big models) and builds `YMap`/`YSeq`/`YScalar`
trees, each with its `Location`, without recursion. No Python object is ever constructed from a
tag and nothing is executed. Duplicate keys are reported, not fatal; alias bombs and deep nesting
are refused as `ModelError`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from umlbot.base.diagnostics import Diagnostics, Location
from umlbot.base.errors import ModelError

#: refuse documents that expand to more nodes than this (aliases can multiply a small file).
MAX_NODES = 500_000
MAX_DEPTH = 100


@dataclass(slots=True)
class YScalar:
    """A scalar: its source text, quoting style ('', "'", '"', '|', '>') and position."""

    text: str
    style: str
    loc: Location
    #: the tag written in the source (`!!int`), if any.
    explicit_tag: str | None = None

    @property
    def tag(self) -> str:
        """The resolved YAML tag (core schema); quoted scalars are strings."""
        return resolve_tag(self.text, not self.style, self.explicit_tag)

    @property
    def value(self) -> Any:
        """The typed value (null, bool, int, float or str), as a YAML 1.2 reader would give it."""
        return scalar_value(self.text, self.tag)

    def content_location(self) -> Location:
        """Where the scalar's content starts (after an opening quote or a block indicator line)."""
        if self.style in ("'", '"'):
            return Location(self.loc.file, self.loc.line, self.loc.column + 1)
        if self.style in ("|", ">"):
            return Location(self.loc.file, self.loc.line + 1, self.loc.column + 2)
        return self.loc


@dataclass(slots=True)
class YSeq:
    """A sequence of nodes."""

    items: list[YNode]
    loc: Location


@dataclass(slots=True)
class YMap:
    """A mapping with scalar keys, in source order; `keys` holds each key's own scalar."""

    items: dict[str, YNode]
    keys: dict[str, YScalar]
    loc: Location
    order: list[str] = field(default_factory=list)

    def get(self, key: str) -> YNode | None:
        return self.items.get(key)

    def key_loc(self, key: str) -> Location:
        k = self.keys.get(key)
        return k.loc if k is not None else self.loc

    def __iter__(self) -> Iterator[str]:
        return iter(self.order)


YNode = YScalar | YSeq | YMap


def scalar_value(text: str, tag: str) -> Any:
    """Convert a scalar's text by its resolved tag; anything unusual stays a string."""
    kind = tag.rsplit(":", 1)[-1]
    if kind == "null":
        return None
    if kind == "bool":
        return text.lower() in ("true", "yes", "on", "y")
    if kind == "int":
        try:
            return int(text.replace("_", ""), 0)
        except ValueError:
            try:
                return int(text.replace("_", ""), 10)
            except ValueError:
                return text
    if kind == "float":
        low = text.lower().replace("_", "")
        if low in (".inf", "+.inf"):
            return math.inf
        if low == "-.inf":
            return -math.inf
        if low == ".nan":
            return math.nan
        try:
            return float(low)
        except ValueError:
            return text
    return text


def to_python(node: YNode | None) -> Any:
    """The plain Python value of a node (dicts, lists, scalars)."""
    if node is None:
        return None
    if isinstance(node, YScalar):
        return node.value
    if isinstance(node, YSeq):
        return [to_python(item) for item in node.items]
    return {key: to_python(node.items[key]) for key in node.order}


def _yaml() -> Any:
    import yaml  # imported on first use: reading a compiled model does not need it

    return yaml


def parse_yaml(text: str, file: str, diagnostics: Diagnostics) -> YNode | None:
    """Build the positioned tree of one YAML document; None for an empty document.

    Raises `ModelError` for a syntax error, a second document, or a document that is too large or
    too deep; duplicate keys go to `diagnostics` (the first value wins).
    """
    import yaml

    loader = yaml.CSafeLoader if getattr(yaml, "__with_libyaml__", False) else yaml.SafeLoader
    try:
        return _build(yaml, yaml.parse(text, Loader=loader), file, diagnostics)
    except ModelError:
        raise
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else 1
        column = mark.column + 1 if mark is not None else 1
        problem = exc.problem or exc.context or "invalid YAML"
        raise ModelError(f"invalid YAML: {problem}", file, line, column) from None
    except yaml.YAMLError as exc:
        raise ModelError(f"invalid YAML: {exc}", file, 1, 1) from None
    except (ValueError, UnicodeError) as exc:
        raise ModelError(f"invalid YAML: {exc}", file, 1, 1) from None


# YAML 1.2 core schema: `on`, `yes` and `off` stay strings (PyYAML's own resolver is YAML 1.1).
_NULL = re.compile(r"~|null|Null|NULL|")
_BOOL = re.compile(r"true|True|TRUE|false|False|FALSE")
_INT = re.compile(r"[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+")
_FLOAT = re.compile(
    r"[-+]?(\.[0-9]+|[0-9]+(\.[0-9]*)?)([eE][-+]?[0-9]+)?|[-+]?\.(inf|Inf|INF)|\.(nan|NaN|NAN)"
)


_MAYBE_NOT_STR = frozenset("~nNtTfF0123456789-+.")


def resolve_tag(value: str, plain: bool, explicit: str | None) -> str:
    """The tag of a scalar: its explicit tag, else str for quoted ones, else by the core schema."""
    if explicit and explicit not in ("!", "?"):
        return explicit
    if not plain or (value and value[0] not in _MAYBE_NOT_STR):
        return "tag:yaml.org,2002:str"
    for kind, pattern in (("null", _NULL), ("bool", _BOOL), ("int", _INT), ("float", _FLOAT)):
        if pattern.fullmatch(value):
            return f"tag:yaml.org,2002:{kind}"
    return "tag:yaml.org,2002:str"


def _build(yaml: Any, events: Iterator[Any], file: str, diagnostics: Diagnostics) -> YNode | None:
    """Turn parser events into `YNode`s in one loop (no recursion: depth is limited by us only).

    Sizes count nodes as if aliases were expanded, so that an alias bomb is refused early.
    """
    scalar_event, alias_event = yaml.ScalarEvent, yaml.AliasEvent
    seq_start, map_start = yaml.SequenceStartEvent, yaml.MappingStartEvent
    seq_end, map_end = yaml.SequenceEndEvent, yaml.MappingEndEvent
    doc_start = yaml.DocumentStartEvent
    root: YNode | None = None
    documents = 0
    total = 0
    aliased = 0  # how many of the `total` nodes come from expanding aliases
    anchors: dict[str, tuple[YNode, int]] = {}
    # open collections: [collection, pending mapping key, expanded size, anchor]
    stack: list[list[Any]] = []
    for event in events:
        cls = type(event)
        mark = event.start_mark
        node: YNode
        if cls is scalar_event:
            plain = event.implicit[0] and not event.style
            node = YScalar(event.value, "" if plain else (event.style or ""),
                           Location(file, mark.line + 1, mark.column + 1), None if plain else event.tag)
            size = 1
            total += 1
            anchor = event.anchor
        elif cls is seq_start or cls is map_start:
            if len(stack) >= MAX_DEPTH:
                raise ModelError(f"document nested too deeply (more than {MAX_DEPTH} levels of "
                                 "lists and mappings)", file, mark.line + 1, mark.column + 1)
            loc = Location(file, mark.line + 1, mark.column + 1)
            collection: YNode = YSeq([], loc) if cls is seq_start else YMap({}, {}, loc)
            stack.append([collection, None, 1, event.anchor])
            total += 1
            continue
        elif cls is seq_end or cls is map_end:
            node, _, size, anchor = stack.pop()
        elif cls is alias_event:
            target = anchors.get(event.anchor or "")
            if target is None:
                raise ModelError(f"unknown alias '*{event.anchor}'", file, mark.line + 1, mark.column + 1)
            node, size = target
            total += size
            aliased += size
            anchor = None
        elif cls is doc_start:
            documents += 1
            if documents > 1:
                raise ModelError("a file holds one YAML document; found a second one", file,
                                 mark.line + 1, mark.column + 1)
            continue
        else:
            continue
        if total > MAX_NODES:
            raise _too_large(total, aliased, file, mark.line + 1, mark.column + 1)
        if anchor:
            anchors[anchor] = (node, size)
        if not stack:
            root = node
            continue
        top = stack[-1]
        top[2] += size
        parent = top[0]
        if type(parent) is YSeq:
            parent.items.append(node)
            continue
        key = top[1]
        if key is None:
            if type(node) is not YScalar:
                raise ModelError("a mapping key must be a plain name", file, node.loc.line, node.loc.column)
            top[1] = node
            continue
        top[1] = None
        if key.text in parent.items:
            diagnostics.error(f"duplicate key {key.text!r}", key.loc)
            continue
        parent.keys[key.text] = key
        parent.items[key.text] = node
        parent.order.append(key.text)
    return root


def _too_large(total: int, aliased: int, file: str, line: int, column: int) -> ModelError:
    """The error for a document past `MAX_NODES`, saying whether aliases made it so (most of its
    `total` nodes are `aliased` ones)."""
    if aliased * 2 > total:
        return ModelError(f"document too large: its aliases expand it to more than {MAX_NODES} YAML "
                          "nodes (lists, mappings and scalars)", file, line, column)
    return ModelError(f"document too large: more than {MAX_NODES} YAML nodes (lists, mappings and "
                      "scalars); split it into more files", file, line, column)


def locate(root: YNode, path: tuple[int | str, ...]) -> Location:
    """The position of the value at a pydantic error path (as deep as the path exists)."""
    node: YNode = root
    loc = root.loc
    for part in path:
        if isinstance(node, YMap) and isinstance(part, str) and part in node.items:
            loc = node.key_loc(part)
            node = node.items[part]
        elif isinstance(node, YSeq) and isinstance(part, int) and 0 <= part < len(node.items):
            node = node.items[part]
            loc = node.loc
        else:
            break
    return loc


def positions(node: YNode | None) -> Any:
    """The positions of a tree as plain JSON (`[line, col]` a scalar; a sequence `{"at", "items"}`,
    a mapping `{"at", "keys", "items"}`): what `locate` needs, for a process that gets a file's
    content already read (`umlbot.services.serve`) and names its `file:line:col` in errors."""
    if node is None:
        return None
    at = [node.loc.line, node.loc.column]
    if isinstance(node, YSeq):
        return {"at": at, "items": [positions(item) for item in node.items]}
    if isinstance(node, YMap):
        return {"at": at, "keys": {key: [k.loc.line, k.loc.column] for key, k in node.keys.items()},
                "items": {key: positions(item) for key, item in node.items.items()}}
    return at


def from_positions(data: Any, file: str) -> YNode | None:
    """The tree `positions` described, with empty scalars: `locate` finds the same places in it."""
    if data is None:
        return None
    if isinstance(data, list):
        return YScalar("", "", Location(file, int(data[0]), int(data[1])))
    at = Location(file, int(data["at"][0]), int(data["at"][1]))
    if "keys" not in data:
        return YSeq([node for item in data["items"] if (node := from_positions(item, file)) is not None], at)
    keys = {key: YScalar(key, "", Location(file, int(line), int(col)))
            for key, (line, col) in data["keys"].items()}
    items = {key: node for key, item in data["items"].items()
             if (node := from_positions(item, file)) is not None}
    return YMap(items, keys, at, list(items))

