"""The studio's edit operations: each one a text edit of a model file (see `textedit`).

`apply_ops(files, ops)` takes the working copy (relative path -> text, None for a file that is there
but cannot be read, which no operation changes) and a list of operations as the page sends them
(docs/studio.md, "Editing") and returns the new texts of the files it changed (None: the file is
removed). An operation that cannot be made raises `EditError` naming what is
wrong; the whole batch is then dropped. Meaning is not checked here: the compiler does that on the
result, so the page shows exactly `umlbot check`'s messages.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, cast

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from umlbot.base.errors import ModelError
from umlbot.compiler.expr_parser import RawExpr, RBinary, RCall, RName, RUnary, parse_expression
from umlbot.compiler.source import (
    ACTIVITIES_DIR,
    ACTIVITY_FILE,
    DEPLOYMENT_FILES,
    MODEL_FILE,
    NODE_FIELDS,
    NODE_KINDS,
)
from umlbot.studio.library_view import check_settings, settings_problems
from umlbot.studio.textedit import (
    EditError,
    Text,
    Value,
    append_item,
    delete_item,
    delete_key,
    events,
    flow,
    get,
    insert_item,
    key_node,
    replace_node,
    scalar,
    set_key,
)

#: node kinds whose single outgoing flow is `next` (or the node written below).
NEXT_KINDS = ("start", "action", "datastore", "join", "send", "accept")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_NODE_ID = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_\-]*")
_PORT_REF = re.compile(r"([A-Za-z_]\w*)\.([A-Za-z_]\w*)")


class Op(BaseModel):
    """One operation; `op` names it, the other keys depend on it (extra keys are refused)."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)

    op: str
    name: str | None = None
    kind: str | None = None
    impl: str | None = None
    settings: dict[str, Any] | None = None
    component: str | None = None
    port: str | None = None
    feature: str | None = None
    source_ref: str | None = Field(default=None, alias="from")
    target_ref: str | None = Field(default=None, alias="to")
    id: str | None = None
    lane: str | None = None
    file: str | None = None
    node: dict[str, Any] | None = None
    fields: dict[str, Any] | None = None
    source: str | None = None
    target: str | None = None
    guard: str | None = None
    diagram: str | None = None
    positions: dict[str, list[float] | None] | None = None
    new_id: str | None = None
    new_name: str | None = None
    text: str | None = None


