"""Completion and argument hints for the page's call and guard editor.

Built from the model as it is now (the editor's view of the working copy) and the component
library: components and their implementation's features (with the implementation's ranges),
swimlanes (virtual lanes can be called, any lane's datastores read as `Lane.name`), the lane's own
datastores, builtins and keywords. Nothing here parses the model format itself.
"""

from __future__ import annotations

import re
from typing import Any

from umlbot.base import catalog
from umlbot.base import library as lib
from umlbot.compiler.checker import SLEEP_BUILTINS

KEYWORDS = ("and", "or", "not", "true", "false", "null")
#: the (dotted) name just before the cursor.
_WORD = re.compile(r"(?<![\w.])[A-Za-z_][\w.]*$")
_CALLEE = re.compile(r"([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)?)\s*$")


def _param_text(param: dict[str, Any]) -> str:
    text = f"{param['name']}: {param['type']}"
    if param.get("minimum") is not None and param.get("maximum") is not None:
        text += f" {param['minimum']:g}..{param['maximum']:g}"
    elif param.get("minimum") is not None:
        text += f" >= {param['minimum']:g}"
    if param.get("unit"):
        text += f" {param['unit']}"
    return text


def _params(spec: lib.FeatureSpec) -> list[dict[str, Any]]:
    return [{"name": p.name, "type": p.type, "minimum": p.minimum, "maximum": p.maximum, "unit": p.unit}
            for p in spec.params]


def _features(component: dict[str, Any]) -> dict[str, lib.FeatureSpec]:
    """The features a component of the model offers: its implementation's, else its kind's."""
    impl = catalog.resolve_implementation(component.get("impl") or "")
    if impl is not None:
        return dict(impl.features)
    kind = component.get("kind")
    kinds = catalog.component_kinds()
    return dict(kinds[kind]) if kind in kinds else {}


def _gives_value(component: dict[str, Any]) -> bool:
    """Whether a component has a feature that returns a value (one that can be read in an
    expression)."""
    return any(spec.returns != "none" for spec in _features(component).values())


def _signature_of(callee: str, components: dict[str, dict[str, Any]]) -> dict[str, Any] | None:
    if callee in SLEEP_BUILTINS:
        unit = SLEEP_BUILTINS[callee]
        params = [{"name": unit, "type": "int", "minimum": 0, "maximum": None, "unit": unit}]
        return {"label": f"{callee}({unit}: int {unit})", "params": params, "returns": "none",
                "doc": f"wait {unit}"}
    head, _, feature = callee.partition(".")
    component = components.get(head)
    if component is None or not feature:
        return None
    spec = _features(component).get(feature)
    if spec is None:
        return None
    params = _params(spec)
    label = f"{head}.{feature}({', '.join(_param_text(p) for p in params)})"
    if spec.returns != "none":
        label += f" -> {spec.returns}"
    return {"label": label, "params": params, "returns": spec.returns, "doc": spec.doc}


def _open_call(before: str) -> tuple[str, int] | None:
    """(callee, index of the argument being typed) of the innermost call the cursor is in."""
    depth = 0
    commas = 0
    quote = ""
    # strings first: blank them out so their brackets and commas do not count
    cleaned = []
    for ch in before:
        if quote:
            cleaned.append(" ")
            if ch == quote:
                quote = ""
            continue
        if ch in "'\"":
            quote = ch
            cleaned.append(" ")
            continue
        cleaned.append(ch)
    text = "".join(cleaned)
    for index in range(len(text) - 1, -1, -1):
        ch = text[index]
        if ch == ")":
            depth += 1
        elif ch == "(":
            if depth == 0:
                match = _CALLEE.search(text[:index])
                return (match.group(1), commas) if match else None
            depth -= 1
        elif ch == "," and depth == 0:
            commas += 1
    return None


