"""The engine and the expression interpreter without MQTT: a fake port records the calls.

These run the compiled test models (and small inline ones) through `Engine` directly, so every
rule of docs/semantics.md is checked quickly and precisely; the MQTT suites then check the same
rules end to end.
"""

from __future__ import annotations

import asyncio
import logging
import time
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from umlbot.base.clock import Clock
from umlbot.base.errors import RemoteError
from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import CompiledModel
from umlbot.compiler.expr import Binary, BuiltinTarget, Call, Const, Expr, FeatureTarget, Ref, Unary
from umlbot.services.orchestrator import Engine, NodeFailed, SignalBoard, TraceRecord
from umlbot.services.orchestrator.expressions import ExpressionCompiler

HEADER = """
name: unit
components:
  RaspberryPI: {kind: system}
  LeftActuator: {kind: actuator}
  RightActuator: {kind: actuator}
  DistanceRead: {kind: sensor}
deployment:
  driver: mock
  components:
    RaspberryPI: {impl: raspberrypi}
    LeftActuator: {impl: l298n, settings: {in1: 22, in2: 23}}
    RightActuator: {impl: l298n, settings: {in1: 24, in2: 25}}
    DistanceRead: {impl: hcsr04, settings: {trigger: 8, echo: 7}}
"""


def compile_text(tmp_path: Path, lanes: str) -> CompiledModel:
    path = tmp_path / "model.yaml"
    path.write_text(HEADER + lanes, encoding="utf-8")
    return compile_model(path)


class FakePort:
    """Records calls; `values[(component, feature)]` scripts replies (a list is consumed in order)."""

    def __init__(self, values: dict[tuple[str, str], Any] | None = None, delay_s: float = 0.0,
                 errors: dict[tuple[str, str], Exception] | None = None) -> None:
        self.values = values or {}
        self.delay_s = delay_s
        self.errors = errors or {}
        self.calls: list[tuple[str, str, list[Any]]] = []
        self.in_flight = 0
        self.max_in_flight = 0
        self.signals: list[tuple[str, Any]] = []
        self.board: SignalBoard | None = None

    async def call(self, component: str, feature: str, args: list[Any]) -> Any:
        self.calls.append((component, feature, args))
        self.in_flight += 1
        self.max_in_flight = max(self.max_in_flight, self.in_flight)
        try:
            if self.delay_s:
                await asyncio.sleep(self.delay_s)
        finally:
            self.in_flight -= 1
        if (component, feature) in self.errors:
            raise self.errors[(component, feature)]
        value = self.values.get((component, feature))
        if isinstance(value, list):
            return value.pop(0) if len(value) > 1 else value[0]
        return value

    def publish_signal(self, name: str, payload: Any) -> None:
        self.signals.append((name, payload))
        if self.board is not None:  # loop the signal back, as the broker does
            asyncio.get_running_loop().call_soon(self.board.deliver, name, payload)


def make_engine(model: CompiledModel, port: FakePort, speed: float = 1.0) -> tuple[Engine, list[TraceRecord]]:
    records: list[TraceRecord] = []
    board = SignalBoard()
    port.board = board
    engine = Engine(model, port, board, Clock(speed), trace=records.append)
    return engine, records


async def run_lanes(engine: Engine, limit_s: float = 5.0) -> None:
    async with asyncio.timeout(limit_s):
        await asyncio.gather(*(engine.run_lane(name) for name in engine.component_lanes()))


# --- expressions --------------------------------------------------------------------------------


class _Runtime:
    exit_requested = False

    async def call_feature(self, component: str, feature: str, args: list[Any]) -> Any:
        return {"value": 42}.get(feature, args)

    async def call_lane(self, lane: str) -> None:
        return None

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(0)


def evaluate(expr: Expr, stores: dict[str, dict[str, Any]] | None = None) -> Any:
    evaluator = ExpressionCompiler(stores or {}, _Runtime()).compile(expr)
    if evaluator.sync is not None:
        sync_value = evaluator.sync()
        assert asyncio.run(evaluator.run()) == sync_value  # both forms agree
        return sync_value
    return asyncio.run(evaluator.run())


