"""The built-in component library: component kinds, their features, and the implementations.

This is the one place that says which features exist, what arguments they take (type and range),
which implementation offers which of them and which service kind serves an implementation. The
compiler checks models against it, the services register exactly these features on the bus, and
the orchestrator uses `safe_stop` to stop actuators. Seed implementation ids (`CModel…`) are
aliases of the canonical ids.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

ArgType = Literal["int", "float", "bool", "str"]
ValueType = Literal["int", "float", "bool", "str", "none"]
ComponentKind = Literal["system", "actuator", "sensor"]
ServiceKind = Literal["motor", "sonar", "servo", "gpio"]


@dataclass(frozen=True)
class Param:
    """One argument of a feature; numeric ranges are inclusive."""

    name: str
    type: ArgType
    minimum: float | None = None
    maximum: float | None = None
    unit: str = ""


@dataclass(frozen=True)
class FeatureSpec:
    """A feature a component offers: its arguments and the type of the value it returns."""

    name: str
    params: tuple[Param, ...] = ()
    returns: ValueType = "none"
    doc: str = ""

    def with_range(self, param: str, minimum: float, maximum: float) -> FeatureSpec:
        """The same feature with one parameter's range narrowed (e.g. a servo's angle 0..180)."""
        params = tuple(
            Param(p.name, p.type, minimum, maximum, p.unit) if p.name == param else p
            for p in self.params
        )
        return FeatureSpec(self.name, params, self.returns, self.doc)


GPIO_PIN = Param("gpio", "int", 0, 27, "BCM pin")

#: The features each component kind can have (SPEC §2). Implementations offer a subset.
KIND_FEATURES: dict[ComponentKind, dict[str, FeatureSpec]] = {
    "system": {
        "readPin": FeatureSpec("readPin", (GPIO_PIN,), "int", "Read a GPIO pin: 0 or 1."),
        "writePin": FeatureSpec(
            "writePin", (GPIO_PIN, Param("value", "int", 0, 1)), "none", "Write 0 or 1 to a GPIO pin."
        ),
    },
    "actuator": {
        "enabled": FeatureSpec("enabled", (Param("on", "bool"),), "none", "Drive (true) or stop (false)."),
        "direction": FeatureSpec(
            "direction", (Param("clockwise", "bool"),), "none", "true = clockwise (forward)."
        ),
        "dutycycle": FeatureSpec(
            "dutycycle", (Param("percent", "int", 0, 100, "%"),), "none", "PWM duty cycle in percent."
        ),
        "angle": FeatureSpec("angle", (Param("degrees", "int", 0, 360, "°"),), "none", "Turn to an angle."),
    },
    "sensor": {
        "value": FeatureSpec("value", (), "int", "Read the sensor (a distance sensor: centimetres)."),
    },
}


@dataclass(frozen=True)
class Implementation:
    """A concrete part that realises a component kind, served by one service kind."""

    id: str
    kind: ComponentKind
    service: ServiceKind
    features: dict[str, FeatureSpec]
    title: str
    aliases: tuple[str, ...] = ()
    #: calls (feature, args) that put this part into a safe, stopped state.
    safe_stop: tuple[tuple[str, tuple[bool | int, ...]], ...] = ()
    settings_doc: dict[str, str] = field(default_factory=dict)


def _pick(kind: ComponentKind, *names: str) -> dict[str, FeatureSpec]:
    return {name: KIND_FEATURES[kind][name] for name in names}


IMPLEMENTATIONS: dict[str, Implementation] = {
    impl.id: impl
    for impl in (
        Implementation(
            id="raspberrypi",
            kind="system",
            service="gpio",
            features=_pick("system", "readPin", "writePin"),
            title="Raspberry Pi GPIO (system)",
            aliases=("CModelSystemRaspberryPI",),
            settings_doc={"pins": "GPIO pins the model may read or write (BCM numbers)"},
        ),
        Implementation(
            id="l298n",
            kind="actuator",
            service="motor",
            features=_pick("actuator", "enabled", "direction", "dutycycle"),
            title="L298N H-bridge motor channel",
            aliases=("CModelL298NActuator",),
            safe_stop=(("enabled", (False,)),),
            settings_doc={
                "in1": "GPIO of input 1",
                "in2": "GPIO of input 2",
                "enable": "GPIO of the enable pin (optional)",
                "pwm_frequency_hz": "software PWM frequency",
                "watchdog_s": "stop when no command arrived for this long (0 = off)",
            },
        ),
        Implementation(
            id="servo",
            kind="actuator",
            service="servo",
            features={"angle": KIND_FEATURES["actuator"]["angle"].with_range("degrees", 0, 180)},
            title="hobby servo, 180°",
            aliases=("CModelActuator",),
            settings_doc={"gpio": "GPIO of the signal wire", "min_pulse_us": "pulse at 0°",
                          "max_pulse_us": "pulse at 180°"},
        ),
        Implementation(
            id="hcsr04",
            kind="sensor",
            service="sonar",
            features=_pick("sensor", "value"),
            title="HC-SR04 ultrasonic range finder",
            aliases=("CModelDistanceSensorHCSR",),
            settings_doc={"trigger": "GPIO of TRIG", "echo": "GPIO of ECHO", "samples": "median of N"},
        ),
    )
}

_ALIASES: dict[str, str] = {
    name.lower(): impl.id for impl in IMPLEMENTATIONS.values() for name in (impl.id, *impl.aliases)
}


def resolve_implementation(name: str) -> Implementation | None:
    """The implementation for an id or seed alias (case-insensitive), or None when unknown."""
    key = _ALIASES.get(name.strip().lower())
    return IMPLEMENTATIONS[key] if key else None


def implementations_for_service(service: ServiceKind) -> list[Implementation]:
    """The implementations that a service kind serves."""
    return [impl for impl in IMPLEMENTATIONS.values() if impl.service == service]
