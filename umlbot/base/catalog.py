"""The component library as assembled: umlbot's own kinds and implementations and the installed
plugins' (`umlbot.base.plugins` loads them once per process), looked up by name.

`umlbot.base.library` declares what a kind, a feature and an implementation are; this module is
where the rest of umlbot asks which ones exist.
"""

from __future__ import annotations

import dataclasses
import importlib
from typing import Any

from umlbot.base.library import ComponentKind, FeatureSpec, Implementation, ServiceKind, ServiceSpec
from umlbot.base.plugins import Catalog
from umlbot.base.plugins import catalog as load_catalog


def catalog() -> Catalog:
    """The assembled library (loaded from the entry points on first use)."""
    return load_catalog()


def resolve_implementation(name: str) -> Implementation | None:
    """The implementation for an id or seed alias (case-insensitive), or None when unknown."""
    lib = catalog()
    key = lib.aliases.get(name.strip().lower())
    return lib.implementations[key] if key else None


def implementations() -> dict[str, Implementation]:
    """Every implementation by canonical id."""
    return catalog().implementations


def implementations_for_service(service: ServiceKind) -> list[Implementation]:
    """The implementations that a service kind serves."""
    return [impl for impl in catalog().implementations.values() if impl.service == service]


def component_kinds() -> dict[ComponentKind, dict[str, FeatureSpec]]:
    """Every component kind with the features a component of it can have."""
    return catalog().kinds


def kind_features(kind: ComponentKind) -> dict[str, FeatureSpec]:
    """The features a component of `kind` can have (empty for an unknown kind)."""
    return catalog().kinds.get(kind, {})


def service_kinds() -> tuple[ServiceKind, ...]:
    """Every service kind's name, built-ins first."""
    return tuple(catalog().services)


def service_spec(kind: ServiceKind) -> ServiceSpec | None:
    """The service kind named `kind`, or None."""
    return catalog().services.get(kind)


def component_features(impl: Implementation, settings: dict[str, Any]) -> Implementation:
    """The implementation as one component deploys it: for one whose features depend on its
    settings (`Implementation.features_from`, e.g. a ROS 2 mapping), those features; else itself."""
    if not impl.features_from:
        return impl
    module, _, function = impl.features_from.partition(":")
    try:
        features = getattr(importlib.import_module(module), function)(impl, dict(settings))
    except Exception:  # the settings check says what is wrong with them
        return impl
    return dataclasses.replace(impl, features=dict(features))
