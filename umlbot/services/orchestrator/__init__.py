"""The orchestrator: executes a compiled model over MQTT (`umlbot run`, and in-process in `umlbot sim`).

`Orchestrator` owns the run's life (start-up checks, fail-safe, exit, trace); `Engine` runs the
swimlanes and knows nothing of MQTT; the expression interpreter never evals anything.
"""

from umlbot.services.orchestrator.engine import Engine, EngineStats, NodeFailed, TraceRecord, used_components
from umlbot.services.orchestrator.orchestrator import (
    DEFAULT_GRACE_S,
    DEFAULT_RECONNECT_WAIT_S,
    DEFAULT_STARTUP_TIMEOUT_S,
    EXIT_FAULT,
    EXIT_OK,
    Orchestrator,
    heartbeat_period_s,
    run_orchestrator,
)
from umlbot.services.orchestrator.signals import SignalBoard
from umlbot.services.orchestrator.trace import TraceRecorder, event_dict

__all__ = [
    "DEFAULT_GRACE_S",
    "DEFAULT_RECONNECT_WAIT_S",
    "DEFAULT_STARTUP_TIMEOUT_S",
    "EXIT_FAULT",
    "EXIT_OK",
    "Engine",
    "EngineStats",
    "NodeFailed",
    "Orchestrator",
    "SignalBoard",
    "TraceRecord",
    "TraceRecorder",
    "event_dict",
    "heartbeat_period_s",
    "run_orchestrator",
    "used_components",
]
