"""The model as the studio page draws it: components, links and activity diagrams as plain JSON.

Built from the compiled model, so the page never parses the model format itself. Node ids are the
model's ids (unique within a lane); an edge id is `<source>-><target>` (with `#n` appended for a
second edge between the same pair). One activity diagram per activity source file, as in
`umlbot render`.
"""

from __future__ import annotations

import bisect
from typing import Any

from umlbot.base.diagnostics import Diagnostic
from umlbot.base.yamlsrc import YMap, YNode, YScalar, YSeq, to_python
from umlbot.compiler.compiled import AcceptNode, CompiledModel, DatastoreNode, Lane, Node, SendNode
from umlbot.compiler.render import diagram_id, diagrams, successors
from umlbot.compiler.source import SourceLane, SourceModel, SourceNode

#: the version of the JSON shape below; bumped on an incompatible change.
VIEW_VERSION = 1


def _node_view(node: Node) -> dict[str, Any]:
    view: dict[str, Any] = {"id": node.id, "kind": node.kind, "label": node.label, "line": node.line}
    if isinstance(node, DatastoreNode):
        view["store"] = node.name
    elif isinstance(node, SendNode):
        view["signal"] = node.signal
    elif isinstance(node, AcceptNode):
        view["signal"] = node.signal
        if node.store is not None:
            view["store"] = node.store
    return view


def lane_view(lane: Lane) -> dict[str, Any]:
    """One swimlane: its nodes in file order and its edges."""
    nodes = sorted(lane.nodes.values(), key=lambda n: (n.line, n.id))
    edges: list[dict[str, Any]] = []
    seen: dict[tuple[str, str], int] = {}
    for node in nodes:
        for target, label in successors(node):
            pair = (node.id, target)
            seen[pair] = seen.get(pair, 0) + 1
            edge_id = f"{node.id}->{target}" + (f"#{seen[pair]}" if seen[pair] > 1 else "")
            edges.append({"id": edge_id, "source": node.id, "target": target, "label": label})
    return {
        "name": lane.name,
        "virtual": lane.virtual,
        "component": lane.component,
        "file": lane.file,
        "line": lane.line,
        "start": lane.start,
        "datastores": list(lane.datastores),
        "nodes": [_node_view(node) for node in nodes],
        "edges": edges,
    }


def model_view(model: CompiledModel) -> dict[str, Any]:
    """The whole model for the page (see docs/studio.md, "The page's data")."""
    components = [
        {
            "name": name,
            "kind": component.kind,
            "impl": component.impl,
            "service": component.service,
            "driver": component.driver,
            "features": list(component.features),
            "ports": dict(component.ports),
        }
        for name, component in sorted(model.components.items())
    ]
    links = [
        {
            "id": link.id,
            "source": {"component": link.source_component, "port": link.source_port},
            "target": {"component": link.target_component, "port": link.target_port},
        }
        for link in model.links
    ]
    activity = [
        {"id": diagram_id, "title": diagram_id.removeprefix("activity-"), "file": lanes[0].file,
         "lanes": [lane_view(lane) for lane in lanes]}
        for diagram_id, lanes in diagrams(model).items()
    ]
    return {
        "version": VIEW_VERSION,
        "name": model.name,
        "signals": list(model.signals),
        "components": components,
        "links": links,
        "diagrams": activity,
    }


def diagnostic_view(diagnostic: Diagnostic) -> dict[str, Any]:
    """One compiler problem, with the `file:line:col: severity: message` text `umlbot check` prints."""
    from umlbot.studio.plain import plain_message

    loc = diagnostic.location
    return {"severity": diagnostic.severity, "message": diagnostic.message, "file": loc.file,
            "line": loc.line, "column": loc.column, "text": str(diagnostic),
            # the same in words a modeller knows (the page shows it; the CLI keeps the message)
            "plain": plain_message(diagnostic.message) or diagnostic.message}


# --- the model as written (the editor's view: also when it does not compile) ------------------------

#: node kinds whose one outgoing flow is `next`, else the node written below.
_NEXT_KINDS = ("start", "action", "datastore", "join", "send", "accept")


def _text(node: YNode | None) -> str | None:
    return node.text if isinstance(node, YScalar) else None


def _source_fields(src: SourceNode) -> dict[str, Any]:
    """A node's keys besides id and kind, as written (expressions as their text)."""
    fields: dict[str, Any] = {}
    for key in src.fields:
        if key in ("id", "kind"):
            continue
        value = src.fields.items[key]
        if key == "branches" and isinstance(value, YSeq):
            fields[key] = [{k: _text(b.items[k]) for k in b} for b in value.items if isinstance(b, YMap)]
        elif key == "targets" and isinstance(value, YSeq):
            fields[key] = [_text(t) for t in value.items]
        else:
            fields[key] = _text(value) if isinstance(value, YScalar) else to_python(value)
    return fields