def parse_ops(raw: Any) -> list[Op]:
    """The operations of a request; EditError naming the bad one."""
    if not isinstance(raw, list):
        raise EditError("'ops' is a list of operations")
    ops: list[Op] = []
    for index, item in enumerate(raw):
        try:
            ops.append(Op.model_validate(item))
        except ValidationError as exc:
            problems = "; ".join(f"{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in exc.errors())
            raise EditError(f"operation {index + 1}: {problems}") from None
        if ops[-1].op not in OPS and ops[-1].op != "set_layout":
            raise EditError(f"operation {index + 1}: unknown op {ops[-1].op!r} "
                            f"(known: {', '.join(OPS)}, set_layout)")
    return ops


class Edits:
    """The files being changed by one batch of operations (texts keyed by relative path).

    A file given as None is there but cannot be read (not UTF-8, no permission, not a file): an
    operation that would change, replace or remove it is refused, so saving never loses it.
    """

    def __init__(self, files: Mapping[str, str | None]) -> None:
        self.files: dict[str, str | None] = dict(files)
        self.changed: set[str] = set()
        self.unreadable = {rel for rel, text in files.items() if text is None}
        #: what the batch renamed, in order (the layout file's positions follow: `rename_positions`)
        self.renames: list[Rename] = []

    def exists(self, rel: str) -> bool:
        return self.files.get(rel) is not None or rel in self.unreadable

    def _refuse_unreadable(self, rel: str) -> None:
        if rel in self.unreadable:
            raise EditError(f"{rel} cannot be read (its error is in the problems): the studio does "
                            "not write over it; fix or remove it on disk, then edit")

    def text(self, rel: str) -> Text:
        content = self.files.get(rel)
        if content is None:
            self._refuse_unreadable(rel)
            raise EditError(f"{rel} does not exist")
        return Text(content, rel)

    def put(self, t: Text) -> None:
        whole = t.whole
        if self.files.get(t.name) != whole:
            self.files[t.name] = whole
            self.changed.add(t.name)

    def create(self, rel: str, content: str) -> None:
        self._refuse_unreadable(rel)
        if self.files.get(rel) is not None:
            raise EditError(f"{rel} exists already")
        self.files[rel] = content
        self.changed.add(rel)

    def remove(self, rel: str) -> None:
        self._refuse_unreadable(rel)
        self.files[rel] = None
        self.changed.add(rel)

    # --- where things are ------------------------------------------------------------------------

    def lane_files(self) -> list[str]:
        """Files that may hold swimlanes: model.yaml, then the activity files in order."""
        return lane_files([rel for rel, text in self.files.items() if text is not None])

    def find_lane(self, lane: str, whole: bool = False
                  ) -> tuple[Text, yaml.MappingNode, yaml.SequenceNode | None, int | None]:
        """(file, the lane's mapping, the `lanes` list holding it or None, its index there).

        In a file of several lanes the text is only that lane's item (unless `whole`): a big
        file is not read whole for an edit of one lane.
        """
        for rel in self.lane_files():
            content = self.files[rel]
            assert content is not None
            if lane not in content:  # cheap: a lane's name is written in its file
                continue
            if not whole:
                part = _lane_part(content, rel, lane)
                if part is not None:
                    return part
            t = Text(content, rel)
            root = t.root()
            if isinstance(root, yaml.MappingNode):
                lanes = get(root, "lanes")
                if isinstance(lanes, yaml.SequenceNode):
                    for index, item in enumerate(lanes.value):
                        if _scalar_text(get(item, "lane")) == lane:
                            return t, cast(yaml.MappingNode, item), lanes, index
                elif rel != MODEL_FILE and _scalar_text(get(root, "lane")) == lane:
                    return t, root, None, None
        unread = sorted(rel for rel in self.unreadable
                        if rel == MODEL_FILE or ACTIVITY_FILE.fullmatch(rel))
        if unread:
            raise EditError(f"no swimlane {lane!r} in the files that can be read "
                            f"({', '.join(unread)} cannot be read)")
        raise EditError(f"no swimlane {lane!r}")

    def model_root(self) -> tuple[Text, yaml.MappingNode]:
        t = self.text(MODEL_FILE)
        root = t.root()
        if not isinstance(root, yaml.MappingNode):
            raise EditError(f"{MODEL_FILE} is not a mapping; fix it in the file first")
        return t, root

    def deployment_file(self) -> str | None:
        for name in DEPLOYMENT_FILES:  # the first there is the one the compiler reads
            if self.exists(name):
                return name
        return None


def lane_files(names: Iterable[str]) -> list[str]:
    """Of the files `names`, those that may hold swimlanes: model.yaml, then the activity files in
    order."""
    names = set(names)
    activities = sorted(rel for rel in names if ACTIVITY_FILE.fullmatch(rel))
    return [MODEL_FILE, *activities] if MODEL_FILE in names else activities


def _lane_part(content: str, rel: str, lane: str
               ) -> tuple[Text, yaml.MappingNode, yaml.SequenceNode, int] | None:
    """The item `- lane: <lane>` of a `lanes:` list as its own text, when it is written so."""
    match = re.search(rf"^( *)- +lane: *['\"]?{re.escape(lane)}['\"]? *(#.*)?\r?$", content, re.MULTILINE)
    if match is None:
        return None
    start = match.start()
    indent = len(match.group(1))
    end = len(content)
    at = content.find("\n", match.end())
    while at >= 0:
        line_end = content.find("\n", at + 1)
        line = content[at + 1:line_end if line_end >= 0 else len(content)]
        stripped = line.lstrip(" ")
        if stripped and not stripped.startswith("#") and len(line) - len(stripped) <= indent:
            end = at + 1
            break
        at = line_end
    t = Text(content[start:end], rel, before=content[:start], after=content[end:])
    try:
        root = t.root()
    except EditError:
        return None
    if not isinstance(root, yaml.SequenceNode) or len(root.value) != 1:
        return None
    item = root.value[0]
    if not isinstance(item, yaml.MappingNode) or _scalar_text(get(item, "lane")) != lane:
        return None
    return t, item, root, 0


def _scalar_text(node: yaml.Node | None) -> str | None:
    return node.value if isinstance(node, yaml.ScalarNode) else None


def _nodes_of(lane_map: yaml.MappingNode, lane: str) -> yaml.SequenceNode:
    nodes = get(lane_map, "nodes")
    if not isinstance(nodes, yaml.SequenceNode):
        raise EditError(f"swimlane {lane!r} has no list of nodes")
    return nodes


def _find_node(nodes: yaml.SequenceNode, lane: str, node_id: str) -> tuple[int, yaml.MappingNode]:
    for index, item in enumerate(nodes.value):
        if _scalar_text(get(item, "id")) == node_id:
            return index, cast(yaml.MappingNode, item)
    raise EditError(f"swimlane {lane!r} has no node {node_id!r}")


def _node_ids(nodes: yaml.SequenceNode) -> list[str]:
    return [text for item in nodes.value if (text := _scalar_text(get(item, "id"))) is not None]


def _a(kind: str) -> str:
    """`a fork`, `an action`."""
    return f"an {kind}" if kind[:1] in "aeiou" else f"a {kind}"


def _need(value: str | None, what: str, op: Op) -> str:
    if value is None or value == "":
        raise EditError(f"{op.op} needs '{what}'")
    return value


# --- activity operations -----------------------------------------------------------------------------


def _lane_nodes(e: Edits, lane: str) -> tuple[Text, yaml.SequenceNode]:
    t, lane_map, _, _ = e.find_lane(lane)
    return t, _nodes_of(lane_map, lane)


def add_node(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    node = dict(op.node or {})
    kind = node.pop("kind", None)
    if kind not in NODE_KINDS:
        raise EditError(f"a node's kind is one of {', '.join(NODE_KINDS)}")
    t, nodes = _lane_nodes(e, lane)
    ids = set(_node_ids(nodes))
    node_id = node.pop("id", None)
    if node_id is None:
        n = 1
        while f"{kind}{n}" in ids:
            n += 1
        node_id = f"{kind}{n}"
    if not isinstance(node_id, str) or not _NODE_ID.fullmatch(node_id):
        raise EditError(f"node id {node_id!r} is not a plain name (letters, digits, _ and -)")
    if node_id in ids:
        raise EditError(f"swimlane {lane!r} has a node {node_id!r} already")
    unknown = [key for key in node if key not in NODE_FIELDS[kind]]
    if unknown:
        raise EditError(f"{_a(kind)} node has no {', '.join(map(repr, unknown))} "
                        f"(its keys: {', '.join(NODE_FIELDS[kind]) or 'none'})")
    item: dict[str, Any] = {"id": node_id, "kind": kind}
    item.update((key, node[key]) for key in NODE_FIELDS[kind] if node.get(key) is not None)
    append_item(t, nodes, item)
    e.put(t)


def set_node(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    node_id = _need(op.id, "id", op)
    for key, value in (op.fields or {}).items():
        t, nodes = _lane_nodes(e, lane)
        _, item = _find_node(nodes, lane, node_id)
        kind = _scalar_text(get(item, "kind")) or ""
        if key not in NODE_FIELDS.get(kind, ()):
            raise EditError(f"{_a(kind)} node has no {key!r} (its keys: "
                            f"{', '.join(NODE_FIELDS.get(kind, ())) or 'none'})")
        if value is None or value == "":
            delete_key(t, item, key)
        else:
            set_key(t, item, key, cast(Value, value), order=("id", "kind", *NODE_FIELDS.get(kind, ())))
        e.put(t)


def remove_node(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    node_id = _need(op.id, "id", op)
    t, nodes = _lane_nodes(e, lane)
    index, _ = _find_node(nodes, lane, node_id)
    delete_item(t, nodes, index)
    e.put(t)
    # flows into the removed node go too
    for source in _node_ids(_lane_nodes(e, lane)[1]):
        _disconnect(e, lane, source, node_id, quiet=True)


def connect(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    source = _need(op.source, "source", op)
    target = _need(op.target, "target", op)
    t, nodes = _lane_nodes(e, lane)
    index, item = _find_node(nodes, lane, source)
    _find_node(nodes, lane, target)
    kind = _scalar_text(get(item, "kind"))
    if kind in NEXT_KINDS:
        following = _node_ids(nodes)[index + 1] if index + 1 < len(nodes.value) else None
        if get(item, "next") is None and following == target:
            return  # it flows on to the node below already
        set_key(t, item, "next", target)
    elif kind == "decision":
        branches = get(item, "branches")
        outputs = branches.value if isinstance(branches, yaml.SequenceNode) else []
        else_at = next((i for i, b in enumerate(outputs) if get(b, "else") is not None), None)
        guard = (op.guard or "").strip()
        if guard == "else" or (guard == "" and else_at is None):
            if else_at is not None:
                raise EditError(f"decision {source!r} has an else output already")
            branch: dict[str, Any] = {"else": target}
        else:
            # no guard given: an empty one, which the checker reports on the decision until the
            # user writes it (a guard nobody typed must not compile)
            branch = {"if": guard, "then": target}
        if not isinstance(branches, yaml.SequenceNode):
            set_key(t, item, "branches", [branch], block=not item.flow_style)
        elif else_at is not None and "then" in branch:
            insert_item(t, branches, else_at, branch)  # the else output stays the last one
        else:
            append_item(t, branches, branch)
    elif kind == "fork":
        targets = get(item, "targets")
        if isinstance(targets, yaml.SequenceNode):
            if target in [_scalar_text(x) for x in targets.value]:
                raise EditError(f"fork {source!r} starts {target!r} already")
            append_item(t, targets, target)
        else:
            set_key(t, item, "targets", [target])
    else:
        raise EditError(f"{kind} node {source!r} has no outgoing flow to connect")
    e.put(t)


def disconnect(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    _disconnect(e, lane, _need(op.source, "source", op), _need(op.target, "target", op), quiet=False)


def _disconnect(e: Edits, lane: str, source: str, target: str, quiet: bool) -> None:
    t, nodes = _lane_nodes(e, lane)
    _, item = _find_node(nodes, lane, source)
    kind = _scalar_text(get(item, "kind"))
    if kind in NEXT_KINDS:
        if _scalar_text(get(item, "next")) == target:
            delete_key(t, item, "next")
        elif not quiet:
            raise EditError(f"{source!r} flows on to {target!r} because it is written just above it: "
                            f"connect {source!r} to another node instead")
    elif kind == "decision":
        while True:  # every output to the target (positions move after each removal)
            branches = get(item, "branches")
            found = [i for i, b in enumerate(branches.value if isinstance(branches, yaml.SequenceNode)
                                             else []) if target in (_scalar_text(get(b, "then")),
                                                                    _scalar_text(get(b, "else")))]
            if not found:
                break
            delete_item(t, cast(yaml.SequenceNode, branches), found[0])
            e.put(t)
            t, nodes = _lane_nodes(e, lane)
            _, item = _find_node(nodes, lane, source)
    elif kind == "fork":
        targets = get(item, "targets")
        if isinstance(targets, yaml.SequenceNode):
            for index in reversed(range(len(targets.value))):
                if _scalar_text(targets.value[index]) == target:
                    delete_item(t, targets, index)
                    break
    e.put(t)


def set_guard(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    source = _need(op.source, "source", op)
    target = _need(op.target, "target", op)
    guard = (op.guard or "").strip()
    t, nodes = _lane_nodes(e, lane)
    _, item = _find_node(nodes, lane, source)
    branches = get(item, "branches")
    if _scalar_text(get(item, "kind")) != "decision" or not isinstance(branches, yaml.SequenceNode):
        raise EditError(f"{source!r} is not a decision with outputs")
    for b in branches.value:
        if not isinstance(b, yaml.MappingNode):
            continue
        if _scalar_text(get(b, "then")) == target or _scalar_text(get(b, "else")) == target:
            break
    else:
        raise EditError(f"decision {source!r} has no output to {target!r}")
    if guard == "else":
        if get(b, "else") is None:
            replace_node(t, b, flow({"else": target}))
    elif guard == "":
        raise EditError("a guard is an expression (or 'else')")
    elif get(b, "if") is not None:
        set_key(t, b, "if", guard, order=("if", "then"))
    else:
        replace_node(t, b, flow({"if": guard, "then": target}))
    e.put(t)


def snake_case(name: str) -> str:
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


#: a top-level `lanes:` key (a cheap test before a file is parsed)
_LANES_KEY = re.compile(r"^lanes\s*:", re.MULTILINE)


def takes_lanes(rel: str, content: str) -> bool:
    """Whether `add_lane` can add a swimlane to the file `rel` (its `file`): model.yaml or an
    activity file whose top-level `lanes:` is a block list with a lane in it (not a file of one
    lane, nor a flow-style or empty list: a new lane then goes to a file of its own). The file's
    YAML is read only up to that list: this is asked after every edit, of big files too."""
    if not (rel == MODEL_FILE or ACTIVITY_FILE.fullmatch(rel)) or not _LANES_KEY.search(content):
        return False
    try:
        stream = events(content)
        opening = (yaml.StreamStartEvent, yaml.DocumentStartEvent, yaml.MappingStartEvent)
        if not all(isinstance(next(stream), kind) for kind in opening):  # a mapping at the top
            return False
        while True:
            key = next(stream)
            if isinstance(key, yaml.MappingEndEvent):
                return False
            if isinstance(key, yaml.ScalarEvent) and key.value == "lanes":
                value = next(stream)
                return (isinstance(value, yaml.SequenceStartEvent) and not value.flow_style
                        and not isinstance(next(stream), yaml.SequenceEndEvent))
            _skip(key, stream)  # a key that is no plain name
            _skip(next(stream), stream)  # its value
    except (yaml.YAMLError, StopIteration):  # not YAML: nothing can be added to it
        return False


def _skip(first: yaml.Event, stream: Iterator[yaml.Event]) -> None:
    """Read the rest of the node that begins with the event `first`."""
    depth = 1 if isinstance(first, yaml.CollectionStartEvent) else 0
    while depth:
        event = next(stream)
        if isinstance(event, yaml.CollectionStartEvent):
            depth += 1
        elif isinstance(event, yaml.CollectionEndEvent):
            depth -= 1


def add_lane(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    if not _NAME.fullmatch(lane):
        raise EditError(f"swimlane name {lane!r} is not a plain name (letters, digits and _)",
                        fields={"lane": "must be a plain name (letters, digits and _; no spaces)"})
    try:
        e.find_lane(lane, whole=True)
    except EditError:
        pass
    else:
        raise EditError(f"there is a swimlane {lane!r} already",
                        fields={"lane": "is taken by another swimlane"})
    starter = [{"id": "start", "kind": "start"}, {"id": "end", "kind": "end"}]
    if op.file is not None:
        t = e.text(op.file)
        if not takes_lanes(op.file, t.whole):
            raise EditError(f"{op.file} holds no block list of 'lanes:'; add the lane to its own file")
        lanes = cast(yaml.SequenceNode, get(cast(yaml.MappingNode, t.root()), "lanes"))
        first = lanes.value[0]
        indent = " " * (t.start(first) - t.line_start(t.start(first)))
        nl = t.newline
        # lanes separated by an empty line get one too
        gap = nl if len(lanes.value) > 1 and t.text[t.end(lanes.value[-2]):t.start(
            lanes.value[-1])].count("\n") > 1 else ""
        block = (f"{nl}{gap}{indent[:-2]}- lane: {lane}{nl}{indent}nodes:{nl}"
                 + nl.join(f"{indent}  - {flow(n)}" for n in starter))
        at = t.end(lanes)
        t.replace(at, at, block)
        e.put(t)
        return
    stem = snake_case(lane)
    rel, n = f"{ACTIVITIES_DIR}/{stem}.yaml", 1
    while e.exists(rel) or e.exists(rel[:-5] + ".yml"):
        n += 1
        rel = f"{ACTIVITIES_DIR}/{stem}_{n}.yaml"
    e.create(rel, f"lane: {lane}\nnodes:\n" + "".join(f"  - {flow(n)}\n" for n in starter))


def remove_lane(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    t, _, lanes, index = e.find_lane(lane, whole=True)
    if lanes is None or index is None:
        e.remove(t.name)
        return
    if len(lanes.value) == 1 and t.name != MODEL_FILE:
        e.remove(t.name)
        return
    delete_item(t, lanes, index)
    e.put(t)


# --- component diagram operations ------------------------------------------------------------------


def _components(e: Edits) -> tuple[Text, yaml.MappingNode, yaml.Node | None]:
    t, root = e.model_root()
    return t, root, get(root, "components")


def add_component(e: Edits, op: Op) -> None:
    name = _need(op.name, "name", op)
    kind = _need(op.kind, "kind", op)
    if not _NAME.fullmatch(name):
        raise EditError(f"component name {name!r} is not a plain name (letters, digits and _)",
                        fields={"name": "must be a plain name (letters, digits and _; no spaces)"})
    t, root, components = _components(e)
    if get(components, name) is not None:
        raise EditError(f"there is a component {name!r} already",
                        fields={"name": "is taken by another component"})
    if isinstance(components, yaml.MappingNode):
        set_key(t, components, name, {"kind": kind})
    else:
        set_key(t, root, "components", {name: {"kind": kind}}, block=True)
    e.put(t)
    if op.impl is not None:
        _write_deployment(e, name, op.impl, op.settings)


def remove_component(e: Edits, op: Op) -> None:
    name = _need(op.name, "name", op)
    t, _, components = _components(e)
    if not isinstance(components, yaml.MappingNode) or not delete_key(t, components, name):
        raise EditError(f"no component {name!r}")
    e.put(t)
    # its links and its deployment entry go with it
    t, root = e.model_root()
    links = get(root, "links")
    if isinstance(links, yaml.SequenceNode):
        for index in reversed(range(len(links.value))):
            ends = [_scalar_text(get(links.value[index], k)) or "" for k in ("from", "to")]
            if any(end.split(".")[0] == name for end in ends):
                delete_item(t, links, index)
        e.put(t)
    rel = e.deployment_file()
    if rel is not None and not rel.endswith(".txt"):
        t = e.text(rel)
        comps = get(_deployment_root(t), "components")
        if isinstance(comps, yaml.MappingNode) and delete_key(t, comps, name):
            e.put(t)
    elif rel is not None:
        t = e.text(rel)
        lines = t.text.splitlines(keepends=True)
        t.text = "".join(line for line in lines
                         if line.split("#", 1)[0].partition("=")[0].strip() != name)
        e.put(t)


def _deployment_root(t: Text) -> yaml.MappingNode:
    root = t.root()
    if isinstance(root, yaml.MappingNode) and isinstance(get(root, "deployment"), yaml.MappingNode):
        root = get(root, "deployment")
    if not isinstance(root, yaml.MappingNode):
        raise EditError(f"{t.name} is not a deployment mapping; fix it in the file first")
    return root


def _write_deployment(e: Edits, component: str, impl: str, settings: dict[str, Any] | None) -> None:
    problem = check_settings(impl, settings or {})
    if problem is not None:
        fields = {f"settings.{key}" if key else "settings": msg
                  for key, msg in settings_problems(impl, settings or {})}
        raise EditError(f"{component}: {problem}", fields=fields)
    entry: dict[str, Any] = {"impl": impl}
    if settings:
        entry["settings"] = settings
    rel = e.deployment_file()
    if rel is None:
        e.create("deployment.yaml", "components:\n" + f"  {component}: {flow(entry)}\n")
        return
    t = e.text(rel)
    if rel.endswith(".txt"):
        if settings:
            raise EditError("deployment.txt holds implementations only (Component=impl): settings need "
                            "a deployment.yaml")
        kept = [line for line in t.text.splitlines(keepends=True)
                if line.split("#", 1)[0].partition("=")[0].strip() != component]
        if kept and not kept[-1].endswith("\n"):
            kept[-1] += "\n"
        t.text = "".join(kept) + f"{component}={impl}\n"
        e.put(t)
        return
    root = _deployment_root(t)
    comps = get(root, "components")
    if isinstance(comps, yaml.MappingNode):
        set_key(t, comps, component, entry)
    else:
        set_key(t, root, "components", {component: entry}, block=True)
    e.put(t)


def set_deployment(e: Edits, op: Op) -> None:
    _write_deployment(e, _need(op.component, "component", op), _need(op.impl, "impl", op), op.settings)


def add_port(e: Edits, op: Op) -> None:
    component = _need(op.component, "component", op)
    port = _need(op.port, "port", op)
    feature = _need(op.feature, "feature", op)
    if not _NAME.fullmatch(port):
        raise EditError(f"port name {port!r} is not a plain name",
                        fields={"port": "must be a plain name (letters, digits and _; no spaces)"})
    t, _, components = _components(e)
    value = get(components, component)
    if value is None or not isinstance(components, yaml.MappingNode):
        raise EditError(f"no component {component!r}")
    if isinstance(value, yaml.ScalarNode):
        replace_node(t, value, flow({"kind": value.value, "ports": {port: feature}}))
    elif isinstance(value, yaml.MappingNode):
        ports = get(value, "ports")
        if isinstance(ports, yaml.MappingNode):
            if get(ports, port) is not None:
                raise EditError(f"component {component!r} has a port {port!r} already")
            set_key(t, ports, port, feature)
        else:
            set_key(t, value, "ports", {port: feature})
    e.put(t)


def remove_port(e: Edits, op: Op) -> None:
    component = _need(op.component, "component", op)
    port = _need(op.port, "port", op)
    t, _, components = _components(e)
    ports = get(get(components, component), "ports")
    if not isinstance(ports, yaml.MappingNode) or not delete_key(t, ports, port):
        raise EditError(f"component {component!r} has no port {port!r}")
    e.put(t)


def add_link(e: Edits, op: Op) -> None:
    ends = [_need(op.source_ref, "from", op), _need(op.target_ref, "to", op)]
    for end in ends:
        if not _PORT_REF.fullmatch(end):
            raise EditError(f"a link end is Component.port, not {end!r}")
    link: dict[str, Any] = {}
    if op.id:
        link["id"] = op.id
    link.update({"from": ends[0], "to": ends[1]})
    t, root = e.model_root()
    links = get(root, "links")
    if isinstance(links, yaml.SequenceNode):
        append_item(t, links, link)
    else:
        set_key(t, root, "links", [link], block=True)
    e.put(t)


def remove_link(e: Edits, op: Op) -> None:
    link_id = _need(op.id, "id", op)
    t, root = e.model_root()
    links = get(root, "links")
    if isinstance(links, yaml.SequenceNode):
        for index, item in enumerate(links.value):
            if (_scalar_text(get(item, "id")) or f"link{index + 1}") == link_id:
                delete_item(t, links, index)
                e.put(t)
                return
    raise EditError(f"no link {link_id!r}")


# --- renames ---------------------------------------------------------------------------------------
#
# A rename changes the name's own token and every token that refers to it, nothing else: the rest
# of each file stays byte for byte. References in expressions are found with the compiler's own
# parser (names with their offsets), so `LeftActuatorX` or a string 'LeftActuator' is not one.


@dataclass(frozen=True)
class Rename:
    """One thing renamed: a node (`lane` is its swimlane), a swimlane or a component. The layout
    file's positions are keyed by these names (`rename_positions`)."""

    kind: str  # "node", "lane" or "component"
    old: str
    new: str
    lane: str | None = None

    def reverse(self) -> Rename:
        return Rename(self.kind, self.new, self.old, self.lane)


def rename_positions(layout: dict[str, Any], renames: Sequence[Rename]) -> bool:
    """Move the positions saved under the renamed names (`<lane>/<node>` keys of the activity
    diagrams, a component's name in `components`) to the new names, in place; True if any moved."""
    moved = False
    for diagram, bucket in (layout.get("positions") or {}).items():
        if not isinstance(bucket, dict):
            continue
        for r in renames:
            for key in list(bucket):
                if r.kind == "node":
                    new_key = f"{r.lane}/{r.new}" if key == f"{r.lane}/{r.old}" else None
                elif diagram == "components":
                    new_key = r.new if r.kind == "component" and key == r.old else None
                else:
                    new_key = r.new + key[len(r.old):] if key.startswith(f"{r.old}/") else None
                if new_key is not None:
                    bucket[new_key] = bucket.pop(key)
                    moved = True
    return moved


class _Patches:
    """Replacements of spans of whole files, made at the end (each file's from its end back)."""

    def __init__(self, e: Edits) -> None:
        self.e = e
        self.texts: dict[str, Text] = {}
        self.spans: dict[str, set[tuple[int, int, str]]] = {}

    def text(self, rel: str) -> Text:
        if rel not in self.texts:
            self.texts[rel] = self.e.text(rel)
        return self.texts[rel]

    def add(self, t: Text, start: int, end: int, new: str) -> None:
        self.spans.setdefault(t.name, set()).add((start + len(t.before), end + len(t.before), new))

    def scalar(self, t: Text, node: yaml.Node | None, edits: Sequence[tuple[int, int, str]]) -> None:
        """Replace `(offset, length, new)` spans of a scalar's value: in place where the value is
        written as it reads (plain or quoted without escapes), else the scalar is written anew."""
        if not isinstance(node, yaml.ScalarNode) or not edits:
            return
        start, end = t.start(node), t.end(node)
        raw = t.text[start:end]
        if node.style in ("'", '"') and len(raw) >= 2 and raw[0] == raw[-1] == node.style:
            start, end, raw = start + 1, end - 1, raw[1:-1]
        elif node.style:
            raw = ""  # a block scalar: written anew
        if raw == node.value:
            for offset, length, new in edits:
                self.add(t, start + offset, start + offset + length, new)
            return
        value = node.value
        for offset, length, new in sorted(edits, reverse=True):
            value = value[:offset] + new + value[offset + length:]
        self.add(t, t.start(node), t.end(node), scalar(value, expression=True))

    def commit(self) -> None:
        for rel, spans in self.spans.items():
            t = self.e.text(rel)
            text = t.text
            last = len(text) + 1
            for start, end, new in sorted(spans, reverse=True):
                if end > last:
                    raise EditError(f"{rel}: two renames of the same text")  # not expected
                text = text[:start] + new + text[end:]
                last = start
            t.text = text
            self.e.put(t)


def _check_new_name(new: str, field_name: str, what: str, taken: Mapping[str, str]) -> None:
    """A new swimlane or component name: a plain identifier, not taken (what the compiler refuses
    besides, e.g. a reserved name, is refused with its message: `Workspace.edit`)."""
    if not _NAME.fullmatch(new):
        raise EditError(f"{what} name {new!r} is not a plain name (letters, digits and _)",
                        fields={field_name: "must be a plain name (letters, digits and _; no spaces, "
                                            "not starting with a digit)"})
    if new in taken:
        raise EditError(f"there is {taken[new]} {new!r} already",
                        fields={field_name: f"is taken by {taken[new]}"})


def _lane_maps(t: Text) -> Iterator[yaml.MappingNode]:
    """The swimlanes of one file (a `lanes:` list, or the file is one lane)."""
    root = t.root()
    if not isinstance(root, yaml.MappingNode):
        return
    lanes = get(root, "lanes")
    if isinstance(lanes, yaml.SequenceNode):
        yield from (item for item in lanes.value if isinstance(item, yaml.MappingNode))
    elif t.name != MODEL_FILE and get(root, "lane") is not None:
        yield root


def _lane_names(e: Edits) -> set[str]:
    return {name for rel in e.lane_files() for lane_map in _lane_maps(e.text(rel))
            if (name := _scalar_text(get(lane_map, "lane"))) is not None}


def _component_names(e: Edits) -> set[str]:
    if e.files.get(MODEL_FILE) is None:
        return set()
    components = get(e.model_root()[1], "components")
    if not isinstance(components, yaml.MappingNode):
        return set()
    return {k.value for k, _ in components.value if isinstance(k, yaml.ScalarNode)}


def _expression_scalars(lane_map: yaml.MappingNode) -> Iterator[yaml.ScalarNode]:
    """The scalars of a swimlane the compiler reads as expressions: calls, values, payloads, guards."""
    nodes = get(lane_map, "nodes")
    for item in nodes.value if isinstance(nodes, yaml.SequenceNode) else []:
        for key in ("call", "value", "payload"):
            node = get(item, key)
            if isinstance(node, yaml.ScalarNode):
                yield node
        branches = get(item, "branches")
        for branch in branches.value if isinstance(branches, yaml.SequenceNode) else []:
            guard = get(branch, "if")
            if isinstance(guard, yaml.ScalarNode):
                yield guard


def _datastores(lane_map: yaml.MappingNode) -> set[str]:
    """The datastores a swimlane writes (a datastore node's `name`, an accept node's `store`)."""
    nodes = get(lane_map, "nodes")
    names: set[str] = set()
    for item in nodes.value if isinstance(nodes, yaml.SequenceNode) else []:
        kind = _scalar_text(get(item, "kind"))
        name = _scalar_text(get(item, "name" if kind == "datastore" else "store" if kind == "accept"
                                else ""))
        if name:
            names.add(name.strip())
    return names


def _names_in(text: str) -> list[tuple[RName, bool]]:
    """Every name of an expression and whether it is called (None: it does not parse)."""
    try:
        expr = parse_expression(text)
    except ModelError:
        return []
    found: list[tuple[RName, bool]] = []
    stack: list[RawExpr] = [expr]
    while stack:
        node = stack.pop()
        if isinstance(node, RName):
            found.append((node, False))
        elif isinstance(node, RCall):
            found.append((node.name, True))
            stack.extend(node.args)
        elif isinstance(node, RUnary):
            stack.append(node.operand)
        elif isinstance(node, RBinary):
            stack.extend((node.left, node.right))
    return found


def _rename_references(e: Edits, p: _Patches, old: str, new: str) -> None:
    """Rename a swimlane's `lane:` and every expression naming `old` (a virtual lane called as
    `Old` or `Old()`, a datastore read `Old.store`, a component's `Old.feature(...)`) in every
    swimlane. A bare `Old` in a lane with a datastore `Old` is that datastore, and stays."""
    for rel in e.lane_files():
        content = e.files[rel]
        if content is None or old not in content:
            continue  # a reference is written out
        t = p.text(rel)
        for lane_map in _lane_maps(t):
            lane_name = _scalar_text(get(lane_map, "lane"))
            if lane_name == old:
                p.scalar(t, get(lane_map, "lane"), [(0, len(old), new)])
            stores = _datastores(lane_map)
            for node in _expression_scalars(lane_map):
                if old not in node.value:
                    continue
                spans: list[tuple[int, int, str]] = []
                for name, called in _names_in(node.value):
                    if name.parts[0] != old or (len(name.parts) == 1 and not called and old in stores):
                        continue
                    if len(name.parts) == 1 and new in stores and not called:
                        raise EditError(
                            f"swimlane {lane_name!r} has a datastore {new!r}: its {old!r} would read "
                            "it after the rename", fields={"new_name": f"is a datastore of swimlane "
                                                                       f"'{lane_name}'"})
                    spans.append((name.offsets[0], len(old), new))
                p.scalar(t, node, spans)


def rename_node(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    old = _need(op.id, "id", op)
    new = _need(op.new_id, "new_id", op)
    t, nodes = _lane_nodes(e, lane)
    _, item = _find_node(nodes, lane, old)
    if new == old:
        return
    if not _NODE_ID.fullmatch(new):
        raise EditError(f"node id {new!r} is not a plain name (letters, digits, _ and -)",
                        fields={"new_id": "must be a plain name (letters, digits, _ and -; no spaces)"})
    if new in _node_ids(nodes):
        raise EditError(f"swimlane {lane!r} has a node {new!r} already",
                        fields={"new_id": "is taken by another node of this swimlane"})
    p = _Patches(e)
    p.scalar(t, get(item, "id"), [(0, len(old), new)])
    for node in nodes.value:  # the flows into it: next, a decision's then/else, a fork's targets
        refs: list[yaml.Node | None] = [get(node, "next")]
        branches = get(node, "branches")
        for branch in branches.value if isinstance(branches, yaml.SequenceNode) else []:
            refs += [get(branch, "then"), get(branch, "else")]
        targets = get(node, "targets")
        refs += targets.value if isinstance(targets, yaml.SequenceNode) else []
        for ref in refs:
            if isinstance(ref, yaml.ScalarNode) and ref.value.strip() == old:
                p.scalar(t, ref, [(ref.value.index(old), len(old), new)])
    p.commit()
    e.renames.append(Rename("node", old, new, lane))


def rename_lane(e: Edits, op: Op) -> None:
    old = _need(op.lane, "lane", op)
    new = _need(op.new_name, "new_name", op)
    e.find_lane(old, whole=True)
    components = _component_names(e)
    if old in components:
        raise EditError(f"swimlane {old!r} is the swimlane of component {old!r}: rename the "
                        "component (its swimlane follows)",
                        fields={"new_name": f"rename component '{old}' instead: its swimlane follows"})
    if new == old:
        return
    taken = {name: "a swimlane" for name in _lane_names(e)}
    taken.update((name, "a component") for name in components)
    _check_new_name(new, "new_name", "swimlane", taken)
    p = _Patches(e)
    _rename_references(e, p, old, new)
    p.commit()
    e.renames.append(Rename("lane", old, new))


def rename_component(e: Edits, op: Op) -> None:
    old = _need(op.component, "component", op)
    new = _need(op.new_name, "new_name", op)
    t, root, components = _components(e)
    knode = key_node(components, old) if isinstance(components, yaml.MappingNode) else None
    if knode is None:
        raise EditError(f"no component {old!r}")
    if new == old:
        return
    lanes = _lane_names(e)
    taken = {name: "a swimlane" for name in lanes if name != old}
    taken.update((name, "another component") for name in _component_names(e))
    _check_new_name(new, "new_name", "component", taken)
    p = _Patches(e)
    p.texts[t.name] = t
    p.scalar(t, knode, [(0, len(old), new)])
    links = get(root, "links")
    for link in links.value if isinstance(links, yaml.SequenceNode) else []:
        for end in (get(link, "from"), get(link, "to")):
            match = _PORT_REF.fullmatch(end.value) if isinstance(end, yaml.ScalarNode) else None
            if match is not None and match.group(1) == old:
                p.scalar(t, end, [(0, len(old), new)])
    # its deployment entries: inline in model.yaml, and in every deployment file there is
    inline = get(root, "deployment")
    if isinstance(inline, yaml.MappingNode):
        _rename_deployment_key(p, t, inline, old, new)
    for rel in DEPLOYMENT_FILES:
        if not e.exists(rel) or old not in (e.files.get(rel) or old):
            continue
        d = p.text(rel)
        if rel.endswith(".txt"):
            at = 0
            for line in d.text.splitlines(keepends=True):
                name, sep, _ = line.split("#", 1)[0].partition("=")
                if sep and name.strip() == old:
                    column = len(name) - len(name.lstrip())
                    p.add(d, at + column, at + column + len(old), new)
                at += len(line)
        else:
            _rename_deployment_key(p, d, _deployment_root(d), old, new)
    _rename_references(e, p, old, new)  # its swimlane and the calls of its features
    p.commit()
    e.renames.append(Rename("component", old, new))


def _rename_deployment_key(p: _Patches, t: Text, root: yaml.MappingNode, old: str, new: str) -> None:
    comps = get(root, "components")
    knode = key_node(comps, old) if isinstance(comps, yaml.MappingNode) else None
    if knode is not None:
        p.scalar(t, knode, [(0, len(old), new)])


#: the most a file's text set in the page may hold (a model file is small; the compiler's own
#: limit on a file's size reports anything bigger).
MAX_TEXT_CHARS = 2_000_000


def set_text(e: Edits, op: Op) -> None:
    """Replace the whole text of an existing model file (the page's text view of a file the
    compiler cannot read, e.g. a YAML syntax error): what the person typed, as typed."""
    rel = _need(op.file, "file", op)
    if op.text is None:
        raise EditError("set_text needs 'text': the file's new text")
    if len(op.text) > MAX_TEXT_CHARS:
        raise EditError(f"{rel}: the text is too long ({len(op.text)} characters; at most {MAX_TEXT_CHARS})")
    e._refuse_unreadable(rel)
    if e.files.get(rel) is None:
        raise EditError(f"{rel} does not exist")
    e.put(Text(op.text, rel))


OPS: dict[str, Callable[[Edits, Op], None]] = {
    "set_text": set_text,
    "add_component": add_component,
    "remove_component": remove_component,
    "set_deployment": set_deployment,
    "add_port": add_port,
    "remove_port": remove_port,
    "add_link": add_link,
    "remove_link": remove_link,
    "add_lane": add_lane,
    "remove_lane": remove_lane,
    "add_node": add_node,
    "set_node": set_node,
    "remove_node": remove_node,
    "connect": connect,
    "disconnect": disconnect,
    "set_guard": set_guard,
    "rename_node": rename_node,
    "rename_lane": rename_lane,
    "rename_component": rename_component,
}


def apply_ops(files: Mapping[str, str | None], ops: list[Op],
              renames: list[Rename] | None = None) -> dict[str, str | None]:
    """Apply `ops` in order to the texts `files`; the changed files' new texts (None: removed).
    What the operations renamed is added to `renames` (for the layout's positions)."""
    edits = Edits(files)
    for index, op in enumerate(ops):
        try:
            OPS[op.op](edits, op)
        except EditError as exc:
            raise EditError(f"operation {index + 1} ({op.op}): {exc}", fields=exc.fields,
                            plain=exc.message) from None
    if renames is not None:
        renames.extend(edits.renames)
    return {rel: edits.files[rel] for rel in sorted(edits.changed) if edits.files[rel] != files.get(rel)}


__all__ = ["OPS", "EditError", "Op", "Rename", "apply_ops", "parse_ops", "rename_positions"]
