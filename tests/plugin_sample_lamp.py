"""A lamp plugin whose service kind has a mock driver and no sim driver (tests/test_sim_run.py):
`umlbot sim` runs such a kind on its mock driver. The spec, its service and its driver in one
module, as a test's small plugin may be."""

from __future__ import annotations

from typing import Any

from umlbot.base.library import ComponentPlugin, FeatureSpec, Implementation, KindSpec, Param, ServiceSpec
from umlbot.base.registry import DriverFactory
from umlbot.services.component_service import ComponentService
from umlbot.services.mock_support import MockDriver, MockSettings

LIGHT = KindSpec("light", (FeatureSpec("lit", (Param("on", "bool"),), "none", "On or off."),))

PLUGIN = ComponentPlugin(
    kinds=(LIGHT,),
    services=(ServiceSpec("lamp", "plugin_sample_lamp:LampService"),),
    implementations=(Implementation(id="led", kind="light", service="lamp", features=LIGHT.pick("lit"),
                                    title="LED", aliases=("CModelLed",), safe_stop=(("lit", (False,)),),
                                    pin_keys=("gpio",)),),
)


class MockLamp(MockDriver):
    """Records what it was told; `on` is the lamp's state."""

    on = False

    def light(self, on: bool) -> None:
        self._enter("light", on)
        with self._cond:
            self.on = on
            self._changed()


class LampService(ComponentService):
    """One lamp on the bus; it logs every change (`lamp_lit`), so a test sees the calls."""

    kind = "lamp"
    handlers = {"lit": "lit"}

    def lit(self, on: bool) -> None:
        lamp: MockLamp = self.driver
        lamp.light(on)
        self.log.info("lamp_lit", on=on)
        self.changed()

    def state(self) -> dict[str, Any]:
        lamp: MockLamp = self.driver
        return {"on": lamp.on}

    def safe_stop(self, reason: str) -> None:
        lamp: MockLamp = self.driver
        lamp.light(False)


FACTORY = DriverFactory(MockSettings, MockLamp)
