"""Plugin objects for tests/test_plugins.py: one good plugin and one of each kind of mistake."""

from __future__ import annotations

from umlbot.base.library import (
    ACTUATOR,
    SENSOR,
    ComponentPlugin,
    FeatureSpec,
    Implementation,
    KindSpec,
    Param,
    ServiceSpec,
)

#: An IR line sensor with a service kind of its own (its service class is never started here).
GOOD = ComponentPlugin(
    services=(ServiceSpec("linesensor", "plugin_samples:NoSuchService"),),
    implementations=(Implementation(id="tcrt5000", kind="sensor", service="linesensor",
                                    features=SENSOR.pick("value"), title="IR line sensor",
                                    aliases=("CModelLineSensor",), pin_keys=("gpio",)),),
)

#: Takes the seed alias of the built-in L298N.
CLASH = ComponentPlugin(implementations=(
    Implementation(id="l298n_clone", kind="actuator", service="motor",
                   features={"enabled": FeatureSpec("enabled", (Param("on", "bool"),))},
                   title="clone", aliases=("CModelL298NActuator",)),
))

#: Widens the actuator's angle range and offers a feature its kind does not have.
BAD_SPEC = ComponentPlugin(implementations=(
    Implementation(id="wide_servo", kind="actuator", service="servo",
                   features={"angle": FeatureSpec("angle", (Param("degrees", "int", 0, 400),)),
                             "value": FeatureSpec("value", (), "int")},
                   title="too wide"),
))

NOT_A_PLUGIN = 42

#: Types a feature cannot have: a parameter of type "double", a return value of type "list"; a
#: service kind's flag that is not a bool.
BAD_TYPES = ComponentPlugin(
    kinds=(KindSpec("lamp", (FeatureSpec("bright", (Param("level", "double", 0, 10),),  # type: ignore[arg-type]
                                         "list"),)),),  # type: ignore[arg-type]
    services=(ServiceSpec("lampsvc", "plugin_samples:NoSuchService",
                          stop_when_orchestrator_offline="yes"),),  # type: ignore[arg-type]
)

#: Safe-stop calls whose arguments do not fit the features they call.
BAD_STOP = ComponentPlugin(implementations=(
    Implementation(id="bad_stop", kind="actuator", service="motor",
                   features=ACTUATOR.pick("enabled", "dutycycle"), title="bad stop",
                   safe_stop=(("enabled", ("abc",)), ("dutycycle", (150,)), ("enabled", ()),
                              ("dutycycle", (True,)))),
))
