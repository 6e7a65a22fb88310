"""The component library and the editable parts of the model format, as JSON for the page.

Generated from the compiler's and the library's own definitions (`umlbot.library`, the node kinds
of `compiler.source`, the driver settings models of `services.registry`), so the page never holds
a second definition of the model format. `library()` is the one conversion of the library.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
from typing import Any

from pydantic import ValidationError

from compiler.checker import RESERVED, SLEEP_BUILTINS
from compiler.source import NODE_FIELDS, NODE_KINDS
from umlbot import library as lib

#: the driver whose settings model describes a part's settings (the real hardware).
SETTINGS_DRIVER = "pigpio"

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
_REQUIRED = {("action", "call"), ("datastore", "name"), ("datastore", "value"), ("decision", "branches"),
             ("fork", "targets"), ("send", "signal"), ("accept", "signal")}


def _param(param: lib.Param) -> dict[str, Any]:
    return {"name": param.name, "type": param.type, "minimum": param.minimum, "maximum": param.maximum,
            "unit": param.unit}


def _feature(spec: lib.FeatureSpec) -> dict[str, Any]:
    return {"params": [_param(p) for p in spec.params], "returns": spec.returns, "doc": spec.doc}


def settings_model(impl: lib.Implementation) -> Any:
    """The pydantic model of an implementation's driver settings, or None when it has none."""
    from services.registry import get_factory
    from umlbot.errors import UnknownDriver

    try:
        return get_factory(impl.service, SETTINGS_DRIVER).settings_model
    except UnknownDriver:
        return None


@lru_cache(maxsize=1)
def library() -> dict[str, Any]:
    """`GET /api/library`: kinds and features, implementations, builtins, node kinds."""
    implementations = []
    for impl in lib.implementations().values():
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
    node_kinds = {
        kind: {"fields": {name: {"type": _FIELD_DOCS[name][0], "required": (kind, name) in _REQUIRED,
                                 "doc": _FIELD_DOCS[name][1]} for name in NODE_FIELDS[kind]}}
        for kind in NODE_KINDS
    }
    return {
        "kinds": {kind: {"features": {name: _feature(spec) for name, spec in features.items()}}
                  for kind, features in lib.component_kinds().items()},
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
    """Why `settings` are not valid for the implementation `impl_name` (None when they are)."""
    from services.registry import driver_settings

    impl = lib.resolve_implementation(impl_name)
    if impl is None:
        known = ", ".join(lib.implementations())
        return f"unknown implementation {impl_name!r} (known: {known})"
    model = settings_model(impl)
    if model is None:
        return None
    try:
        model.model_validate(driver_settings(SETTINGS_DRIVER, settings))
    except ValidationError as exc:
        return "invalid settings: " + "; ".join(
            f"{'.'.join(str(p) for p in err['loc']) or 'settings'}: {err['msg']}" for err in exc.errors())
    return None
