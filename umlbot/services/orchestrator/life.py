"""The life of a run as an explicit state machine: its phases, the moves between them, and the
faults that end it, typed.

A run starts in `STARTING`, goes `RUNNING` once its components are online and its actuators
stopped, may pass through `STOPPING` (termination requested: the lanes get their grace period) and
ends `STOPPED` or `FAILED`; a fault moves it to `FAILED` from any phase before the end. Each phase
is what the orchestrator's retained status says (docs/semantics.md). Listeners hear every move and
the first fault, on the orchestrator's event loop: that is how `umlbot sim` halts its world at the
first fault without knowing the orchestrator's inside.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum

from umlbot.base.errors import NotConnected, OrchestratorError


class Phase(StrEnum):
    """Where a run is; the value is its retained status's `state`."""

    STARTING = "starting"
    RUNNING = "running"
    STOPPING = "stopping"
    STOPPED = "stopped"
    FAILED = "failed"


class FaultKind(StrEnum):
    """Why a run failed (the fail-safe stop's cause)."""

    #: it could not start: the broker, a component not online, the actuators not stopped
    START = "start"
    #: a node raised: a feature call timed out or got an error reply, an expression failed
    NODE = "node"
    #: a component the model uses went offline (or any state but online) while it ran
    COMPONENT_LOST = "component lost"
    #: the connection to the MQTT broker was lost while it ran
    BROKER_LOST = "broker lost"
    #: a bug in the orchestrator itself (a lane crashed): the robot is still stopped safely
    INTERNAL = "internal"


BROKER_LOST_REASON = "connection to the MQTT broker lost"


@dataclass(frozen=True, slots=True)
class Fault:
    """A fail-safe stop's cause: its kind, the reason in words, and what it concerns."""

    kind: FaultKind
    reason: str
    #: the component concerned (COMPONENT_LOST), None otherwise
    component: str | None = None
    #: the exception behind it (a node's: what its call or expression raised), when there is one
    cause: BaseException | None = None

    @property
    def broker_symptom(self) -> bool:
        """A fault that a broker going down explains: it sends the last wills first, and calls
        find no connection as it goes."""
        if self.kind in (FaultKind.COMPONENT_LOST, FaultKind.BROKER_LOST):
            return True
        return isinstance(self.cause, NotConnected)

    @classmethod
    def broker_lost(cls) -> Fault:
        return cls(FaultKind.BROKER_LOST, BROKER_LOST_REASON)


#: the moves a run may make; a fault moves any unfinished phase to FAILED
MOVES: dict[Phase, frozenset[Phase]] = {
    Phase.STARTING: frozenset({Phase.RUNNING, Phase.STOPPED, Phase.FAILED}),
    Phase.RUNNING: frozenset({Phase.STOPPING, Phase.STOPPED, Phase.FAILED}),
    Phase.STOPPING: frozenset({Phase.STOPPED, Phase.FAILED}),
    Phase.STOPPED: frozenset(),
    Phase.FAILED: frozenset(),
}

MoveListener = Callable[[Phase, str | None], None]
FaultListener = Callable[[Fault], None]


class IllegalMove(OrchestratorError):
    """A move the state machine does not allow (a bug of the orchestrator)."""


class Life:
    """The phase of one run, its first fault and why termination was requested.

    Not thread-safe: used on the orchestrator's event loop only.
    """

    def __init__(self) -> None:
        self.phase = Phase.STARTING
        #: the reason the current phase was entered with (kept for re-publishing the status)
        self.reason: str | None = None
        #: the first fault, None while nothing went wrong
        self.fault: Fault | None = None
        #: why termination was requested, None until it was
        self.exit_reason: str | None = None
        self._on_move: list[MoveListener] = []
        self._on_fault: list[FaultListener] = []

    @property
    def ended(self) -> bool:
        return not MOVES[self.phase]

    @property
    def active(self) -> bool:
        """The model runs (or its lanes finish their grace period)."""
        return self.phase in (Phase.RUNNING, Phase.STOPPING)

    def on_move(self, listener: MoveListener) -> None:
        """Call `listener(phase, reason)` after every move."""
        self._on_move.append(listener)

    def on_fault(self, listener: FaultListener) -> None:
        """Call `listener(fault)` once, for the first fault."""
        self._on_fault.append(listener)

    def move(self, phase: Phase, reason: str | None = None) -> None:
        """Enter `phase`; `IllegalMove` when the machine does not allow it."""
        if phase not in MOVES[self.phase]:
            raise IllegalMove(f"the orchestrator cannot go from {self.phase} to {phase}")
        self.phase, self.reason = phase, reason
        for listener in list(self._on_move):
            listener(phase, reason)

    def fail(self, fault: Fault) -> bool:
        """Record the first fault (later ones are ignored); True when this one was the first."""
        if self.fault is not None:
            return False
        self.fault = fault
        for listener in list(self._on_fault):
            listener(fault)
        return True

    def reclassify(self, fault: Fault) -> None:
        """Name the first fault after what really caused it (the broker's end behind a component
        that went offline just before): the listeners heard the first report already."""
        self.fault = fault

    def request_exit(self, reason: str) -> bool:
        """Record why termination was requested; True for the first request."""
        if self.exit_reason is not None:
            return False
        self.exit_reason = reason
        return True