def _source_label(kind: str, node_id: str, fields: dict[str, Any]) -> str:
    """The node's label as the compiler writes it once it is complete; a part not written yet is
    left out (a new datastore is drawn `datastore1` until its name is typed, a new send `send`),
    never shown as a made-up value."""
    def part(key: str) -> str:
        value = fields.get(key)
        return "" if value is None else str(value).strip()

    if kind == "action":
        return part("call") or node_id
    if kind == "datastore":
        name, value = part("name"), part("value")
        if name and value:
            return f"{name} = {value}"
        return name or (f"? = {value}" if value else node_id)  # "?": as a flow's unwritten guard
    if kind in ("start", "end", "fork", "join"):
        return kind
    if kind == "send":
        signal, payload = part("signal"), part("payload")
        return " ".join(x for x in ("send", signal) if x) + (f"({payload})" if payload else "")
    if kind == "accept":
        signal, store = part("signal"), part("store")
        return " ".join(x for x in ("accept", signal) if x) + (f" -> {store}" if store else "")
    return node_id


def _source_edges(kind: str, fields: dict[str, Any], following: str | None) -> list[tuple[str, str]]:
    if kind in _NEXT_KINDS:
        target = fields.get("next") if "next" in fields else following
        return [(str(target), "")] if target else []
    if kind == "decision":
        # an output whose guard is not written yet is labelled "?" (the checker reports it)
        out = [(str(b["then"]), str(b.get("if") or "").strip() or "?") for b in fields.get("branches") or []
               if isinstance(b, dict) and b.get("then") and "else" not in b]
        out += [(str(b["else"]), "else") for b in fields.get("branches") or []
                if isinstance(b, dict) and b.get("else")]
        return out
    if kind == "fork":
        return [(str(t), "") for t in fields.get("targets") or [] if t]
    return []


def source_lane_view(lane: SourceLane, components: set[str]) -> dict[str, Any]:
    """One swimlane as written: its nodes in file order (with their fields) and their flows."""
    nodes: list[dict[str, Any]] = []
    edges: list[dict[str, Any]] = []
    seen: dict[tuple[str, str], int] = {}
    datastores: list[str] = []
    for index, src in enumerate(lane.nodes):
        fields = _source_fields(src)
        nodes.append({"id": src.id, "kind": src.kind, "label": _source_label(src.kind, src.id, fields),
                      "line": src.loc.line, "column": src.loc.column, "fields": fields})
        written = {"datastore": "name", "accept": "store"}.get(src.kind)
        name = fields.get(written) if written else None
        if isinstance(name, str) and name not in datastores:
            datastores.append(name)
        following = lane.nodes[index + 1].id if index + 1 < len(lane.nodes) else None
        for target, label in _source_edges(src.kind, fields, following):
            pair = (src.id, target)
            seen[pair] = seen.get(pair, 0) + 1
            edge_id = f"{src.id}->{target}" + (f"#{seen[pair]}" if seen[pair] > 1 else "")
            edges.append({"id": edge_id, "source": src.id, "target": target, "label": label})
    start = next((n.id for n in lane.nodes if n.kind == "start"), None)
    return {"name": lane.name, "virtual": lane.name not in components,
            "component": lane.name if lane.name in components else None, "file": lane.file,
            "line": lane.loc.line, "start": start, "datastores": sorted(datastores), "nodes": nodes,
            "edges": edges}


class LaneViews:
    """The views of swimlanes (`source_lane_view`, `node_index`'s rows) kept from one answer to
    the next by the `SourceLane` object: the incremental check (`IncrementalCheck`) gives the same
    object for a swimlane whose text did not change, so an edit makes again only the views of the
    swimlanes it changed. What is kept is what would be made again."""

    def __init__(self) -> None:
        self._views: dict[tuple[int, bool], tuple[SourceLane, dict[str, Any]]] = {}
        self._rows: dict[int, tuple[SourceLane, list[tuple[int, str, str | None]]]] = {}

    def view(self, lane: SourceLane, components: set[str]) -> dict[str, Any]:
        key = (id(lane), lane.name in components)
        kept = self._views.get(key)
        if kept is None or kept[0] is not lane:
            kept = self._views[key] = (lane, source_lane_view(lane, components))
        return kept[1]

    def rows(self, lane: SourceLane) -> list[tuple[int, str, str | None]]:
        kept = self._rows.get(id(lane))
        if kept is None or kept[0] is not lane:
            kept = self._rows[id(lane)] = (lane, _lane_rows(lane))
        return kept[1]

    def keep_only(self, source: SourceModel) -> None:
        """Forget the views of swimlanes that are not in `source` (the last answer's)."""
        there = {id(lane) for lane in source.lanes}
        self._views = {key: kept for key, kept in self._views.items() if key[0] in there}
        self._rows = {key: kept for key, kept in self._rows.items() if key in there}


