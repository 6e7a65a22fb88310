"""Plugin objects for tests/test_plugins.py: one good plugin and one of each kind of mistake."""

from __future__ import annotations

from umlbot.library import SENSOR, ComponentPlugin, FeatureSpec, Implementation, Param, ServiceSpec

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
