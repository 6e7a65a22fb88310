"""The expression interpreter: turns a compiled expression tree into small Python closures, once.

Each tree (`umlbot.compiler.expr`) is translated when the orchestrator loads the model into nested
closures that read datastores straight from their lane's dict. A tree without calls that wait
(feature calls, virtual lanes, `usleep`/`msleep`) becomes a plain function, so guards and datastore
values run without an `await`; a tree with such calls becomes a coroutine function. Nothing is ever
passed to eval/exec: every operator maps to one fixed Python operation from `BINARY_OPERATIONS`.
"""

from __future__ import annotations

from collections.abc import Callable, Coroutine
from dataclasses import dataclass
from typing import Any, Protocol

from umlbot.compiler.expr import (
    BINARY_OPERATIONS,
    Binary,
    BuiltinTarget,
    Call,
    Const,
    Expr,
    FeatureTarget,
    LaneTarget,
    Ref,
    Unary,
)

#: A model value: bool, int, float, str, None, or whatever JSON a service or a signal delivered.
Value = Any
SyncFn = Callable[[], Value]
AsyncFn = Callable[[], Coroutine[Any, Any, Value]]


class Runtime(Protocol):
    """What an expression can reach at run time: the features, the virtual lanes, the builtins."""

    @property
    def exit_requested(self) -> bool:
        """The value of `Application.exit`."""

    async def call_feature(self, component: str, feature: str, args: list[Value]) -> Value:
        """One request/reply to a component's service; raises on time-out or error reply."""

    async def call_lane(self, lane: str) -> None:
        """Run virtual swimlane `lane` from its start to an end."""

    async def sleep(self, seconds: float) -> None:
        """Sleep for `seconds` of (sim) time."""


@dataclass(frozen=True, slots=True)
class Evaluator:
    """A compiled expression: `sync` is set when it never waits; `run` always works (awaitable)."""

    sync: SyncFn | None
    run: AsyncFn


def _as_async(fn: SyncFn) -> AsyncFn:
    async def run() -> Value:
        return fn()

    return run


class ExpressionCompiler:
    """Compiles expression trees against one orchestrator's datastores and runtime."""

    def __init__(self, stores: dict[str, dict[str, Value]], runtime: Runtime) -> None:
        self._stores = stores
        self._runtime = runtime

    def compile(self, expr: Expr) -> Evaluator:
        """The evaluator of `expr`."""
        sync = self._sync(expr)
        if sync is not None:
            return Evaluator(sync, _as_async(sync))
        return Evaluator(None, self._async(expr))

    # --- expressions that never wait ----------------------------------------------------------

    def _sync(self, expr: Expr) -> SyncFn | None:
        """A plain function for `expr`, or None when evaluating it has to wait."""
        if isinstance(expr, Const):
            value = expr.value
            return lambda: value
        if isinstance(expr, Ref):
            store = self._store(expr.lane)
            name = expr.name
            get = store.get
            return lambda: get(name)
        if isinstance(expr, Unary):
            operand = self._sync(expr.operand)
            if operand is None:
                return None
            if expr.operator == "not":
                return lambda: not operand()
            return lambda: -operand()
        if isinstance(expr, Binary):
            left = self._sync(expr.left)
            right = self._sync(expr.right)
            if left is None or right is None:
                return None
            if expr.operator == "and":
                return lambda: bool(left()) and bool(right())
            if expr.operator == "or":
                return lambda: bool(left()) or bool(right())
            op = BINARY_OPERATIONS[expr.operator]
            return lambda: op(left(), right())
        if isinstance(expr, Call):
            target = expr.target
            if isinstance(target, BuiltinTarget) and target.name == "Application.exit":
                runtime = self._runtime
                return lambda: runtime.exit_requested
            return None
        raise TypeError(f"unknown expression node {expr!r}")  # pragma: no cover - exhaustive union

    # --- expressions that wait ---------------------------------------------------------------

    def _async(self, expr: Expr) -> AsyncFn:
        """A coroutine function for `expr` (used only where some part of it waits)."""
        sync = self._sync(expr)
        if sync is not None:
            return _as_async(sync)
        if isinstance(expr, Unary):
            operand = self._async(expr.operand)
            if expr.operator == "not":

                async def negate() -> Value:
                    return not await operand()

                return negate

            async def minus() -> Value:
                return -(await operand())

            return minus
        if isinstance(expr, Binary):
            return self._async_binary(expr)
        if isinstance(expr, Call):
            return self._async_call(expr)
        raise TypeError(f"expression node {expr!r} cannot wait")  # pragma: no cover

    def _async_binary(self, expr: Binary) -> AsyncFn:
        left = self._async(expr.left)
        right = self._async(expr.right)
        if expr.operator == "and":

            async def both() -> Value:
                return bool(await left()) and bool(await right())

            return both
        if expr.operator == "or":

            async def either() -> Value:
                return bool(await left()) or bool(await right())

            return either
        op = BINARY_OPERATIONS[expr.operator]

        async def apply() -> Value:
            first = await left()
            return op(first, await right())

        return apply

    def _async_call(self, expr: Call) -> AsyncFn:
        runtime = self._runtime
        args = [self.compile(arg) for arg in expr.args]
        target = expr.target

        async def evaluate_args() -> list[Value]:
            return [arg.sync() if arg.sync is not None else await arg.run() for arg in args]

        if isinstance(target, FeatureTarget):
            component, feature = target.component, target.feature

            async def call_feature() -> Value:
                return await runtime.call_feature(component, feature, await evaluate_args())

            return call_feature
        if isinstance(target, LaneTarget):
            lane = target.lane

            async def call_lane() -> Value:
                await runtime.call_lane(lane)
                return None

            return call_lane
        if target.name == "usleep":
            scale = 1e-6
        elif target.name == "msleep":
            scale = 1e-3
        else:
            raise ValueError(f"unknown builtin {target.name!r}")

        async def sleep() -> Value:
            values = await evaluate_args()
            await runtime.sleep(float(values[0]) * scale if values else 0.0)
            return None

        return sleep

    def _store(self, lane: str) -> dict[str, Value]:
        store = self._stores.get(lane)
        if store is None:
            store = self._stores[lane] = {}
        return store
