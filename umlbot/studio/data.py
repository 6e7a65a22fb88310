"""What the studio's page gets besides the live events (the hello), and the protocol's limits:
shared by the server, the editing API and the event sources, below all three."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

#: the version of the page's WebSocket protocol (docs/studio.md).
PROTOCOL_VERSION = 1
#: the largest request body accepted (an edit batch, a completion request).
MAX_BODY = 1 << 20


@dataclass
class StudioData:
    """What the page shows besides the live events: the model, its problems, a replay, a track."""

    mode: str  # "live" or "replay"
    robot: str
    source: str
    model: dict[str, Any] | None
    diagnostics: list[dict[str, Any]]
    track: dict[str, Any] | None = None
    replay: dict[str, Any] | None = None
    #: the editing session's part of the hello (None: the page cannot edit).
    edit: Callable[[], dict[str, Any]] | None = None
    #: the model's `call_timeout_s` (a call unanswered this long is reported, until the
    #: orchestrator's status says the run's own time-out).
    call_timeout_s: float | None = None
    #: a fleet hub (`--fleet`): the page shows the fleet view from `GET /api/fleet`.
    fleet: bool = False

    def hello(self) -> dict[str, Any]:
        return {"type": "hello", "version": PROTOCOL_VERSION, "mode": self.mode, "robot": self.robot,
                "source": self.source, "model": self.model, "diagnostics": self.diagnostics,
                "track": self.track, "replay": self.replay,
                "edit": self.edit() if self.edit is not None else None, "fleet": self.fleet}
