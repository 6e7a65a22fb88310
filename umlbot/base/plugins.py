"""Plugins: component kinds, implementations, service kinds and drivers from installed packages.

Two entry point groups, read once per process:

- ``umlbot.components``: each entry point names a `umlbot.base.library.ComponentPlugin` (new component
  kinds with their features, service kinds, implementations). Its module is imported to read it,
  so it must be light: declarations only, no driver or hardware imports.
- ``umlbot.drivers``: each entry point is named ``<service kind>.<driver>`` (``motor.lgpio``) and
  names a `umlbot.base.registry.DriverFactory`. Only the name is read here; the module is imported
  when a service chooses that driver.

umlbot registers its own kinds, services and drivers the same way (its pyproject.toml), and they
are read first, then the plugins by package name, so a plugin can add but never replace. A plugin
that cannot be imported (an exception or a `sys.exit()` in its module), whose spec is wrong or
whose names clash with what is already there is skipped as a whole, and so are the drivers of its
package; the problem names the entry point and its package, is logged once as a warning and
listed by `umlbot plugins`.
"""

from __future__ import annotations

import importlib
import re
import threading
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, get_args

from umlbot.base.entrypoints import EntryPointLike as EntryPoint
from umlbot.base.entrypoints import entry_points
from umlbot.base.errors import ArgumentError
from umlbot.base.library import (
    ArgType,
    ComponentPlugin,
    FeatureSpec,
    Implementation,
    KindSpec,
    Param,
    ServiceSpec,
    ValueType,
    check_args,
)
from umlbot.base.logs import get_logger

log = get_logger("umlbot.base.plugins")

COMPONENTS_GROUP = "umlbot.components"
DRIVERS_GROUP = "umlbot.drivers"
#: The distribution whose entry points are read first (umlbot itself).
HOME_PACKAGE = "umlbot"

NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*\Z")
DRIVER_NAME = re.compile(r"([a-z][a-z0-9_]*)\.([a-z][a-z0-9_]*)\Z")


@dataclass(frozen=True)
class PluginProblem:
    """A plugin that was skipped, and why."""

    plugin: str
    group: str
    package: str
    message: str

    def __str__(self) -> str:
        return f"plugin {self.plugin!r} ({self.group}, package {self.package}): {self.message}"


@dataclass(frozen=True)
class DriverEntry:
    """A registered driver: where its `DriverFactory` lives and which package provides it."""

    kind: str
    name: str
    target: str  # "module:attribute"
    package: str

    def load(self) -> Any:
        """Import the module and return the attribute (the caller checks its type)."""
        module_name, _, attribute = self.target.partition(":")
        obj: Any = importlib.import_module(module_name)
        for part in attribute.split("."):
            obj = getattr(obj, part)
        return obj


@dataclass
class PackageInfo:
    """What one installed package contributes (for `umlbot plugins`)."""

    package: str
    version: str
    kinds: list[str] = field(default_factory=list)
    services: list[str] = field(default_factory=list)
    implementations: list[str] = field(default_factory=list)  # "id (alias, …)"
    drivers: list[str] = field(default_factory=list)  # "kind.name"


@dataclass
class Catalog:
    """The assembled library: everything the built-ins and the plugins provide."""

    kinds: dict[str, dict[str, FeatureSpec]] = field(default_factory=dict)
    services: dict[str, ServiceSpec] = field(default_factory=dict)
    implementations: dict[str, Implementation] = field(default_factory=dict)
    aliases: dict[str, str] = field(default_factory=dict)  # lower-case id or alias -> id
    drivers: dict[tuple[str, str], DriverEntry] = field(default_factory=dict)
    packages: dict[str, PackageInfo] = field(default_factory=dict)
    problems: list[PluginProblem] = field(default_factory=list)
    #: "kind:<name>", "service:<name>", "impl:<id>" -> the package that provides it.
    origin: dict[str, str] = field(default_factory=dict)

    def problems_for(self, package_or_plugin: str) -> list[PluginProblem]:
        return [p for p in self.problems if package_or_plugin in (p.plugin, p.package.split(" ")[0])]


def _package(ep: EntryPoint) -> tuple[str, str]:
    dist = ep.dist
    if dist is None:
        return "?", "?"
    return dist.metadata["Name"] or "?", dist.version or "?"


