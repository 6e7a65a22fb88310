"""SIGINT and SIGTERM for the long-running commands (`umlbot service`, `umlbot monitor`).

While a command starts (connecting to a broker may wait up to its connect time-out) a signal
interrupts it at once, as Ctrl-C does by default: KeyboardInterrupt unwinds through the
command's clean-up and `umlbot` exits with 130. Once the command runs, a signal only asks it to
stop, so it ends its work in order.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType, TracebackType


class StopSignals:
    """Context manager: installs the handlers, restores the previous ones on exit."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.stop = threading.Event()
        self._running = False
        self._previous: dict[signal.Signals, object] = {}

    def running(self) -> None:
        """The command has started: from now on a signal sets `stop` instead of interrupting."""
        self._running = True

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if not self._running:
            raise KeyboardInterrupt
        self.stop.set()

    def __enter__(self) -> StopSignals:
        self._previous = {sig: signal.signal(sig, self._handle) for sig in self.SIGNALS}
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]
