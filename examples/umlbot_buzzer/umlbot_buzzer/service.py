"""The buzzer service: `enabled(bool)` and `tone(hz)` on the bus for one passive buzzer.

State: `{"on": bool, "tone_hz": int}`. A safety stop (service stopping, broker lost, the
orchestrator offline, stopped or failed: `stop_when_orchestrator_offline` in spec.py) silences it;
the orchestrator also calls `enabled(false)` at start and end (the implementation's `safe_stop`).
"""

from __future__ import annotations

from typing import Any

from umlbot.services.component_service import ComponentService
from umlbot_buzzer.driver import DEFAULT_TONE_HZ, Buzzer


class BuzzerService(ComponentService):
    """One buzzer on the bus."""

    kind = "buzzer"
    handlers = {"enabled": "enabled", "tone": "tone"}

    on = False
    tone_hz = DEFAULT_TONE_HZ

    @property
    def buzzer(self) -> Buzzer:
        buzzer: Buzzer = self.driver
        return buzzer

    def enabled(self, on: bool) -> None:
        with self.lock:
            if on:
                self.buzzer.play(self.tone_hz)
            else:
                self.buzzer.silence()
            self.on = on
        self.changed()

    def tone(self, hz: int) -> None:
        with self.lock:
            if self.on:
                self.buzzer.play(hz)
            self.tone_hz = hz
        self.changed()

    def state(self) -> dict[str, Any]:
        with self.lock:
            return {"on": self.on, "tone_hz": self.tone_hz}

    def safe_stop(self, reason: str) -> None:
        with self.lock:
            was_on, self.on = self.on, False
            self.buzzer.silence()
        if was_on:
            self.changed()