def _order(eps: Iterable[EntryPoint]) -> list[EntryPoint]:
    """Unique entry points, umlbot's own first, then by package and name (a stable order).

    An entry point is the same one only within one package: two packages that declare the very
    same line are two claims, and the later package's is the one skipped."""
    unique: dict[tuple[str, str, str, str], EntryPoint] = {}
    for ep in eps:
        unique.setdefault((_package(ep)[0].lower(), ep.group, ep.name, ep.value), ep)

    def key(ep: EntryPoint) -> tuple[bool, str, str]:
        name = _package(ep)[0]
        return (name.lower() != HOME_PACKAGE, name.lower(), ep.name)

    return sorted(unique.values(), key=key)


# --- checking a component plugin ------------------------------------------------------------------


ARG_TYPES: tuple[str, ...] = get_args(ArgType)
VALUE_TYPES: tuple[str, ...] = get_args(ValueType)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _check_param(where: str, param: Any, of_kind: Param | None) -> list[str]:
    if not isinstance(param, Param):
        return [f"{where}: a parameter must be a umlbot.base.library.Param, got {type(param).__name__}"]
    if param.type not in ARG_TYPES:
        return [f"{where}: parameter {param.name}: type {param.type!r} is not one of {', '.join(ARG_TYPES)}"]
    if not all(bound is None or _is_number(bound) for bound in (param.minimum, param.maximum)):
        return [f"{where}: parameter {param.name}: minimum and maximum must be numbers or None"]
    if of_kind is None:
        return []
    problems = []
    if (param.name, param.type) != (of_kind.name, of_kind.type):
        problems.append(f"{where}: parameter {param.name}: {param.type} differs from the kind's "
                        f"{of_kind.name}: {of_kind.type}")
    if of_kind.minimum is not None and (param.minimum is None or param.minimum < of_kind.minimum):
        problems.append(f"{where}: {param.name} may only narrow the kind's minimum {of_kind.minimum:g}")
    if of_kind.maximum is not None and (param.maximum is None or param.maximum > of_kind.maximum):
        problems.append(f"{where}: {param.name} may only narrow the kind's maximum {of_kind.maximum:g}")
    return problems


def _check_feature(where: str, spec: Any, of_kind: FeatureSpec | None = None) -> list[str]:
    if not isinstance(spec, FeatureSpec):
        return [f"{where}: a feature must be a umlbot.base.library.FeatureSpec, got {type(spec).__name__}"]
    if not NAME.match(spec.name):
        return [f"{where}: feature name {spec.name!r} is not an identifier"]
    if of_kind is not None and (len(spec.params) != len(of_kind.params) or spec.returns != of_kind.returns):
        return [f"{where}: feature {spec.name} must take the kind's {len(of_kind.params)} argument(s) "
                f"and return {of_kind.returns}"]
    problems: list[str] = []
    for index, param in enumerate(spec.params):
        problems += _check_param(f"{where}.{spec.name}", param, of_kind.params[index] if of_kind else None)
    if spec.returns not in VALUE_TYPES:
        problems.append(f"{where}: feature {spec.name} returns {spec.returns!r}, not one of "
                        f"{', '.join(VALUE_TYPES)}")
    return problems


def _check_safe_stop(where: str, impl: Implementation) -> list[str]:
    """Each safe-stop call names a feature the implementation offers, with arguments that fit it."""
    calls: Any = impl.safe_stop
    if not isinstance(calls, tuple):
        return [f"{where}: safe_stop must be a tuple of (feature, arguments) pairs"]
    problems: list[str] = []
    for call in calls:
        if not (isinstance(call, tuple) and len(call) == 2 and isinstance(call[0], str)
                and isinstance(call[1], tuple)):
            problems.append(f"{where}: safe_stop {call!r} is not a (feature, arguments tuple) pair")
            continue
        feature, args = call
        shown = f"safe_stop {feature}({', '.join(repr(arg) for arg in args)})"
        spec: Any = impl.features.get(feature)
        if spec is None:
            problems.append(f"{where}: safe_stop calls {feature!r}, which it does not offer")
        elif not isinstance(spec, FeatureSpec):
            continue  # reported with the features
        else:
            try:  # the check every request gets from its service: a stop it would refuse is wrong
                check_args(spec, list(args))
            except ArgumentError as exc:
                problems.append(f"{where}: {shown}: {exc.message}")
    return problems


