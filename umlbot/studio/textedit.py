"""Edits of a YAML file's text that leave every byte outside the edited span as it was.

The studio changes a model the way a person would: it replaces one value, inserts one line, or
deletes one item, so comments, key order, quoting and spacing of everything else stay. Places are
found with PyYAML's composer (positions only; nothing is constructed from the document): the
start and end of each node, line and column. New values are written in the file's usual style, a
flow mapping on one line (`- {id: halt, kind: action, call: Stop}`), with quotes only when YAML
(read by the compiler's YAML 1.2 core schema) needs them.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import yaml

from umlbot.base.yamlsrc import resolve_tag

Value = str | int | float | bool | None | list[Any] | dict[str, Any]


class EditError(ValueError):
    """An edit that cannot be made (the message says what and where).

    `fields` maps the request's keys the problem is about (`name`, `settings.gpio`) to what is
    wrong with each, in words for the person who typed them; `message` is the message without
    the operation's number (what the page shows next to the field or in its notice).
    """

    def __init__(self, message: str, *, fields: dict[str, str] | None = None,
                 plain: str | None = None) -> None:
        super().__init__(message)
        self.fields: dict[str, str] = dict(fields or {})
        self.message = plain if plain is not None else message

    def answer(self) -> dict[str, Any]:
        """The body of the request's 400 answer."""
        body: dict[str, Any] = {"error": str(self), "message": self.message}
        if self.fields:
            body["fields"] = self.fields
        return body


_Loader: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def compose(text: str, name: str) -> yaml.Node | None:
    """The node tree of `text` (positions and texts; no Python object is constructed);
    EditError when it is not valid YAML."""
    try:
        node: yaml.Node | None = yaml.compose(text, Loader=_Loader)
    except yaml.YAMLError as exc:
        raise EditError(f"{name} is not valid YAML ({exc}); fix it in the file first") from None
    return node


def events(text: str) -> Iterator[yaml.Event]:
    """The YAML events of `text`, read as far as they are taken (a big file is not read whole to
    look at its first keys); yaml.YAMLError where it is not valid YAML."""
    return cast(Iterator[yaml.Event], yaml.parse(text, Loader=_Loader))


# --- scalars and one-line values -------------------------------------------------------------------


def scalar(value: str | int | float | bool | None, expression: bool = False) -> str:
    """`value` as a YAML scalar that is safe in a flow collection and reads back as `value`.

    An `expression` (a call, guard or value: the compiler reads its text) stays plain when its
    text reads back unchanged, as `70` or `true`; other strings are quoted when YAML would read
    them as something else than a string.
    """
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise EditError(f"{value} is not a number a model can hold")
        return repr(value)
    text = str(yaml.safe_dump([value], default_flow_style=True, width=math.inf, allow_unicode=True))
    text = text.strip()[1:-1].strip()
    if not text.startswith(("'", '"')) and "\n" not in text and _plain_reads_back(text, value):
        tag = resolve_tag(text, True, None)
        if tag == "tag:yaml.org,2002:str" or (expression and not tag.endswith(":null")):
            return text
    elif expression and value and _plain_reads_back(value, value) and not resolve_tag(
            value, True, None).endswith((":null", ":str")):
        return value
    if value.isprintable():
        return "'" + value.replace("'", "''") + "'"
    return _double(value)


def _plain_reads_back(text: str, value: str) -> bool:
    """True when `text` written plain in a flow list reads back as one scalar `value`."""
    try:
        node = yaml.compose(f"[{text}]", Loader=_Loader)
    except yaml.YAMLError:
        return False
    return (isinstance(node, yaml.SequenceNode) and len(node.value) == 1
            and isinstance(node.value[0], yaml.ScalarNode) and not node.value[0].style
            and node.value[0].value == value)


def _double(value: str) -> str:
    dumped = str(yaml.safe_dump([value], default_flow_style=True, width=math.inf, default_style='"'))
    return dumped.strip()[1:-1].strip()


