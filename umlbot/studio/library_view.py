"""The component library and the editable parts of the model format, as JSON for the page.

Generated from the compiler's and the library's own definitions (`umlbot.base.library`, the node kinds
of `umlbot.compiler.source`, the hardware drivers' settings models of `umlbot.base.registry`, built-in and
plugins' alike), so the page never holds
a second definition of the model format. `library()` is the one conversion of the library.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from functools import lru_cache
from typing import Any

from umlbot.base import catalog
from umlbot.base import library as lib
from umlbot.compiler.checker import RESERVED, SLEEP_BUILTINS
from umlbot.compiler.source import NODE_FIELDS, NODE_KINDS

_FIELD_DOCS: dict[str, tuple[str, str]] = {
    "next": ("node", "the node that follows (default: the node written below)"),
    "call": ("expression", "Component.feature(args), a virtual lane, or msleep(ms) / usleep(us)"),
    "name": ("name", "the datastore written"),
    "value": ("expression", "the value stored"),
    "branches": ("branches", "outputs {if: guard, then: node} and at most one {else: node}"),
    "targets": ("nodes", "the nodes started concurrently (two or more)"),
    "signal": ("name", "the signal's name (topic umlbot/<robot>/signal/<name>)"),
    "payload": ("expression", "the value sent (optional)"),
    "store": ("name", "the datastore that receives the payload (optional)"),
}
#: what each node kind does, in a few words (the palette's tooltips)
_KIND_DOCS: dict[str, str] = {
    "start": "where the lane begins", "end": "where the lane ends",
    "action": "calls a feature, a lane or a builtin", "datastore": "a named value",
    "decision": "branches on guards", "fork": "runs branches at once", "join": "waits for every branch",
    "send": "sends a signal", "accept": "waits for a signal",
}
_REQUIRED = {("action", "call"), ("datastore", "name"), ("datastore", "value"), ("decision", "branches"),
             ("fork", "targets"), ("send", "signal"), ("accept", "signal")}


def _param(param: lib.Param) -> dict[str, Any]:
    return {"name": param.name, "type": param.type, "minimum": param.minimum, "maximum": param.maximum,
            "unit": param.unit}


def _feature(spec: lib.FeatureSpec) -> dict[str, Any]:
    return {"params": [_param(p) for p in spec.params], "returns": spec.returns, "doc": spec.doc}


def settings_model(impl: lib.Implementation) -> Any:
    """The settings model the page's form is built from (the first hardware driver's), or None."""
    from umlbot.base.registry import hardware_settings_models

    models = hardware_settings_models(impl.service)
    return models[0][1] if models else None


@lru_cache(maxsize=1)
def library() -> dict[str, Any]:
    """`GET /api/library`: kinds and features, implementations, builtins, node kinds."""
    implementations = []
    for impl in catalog.implementations().values():
        model = settings_model(impl)
        implementations.append({
            "id": impl.id, "kind": impl.kind, "service": impl.service, "title": impl.title,
            "aliases": list(impl.aliases),
            "features": {name: _feature(spec) for name, spec in impl.features.items()},
            "settings_doc": dict(impl.settings_doc),
            "settings_schema": model.model_json_schema() if model is not None else None,
        })
    builtins = [
        {"name": name, "params": [{"name": unit, "type": "int", "minimum": 0, "maximum": None,
                                   "unit": unit}], "returns": "none",
         "doc": f"wait {'milliseconds' if unit == 'ms' else 'microseconds'}"}
        for name, unit in SLEEP_BUILTINS.items()
    ] + [{"name": "Application.exit", "params": None, "returns": "bool",
          "doc": "true once the robot was asked to stop"}]
    # in the compiler's order (the palette's); a field of type "expression" is edited with completion
    node_kinds = {
        kind: {"doc": _KIND_DOCS[kind],
               "fields": {name: {"type": _FIELD_DOCS[name][0], "required": (kind, name) in _REQUIRED,
                                 "doc": _FIELD_DOCS[name][1]} for name in NODE_FIELDS[kind]}}
        for kind in NODE_KINDS
    }
    return {
        "kinds": {kind: {"features": {name: _feature(spec) for name, spec in features.items()}}
                  for kind, features in catalog.component_kinds().items()},
        "implementations": implementations,
        "builtins": builtins,
        "node_kinds": node_kinds,
        "reserved": sorted(RESERVED),
        "expression_help": {
            "operators": ["or", "and", "not", "==", "!=", "<", "<=", ">", ">=", "+", "-", "*", "/", "%"],
            "constants": ["true", "false", "null"],
            "doc": "docs/model-format.md#expressions",
        },
    }


def check_settings(impl_name: str, settings: Mapping[str, Any]) -> str | None:
    """Why `settings` are not valid for the implementation `impl_name` on the hardware (None when
    they are): the editor deploys a component with the settings every hardware driver accepts."""
    from umlbot.base.registry import AUTO, settings_problems

    impl = catalog.resolve_implementation(impl_name)
    if impl is None:
        known = ", ".join(catalog.implementations())
        return f"unknown implementation {impl_name!r} (known: {known})"
    problems = [f"{'.'.join(str(p) for p in path) or 'settings'}: {msg}"
                for path, msg in settings_problems(impl.service, AUTO, settings)]
    return "invalid settings: " + "; ".join(problems) if problems else None


def settings_problems(impl_name: str, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
    """(setting, what is wrong) for each problem `check_settings` finds, in words for the person
    who typed the value ("must be at most 27"); the setting is "" for the settings as a whole."""
    from umlbot.base.registry import AUTO
    from umlbot.base.registry import settings_problems as problems

    impl = catalog.resolve_implementation(impl_name)
    if impl is None:
        return [("", f"unknown implementation {impl_name!r}")]
    out: list[tuple[str, str]] = []
    for path, msg in problems(impl.service, AUTO, settings):
        key = str(path[0]) if path else ""
        entry = (key, _plain(msg))
        if entry not in out:
            out.append(entry)
    return out


_PYDANTIC_WORDS = (
    (re.compile(r"^Input should be less than or equal to (.+)$"), r"must be at most \1"),
    (re.compile(r"^Input should be greater than or equal to (.+)$"), r"must be at least \1"),
    (re.compile(r"^Input should be less than (.+)$"), r"must be below \1"),
    (re.compile(r"^Input should be greater than (.+)$"), r"must be above \1"),
    (re.compile(r"^Input should be a valid integer.*$"), "must be a whole number"),
    (re.compile(r"^Input should be a valid number.*$"), "must be a number"),
    (re.compile(r"^Field required$"), "is required"),
    (re.compile(r"^Extra inputs are not permitted$"), "is not a setting of this part"),
)


def _plain(msg: str) -> str:
    for pattern, words in _PYDANTIC_WORDS:
        if pattern.match(msg):
            return pattern.sub(words, msg)
    return msg[0].lower() + msg[1:] if msg else msg
