"""The one place that maps (service kind, driver name) to a driver factory.

A service host asks `create_driver(kind, driver, component, settings)` for the driver of one
component; the driver name comes from `--driver` or the deployment (component override, then the
deployment's default; `auto` picks the GPIO backend this machine has). The drivers are the
``umlbot.drivers`` entry points (`umlbot.base.plugins`), umlbot's own and any plugin's alike, each a
lazy reference to a `DriverFactory`: a driver's module is imported only when it is chosen, so
`pigpio` is imported only by the pigpio drivers and a simulator only by the sim drivers.

Adding a driver backend: write `umlbot/services/<kind>/<name>.py` (or a module of your package) exposing
``FACTORY = DriverFactory(Settings, create)`` where ``create(component, settings)`` returns an
object satisfying the kind's Protocol (`umlbot/services/<kind>/driver.py`), then add one entry point
``"<kind>.<name>" = "module:FACTORY"`` to the ``umlbot.drivers`` group of the pyproject.toml. Code
that must bind a driver to live objects (a simulated world) can instead call `register_driver()`
at run time with a factory closure; that entry overrides the entry points for this process.

Settings: the component's deployment `settings` mapping is validated by the factory's pydantic
model. Keys prefixed with another driver's name (`mock_…`, `sim_…`) are dropped first, so one
deployment can carry the settings of every backend and `--driver` switches between them. The mock
and sim drivers ignore the hardware keys, but do not let a wrong one through: the settings they
are given are also checked against every hardware driver's model, with only the missing required
keys (pins) forgiven (`hardware_problems`), so a deployment that runs under mock or sim is not
refused on the robot for a misspelt key or a pin out of range.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from pydantic import BaseModel, ValidationError

from umlbot.base.catalog import service_kinds
from umlbot.base.errors import ConfigError, DriverError, UnknownDriver
from umlbot.base.library import ServiceKind
from umlbot.base.plugins import catalog

S = TypeVar("S", bound=BaseModel)

#: The driver name that stands for the GPIO backend this machine has (`umlbot.base.autodetect`).
AUTO = "auto"

#: Driver names whose settings live under a `<name>_` key prefix in a shared settings mapping.
PREFIXED_DRIVERS: tuple[str, ...] = ("mock", "sim")


class SettingsError(ConfigError):
    """A driver refused a component's settings; `problems` are (path in the settings, message)."""

    def __init__(self, component: str, problems: list[tuple[tuple[int | str, ...], str]],
                 message: str) -> None:
        super().__init__(message)
        self.component = component
        self.problems = problems


@dataclass(frozen=True)
class DriverFactory(Generic[S]):
    """How to build one driver: the pydantic model of its settings and a constructor.

    `create(component, settings)` receives the component's name (for logs and errors) and its
    validated settings, and returns an object satisfying the kind's driver Protocol.
    """

    settings_model: type[S]
    create: Callable[[str, S], Any]

    def build(self, component: str, raw_settings: Mapping[str, Any]) -> Any:
        """Validate `raw_settings` and build the driver; a bad setting raises `ConfigError`."""
        try:
            settings = self.settings_model.model_validate(dict(raw_settings))
        except ValidationError as exc:
            problems = [(tuple(err["loc"]), str(err["msg"])) for err in exc.errors()]
            raise SettingsError(component, problems,
                                f"{component}: invalid settings: {_describe(problems)}") from exc
        return self.create(component, settings)


_runtime: dict[tuple[ServiceKind, str], DriverFactory[Any]] = {}
_lock = threading.Lock()


def register_driver(kind: ServiceKind, name: str, factory: DriverFactory[Any]) -> None:
    """Add or replace a driver for this process (e.g. sim drivers bound to a running world)."""
    with _lock:
        _runtime[(kind, name)] = factory


def unregister_driver(kind: ServiceKind, name: str) -> None:
    """Remove a driver added with `register_driver`; unknown names are ignored."""
    with _lock:
        _runtime.pop((kind, name), None)


def known_drivers(kind: ServiceKind) -> list[str]:
    """Every driver name available for a service kind, sorted."""
    with _lock:
        runtime = {name for (k, name) in _runtime if k == kind}
    return sorted(runtime | {name for (k, name) in catalog().drivers if k == kind} | {AUTO})


def get_factory(kind: ServiceKind, driver: str) -> DriverFactory[Any]:
    """The factory of a driver; `UnknownDriver` (listing the known names) when there is none."""
    if kind not in service_kinds():
        raise UnknownDriver(f"unknown service kind {kind!r}; known kinds: {', '.join(service_kinds())}")
    chosen_by_auto = driver == AUTO
    driver = resolve_driver(driver)
    with _lock:
        runtime = _runtime.get((kind, driver))
    if runtime is not None:
        return runtime
    entry = catalog().drivers.get((kind, driver))
    if entry is None:
        why = f"driver auto chose {driver!r} here, but there is no " if chosen_by_auto else "unknown "
        raise UnknownDriver(f"{why}{kind} driver {driver!r}; known drivers: {', '.join(known_drivers(kind))}")
    try:
        factory = entry.load()
    except DriverError:
        raise
    except (Exception, SystemExit) as exc:  # a plugin's driver module that does not import (or exits)
        raise DriverError(f"the {kind} driver {driver!r} of package {entry.package} cannot be loaded "
                          f"from {entry.target}: {type(exc).__name__}: {exc}") from exc
    if not isinstance(factory, DriverFactory):
        raise DriverError(f"the {kind} driver {driver!r} of package {entry.package}: {entry.target} is a "
                          f"{type(factory).__name__}, not a umlbot.base.registry.DriverFactory")
    return factory


