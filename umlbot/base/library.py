"""The component library: component kinds, their features, the implementations and service kinds.

This is the one place that says which features exist, what arguments they take (type and range),
which implementation offers which of them and which service kind serves an implementation. The
compiler checks models against it, the services register exactly these features on the bus, and
the orchestrator uses `safe_stop` to stop actuators. Seed implementation ids (`CModel…`) are
aliases of the canonical ids.

The library is assembled from `ComponentPlugin`s found through the `umlbot.components` entry
point group (see `umlbot.base.plugins`); umlbot's own kinds, implementations and services below
(`BUILTIN`) are registered through that group too, in umlbot's pyproject.toml. Look things up
with the functions at the end (`resolve_implementation`, `kind_features`, `service_spec` …),
never in `BUILTIN` directly, so that plugins are seen exactly like built-ins.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from typing import Any, Literal

from umlbot.base.errors import ArgumentError

ArgType = Literal["int", "float", "bool", "str"]
ValueType = Literal["int", "float", "bool", "str", "none"]
#: An argument of a safe-stop call (of the type of the feature's parameter).
StopArg = bool | int | float | str
#: A component kind's name: `system`, `actuator`, `sensor`, or one a plugin adds.
ComponentKind = str
#: A service kind's name: `motor`, `sonar`, `servo`, `gpio`, or one a plugin adds.
ServiceKind = str


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


def _describe(value: Any) -> str:
    """A short JSON rendering of a bad argument for an error message (any value, any depth)."""
    try:
        text = json.dumps(value)
    except (ValueError, OverflowError, RecursionError):  # too deep: say what it is
        text = type(value).__name__
    return text if len(text) <= 40 else text[:37] + "..."


def check_arg(param: Param, value: Any) -> Any:
    """The argument converted to the parameter's type; raises `ArgumentError` (`bad_args`,
    `out_of_range`). The one check of a feature's argument: the services apply it to every
    request, the plugin loader to a safe stop's arguments."""
    converted: Any
    if param.type == "bool":
        if isinstance(value, bool):
            converted = value
        elif isinstance(value, int) and value in (0, 1):
            converted = bool(value)
        else:
            raise ArgumentError("bad_args", f"{param.name} must be true or false, got {_describe(value)}")
    elif param.type == "int":
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ArgumentError("bad_args", f"{param.name} must be an integer, got {_describe(value)}")
        if isinstance(value, float):
            if not math.isfinite(value) or value != int(value):
                raise ArgumentError("bad_args", f"{param.name} must be an integer, got {_describe(value)}")
            value = int(value)
        converted = value
    elif param.type == "float":
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ArgumentError("bad_args", f"{param.name} must be a number, got {_describe(value)}")
        try:
            converted = float(value)  # an integer of 400 digits does not fit
        except OverflowError:
            converted = math.inf
        if not math.isfinite(converted):
            raise ArgumentError("bad_args", f"{param.name} must be a finite number")
    else:
        if not isinstance(value, str):
            raise ArgumentError("bad_args", f"{param.name} must be a string, got {_describe(value)}")
        converted = value
    if param.type in ("int", "float") and (
        (param.minimum is not None and converted < param.minimum)
        or (param.maximum is not None and converted > param.maximum)
    ):
        low = "-inf" if param.minimum is None else f"{param.minimum:g}"
        high = "inf" if param.maximum is None else f"{param.maximum:g}"
        unit = f" {param.unit}" if param.unit else ""
        raise ArgumentError("out_of_range",
                        f"{param.name}={_describe(converted)} is outside {low}..{high}{unit}")
    return converted


def check_args(spec: FeatureSpec, args: list[Any]) -> list[Any]:
    """A call's arguments checked against its feature spec and converted; raises `ArgumentError`."""
    if len(args) != len(spec.params):
        names = ", ".join(p.name for p in spec.params)
        raise ArgumentError(
            "bad_args",
            f"{spec.name} takes {len(spec.params)} argument(s) ({names}), got {len(args)}",
        )
    return [check_arg(param, value) for param, value in zip(spec.params, args, strict=True)]


@dataclass(frozen=True)
class KindSpec:
    """A component kind of the component diagram and every feature a component of it can have."""

    name: ComponentKind
    features: tuple[FeatureSpec, ...]
    doc: str = ""

    def pick(self, *names: str) -> dict[str, FeatureSpec]:
        """The named features of this kind, for an implementation that offers a subset."""
        by_name = {spec.name: spec for spec in self.features}
        return {name: by_name[name] for name in names}


@dataclass(frozen=True)
class ServiceSpec:
    """A service kind: the `ComponentService` subclass ("module:Class") serving its components."""

    name: ServiceKind
    service: str
    doc: str = ""
    #: the host puts every served component into its safe state (`ComponentService.safe_stop`)
    #: when the orchestrator's status says offline (its last will), stopped or failed, and
    #: `umlbot service all` stops these kinds first: for parts that must not go on without it.
    stop_when_orchestrator_offline: bool = False


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
    safe_stop: tuple[tuple[str, tuple[StopArg, ...]], ...] = ()
    settings_doc: dict[str, str] = field(default_factory=dict)
    #: settings keys that name a GPIO this part owns (no other component may use it).
    pin_keys: tuple[str, ...] = ()
    #: settings keys that list GPIOs this part owns (`pins: [5, 6]`), as `pin_keys` for each one.
    pin_list_keys: tuple[str, ...] = ()
    #: "module:function" `(impl, settings) -> {name: FeatureSpec}` when the features depend on
    #: the deployment's settings (a ROS 2 mapping names them); they need not be features of the
    #: kind, and `features` are what it offers when the settings say nothing usable.
    features_from: str = ""


