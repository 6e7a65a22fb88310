"""The sim buzzer: the simulated world has no sound, so it logs each tone with the sim's time.

It needs a world to be running in this process (`umlbot sim`), like every sim driver, and reads
its clock so the log says when the model sounded the buzzer.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from umlbot.base.errors import DriverError, SimError
from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.simworld import connect_world

log = get_logger("umlbot.buzzer.sim")


class SimBuzzerSettings(BaseModel):
    """The real buzzer's settings are accepted and ignored."""

    model_config = ConfigDict(extra="ignore", frozen=True)


class SimBuzzer:
    """Satisfies `Buzzer`; `tones` lists what it played, None for each silence after a tone."""

    def __init__(self, component: str) -> None:
        self.component = component
        self.playing_hz: int | None = None
        self.tones: list[int | None] = []
        self._closed = False

    def play(self, hz: int) -> None:
        if self._closed:
            raise DriverError(f"{self.component}: driver is closed")
        self.playing_hz = hz
        self.tones.append(hz)
        log.info("buzzer_on", component=self.component, hz=hz)

    def silence(self) -> None:
        if self.playing_hz is not None:
            self.tones.append(None)
            log.info("buzzer_off", component=self.component)
        self.playing_hz = None

    def close(self) -> None:
        self.silence()
        self._closed = True


def create(component: str, settings: SimBuzzerSettings) -> SimBuzzer:
    """A sim buzzer; fails like the other sim drivers when no simulated world runs."""
    try:
        connect_world()
    except SimError as exc:
        raise DriverError(f"{component}: {exc}") from exc
    return SimBuzzer(component)


FACTORY = DriverFactory(SimBuzzerSettings, create)
