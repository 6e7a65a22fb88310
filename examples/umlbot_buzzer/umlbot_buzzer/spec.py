"""What this plugin adds to umlbot's component library (the `umlbot.components` entry point).

Declarations only: this module is imported whenever umlbot reads its library, so it must not
import drivers or hardware modules.
"""

from __future__ import annotations

from umlbot.base.library import ComponentPlugin, FeatureSpec, Implementation, KindSpec, Param, ServiceSpec

#: A new component kind for the component diagram: something that makes a sound.
SOUNDER = KindSpec("sounder", (
    FeatureSpec("enabled", (Param("on", "bool"),), "none", "Sound (true) or silence (false)."),
    FeatureSpec("tone", (Param("hz", "int", 20, 20000, "Hz"),), "none", "The pitch of the sound."),
), "A buzzer or speaker.")

PLUGIN = ComponentPlugin(
    kinds=(SOUNDER,),
    # a buzzer left sounding by an orchestrator that died is silenced, as a motor is stopped
    services=(ServiceSpec("buzzer", "umlbot_buzzer.service:BuzzerService", "passive buzzers",
                          stop_when_orchestrator_offline=True),),
    implementations=(
        Implementation(
            id="passive_buzzer",
            kind="sounder",
            service="buzzer",
            # A passive buzzer is driven by software PWM: lgpio reaches 10 kHz.
            features={"enabled": SOUNDER.pick("enabled")["enabled"],
                      "tone": SOUNDER.pick("tone")["tone"].with_range("hz", 20, 10000)},
            title="passive piezo buzzer on one GPIO",
            aliases=("CModelBuzzer",),
            safe_stop=(("enabled", (False,)),),
            settings_doc={"gpio": "GPIO of the buzzer's signal pin"},
            pin_keys=("gpio",),
        ),
    ),
)
