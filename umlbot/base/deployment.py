"""The deployment: which implementation realises each component, with which driver and settings.

Two formats are read. The seed's plain format, one `<component>=<implementation id>` a line
(`#` comments and blank lines allowed), and the rich YAML format::

    robot: car                 # optional robot id
    driver: auto               # default driver for every component: auto, lgpio, pigpio, sim, mock
    components:
      LeftActuator:
        impl: l298n
        settings: {in1: 22, in2: 23}
      DistanceRead:
        impl: hcsr04
        driver: mock           # per-component override
        settings: {trigger: 8, echo: 7}

Implementation-specific settings are validated by the driver that uses them; this module only
checks the shape and resolves implementation ids (seed aliases included).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, ValidationError

from umlbot.base.catalog import implementations, resolve_implementation
from umlbot.base.errors import ConfigError
from umlbot.base.files import load_yaml_node, read_text, validation_problem, where
from umlbot.base.library import Implementation, ServiceKind


class ComponentDeployment(BaseModel):
    """One component's binding: implementation id, optional driver override, driver settings."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    impl: str
    driver: str | None = None
    settings: dict[str, Any] = Field(default_factory=dict)

    @property
    def implementation(self) -> Implementation:
        impl = resolve_implementation(self.impl)
        if impl is None:
            raise ConfigError(f"unknown implementation id {self.impl!r}")
        return impl


class Deployment(BaseModel):
    """Every component of the robot with its implementation; `driver` is the default driver."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    robot: str | None = None
    driver: str = "auto"
    components: dict[str, ComponentDeployment] = Field(default_factory=dict)
    # where it was read from, for errors at `file:line:col` (`where`)
    _source: str = PrivateAttr(default="deployment")
    _root: Any = PrivateAttr(default=None)  # the positioned YAML tree, or None (plain format)
    _prefix: tuple[str, ...] = PrivateAttr(default=())  # under a top-level `deployment:` key
    _positions: Any = PrivateAttr(default=None)  # the tree's positions as JSON (`from_handover`)

    def where(self, *path: int | str) -> str:
        """`file:line:col` of a value of the deployment (`"components", name, "settings", key`),
        as deep as it is written; just the file for the plain format."""
        if self._root is None and self._positions is not None:  # rebuilt when an error needs it
            from umlbot.base.yamlsrc import from_positions

            self._root = from_positions(self._positions, self._source)
        return where(self._source, self._root, (*self._prefix, *path))

    def handover(self) -> dict[str, Any]:
        """The deployment as plain JSON with where it was read from (`from_handover`): what
        `umlbot service` hands the serving process, which names the same `file:line:col`."""
        from umlbot.base.yamlsrc import positions

        tree = self._positions if self._root is None else positions(self._root)
        return {"source": self._source, "prefix": list(self._prefix), "positions": tree,
                "deployment": self.model_dump(mode="python")}

    @classmethod
    def from_handover(cls, data: Mapping[str, Any]) -> Deployment:
        """The deployment `handover` gave, validated again (its positioned tree is rebuilt only
        when `where` needs it: a serving process that names no error never imports yamlsrc)."""
        deployment = cls.model_validate(data["deployment"])
        deployment._source, deployment._prefix = str(data["source"]), tuple(str(p) for p in data["prefix"])
        deployment._positions = data["positions"]
        return deployment

    def driver_for(self, component: str) -> str:
        """The driver name for a component: its own override or the deployment's default."""
        return self.components[component].driver or self.driver

    def components_of_service(self, service: ServiceKind) -> dict[str, ComponentDeployment]:
        """The components a service kind serves, by name, in a stable order."""
        return {
            name: comp
            for name, comp in sorted(self.components.items())
            if (impl := resolve_implementation(comp.impl)) is not None and impl.service == service
        }


class PinSetting(NamedTuple):
    """One GPIO a component's settings name: the pin, the settings key, and the path of the value
    under `settings` (`("in1",)`, or `("pins", 1)` for the second entry of a pin list)."""

    pin: int
    key: str
    path: tuple[str | int, ...]


def component_pins(impl: Implementation | None, settings: dict[str, Any]) -> list[PinSetting]:
    """Every GPIO a component's settings name, in the order written: the single-pin keys of its
    implementation (`pin_keys`) and each entry of its pin-list keys (`pin_list_keys`). The one
    place that reads pins from settings (the shared-pin check, the gpio service's reserved pins).
    Values that are not pin numbers are left to the driver's settings check."""
    if impl is None:
        return []
    found: list[PinSetting] = []
    for key, value in settings.items():
        if key in impl.pin_keys:
            values: list[tuple[tuple[str | int, ...], Any]] = [((key,), value)]
        elif key in impl.pin_list_keys and isinstance(value, list):
            values = [((key, index), item) for index, item in enumerate(value)]
        else:
            continue
        found += [PinSetting(pin, key, path) for path, pin in values
                  if isinstance(pin, int) and not isinstance(pin, bool)]
    return found