def c(value: Any) -> Const:
    return Const(value=value)


def b(op: str, left: Expr, right: Expr) -> Binary:
    return Binary.model_validate({"operator": op, "left": left, "right": right})


@pytest.mark.parametrize(
    ("expr", "expected"),
    [
        (b("+", c(2), c(3)), 5),
        (b("+", c("ab"), c("cd")), "abcd"),
        (b("-", c(2), c(3.5)), -1.5),
        (b("*", c(4), c(2)), 8),
        (b("/", c(7), c(2)), 3.5),
        (b("%", c(-7), c(3)), 2),
        (b("==", c(1), c(1.0)), True),
        (b("!=", c("a"), c("b")), True),
        (b("<", c(1), c(2)), True),
        (b("<=", c(2), c(2)), True),
        (b(">", c(1), c(2)), False),
        (b(">=", c(3), c(2)), True),
        (b("and", c(True), c(False)), False),
        (b("or", c(False), c(True)), True),
        (Unary(operator="not", operand=c(False)), True),
        (Unary(operator="-", operand=c(4)), -4),
        (Ref(lane="L", name="x"), 7),
        (Ref(lane="L", name="never_written"), None),
        (b("+", Ref(lane="L", name="x"), c(1)), 8),
    ],
)
def test_operators(expr: Expr, expected: Any) -> None:
    assert evaluate(expr, {"L": {"x": 7}}) == expected


def test_and_or_short_circuit_skip_the_right_operand() -> None:
    # the right operand would raise (division by zero) if it were evaluated
    boom = b("/", c(1), c(0))
    assert evaluate(b("and", c(False), boom)) is False
    assert evaluate(b("or", c(True), boom)) is True
    with pytest.raises(ZeroDivisionError):
        evaluate(b("and", c(True), boom))


def test_feature_calls_make_an_expression_wait_and_others_not() -> None:
    compiler = ExpressionCompiler({}, _Runtime())
    call = Call(target=FeatureTarget(component="DistanceRead", feature="value"))
    assert compiler.compile(b("+", c(1), c(2))).sync is not None
    assert compiler.compile(Call(target=BuiltinTarget(name="Application.exit"))).sync is not None
    waiting = compiler.compile(b(">", call, c(20)))
    assert waiting.sync is None
    assert asyncio.run(waiting.run()) is True
    assert evaluate(Unary(operator="-", operand=call)) == -42


@given(st.integers(-10**6, 10**6), st.integers(-10**6, 10**6))
@settings(max_examples=60, deadline=None)
def test_arithmetic_matches_python(x: int, y: int) -> None:
    stores = {"L": {"x": x, "y": y}}
    ref_x, ref_y = Ref(lane="L", name="x"), Ref(lane="L", name="y")
    assert evaluate(b("+", ref_x, ref_y), stores) == x + y
    assert evaluate(b("*", ref_x, ref_y), stores) == x * y
    assert evaluate(b("<", ref_x, ref_y), stores) == (x < y)
    if y:
        assert evaluate(b("%", ref_x, ref_y), stores) == x % y


# --- engine --------------------------------------------------------------------------------------


def test_fork_join_in_flight_at_once(tmp_path: Path) -> None:
    model = compile_model(Path(__file__).parent / "models" / "fork.yaml")
    port = FakePort(delay_s=0.1)
    engine, records = make_engine(model, port)
    began = time.monotonic()
    asyncio.run(run_lanes(engine))
    elapsed = time.monotonic() - began
    assert port.max_in_flight == 2
    assert elapsed < 0.18
    assert [r[1] for r in records].count("joined") == 1
    assert engine.stores["RaspberryPI"]["done"] is True


def test_decision_takes_first_guard_that_holds_then_else(tmp_path: Path) -> None:
    model = compile_text(tmp_path, """
lanes:
  - lane: RaspberryPI
    nodes:
      - {id: start, kind: start}
      - {id: init, kind: datastore, name: n, value: 0}
      - id: loop
        kind: decision
        branches:
          - {if: n >= 3, then: done}
          - {if: n >= 0, then: inc}
          - {else: done}
      - {id: inc, kind: datastore, name: n, value: n + 1, next: loop}
      - {id: done, kind: end}
""")
    engine, records = make_engine(model, FakePort())
    asyncio.run(run_lanes(engine))
    assert engine.stores["RaspberryPI"]["n"] == 3
    decisions = [r for r in records if r[1] == "loop"]
    assert [r[6] for r in decisions] == ["inc", "inc", "inc", "done"]


