"""The activity engine: runs the compiled swimlanes as asyncio tokens, without knowing about MQTT.

Each lane's nodes are translated once into `Step`s (expressions into closures, see
`umlbot.services.orchestrator.expressions`). A lane run (an *activation*) starts with one token at the
start node, walked inline by the caller's task: a component lane's task, or the token that called a
virtual lane (a call is an `await`, so virtual lanes are re-entrant: every call has its own tokens
and join counts; datastores belong to the lane and are shared by all its calls). A fork spawns one
task per outgoing flow; a join lets the last arriving flow continue once; an end node ends the whole
activation (other tokens are cancelled); when no token is left the activation ends too (a flow
stopped at a decision with no match, for instance).

The engine reaches the outside world only through a `Port` (feature calls and signal publishing)
and reports each executed node to an optional trace sink. Nodes that never wait (datastore and
decision with plain expressions) run without an `await`; the walker yields to the event loop every
`YIELD_EVERY` steps so a busy loop cannot starve the other lanes or block cancellation.
"""

from __future__ import annotations

import asyncio
import collections
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

from umlbot.base.clock import Clock
from umlbot.base.errors import OrchestratorError
from umlbot.compiler.compiled import (
    AcceptNode,
    ActionNode,
    CompiledModel,
    DatastoreNode,
    DecisionNode,
    EndNode,
    ForkNode,
    JoinNode,
    Lane,
    Node,
    SendNode,
    StartNode,
)
from umlbot.compiler.expr import Call, FeatureTarget
from umlbot.services.orchestrator.expressions import Evaluator, ExpressionCompiler, Value
from umlbot.services.orchestrator.signals import SignalBoard

#: the walker gives the event loop a turn after this many steps in a row.
YIELD_EVERY = 128

# step codes, compared in the walker's hot loop
START, END, ACTION, DATASTORE, DECISION, FORK, JOIN, SEND, ACCEPT = range(9)
_CODES: dict[str, int] = {
    "start": START,
    "end": END,
    "action": ACTION,
    "datastore": DATASTORE,
    "decision": DECISION,
    "fork": FORK,
    "join": JOIN,
    "send": SEND,
    "accept": ACCEPT,
}

# what a token's walk ended with
_ENDED, _STOPPED, _FORKED = range(3)

#: One executed node, as the engine reports it (cheap to make; the trace module turns it into a
#: `TraceEvent`): lane, node id, kind, label, start and end (epoch seconds), value, error, warning.
TraceRecord = tuple[str, str, str, str, float, float, Value, str | None, str | None]
TraceSink = Callable[[TraceRecord], None]


class Port(Protocol):
    """The engine's way out: feature calls and signal publishing (MQTT in the orchestrator)."""

    async def call(self, component: str, feature: str, args: list[Value]) -> Value:
        """One request/reply; raises `CallTimeout`, `RemoteError` or `NotConnected`."""

    def publish_signal(self, name: str, payload: Value) -> None:
        """Publish signal `name` with its JSON payload."""


class NodeFailed(OrchestratorError):
    """A node raised: a feature call failed, or an expression could not be evaluated."""

    def __init__(self, lane: str, node: str, label: str, cause: BaseException) -> None:
        what = f" ({label})" if label else ""
        super().__init__(f"lane {lane}, node {node}{what}: {cause}")
        self.lane = lane
        self.node = node
        self.label = label
        self.cause = cause


@dataclass(slots=True, eq=False)
class Step:
    """One node, ready to run: its code and what its kind needs."""

    id: str
    code: int
    kind: str
    label: str
    next: str = ""
    #: action: the call; datastore: the value; send: the payload (None: no payload).
    expr: Evaluator | None = None
    #: datastore name, signal name of send/accept.
    name: str = ""
    #: accept: the datastore receiving the payload.
    store: str | None = None
    #: decision: (guard or None for else, target) in declared order.
    branches: tuple[tuple[Evaluator | None, str], ...] = ()
    #: fork: the targets.
    targets: tuple[str, ...] = ()
    #: join: the nodes flows arrive from.
    incoming: tuple[str, ...] = ()
    #: action: True when it calls a component feature (counted in the action statistics).
    feature_call: bool = False


@dataclass(slots=True, eq=False)
class LaneProgram:
    """A lane's steps, its datastores (shared by all its activations) and where it starts."""

    name: str
    virtual: bool
    component: str | None
    start: str
    steps: dict[str, Step]
    store: dict[str, Value]


@dataclass(slots=True, eq=False)
class Activation:
    """One run of a lane: its spawned tokens and the arrivals counted at its joins."""

    program: LaneProgram
    tasks: set[asyncio.Task[None]] = field(default_factory=set)
    arrivals: dict[str, dict[str, int]] = field(default_factory=dict)
    finished: asyncio.Future[None] | None = None


#: feature-call latencies kept for statistics (the newest; a long run must not grow without bound).
LATENCIES_KEPT = 100_000


