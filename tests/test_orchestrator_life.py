"""The life of a run as a state machine (umlbot.services.orchestrator.life): which moves it allows,
that the first fault is the one kept and heard, and which faults a broker's end explains."""

from __future__ import annotations

import pytest

from umlbot.base.errors import CallTimeout, NotConnected, RemoteError
from umlbot.services.orchestrator.life import MOVES, Fault, FaultKind, IllegalMove, Life, Phase


def test_a_run_moves_from_starting_through_running_and_stopping_to_its_end() -> None:
    life = Life()
    heard: list[tuple[Phase, str | None]] = []
    life.on_move(lambda phase, reason: heard.append((phase, reason)))
    assert (life.phase, life.active, life.ended) == (Phase.STARTING, False, False)
    life.move(Phase.RUNNING)
    assert (life.phase, life.active, life.ended) == (Phase.RUNNING, True, False)
    life.move(Phase.STOPPING, "SIGTERM received")
    assert (life.active, life.reason) == (True, "SIGTERM received")
    life.move(Phase.STOPPED, "SIGTERM received")
    assert (life.phase, life.active, life.ended) == (Phase.STOPPED, False, True)
    assert heard == [(Phase.RUNNING, None), (Phase.STOPPING, "SIGTERM received"),
                     (Phase.STOPPED, "SIGTERM received")]


@pytest.mark.parametrize(("start", "to"), [
    (Phase.STARTING, Phase.STOPPING),  # nothing runs yet: there is no grace period to enter
    (Phase.RUNNING, Phase.STARTING),
    (Phase.STOPPING, Phase.RUNNING),
    (Phase.STOPPED, Phase.RUNNING),
    (Phase.FAILED, Phase.STOPPED),
    (Phase.STOPPED, Phase.STOPPED),
])
def test_moves_the_machine_does_not_allow_are_refused(start: Phase, to: Phase) -> None:
    life = Life()
    path = {Phase.STARTING: [], Phase.RUNNING: [Phase.RUNNING],
            Phase.STOPPING: [Phase.RUNNING, Phase.STOPPING], Phase.STOPPED: [Phase.STOPPED],
            Phase.FAILED: [Phase.FAILED]}[start]
    for phase in path:
        life.move(phase)
    with pytest.raises(IllegalMove, match=f"from {start} to {to}"):
        life.move(to)
    assert life.phase is start


def test_every_unfinished_phase_can_fail_and_the_ends_are_final() -> None:
    for phase, allowed in MOVES.items():
        assert (Phase.FAILED in allowed) == (phase not in (Phase.STOPPED, Phase.FAILED))
    assert not MOVES[Phase.STOPPED] and not MOVES[Phase.FAILED]


def test_the_first_fault_is_kept_and_heard_once() -> None:
    life = Life()
    heard: list[Fault] = []
    life.on_fault(heard.append)
    first = Fault(FaultKind.COMPONENT_LOST, "component DistanceRead went offline", "DistanceRead")
    assert life.fail(first)
    timeout = CallTimeout("DistanceRead", "value", 2.0)
    assert not life.fail(Fault(FaultKind.NODE, "lane Main, node n1: timed out", cause=timeout))
    assert life.fault is first and heard == [first]
    life.reclassify(Fault.broker_lost())  # what really caused it: named after it, not heard again
    assert life.fault is not None and life.fault.kind is FaultKind.BROKER_LOST and heard == [first]


def test_only_an_exit_request_that_comes_first_counts() -> None:
    life = Life()
    assert life.request_exit("SIGINT received")
    assert not life.request_exit("exit requested over MQTT")
    assert life.exit_reason == "SIGINT received"


@pytest.mark.parametrize(("fault", "symptom"), [
    (Fault(FaultKind.COMPONENT_LOST, "component LeftActuator went offline", "LeftActuator"), True),
    (Fault.broker_lost(), True),
    (Fault(FaultKind.NODE, "lane Main, node n1: lost", cause=NotConnected("the connection was lost")), True),
    (Fault(FaultKind.NODE, "lane Main, node n1: refused", cause=RemoteError("out_of_range", "150")), False),
    (Fault(FaultKind.NODE, "lane Main, node n1: late", cause=CallTimeout("DistanceRead", "value", 2)), False),
    (Fault(FaultKind.START, "component(s) not online after 10 s"), False),
    (Fault(FaultKind.INTERNAL, "lane Main: internal error", cause=RuntimeError("bug")), False),
])
def test_which_faults_a_broker_going_down_explains(fault: Fault, symptom: bool) -> None:
    assert fault.broker_symptom is symptom