def source_view(source: SourceModel, views: LaneViews | None = None) -> dict[str, Any]:
    """The model as its files say, in `model_view`'s shape plus each node's `fields`, each
    component's `settings`; drawn by the editor also while the model has errors. `views`: the
    swimlanes' views kept from the last answer (`LaneViews`)."""
    from umlbot.base.catalog import component_kinds, resolve_implementation

    deployment = source.deployment.deployment if source.deployment is not None else None
    components = []
    for name, comp in sorted(source.components.items()):
        entry = deployment.components.get(name) if deployment is not None else None
        impl = resolve_implementation(entry.impl) if entry is not None else None
        kinds = component_kinds()
        kind_features = kinds.get(comp.kind or "", {})
        components.append({
            "name": name, "kind": comp.kind,
            "impl": impl.id if impl is not None else (entry.impl if entry is not None else None),
            "service": impl.service if impl is not None else None,
            "driver": (entry.driver or deployment.driver) if entry is not None and deployment is not None
            else None,
            "features": list(impl.features if impl is not None else kind_features),
            "ports": {port: feature for port, (feature, _) in comp.ports.items()},
            "settings": dict(entry.settings) if entry is not None else {},
            "line": comp.loc.line,
        })
    links = [{"id": link.id,
              "source": {"component": link.source.component, "port": link.source.port},
              "target": {"component": link.target.component, "port": link.target.port}}
             for link in source.links if link.source is not None and link.target is not None]
    names = set(source.components)
    grouped: dict[str, list[SourceLane]] = {}
    for lane in sorted(source.lanes, key=lambda x: (x.file, x.loc.line, x.name)):
        grouped.setdefault(diagram_id(lane.file), []).append(lane)
    signals = sorted({text for lane in source.lanes for n in lane.nodes if n.kind in ("send", "accept")
                      and (text := _text(n.fields.get("signal")))})
    return {
        "version": VIEW_VERSION,
        "name": source.name,
        "signals": signals,
        "components": components,
        "links": links,
        "diagrams": [{"id": key, "title": key.removeprefix("activity-"), "file": lanes[0].file,
                      "lanes": [views.view(lane, names) if views is not None else
                                source_lane_view(lane, names) for lane in lanes]}
                     for key, lanes in grouped.items()],
    }


def _lane_rows(lane: SourceLane) -> list[tuple[int, str, str | None]]:
    return [(lane.loc.line, lane.name, None), *((node.loc.line, lane.name, node.id) for node in lane.nodes)]


def node_index(source: SourceModel, views: LaneViews | None = None
               ) -> dict[str, list[tuple[int, str, str | None]]]:
    """Per file (relative path): (line, lane, node id or None for the lane's header), sorted."""
    index: dict[str, list[tuple[int, str, str | None]]] = {}
    for lane in source.lanes:
        rows = index.setdefault(lane.file, [])
        rows.extend(views.rows(lane) if views is not None else _lane_rows(lane))
    for rows in index.values():
        rows.sort(key=lambda row: row[0])
    return index


#: a deployment position (file, line, column) -> the component and the editor's field there
#: (`settings.<key>`, `impl`, or None for the component's entry).
FieldIndex = dict[tuple[str, int, int], tuple[str, str | None]]


def deployment_fields(source: SourceModel) -> FieldIndex:
    """Where each component's deployment entry, implementation and settings are written: the
    positions the compiler reports their problems at (a pin wired twice, a refused setting)."""
    from umlbot.base.yamlsrc import locate

    dep = source.deployment
    root = dep.root if dep is not None else None
    out: FieldIndex = {}
    components = root.items.get("components") if isinstance(root, YMap) else None
    if root is None or not isinstance(components, YMap):
        return out
    for name, entry in components.items.items():
        at = locate(root, ("components", name))
        out[(at.file, at.line, at.column)] = (name, None)
        if not isinstance(entry, YMap):
            continue
        for key in ("impl",):
            if key in entry.items:
                at = locate(root, ("components", name, key))
                out[(at.file, at.line, at.column)] = (name, key)
        settings = entry.items.get("settings")
        for key in settings.items if isinstance(settings, YMap) else {}:
            at = locate(root, ("components", name, "settings", key))
            out[(at.file, at.line, at.column)] = (name, f"settings.{key}")
    return out


def attribute(view: dict[str, Any], rel: str | None,
              index: dict[str, list[tuple[int, str, str | None]]],
              fields: FieldIndex | None = None) -> dict[str, Any]:
    """Add `relpath` and the `lane`/`node` a diagnostic points into (by its file and line), or the
    `component` and its deployment `field` (by its position in the deployment)."""
    view["relpath"] = rel
    rows = index.get(rel or "")
    if rows:
        at = bisect.bisect_right(rows, view["line"], key=lambda row: row[0]) - 1
        if at >= 0:
            view["lane"], view["node"] = rows[at][1], rows[at][2]
    owner = (fields or {}).get((view["file"], view["line"], view["column"]))
    if owner is not None:
        view["component"], view["field"] = owner
    return view