@dataclass(slots=True)
class EngineStats:
    """What the engine executed: node count and the latency of each feature-call action."""

    nodes: int = 0
    actions: int = 0
    #: seconds per feature-call action, the newest `LATENCIES_KEPT`.
    action_latency_s: collections.deque[float] = field(
        default_factory=lambda: collections.deque(maxlen=LATENCIES_KEPT)
    )
    #: nodes skipped because a flow stopped (decision without a match).
    stopped_flows: int = 0


class Engine:
    """Runs a compiled model's lanes; see the module docstring for the execution rules."""

    def __init__(
        self,
        model: CompiledModel,
        port: Port,
        signals: SignalBoard | None = None,
        clock: Clock | None = None,
        trace: TraceSink | None = None,
    ) -> None:
        self.model = model
        self.port = port
        self.signals = signals or SignalBoard.for_model(model)
        self.clock = clock or Clock(1.0)
        self.trace = trace
        self.stats = EngineStats()
        #: `Application.exit`: set once termination was requested.
        self.exit_requested = False
        #: datastores by lane name; `Lane.name` references read these dicts directly.
        self.stores: dict[str, dict[str, Value]] = {name: {} for name in model.lanes}
        self._compiler = ExpressionCompiler(self.stores, self)
        self.programs: dict[str, LaneProgram] = {
            name: self._program(lane) for name, lane in model.lanes.items()
        }

    # --- Runtime (what expressions call) ----------------------------------------------------------

    async def call_feature(self, component: str, feature: str, args: list[Value]) -> Value:
        """A component feature call through the port."""
        return await self.port.call(component, feature, args)

    async def call_lane(self, lane: str) -> None:
        """Run virtual lane `lane` to an end (a call from an action or an expression)."""
        await self.activate(self.programs[lane])

    async def sleep(self, seconds: float) -> None:
        """`usleep`/`msleep`: sim time through the shared clock."""
        await self.clock.asleep(seconds)

    # --- lanes ------------------------------------------------------------------------------------

    def component_lanes(self) -> list[str]:
        """The lanes that start at start-up (every non-virtual lane), in name order."""
        return sorted(name for name, program in self.programs.items() if not program.virtual)

    async def run_lane(self, name: str) -> None:
        """Run a component lane until it ends (or is cancelled)."""
        await self.activate(self.programs[name])

    async def activate(self, program: LaneProgram) -> None:
        """One run of `program`: walk from its start until it ends; spawned tokens are awaited."""
        act = Activation(program)
        try:
            outcome = await self._walk(act, program.start, "")
            if outcome == _FORKED and act.finished is not None:
                await act.finished
        finally:
            if act.tasks:
                tasks = list(act.tasks)
                for task in tasks:
                    task.cancel()
                await asyncio.wait(tasks)

    async def _token(self, act: Activation, node_id: str, prev: str) -> None:
        """A spawned token (one outgoing flow of a fork)."""
        finished = act.finished
        assert finished is not None
        try:
            outcome = await self._walk(act, node_id, prev)
        except asyncio.CancelledError:
            act.tasks.discard(asyncio.current_task())
            raise
        except Exception as exc:
            act.tasks.discard(asyncio.current_task())
            if not finished.done():
                finished.set_exception(exc)
            return
        act.tasks.discard(asyncio.current_task())
        if (outcome == _ENDED or not act.tasks) and not finished.done():
            finished.set_result(None)

    async def _walk(self, act: Activation, node_id: str, prev: str) -> int:
        """Walk one token from `node_id` until it ends, stops or forks; returns which."""
        program = act.program
        steps = program.steps
        store = program.store
        lane = program.name
        trace = self.trace
        stats = self.stats
        # trace timestamps in the robot's time: the wall clock on a robot, sim time in the simulator
        # (it moves from event to event, paced by `speed`: see umlbot.sim.clock)
        clock = time.time if type(self.clock) is Clock and self.clock.speed == 1.0 else self.clock.epoch
        budget = YIELD_EVERY
        value: Value = None
        while True:
            step = steps[node_id]
            code = step.code
            start = clock() if trace is not None else 0.0
            try:
                if code == DATASTORE:
                    expr = step.expr
                    assert expr is not None
                    value = expr.sync() if expr.sync is not None else await expr.run()
                    store[step.name] = value
                    nxt = step.next
                elif code == DECISION:
                    nxt = ""
                    for guard, target in step.branches:
                        if guard is None:
                            nxt = target
                            break
                        holds = guard.sync() if guard.sync is not None else await guard.run()
                        if holds:
                            nxt = target
                            break
                    value = nxt or None
                    if not nxt:
                        stats.nodes += 1
                        stats.stopped_flows += 1
                        if trace is not None:
                            trace((lane, step.id, step.kind, step.label, start, clock(), None, None,
                                   "no guard holds and there is no else: this flow stops"))
                        return _STOPPED
                elif code == ACTION:
                    expr = step.expr
                    assert expr is not None
                    if step.feature_call:
                        began = time.perf_counter()
                        value = await expr.run()
                        stats.actions += 1
                        stats.action_latency_s.append(time.perf_counter() - began)
                    else:
                        value = expr.sync() if expr.sync is not None else await expr.run()
                    nxt = step.next
                elif code == START:
                    value = None
                    nxt = step.next
                elif code == END:
                    stats.nodes += 1
                    if trace is not None:
                        trace((lane, step.id, step.kind, step.label, start, clock(), None, None, None))
                    return _ENDED
                elif code == SEND:
                    expr = step.expr
                    if expr is None:
                        value = None
                    else:
                        value = expr.sync() if expr.sync is not None else await expr.run()
                    self.port.publish_signal(step.name, value)
                    nxt = step.next
                elif code == ACCEPT:
                    value = await self.signals.wait(step.name)
                    if step.store is not None:
                        store[step.store] = value
                    nxt = step.next
                elif code == FORK:
                    stats.nodes += 1
                    if trace is not None:
                        trace((lane, step.id, step.kind, step.label, start, clock(), None, None, None))
                    self._fork(act, step)
                    return _FORKED
                elif code == JOIN:
                    counts = act.arrivals.get(step.id)
                    if counts is None:
                        counts = act.arrivals[step.id] = dict.fromkeys(step.incoming, 0)
                    counts[prev] = counts.get(prev, 0) + 1
                    if not all(counts[source] > 0 for source in step.incoming):
                        return _STOPPED  # this flow waits here; the last one to arrive continues
                    for source in step.incoming:
                        counts[source] -= 1
                    value = None
                    nxt = step.next
                else:  # pragma: no cover - codes are exhaustive
                    raise AssertionError(f"unknown step code {code}")
            except (asyncio.CancelledError, NodeFailed):
                raise
            except Exception as exc:
                if trace is not None:
                    trace((lane, step.id, step.kind, step.label, start, clock(), None, _describe(exc), None))
                raise NodeFailed(lane, step.id, step.label, exc) from exc
            stats.nodes += 1
            if trace is not None:
                trace((lane, step.id, step.kind, step.label, start, clock(), value, None, None))
            prev = node_id
            node_id = nxt
            budget -= 1
            if not budget:
                budget = YIELD_EVERY
                await asyncio.sleep(0)

    def _fork(self, act: Activation, step: Step) -> None:
        if act.finished is None:
            act.finished = asyncio.get_running_loop().create_future()
        for target in step.targets:
            task = asyncio.create_task(self._token(act, target, step.id), name=f"{act.program.name}:{target}")
            act.tasks.add(task)

    # --- translation --------------------------------------------------------------------------------

    def _program(self, lane: Lane) -> LaneProgram:
        store = self.stores[lane.name]
        steps = {node_id: self._step(node) for node_id, node in lane.nodes.items()}
        return LaneProgram(lane.name, lane.virtual, lane.component, lane.start, steps, store)

    def _step(self, node: Node) -> Step:
        step = Step(node.id, _CODES[node.kind], node.kind, node.label or node.id)
        compile_expr = self._compiler.compile
        if isinstance(node, StartNode | JoinNode | SendNode | AcceptNode | ActionNode | DatastoreNode):
            step.next = node.next
        if isinstance(node, ActionNode):
            step.expr = compile_expr(node.call)
            step.feature_call = _is_feature_call(node.call)
        elif isinstance(node, DatastoreNode):
            step.expr = compile_expr(node.value)
            step.name = node.name
        elif isinstance(node, DecisionNode):
            step.branches = tuple(
                (None if b.guard is None else compile_expr(b.guard), b.target) for b in node.branches
            )
        elif isinstance(node, ForkNode):
            step.targets = tuple(node.targets)
        elif isinstance(node, JoinNode):
            step.incoming = tuple(node.incoming)
        elif isinstance(node, SendNode):
            step.expr = None if node.payload is None else compile_expr(node.payload)
            step.name = node.signal
        elif isinstance(node, AcceptNode):
            step.name = node.signal
            step.store = node.store
        elif not isinstance(node, StartNode | EndNode):  # pragma: no cover - exhaustive union
            raise TypeError(f"unknown node {node!r}")
        return step


