"""The component library and the editable parts of the model format, as JSON for the page.

Generated from the compiler's and the library's own definitions (`umlbot.library`, the node kinds
of `compiler.source`, the hardware drivers' settings models of `services.registry`, built-in and
plugins' alike), so the page never holds
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
from umlbot.logs import get_logger

log = get_logger(__name__)

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


def settings_models(impl: lib.Implementation) -> list[tuple[str, Any]]:
    """The pydantic models of an implementation's settings on the real hardware: one per hardware
    driver of its service kind (every driver but `auto` and the mock and sim ones, built-in or a
    plugin's), the same model once. `driver: auto` may pick any of them, so a deployment's
    settings must satisfy each. Empty when the service kind has no hardware driver."""
    from services.registry import AUTO, PREFIXED_DRIVERS, get_factory, known_drivers
    from umlbot.errors import DriverError, UnknownDriver

    models: list[tuple[str, Any]] = []
    for driver in known_drivers(impl.service):
        if driver == AUTO or driver in PREFIXED_DRIVERS:
            continue
        try:
            model = get_factory(impl.service, driver).settings_model
        except (UnknownDriver, DriverError) as exc:  # a plugin's driver that does not load
            log.warning("studio: no settings model from a driver", driver=driver, error=str(exc))
            continue
        if all(model is not seen for _, seen in models):
            models.append((driver, model))
    return models


def settings_model(impl: lib.Implementation) -> Any:
    """The settings model the page's form is built from (the first hardware driver's), or None."""
    models = settings_models(impl)
    return models[0][1] if models else None


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
    problems: list[str] = []
    for driver, model in settings_models(impl):
        try:
            model.model_validate(driver_settings(driver, settings))
        except ValidationError as exc:
            for err in exc.errors():
                problem = f"{'.'.join(str(p) for p in err['loc']) or 'settings'}: {err['msg']}"
                if problem not in problems:
                    problems.append(problem)
    return "invalid settings: " + "; ".join(problems) if problems else None