#: keys whose values are expressions (the compiler parses their text).
EXPRESSION_KEYS = frozenset({"call", "value", "payload", "if"})


def flow(value: Value, expression: bool = False) -> str:
    """`value` on one line: a scalar, `[a, b]` or `{key: value, …}` (keys in the given order)."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{scalar(key)}: {flow(item, key in EXPRESSION_KEYS)}"
                               for key, item in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(flow(item) for item in value) + "]"
    return scalar(value, expression)


# --- the text with positions -----------------------------------------------------------------------


@dataclass
class Text:
    """One file's text being edited; every edit recomputes the line table (files are small)."""

    text: str
    name: str
    #: when `text` is one part of the file (a swimlane of a big file): the text around it.
    before: str = ""
    after: str = ""
    _starts: tuple[str, list[int]] | None = field(default=None, repr=False, compare=False)

    @property
    def whole(self) -> str:
        """The file's whole text."""
        return self.before + self.text + self.after

    @property
    def newline(self) -> str:
        return "\r\n" if "\r\n" in self.text else "\n"

    def root(self) -> yaml.Node | None:
        return compose(self.text, self.name)

    def offset(self, mark: yaml.Mark) -> int:
        """The character offset of a composer mark (from its line and column)."""
        starts = self._line_starts()
        line, column = int(mark.line), int(mark.column)
        if line >= len(starts):
            return len(self.text)
        return starts[line] + column

    def _line_starts(self) -> list[int]:
        cached = self._starts
        if cached is not None and cached[0] is self.text:
            return cached[1]
        starts = [0]
        index = self.text.find("\n")
        while index >= 0:
            starts.append(index + 1)
            index = self.text.find("\n", index + 1)
        self._starts = (self.text, starts)
        return starts

    def line_start(self, offset: int) -> int:
        return self.text.rfind("\n", 0, offset) + 1

    def line_end(self, offset: int) -> int:
        """The offset just after the newline of the line holding `offset` (or the text's end)."""
        index = self.text.find("\n", offset)
        return len(self.text) if index < 0 else index + 1

    def replace(self, start: int, end: int, new: str) -> None:
        self.text = self.text[:start] + new + self.text[end:]

    def insert_line_after(self, offset: int, line: str) -> None:
        """Insert `line` (without newline) as a new line after the line holding `offset`."""
        at = self.line_end(offset)
        prefix = ""
        if at == len(self.text) and self.text and not self.text.endswith("\n"):
            prefix = self.newline
        self.replace(at, at, prefix + line + self.newline)

    # --- node extents ----------------------------------------------------------------------------

    def start(self, node: yaml.Node) -> int:
        return self.offset(node.start_mark)

    def end(self, node: yaml.Node) -> int:
        """Where the node's own text ends (a block collection: where its last value ends)."""
        while isinstance(node, yaml.CollectionNode) and not node.flow_style and node.value:
            last = node.value[-1]
            node = last[1] if isinstance(node, yaml.MappingNode) else last
        end = self.offset(node.end_mark)
        if isinstance(node, yaml.ScalarNode) and node.style in ("|", ">"):
            end = self.line_start(end) - 1 if self.text[self.line_start(end):end].strip() == "" else end
        # a plain or quoted scalar ends where its text ends; trailing spaces are not part of it
        while end > self.start(node) and self.text[end - 1] in " \t\r\n":
            end -= 1
        return end

    def indent_of(self, offset: int) -> str:
        start = self.line_start(offset)
        return " " * (offset - start)

    def owns_line(self, offset: int) -> bool:
        """True when only spaces (or `- ` item markers) come before `offset` on its line."""
        before = self.text[self.line_start(offset):offset]
        return before.strip() == ""


# --- mappings and sequences ------------------------------------------------------------------------


def get(mapping: yaml.Node | None, key: str) -> yaml.Node | None:
    """The value under `key` of a mapping node (None when absent or not a mapping)."""
    if not isinstance(mapping, yaml.MappingNode):
        return None
    for k, v in mapping.value:
        if isinstance(k, yaml.ScalarNode) and k.value == key:
            return v
    return None