def _is_feature_call(call: Call) -> bool:
    return isinstance(call.target, FeatureTarget)


def _describe(exc: BaseException) -> str:
    text = str(exc)
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def used_components(model: CompiledModel) -> set[str]:
    """Every component whose feature some expression of the model calls."""
    found: set[str] = set()
    for lane in model.lanes.values():
        for node in lane.nodes.values():
            for expr in _expressions(node):
                _collect_components(expr, found)
    return found


def _expressions(node: Node) -> list[object]:
    if isinstance(node, ActionNode):
        return [node.call]
    if isinstance(node, DatastoreNode):
        return [node.value]
    if isinstance(node, DecisionNode):
        return [b.guard for b in node.branches if b.guard is not None]
    if isinstance(node, SendNode) and node.payload is not None:
        return [node.payload]
    return []


def _collect_components(expr: object, found: set[str]) -> None:
    from umlbot.compiler.expr import Binary, Unary

    if isinstance(expr, Call):
        if isinstance(expr.target, FeatureTarget):
            found.add(expr.target.component)
        for arg in expr.args:
            _collect_components(arg, found)
    elif isinstance(expr, Unary):
        _collect_components(expr.operand, found)
    elif isinstance(expr, Binary):
        _collect_components(expr.left, found)
        _collect_components(expr.right, found)