def _check_plugin(plugin: ComponentPlugin, lib: Catalog) -> list[str]:
    """Everything wrong with `plugin` against what `lib` already holds (empty: it may be added)."""
    problems: list[str] = []
    # Typed Any: a third-party spec may hold anything, whatever its annotations say.
    new_kinds: tuple[Any, ...] = plugin.kinds
    new_services: tuple[Any, ...] = plugin.services
    new_impls: tuple[Any, ...] = plugin.implementations
    kinds = dict(lib.kinds)
    for kind in new_kinds:
        if not isinstance(kind, KindSpec):
            problems.append(f"a kind must be a umlbot.base.library.KindSpec, got {type(kind).__name__}")
            continue
        if not NAME.match(kind.name):
            problems.append(f"kind name {kind.name!r} is not an identifier")
        elif kind.name in kinds:
            owner = lib.origin.get("kind:" + kind.name, "this plugin")
            problems.append(f"component kind {kind.name!r} is already defined by {owner}")
        for spec in kind.features:
            problems += _check_feature(f"kind {kind.name}", spec)
        kinds[kind.name] = {spec.name: spec for spec in kind.features if isinstance(spec, FeatureSpec)}
    services = set(lib.services)
    for service in new_services:
        if not isinstance(service, ServiceSpec):
            problems.append(f"a service kind must be a umlbot.base.library.ServiceSpec, "
                            f"got {type(service).__name__}")
            continue
        if not DRIVER_NAME.match(f"{service.name}.x"):
            problems.append(f"service kind name {service.name!r} must be lower-case letters, digits and _")
        elif service.name in services:
            problems.append(f"service kind {service.name!r} is already defined by "
                            f"{lib.origin.get('service:' + service.name, 'this plugin')}")
        if not re.fullmatch(r"[\w.]+:[\w.]+", service.service):
            problems.append(f"service kind {service.name!r}: {service.service!r} is not 'module:Class'")
        stops: Any = service.stop_when_orchestrator_offline
        if not isinstance(stops, bool):
            problems.append(f"service kind {service.name!r}: stop_when_orchestrator_offline must be "
                            "true or false")
        services.add(service.name)
    aliases = dict(lib.aliases)
    for impl in new_impls:
        if not isinstance(impl, Implementation):
            problems.append(f"an implementation must be a umlbot.base.library.Implementation, "
                            f"got {type(impl).__name__}")
            continue
        where = f"implementation {impl.id!r}"
        for name in (impl.id, *impl.aliases):
            if not isinstance(name, str) or not NAME.match(name):
                problems.append(f"{where}: id or alias {name!r} is not an identifier")
            elif name.lower() in aliases:
                owner = aliases[name.lower()]
                problems.append(f"{where}: the id or alias {name!r} is already taken by implementation "
                                f"{owner!r} of {lib.origin.get('impl:' + owner, 'this plugin')}")
            else:
                aliases[name.lower()] = impl.id
        if impl.kind not in kinds:
            problems.append(f"{where}: unknown component kind {impl.kind!r} (known: {', '.join(kinds)})")
            continue
        if impl.service not in services:
            problems.append(f"{where}: unknown service kind {impl.service!r} "
                            f"(known: {', '.join(sorted(services))})")
        if isinstance(impl.features, dict) and impl.features_from:
            continue  # its features depend on the deployment's settings (`component_features`)
        if not isinstance(impl.features, dict) or not impl.features:
            problems.append(f"{where}: features must be a non-empty mapping name -> FeatureSpec")
            continue
        for name, spec in impl.features.items():
            of_kind = kinds[impl.kind].get(name)
            if of_kind is None:
                problems.append(f"{where}: feature {name!r} is not a feature of kind {impl.kind} "
                                f"(it has: {', '.join(kinds[impl.kind])})")
            elif not isinstance(spec, FeatureSpec) or spec.name != name:
                problems.append(f"{where}: features[{name!r}] must be the FeatureSpec named {name!r}")
            else:
                problems += _check_feature(where, spec, of_kind)
        problems += _check_safe_stop(where, impl)
    return problems