def test_decision_without_match_stops_the_flow_with_a_warning(tmp_path: Path) -> None:
    model = compile_text(tmp_path, """
lanes:
  - lane: RaspberryPI
    nodes:
      - {id: start, kind: start}
      - {id: d, kind: decision, branches: [{if: 1 > 2, then: never}]}
      - {id: never, kind: action, call: LeftActuator.enabled(true)}
      - {id: end, kind: end}
""")
    port = FakePort()
    engine, records = make_engine(model, port)
    asyncio.run(run_lanes(engine))
    assert port.calls == []
    warning = [r for r in records if r[8] is not None]
    assert len(warning) == 1 and warning[0][1] == "d"
    assert "no guard holds" in str(warning[0][8])
    assert engine.stats.stopped_flows == 1


def test_virtual_lane_is_reentrant_and_shares_its_datastores(tmp_path: Path) -> None:
    model = compile_text(tmp_path, """
lanes:
  - lane: RaspberryPI
    nodes:
      - {id: start, kind: start}
      - {id: call, kind: action, call: Slow}
      - {id: end, kind: end}
  - lane: DistanceRead
    nodes:
      - {id: start, kind: start}
      - {id: call, kind: action, call: Slow()}
      - {id: end, kind: end}
  - lane: Slow
    nodes:
      - {id: start, kind: start}
      - {id: read, kind: datastore, name: last, value: DistanceRead.value()}
      - {id: count, kind: datastore, name: calls, value: calls + 1}
      - {id: end, kind: end}
""")
    # calls starts as None: make it numeric through the shared store before running
    port = FakePort({("DistanceRead", "value"): [30, 40]}, delay_s=0.1)
    engine, records = make_engine(model, port)
    engine.stores["Slow"]["calls"] = 0
    began = time.monotonic()
    asyncio.run(run_lanes(engine))
    assert time.monotonic() - began < 0.18  # both calls of Slow ran at once
    assert port.max_in_flight == 2
    assert engine.stores["Slow"]["calls"] == 2
    assert engine.stores["Slow"]["last"] in (30, 40)
    assert [r[0] for r in records if r[1] == "read"] == ["Slow", "Slow"]


def test_end_node_in_one_branch_ends_the_whole_activation(tmp_path: Path) -> None:
    model = compile_text(tmp_path, """
lanes:
  - lane: RaspberryPI
    nodes:
      - {id: start, kind: start}
      - {id: f, kind: fork, targets: [quick, slow]}
      - {id: quick, kind: decision, branches: [{if: true, then: early}, {else: j}]}
      - {id: early, kind: end}
      - {id: slow, kind: action, call: msleep(5000), next: j}
      - {id: j, kind: join}
      - {id: end, kind: end}
""")
    engine, records = make_engine(model, FakePort())
    began = time.monotonic()
    asyncio.run(run_lanes(engine, limit_s=2.0))
    assert time.monotonic() - began < 1.0
    assert "j" not in [r[1] for r in records]


def test_node_failure_names_lane_node_and_cause(tmp_path: Path) -> None:
    model = compile_text(tmp_path, """
lanes:
  - lane: RaspberryPI
    nodes:
      - {id: start, kind: start}
      - {id: go, kind: action, call: LeftActuator.enabled(true)}
      - {id: end, kind: end}
""")
    port = FakePort(errors={("LeftActuator", "enabled"): RemoteError("driver_error", "pins", "LeftActuator",
                                                                      "enabled")})
    engine, records = make_engine(model, port)
    with pytest.raises(NodeFailed) as caught:
        asyncio.run(run_lanes(engine))
    assert caught.value.lane == "RaspberryPI" and caught.value.node == "go"
    assert "driver_error" in str(caught.value)
    assert records[-1][1] == "go" and "driver_error" in str(records[-1][7])


