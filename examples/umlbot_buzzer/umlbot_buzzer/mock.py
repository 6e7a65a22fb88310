"""A mock buzzer: records what it played; no hardware (`mock_…` settings as every mock driver)."""

from __future__ import annotations

from umlbot.base.registry import DriverFactory
from umlbot.services.mock_support import MockDriver, MockSettings


class MockBuzzer(MockDriver):
    """Satisfies `Buzzer`. State: `playing_hz` (None when silent)."""

    def __init__(self, component: str, settings: MockSettings | None = None) -> None:
        super().__init__(component, settings or MockSettings())
        self.playing_hz: int | None = None

    def play(self, hz: int) -> None:
        self._enter("play", hz)
        with self._cond:
            self.playing_hz = hz
            self._changed()

    def silence(self) -> None:
        with self._cond:  # a safety stop never fails
            self._record("silence")
            self.playing_hz = None
            self._changed()

    def close(self) -> None:
        with self._cond:
            if self.closed:
                return
            self.silence()
            self._record("close")
            self.closed = True


FACTORY = DriverFactory(MockSettings, MockBuzzer)
