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
from collections.abc import Callable, Mapping
from typing import Any, cast

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from compiler.source import (
    ACTIVITIES_DIR,
    ACTIVITY_FILE,
    DEPLOYMENT_FILES,
    MODEL_FILE,
    NODE_FIELDS,
    NODE_KINDS,
)
from umlbot.studio.library_view import check_settings
from umlbot.studio.textedit import (
    EditError,
    Text,
    Value,
    append_item,
    delete_item,
    delete_key,
    flow,
    get,
    insert_item,
    replace_node,
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
        names = [rel for rel, text in self.files.items() if text is not None
                 and ACTIVITY_FILE.fullmatch(rel)]
        return [MODEL_FILE, *sorted(names)] if self.files.get(MODEL_FILE) is not None else sorted(names)

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
            set_key(t, item, key, cast(Value, value))
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
        set_key(t, b, "if", guard)
    else:
        replace_node(t, b, flow({"if": guard, "then": target}))
    e.put(t)


def snake_case(name: str) -> str:
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def add_lane(e: Edits, op: Op) -> None:
    lane = _need(op.lane, "lane", op)
    if not _NAME.fullmatch(lane):
        raise EditError(f"swimlane name {lane!r} is not a plain name (letters, digits and _)")
    try:
        e.find_lane(lane, whole=True)
    except EditError:
        pass
    else:
        raise EditError(f"there is a swimlane {lane!r} already")
    starter = [{"id": "start", "kind": "start"}, {"id": "end", "kind": "end"}]
    if op.file is not None:
        t = e.text(op.file)
        root = t.root()
        lanes = get(root, "lanes") if isinstance(root, yaml.MappingNode) else None
        if not isinstance(lanes, yaml.SequenceNode) or lanes.flow_style or not lanes.value:
            raise EditError(f"{op.file} holds no block list of 'lanes:'; add the lane to its own file")
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
        raise EditError(f"component name {name!r} is not a plain name (letters, digits and _)")
    t, root, components = _components(e)
    if get(components, name) is not None:
        raise EditError(f"there is a component {name!r} already")
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
        raise EditError(f"{component}: {problem}")
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
        raise EditError(f"port name {port!r} is not a plain name")
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


OPS: dict[str, Callable[[Edits, Op], None]] = {
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
}


def apply_ops(files: Mapping[str, str | None], ops: list[Op]) -> dict[str, str | None]:
    """Apply `ops` in order to the texts `files`; the changed files' new texts (None: removed)."""
    edits = Edits(files)
    for index, op in enumerate(ops):
        try:
            OPS[op.op](edits, op)
        except EditError as exc:
            raise EditError(f"operation {index + 1} ({op.op}): {exc}") from None
    return {rel: edits.files[rel] for rel in sorted(edits.changed) if edits.files[rel] != files.get(rel)}


__all__ = ["OPS", "EditError", "Op", "apply_ops", "parse_ops"]