def _add_plugin(lib: Catalog, plugin: ComponentPlugin, package: str) -> None:
    info = lib.packages[package]
    for kind in plugin.kinds:
        lib.kinds[kind.name] = {spec.name: spec for spec in kind.features}
        lib.origin[f"kind:{kind.name}"] = package
        info.kinds.append(kind.name)
    for service in plugin.services:
        lib.services[service.name] = service
        lib.origin[f"service:{service.name}"] = package
        info.services.append(service.name)
    for impl in plugin.implementations:
        lib.implementations[impl.id] = impl
        lib.origin[f"impl:{impl.id}"] = package
        for name in (impl.id, *impl.aliases):
            lib.aliases[name.lower()] = impl.id
        info.implementations.append(impl.id + (f" ({', '.join(impl.aliases)})" if impl.aliases else ""))


# --- assembling the catalog -------------------------------------------------------------------------


def build_catalog(components: Iterable[EntryPoint], drivers: Iterable[EntryPoint]) -> Catalog:
    """The library from these entry points; bad ones become `problems` and are left out."""
    lib = Catalog()

    def info(ep: EntryPoint) -> tuple[str, PackageInfo]:
        name, version = _package(ep)
        if name not in lib.packages:
            lib.packages[name] = PackageInfo(name, version)
        return f"{name} {version}", lib.packages[name]

    for ep in _order(components):
        label, _ = info(ep)
        try:
            plugin = ep.load()
        # any error in third-party code, even a sys.exit() at import: skip that plugin only (a
        # KeyboardInterrupt still ends the command)
        except (Exception, SystemExit) as exc:
            lib.problems.append(PluginProblem(ep.name, ep.group, label, f"cannot import {ep.value}: "
                                              f"{type(exc).__name__}: {exc}"))
            continue
        if not isinstance(plugin, ComponentPlugin):
            kind_of = type(plugin).__name__
            lib.problems.append(PluginProblem(ep.name, ep.group, label, f"{ep.value} is a {kind_of}, "
                                              "not a umlbot.base.library.ComponentPlugin"))
            continue
        try:
            found = _check_plugin(plugin, lib)
        except Exception as exc:  # a spec too broken to check (wrong types deep inside)
            found = [f"bad spec: {type(exc).__name__}: {exc}"]
        if found:
            lib.problems.append(PluginProblem(ep.name, ep.group, label, "; ".join(found)))
            continue
        _add_plugin(lib, plugin, _package(ep)[0])

    for ep in _order(drivers):
        label, package = info(ep)
        match = DRIVER_NAME.match(ep.name)
        if match is None:
            lib.problems.append(PluginProblem(ep.name, ep.group, label,
                                              "a driver entry point is named '<service kind>.<driver>'"))
            continue
        kind, name = match.groups()
        skipped = [p.plugin for p in lib.problems_for(package.package) if p.group == COMPONENTS_GROUP]
        if skipped:  # the package's drivers go down with it: they may rely on what it left out
            lib.problems.append(PluginProblem(ep.name, ep.group, label, "skipped with this package's "
                                              f"component plugin{'s' if len(skipped) > 1 else ''} "
                                              f"{', '.join(map(repr, skipped))}"))
            continue
        if kind not in lib.services:
            lib.problems.append(PluginProblem(ep.name, ep.group, label, f"unknown service kind {kind!r} "
                                              f"(known: {', '.join(lib.services)})"))
            continue
        existing = lib.drivers.get((kind, name))
        if existing is not None:
            lib.problems.append(PluginProblem(ep.name, ep.group, label, f"the {kind} driver {name!r} is "
                                              f"already provided by {existing.package}"))
            continue
        lib.drivers[(kind, name)] = DriverEntry(kind, name, ep.value, package.package)
        package.drivers.append(ep.name)
    lib.packages = {name: p for name, p in lib.packages.items() if p.kinds or p.services or
                    p.implementations or p.drivers or lib.problems_for(name)}
    return lib


_lock = threading.Lock()
_catalog: Catalog | None = None


def catalog() -> Catalog:
    """The library of this process: built once from the installed entry points."""
    global _catalog
    with _lock:
        if _catalog is None:
            # read without importlib.metadata where it can be (umlbot.base.entrypoints: 2.8 MB)
            _catalog = build_catalog(entry_points(COMPONENTS_GROUP), entry_points(DRIVERS_GROUP))
            for problem in _catalog.problems:
                log.warning("plugin_skipped", plugin=problem.plugin, group=problem.group,
                            package=problem.package, error=problem.message)
        return _catalog


def reload() -> Catalog:
    """Read the entry points again (after installing a package in this process; tests)."""
    global _catalog
    with _lock:
        _catalog = None
    return catalog()