def key_node(mapping: yaml.MappingNode, key: str) -> yaml.Node | None:
    for k, _ in mapping.value:
        if isinstance(k, yaml.ScalarNode) and k.value == key:
            return k
    return None


def is_null(node: yaml.Node | None) -> bool:
    return (isinstance(node, yaml.ScalarNode) and not node.style
            and node.value in ("", "~", "null", "Null", "NULL"))


def replace_node(t: Text, node: yaml.Node, new: str) -> None:
    """Replace a node's text by `new` (one line)."""
    t.replace(t.start(node), t.end(node), new)


def set_key(t: Text, mapping: yaml.MappingNode, key: str, value: Value, block: bool = False,
            order: Sequence[str] = ()) -> None:
    """Set `key` of `mapping` to `value`: its value's text is replaced, or a new entry is added at
    the mapping's end (in a block mapping on its own line; `block` writes a list as a block list).
    With `order` (the keys in the order people write them), a new key goes before the first key
    of the mapping that `order` puts after it: `call` before `next`, whichever was set first."""
    current = get(mapping, key)
    if (isinstance(current, yaml.ScalarNode) and isinstance(value, str) and current.value == value
            and not is_null(current)):
        return  # the same text already, whatever its quoting: leave the bytes alone
    if current is not None and not (block and is_null(current)):
        replace_node(t, current, flow(value, key in EXPRESSION_KEYS))
        return
    if current is not None:  # `key:` with nothing after it: the block value goes below
        knode = key_node(mapping, key)
        assert knode is not None
        at = t.start(knode)
        lines = _block_lines(t.indent_of(at), key, value)
        t.replace(t.line_start(at), t.line_end(at), t.newline.join(lines) + t.newline)
        return
    later = _later_key(mapping, key, order)
    if later is not None and mapping.flow_style:
        at = t.start(later)
        t.replace(at, at, f"{scalar(key)}: {flow(value, key in EXPRESSION_KEYS)}, ")
        return
    if mapping.flow_style or not mapping.value:
        _flow_append(t, mapping, f"{scalar(key)}: {flow(value, key in EXPRESSION_KEYS)}")
        return
    first = mapping.value[0][0]
    indent = t.indent_of(t.start(first))
    if not t.owns_line(t.start(first)):  # the first key follows `- `: align with it
        indent = " " * (t.start(first) - t.line_start(t.start(first)))
    lines = (_block_lines(indent, key, value) if block
             else [f"{indent}{scalar(key)}: {flow(value, key in EXPRESSION_KEYS)}"])
    if later is not None and t.owns_line(t.start(later)):
        at = t.line_start(t.start(later))
        t.replace(at, at, t.newline.join(lines) + t.newline)
        return
    at = t.end(mapping)
    for line in reversed(lines):
        t.insert_line_after(at, line)


def _later_key(mapping: yaml.MappingNode, key: str, order: Sequence[str]) -> yaml.Node | None:
    """The first key node of `mapping` that `order` puts after `key` (None: `key` goes last)."""
    if key not in order:
        return None
    rank = order.index(key)
    for knode, _ in mapping.value:
        if isinstance(knode, yaml.ScalarNode) and knode.value in order and order.index(knode.value) > rank:
            return knode
    return None


def _block_lines(indent: str, key: str, value: Value) -> list[str]:
    """`key: value` as block lines: a list as `- item` lines, a mapping as `k: v` lines."""
    if isinstance(value, list) and value:
        return [f"{indent}{scalar(key)}:"] + [f"{indent}  - {flow(item)}" for item in value]
    if isinstance(value, dict) and value:
        return [f"{indent}{scalar(key)}:"] + [f"{indent}  {scalar(k)}: {flow(v)}" for k, v in value.items()]
    return [f"{indent}{scalar(key)}: {flow(value)}"]


