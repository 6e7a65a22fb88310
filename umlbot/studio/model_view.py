"""The model as the studio page draws it: components, links and activity diagrams as plain JSON.

Built from the compiled model, so the page never parses the model format itself. Node ids are the
model's ids (unique within a lane); an edge id is `<source>-><target>` (with `#n` appended for a
second edge between the same pair). One activity diagram per activity source file, as in
`umlbot render`.
"""

from __future__ import annotations

from typing import Any

from compiler.compiled import (
    AcceptNode,
    CompiledModel,
    DatastoreNode,
    DecisionNode,
    EndNode,
    ForkNode,
    Lane,
    Node,
    SendNode,
)
from compiler.diagnostics import Diagnostic
from compiler.render import diagrams

#: the version of the JSON shape below; bumped on an incompatible change.
VIEW_VERSION = 1


def _edges(node: Node) -> list[tuple[str, str]]:
    """(target, label) of every outgoing flow; a decision's labels are its guards (`else` last)."""
    if isinstance(node, DecisionNode):
        return [(b.target, b.label or ("else" if b.guard is None else "")) for b in node.branches]
    if isinstance(node, ForkNode):
        return [(target, "") for target in node.targets]
    if isinstance(node, EndNode):
        return []
    return [(node.next, "")]


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
        for target, label in _edges(node):
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
    loc = diagnostic.location
    return {"severity": diagnostic.severity, "message": diagnostic.message, "file": loc.file,
            "line": loc.line, "column": loc.column, "text": str(diagnostic)}