def test_send_and_accept_between_lanes_with_payload(tmp_path: Path) -> None:
    model = compile_text(tmp_path, """
lanes:
  - lane: RaspberryPI
    nodes:
      - {id: start, kind: start}
      - {id: wait, kind: accept, signal: go, store: got}
      - {id: end, kind: end}
  - lane: DistanceRead
    nodes:
      - {id: start, kind: start}
      - {id: nap, kind: action, call: msleep(20)}
      - {id: send, kind: send, signal: go, payload: 6 * 7}
      - {id: end, kind: end}
""")
    port = FakePort()
    engine, _ = make_engine(model, port)
    asyncio.run(run_lanes(engine))
    assert port.signals == [("go", 42)]
    assert engine.stores["RaspberryPI"]["got"] == 42


def test_busy_lanes_share_the_loop(tmp_path: Path) -> None:
    # two lanes that never wait still interleave (the walker yields), and Application.exit stops them
    model = compile_text(tmp_path, """
lanes:
  - lane: RaspberryPI
    nodes:
      - {id: start, kind: start}
      - {id: inc, kind: datastore, name: n, value: 1}
      - {id: d, kind: decision, branches: [{if: Application.exit, then: end}, {else: inc}]}
      - {id: end, kind: end}
  - lane: DistanceRead
    nodes:
      - {id: start, kind: start}
      - {id: inc, kind: datastore, name: n, value: 1}
      - {id: d, kind: decision, branches: [{if: Application.exit, then: end}, {else: inc}]}
      - {id: end, kind: end}
""")
    engine, records = make_engine(model, FakePort())

    async def main() -> None:
        task = asyncio.ensure_future(run_lanes(engine))
        await asyncio.sleep(0.05)
        engine.exit_requested = True
        await asyncio.wait_for(task, 2.0)

    asyncio.run(main())
    lanes = {r[0] for r in records[:5000]}
    assert lanes == {"RaspberryPI", "DistanceRead"}


def test_a_models_signal_board_holds_only_accepted_names_and_logs_foreign_ones_rarely(
    caplog: pytest.LogCaptureFixture, capsys: pytest.CaptureFixture[str]
) -> None:
    caplog.set_level(logging.DEBUG)
    now = [0.0]
    model = compile_model(Path(__file__).parent / "models" / "held_signals.yaml")
    board = SignalBoard.for_model(model, clock=lambda: now[0])
    assert board.accepted == frozenset({"go", "note"})
    assert board.deliver("done", 1) == 0  # the model's own send, accepted by none of its nodes
    for second in range(150):  # a foreign name every 10 ms for 150 s
        now[0] = float(second)
        for i in range(100):
            assert board.deliver(f"x{second}-{i}", i) == 0
    board.deliver("note", "n")
    assert board.held("note") and not board.held("done") and not board.held("x0-0")
    assert board.ignored == 1 + 150 * 100
    printed = capsys.readouterr()
    logged = printed.out + printed.err + "\n".join(str(r.msg) for r in caplog.records)
    # one line at the first, then at most one a minute (0 s, 60 s, 120 s), each with its count
    assert logged.count("ignoring signals that no accept node of the model waits for") == 3, logged
    assert "x0-0" in logged and "x60-0" in logged and "x120-0" in logged and "done" not in logged
    assert "ignored=6000" in logged or "'ignored': 6000" in logged or '"ignored": 6000' in logged, logged


def test_signal_board_holds_the_newest_unconsumed_occurrence() -> None:
    async def main() -> list[Any]:
        board = SignalBoard()
        board.deliver("go", 1)
        board.deliver("go", 2)  # replaces 1
        first = await board.wait("go")
        waiter_a = asyncio.ensure_future(board.wait("go"))
        waiter_b = asyncio.ensure_future(board.wait("go"))
        await asyncio.sleep(0)
        woke = board.deliver("go", 3)  # every waiting accept gets it
        return [first, woke, await waiter_a, await waiter_b, board.held("go")]

    assert asyncio.run(main()) == [2, 2, 3, 3, False]