@dataclass(frozen=True)
class ComponentPlugin:
    """What one `umlbot.components` entry point provides: new kinds, service kinds, implementations."""

    kinds: tuple[KindSpec, ...] = ()
    services: tuple[ServiceSpec, ...] = ()
    implementations: tuple[Implementation, ...] = ()


GPIO_PIN = Param("gpio", "int", 0, 27, "BCM pin")

#: The built-in component kinds and the features each can have (SPEC §2).
SYSTEM = KindSpec("system", (
    FeatureSpec("readPin", (GPIO_PIN,), "int", "Read a GPIO pin: 0 or 1."),
    FeatureSpec("writePin", (GPIO_PIN, Param("value", "int", 0, 1)), "none", "Write 0 or 1 to a GPIO pin."),
))
ACTUATOR = KindSpec("actuator", (
    FeatureSpec("enabled", (Param("on", "bool"),), "none", "Drive (true) or stop (false)."),
    FeatureSpec("direction", (Param("clockwise", "bool"),), "none", "true = clockwise (forward)."),
    FeatureSpec("dutycycle", (Param("percent", "int", 0, 100, "%"),), "none", "PWM duty cycle in percent."),
    FeatureSpec("angle", (Param("degrees", "int", 0, 360, "°"),), "none", "Turn to an angle."),
))
SENSOR = KindSpec("sensor", (
    FeatureSpec("value", (), "int", "Read the sensor (a distance sensor: centimetres)."),
))

CAMERA = KindSpec("camera", (
    FeatureSpec("distance", (Param("angle_deg", "int", -30, 30, "°"),), "int",
                "cm to the nearest surface in that direction (+ = left), -1 = no reading."),
    FeatureSpec("nearest", (), "int", "cm to the nearest surface in view, -1 = no reading."),
    FeatureSpec("nearestBearing", (), "int", "direction of the nearest surface in degrees (+ = left)."),
    FeatureSpec("freeWidth", (), "int", "cm of free way straight ahead (0 = blocked or no reading)."),
    FeatureSpec("reach", (Param("angle_deg", "int", -30, 30, "°"),), "int",
                "cm a strip the car's width is free in that direction (+ = left), -1 = no reading."),
    FeatureSpec("openBearing", (), "int", "direction (degrees, + = left) in which the way is free farthest."),
), "a camera that measures distances (a stereo pair)")


#: umlbot's own kinds, service kinds and implementations, registered as the entry point `builtin`.
BUILTIN = ComponentPlugin(
    kinds=(SYSTEM, ACTUATOR, SENSOR, CAMERA),
    services=(
        ServiceSpec("motor", "umlbot.services.motor.service:MotorService", "L298N motor channels",
                    stop_when_orchestrator_offline=True),
        ServiceSpec("sonar", "umlbot.services.sonar.service:SonarService", "HC-SR04 range finders"),
        ServiceSpec("servo", "umlbot.services.servo.service:ServoService", "hobby servos"),
        ServiceSpec("gpio", "umlbot.services.gpio.service:GpioService", "plain GPIO pins of the system"),
        ServiceSpec("stereo", "umlbot.services.stereo.service:StereoService",
                    "stereo cameras: depth by OpenCV (extra umlbot[stereo])"),
    ),
    implementations=(
        Implementation(
            id="raspberrypi",
            kind="system",
            service="gpio",
            features=SYSTEM.pick("readPin", "writePin"),
            title="Raspberry Pi GPIO (system)",
            aliases=("CModelSystemRaspberryPI",),
            settings_doc={"pins": "GPIO pins the model may read or write (BCM numbers)"},
            pin_list_keys=("pins",),
        ),
        Implementation(
            id="l298n",
            kind="actuator",
            service="motor",
            features=ACTUATOR.pick("enabled", "direction", "dutycycle"),
            title="L298N H-bridge motor channel",
            aliases=("CModelL298NActuator",),
            safe_stop=(("enabled", (False,)),),
            pin_keys=("in1", "in2", "enable"),
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
            features={"angle": ACTUATOR.pick("angle")["angle"].with_range("degrees", 0, 180)},
            title="hobby servo, 180°",
            aliases=("CModelActuator",),
            settings_doc={"gpio": "GPIO of the signal wire", "min_pulse_us": "pulse at 0°",
                          "max_pulse_us": "pulse at 180°"},
            pin_keys=("gpio",),
        ),
        Implementation(
            id="hcsr04",
            kind="sensor",
            service="sonar",
            features=SENSOR.pick("value"),
            title="HC-SR04 ultrasonic range finder",
            aliases=("CModelDistanceSensorHCSR",),
            settings_doc={"trigger": "GPIO of TRIG", "echo": "GPIO of ECHO", "samples": "median of N"},
            pin_keys=("trigger", "echo"),
        ),
        Implementation(
            id="stereo_camera",
            kind="camera",
            aliases=("CModelStereoCamera",),
            service="stereo",
            features=CAMERA.pick("distance", "nearest", "nearestBearing", "freeWidth", "reach",
                                  "openBearing"),
            title="stereo camera pair (two Pi camera modules or a USB stereo camera)",
            settings_doc={"calibration": "the file 'umlbot calibrate stereo' wrote",
                          "source": "picamera2 or opencv", "width_px": "image width",
                          "height_px": "image height"},
        ),
    ),
)