def driver_settings(driver: str, settings: Mapping[str, Any]) -> dict[str, Any]:
    """The settings a driver sees: keys prefixed for *another* driver (`mock_`, `sim_`) removed."""
    foreign = tuple(f"{name}_" for name in PREFIXED_DRIVERS if name != driver)
    return {key: value for key, value in settings.items() if not key.startswith(foreign)}


def create_driver(kind: ServiceKind, driver: str, component: str, settings: Mapping[str, Any]) -> Any:
    """Build the driver of one component from its deployment settings.

    Raises `UnknownDriver` for an unknown name, `ConfigError` for invalid settings (for the mock
    and sim drivers also the hardware keys: `hardware_problems`) and `DriverError` when the
    hardware cannot be reached (e.g. pigpiod not running).
    """
    factory = get_factory(kind, driver)
    if resolve_driver(driver) in PREFIXED_DRIVERS:
        problems = hardware_problems(kind, settings)
        if problems:
            raise SettingsError(component, problems,
                                f"{component}: invalid settings: {_describe(problems)}")
    return factory.build(component, driver_settings(driver, settings))


def resolve_driver(driver: str) -> str:
    """The driver name that runs: `auto` resolved to the backend this machine has."""
    if driver != AUTO:
        return driver
    from umlbot.base.autodetect import auto_driver

    return auto_driver()


def _describe(problems: list[tuple[tuple[int | str, ...], str]]) -> str:
    return "; ".join(f"{'.'.join(str(p) for p in path) or 'settings'}: {message}"
                     for path, message in problems)


def hardware_problems(kind: ServiceKind,
                      settings: Mapping[str, Any]) -> list[tuple[tuple[int | str, ...], str]]:
    """What the hardware drivers (every one `driver: auto` may pick) refuse in `settings` besides
    a missing required key: a misspelt key, a value of the wrong type or out of range. The mock
    and sim drivers run without pins but are held to this, so that what runs there is not
    refused on the robot."""
    problems: list[tuple[tuple[int | str, ...], str]] = []
    for name, model in hardware_settings_models(kind):
        try:
            model.model_validate(driver_settings(name, settings))
        except ValidationError as exc:
            for err in exc.errors():
                problem = (tuple(err["loc"]), str(err["msg"]))
                if err["type"] != "missing" and problem not in problems:
                    problems.append(problem)
    return problems


def hardware_settings_models(kind: ServiceKind) -> list[tuple[str, type[BaseModel]]]:
    """The settings models of a service kind's hardware drivers (every driver but `auto` and the
    mock and sim ones, built-in or a plugin's), each model once. `driver: auto` may pick any of
    them, so settings meant for the hardware must satisfy each. A plugin's driver that does not
    load is left out (`umlbot plugins` reports it)."""
    models: list[tuple[str, type[BaseModel]]] = []
    for driver in known_drivers(kind):
        if driver == AUTO or driver in PREFIXED_DRIVERS:
            continue
        try:
            model = get_factory(kind, driver).settings_model
        except (UnknownDriver, DriverError):
            continue
        if all(model is not seen for _, seen in models):
            models.append((driver, model))
    return models


def settings_problems(kind: ServiceKind, driver: str,
                      settings: Mapping[str, Any]) -> list[tuple[tuple[int | str, ...], str]]:
    """Why a component's deployment `settings` would be refused when its service starts with
    `driver` (`auto`: by every hardware driver; `mock`, `sim`: by their own model and, but for a
    missing key, by every hardware driver): (path in the settings, message) pairs, empty when
    they are valid. The check `umlbot check` and the studio make before any service runs."""
    hardware: list[tuple[tuple[int | str, ...], str]] = []
    if driver == AUTO:
        models = hardware_settings_models(kind)
    else:
        if driver in PREFIXED_DRIVERS:
            hardware = hardware_problems(kind, settings)
        try:
            models = [(driver, get_factory(kind, driver).settings_model)]
        except UnknownDriver as exc:
            return [((), str(exc))]
        except DriverError:
            return []  # a plugin's driver that does not load: `umlbot plugins` says why
    problems = hardware
    for name, model in models:
        try:
            model.model_validate(driver_settings(name, settings))
        except ValidationError as exc:
            for err in exc.errors():
                problem = (tuple(err["loc"]), str(err["msg"]))
                if problem not in problems:
                    problems.append(problem)
    return problems

