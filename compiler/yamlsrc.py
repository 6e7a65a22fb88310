"""YAML read with the position of every value, for error messages that point at the exact spot.

`parse_yaml` composes the document with ruamel.yaml (no Python objects are constructed from tags,
nothing is executed) and turns it into `YMap`/`YSeq`/`YScalar`, each with its `Location`.
Duplicate keys are reported, not fatal; alias bombs and deep nesting are refused as `ModelError`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from compiler.diagnostics import Diagnostics, Location
from umlbot.errors import ModelError

#: refuse documents that expand to more nodes than this (aliases can multiply a small file).
MAX_NODES = 500_000
MAX_DEPTH = 100


@dataclass
class YScalar:
    """A scalar: its source text, resolved YAML tag and quoting style ('', "'", '"', '|', '>')."""

    text: str
    tag: str
    style: str
    loc: Location

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


@dataclass
class YSeq:
    """A sequence of nodes."""

    items: list[YNode]
    loc: Location


@dataclass
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


def parse_yaml(text: str, file: str, diagnostics: Diagnostics) -> YNode | None:
    """Compose one YAML document; None for an empty document.

    Raises `ModelError` for a syntax error or a document that is too large or too deep; duplicate
    keys go to `diagnostics` (the first value wins).
    """
    from ruamel.yaml import YAML
    from ruamel.yaml.error import MarkedYAMLError, YAMLError

    yaml = YAML(typ="safe", pure=True)
    try:
        root = yaml.compose(text)
    except MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else 1
        column = mark.column + 1 if mark is not None else 1
        problem = exc.problem or exc.context or "invalid YAML"
        raise ModelError(f"invalid YAML: {problem}", file, line, column) from None
    except (YAMLError, ValueError, RecursionError) as exc:
        raise ModelError(f"invalid YAML: {exc}", file, 1, 1) from None
    if root is None:
        return None
    return _Converter(file, diagnostics).convert(root, 0)


class _Converter:
    def __init__(self, file: str, diagnostics: Diagnostics) -> None:
        self.file = file
        self.diagnostics = diagnostics
        self.count = 0

    def loc(self, node: Any) -> Location:
        mark = node.start_mark
        return Location(self.file, mark.line + 1, mark.column + 1)

    def convert(self, node: Any, depth: int) -> YNode:
        from ruamel.yaml.nodes import MappingNode, ScalarNode, SequenceNode

        self.count += 1
        if self.count > MAX_NODES:
            raise ModelError("document too large (aliases expand too far?)", self.file, 1, 1)
        if depth > MAX_DEPTH:
            raise ModelError("document nested too deeply", self.file, *self._lc(node))
        if isinstance(node, ScalarNode):
            return YScalar(str(node.value), str(node.tag), node.style or "", self.loc(node))
        if isinstance(node, SequenceNode):
            return YSeq([self.convert(item, depth + 1) for item in node.value], self.loc(node))
        if isinstance(node, MappingNode):
            result = YMap({}, {}, self.loc(node))
            for key_node, value_node in node.value:
                if not isinstance(key_node, ScalarNode):
                    raise ModelError("a mapping key must be a plain name", self.file, *self._lc(key_node))
                key = str(key_node.value)
                if key in result.items:
                    self.diagnostics.error(f"duplicate key {key!r}", self.loc(key_node))
                    continue
                result.keys[key] = YScalar(key, str(key_node.tag), key_node.style or "", self.loc(key_node))
                result.items[key] = self.convert(value_node, depth + 1)
                result.order.append(key)
            return result
        raise ModelError("unsupported YAML node", self.file, *self._lc(node))

    def _lc(self, node: Any) -> tuple[int, int]:
        mark = node.start_mark
        return mark.line + 1, mark.column + 1