def delete_key(t: Text, mapping: yaml.MappingNode, key: str) -> bool:
    """Remove `key` and its value; False when the mapping has no such key."""
    for index, (k, v) in enumerate(mapping.value):  # noqa: B007 (used after the loop)
        if isinstance(k, yaml.ScalarNode) and k.value == key:
            break
    else:
        return False
    if mapping.flow_style:
        _flow_remove(t, mapping, index)
        return True
    start = t.start(k)
    if not t.owns_line(start):
        if len(mapping.value) == 1:
            raise EditError(f"{t.name}: cannot remove the only key {key!r} of a list item")
        # `- key: value` — the next key takes its place after the dash
        nxt = mapping.value[index + 1][0]
        t.replace(start, t.start(nxt), "")
        return True
    t.replace(t.line_start(start), t.line_end(t.end(v)), "")
    return True


def append_item(t: Text, seq: yaml.SequenceNode, item: Value) -> None:
    """Add `item` at the end of a sequence (a block list: a new `- item` line)."""
    if seq.flow_style or not seq.value:
        _flow_append(t, seq, flow(item))
        return
    first = seq.value[0]
    dash = t.text.rfind("-", 0, t.start(first))
    indent = " " * (dash - t.line_start(dash))
    t.insert_line_after(t.end(seq), f"{indent}- {flow(item)}")


def insert_item(t: Text, seq: yaml.SequenceNode, index: int, item: Value) -> None:
    """Add `item` before item `index` of a sequence (a block list: a new `- item` line above it)."""
    entry = flow(item)
    before = seq.value[index]
    if seq.flow_style:
        at = t.start(before)
        t.replace(at, at, f"{entry}, ")
        return
    dash = t.text.rfind("-", 0, t.start(before))
    if not t.owns_line(dash):  # `key: - item` cannot be; a nested `- - item` is not ours to split
        raise EditError(f"{t.name}: cannot add to this list here")
    at = t.line_start(dash)
    while at > 0 and t.text[t.line_start(at - 1):at].strip().startswith("#"):
        at = t.line_start(at - 1)  # the comments above the item stay with it
    t.replace(at, at, f"{t.indent_of(dash)}- {entry}{t.newline}")


def delete_item(t: Text, seq: yaml.SequenceNode, index: int) -> None:
    """Remove item `index` of a sequence (a block item: its lines, comments above it stay)."""
    if seq.flow_style:
        _flow_remove(t, seq, index)
        return
    item = seq.value[index]
    dash = t.text.rfind("-", 0, t.start(item))
    t.replace(t.line_start(dash), t.line_end(t.end(item)), "")


def _flow_append(t: Text, collection: yaml.CollectionNode, entry: str) -> None:
    """Add an entry before the closing bracket of a flow collection (or fill `[]`/`{}`)."""
    if not collection.flow_style:
        raise EditError(f"{t.name}: cannot add to this list here")
    close = t.offset(collection.end_mark) - 1
    while close > 0 and t.text[close] != ("}" if isinstance(collection, yaml.MappingNode) else "]"):
        close -= 1
    if collection.value:
        last = collection.value[-1]
        last_node = last[1] if isinstance(collection, yaml.MappingNode) else last
        at = t.end(last_node)
        t.replace(at, at, f", {entry}")
    else:
        t.replace(close, close, entry)


def _flow_remove(t: Text, collection: yaml.CollectionNode, index: int) -> None:
    """Remove entry `index` of a flow collection with its separating comma."""
    entries = collection.value
    entry = entries[index]
    first, last = (entry[0], entry[1]) if isinstance(collection, yaml.MappingNode) else (entry, entry)
    start, end = t.start(first), t.end(last)
    if index > 0:
        previous = entries[index - 1]
        prev_end = t.end(previous[1] if isinstance(collection, yaml.MappingNode) else previous)
        t.replace(prev_end, end, "")
    elif len(entries) > 1:
        nxt = entries[1]
        t.replace(start, t.start(nxt[0] if isinstance(collection, yaml.MappingNode) else nxt), "")
    else:
        t.replace(start, end, "")