def complete(model: dict[str, Any] | None, lane: str | None, text: str, cursor: int | None,
             field: str | None = None) -> dict[str, Any]:
    """Completions at `cursor` in `text` (a call, guard or value of a node of `lane`)."""
    cursor = len(text) if cursor is None else max(0, min(cursor, len(text)))
    before = text[:cursor]
    components = {c["name"]: c for c in (model or {}).get("components", [])}
    lanes = {x["name"]: x for d in (model or {}).get("diagrams", []) for x in d["lanes"]}
    word = _WORD.search(before)
    typed = word.group(0) if word else ""
    head: str | None = None
    partial = typed
    if "." in typed:
        head, _, partial = typed.rpartition(".")
    call = _open_call(before)
    in_argument = call is not None  # a value: no sleeps, no lane calls (they give none)
    # an argument, a guard or a datastore's value needs a value: nothing that gives none is offered
    # (a feature returning none, a component without a feature that returns something)
    needs_value = in_argument or (field is not None and field != "call")
    items: list[dict[str, Any]] = []
    if head is not None:
        if head in components:
            for name, spec in _features(components[head]).items():
                if needs_value and spec.returns == "none":
                    continue
                sig = _signature_of(f"{head}.{name}", components)
                items.append({"label": name, "kind": "feature", "detail": sig["label"] if sig else name,
                              "insert": f"{name}(" if spec.params else f"{name}()"})
        if head in lanes:
            for store in lanes[head]["datastores"]:
                items.append({"label": store, "kind": "datastore", "detail": f"datastore of {head}",
                              "insert": store})
        if head == "Application":
            items.append({"label": "exit", "kind": "builtin", "detail": "Application.exit -> bool",
                          "insert": "exit"})
    else:
        own = lanes.get(lane or "")
        if own is not None:
            items += [{"label": s, "kind": "datastore", "detail": f"datastore of {lane}", "insert": s}
                      for s in own["datastores"]]
        items += [{"label": name, "kind": "component", "detail": f"{c.get('kind')} ({c.get('impl')})",
                   "insert": f"{name}."} for name, c in sorted(components.items())
                  if not needs_value or _gives_value(c)]
        for name, other in sorted(lanes.items()):
            # (a lane calling itself is recursion, which the checker refuses)
            if other["virtual"] and field in (None, "call") and not in_argument and name != lane:
                items.append({"label": name, "kind": "lane", "detail": "call the virtual swimlane",
                              "insert": name})
            elif other["datastores"] and name != lane:
                items.append({"label": name, "kind": "lane", "detail": "its datastores: Lane.name",
                              "insert": f"{name}."})
        if not needs_value:
            items += [{"label": name, "kind": "builtin", "detail": f"{name}({unit})", "insert": f"{name}("}
                      for name, unit in SLEEP_BUILTINS.items()]
        # Application.exit is a bool: a value too, so it is offered everywhere
        items.append({"label": "Application", "kind": "builtin", "detail": "Application.exit -> bool",
                      "insert": "Application."})
        items += [{"label": k, "kind": "keyword", "detail": "", "insert": k} for k in KEYWORDS]
    low = partial.lower()
    items = [item for item in items if item["label"].lower().startswith(low)]
    signature = None
    if call is not None:
        sig = _signature_of(call[0], components)
        if sig is not None:
            signature = {**sig, "active": min(call[1], max(len(sig["params"]) - 1, 0))}
            if head is None and sig["params"]:
                items = _fitting_first(items, sig["params"][signature["active"]]["type"])
    return {"items": items, "replace": [cursor - len(partial), cursor], "signature": signature}


#: the literals a value of a parameter's type can be written as.
_LITERALS = {"bool": ("true", "false")}


def _fitting_first(items: list[dict[str, Any]], param_type: str) -> list[dict[str, Any]]:
    """Inside an argument: the literals of its type first (`true`, `false` for a bool), then the
    rest in their order; literals of another type (`true` for an int, `null`) last."""
    literals = _LITERALS.get(param_type, ())
    other = {k for t, values in _LITERALS.items() if t != param_type for k in values} | {"null"}

    def rank(item: dict[str, Any]) -> int:
        if item["kind"] == "keyword" and item["label"] in literals:
            return 0
        return 2 if item["kind"] == "keyword" and item["label"] in other else 1

    return sorted(items, key=rank)  # stable: the order within a rank stays