def owned_pins(deployment: Deployment) -> dict[int, str]:
    """GPIO -> component for every pin a component's settings name (the first one, in file order)."""
    owners: dict[int, str] = {}
    for name, comp in deployment.components.items():
        for setting in component_pins(resolve_implementation(comp.impl), comp.settings):
            owners.setdefault(setting.pin, name)
    return owners


class SharedPin(NamedTuple):
    """A GPIO setting naming a pin another component already owns."""

    pin: int
    component: str
    key: str
    first: str
    first_key: str
    path: tuple[str | int, ...]  # of the value under the component's `settings`

    def message(self) -> str:
        return shared_pin_message(self.pin, self.component, self.key, self.first, self.first_key)


def shared_pin_message(pin: int, component: str, key: str, first: str, first_key: str) -> str:
    """The one wording of a GPIO wired to two components (`umlbot check` and the service host)."""
    return (f"GPIO {pin} ('{key}' of '{component}') is already wired to '{first}' ('{first_key}'): "
            "each pin belongs to one component")


def shared_pins(deployment: Deployment) -> list[SharedPin]:
    """Every GPIO setting (a single pin, or an entry of a pin list such as gpio's `pins`) that
    names a pin another component already owns, in file order."""
    owners: dict[int, tuple[str, str]] = {}
    shared: list[SharedPin] = []
    for name, comp in deployment.components.items():
        for pin, key, path in component_pins(resolve_implementation(comp.impl), comp.settings):
            if pin in owners and owners[pin][0] != name:
                shared.append(SharedPin(pin, name, key, *owners[pin], path))
            else:
                owners.setdefault(pin, (name, key))
    return shared


def parse_plain(text: str, source: str = "<deployment>") -> Deployment:
    """Parse the seed's `<component>=<implementation id>` format."""
    components: dict[str, ComponentDeployment] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        name, sep, impl = (part.strip() for part in line.partition("="))
        if not sep or not name or not impl:
            raise ConfigError(f"{source}:{lineno}: expected '<component>=<implementation id>', got {raw!r}")
        if name in components:
            raise ConfigError(f"{source}:{lineno}: component {name!r} deployed twice")
        components[name] = ComponentDeployment(impl=impl)
    deployment = Deployment(components=components)
    deployment._source = source
    return deployment


def is_plain_format(text: str) -> bool:
    """True when the text looks like the seed's plain format (every content line `a=b`)."""
    lines = [ln.split("#", 1)[0].strip() for ln in text.splitlines()]
    content = [ln for ln in lines if ln]
    return bool(content) and all("=" in ln and ":" not in ln for ln in content)


def parse_deployment(text: str, source: str = "<deployment>") -> Deployment:
    """Parse either format; errors name the source and say what is wrong."""
    deployment = _parse_either(text, source)
    for name, comp in deployment.components.items():
        if resolve_implementation(comp.impl) is None:
            raise ConfigError(f"{deployment.where('components', name, 'impl')}: component {name!r}: "
                              f"unknown implementation id {comp.impl!r} "
                              f"(known: {', '.join(sorted(implementations()))})")
    return deployment


def _parse_either(text: str, source: str) -> Deployment:
    if is_plain_format(text):
        return parse_plain(text, source)
    from umlbot.base.yamlsrc import to_python

    root = load_yaml_node(text, source)
    data = to_python(root)
    if not isinstance(data, dict):
        raise ConfigError(f"{where(source, root)}: a deployment is a mapping with 'components'")
    prefix: tuple[str, ...] = ()
    if "deployment" in data and isinstance(data["deployment"], dict):
        data, prefix = data["deployment"], ("deployment",)
    try:
        deployment = Deployment.model_validate(data)
    except ValidationError as exc:
        problem = validation_problem(exc.errors(), source, root, "invalid deployment", prefix)
        if "components" in data and not any(isinstance(c, dict) and "impl" in c
                                             for c in (data["components"] or {}).values()
                                             if isinstance(data["components"], dict)):
            problem += " — is this a deployment? (each component names its 'impl')"
        raise ConfigError(problem) from exc
    deployment._source, deployment._root, deployment._prefix = source, root, prefix
    return deployment


def load_deployment(path: str | Path) -> Deployment:
    """Read a deployment file in either format."""
    return parse_deployment(read_text(path, "deployment"), str(path))
