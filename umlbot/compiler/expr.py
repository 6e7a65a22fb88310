"""The expression tree of the model language, as the compiler writes it and the orchestrator reads it.

Expressions appear in guards, datastore values, action calls, send payloads and arguments. The
compiler parses the source text into these nodes (see `umlbot.compiler.expr_parser`), resolves every name
and type-checks the tree; the orchestrator only interprets it. Nothing here is ever eval'd.

Semantics the interpreter follows (also in docs/model-format.md):
- `const` is a literal: int, float, bool, str or None.
- `ref` reads datastore `name` of swimlane `lane` (always resolved; a bare `name` in the source
  means the current lane's datastore). A datastore not yet written reads as None.
- `call` calls a component feature (`FeatureTarget`), a virtual swimlane (`LaneTarget`, no
  arguments, value None) or a builtin (`BuiltinTarget`: `usleep(us)`, `msleep(ms)`,
  `Application.exit` → bool).
- `unary`: `not` (bool) and `-` (number).
- `binary`: `+ - * / %` on numbers (`/` is true division and gives a float, `%` is Python's
  modulo, `+` also joins two strings), comparisons `== != < <= > >=` give a bool, `and`/`or`
  take bools, give a bool and short-circuit (the right operand is not evaluated when the left one
  decides).
"""

from __future__ import annotations

import operator
from collections.abc import Callable
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field

#: The value of a literal; `bool` first so that `true` never turns into 1.
ConstValue = bool | int | float | str | None

UnaryOperator = Literal["not", "-"]
BinaryOperator = Literal["+", "-", "*", "/", "%", "==", "!=", "<", "<=", ">", ">=", "and", "or"]

#: The builtins, by the name a model writes them with.
BUILTINS: tuple[str, ...] = ("usleep", "msleep", "Application.exit")


class _Node(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Const(_Node):
    """A literal value."""

    op: Literal["const"] = "const"
    value: ConstValue


class Ref(_Node):
    """A read of datastore `name` in swimlane `lane`."""

    op: Literal["ref"] = "ref"
    lane: str
    name: str


class FeatureTarget(_Node):
    """A call of `feature` on the component `component` (one MQTT request/reply)."""

    kind: Literal["feature"] = "feature"
    component: str
    feature: str


class LaneTarget(_Node):
    """A call of a virtual swimlane: run it from its start to an end, then return None."""

    kind: Literal["lane"] = "lane"
    lane: str


class BuiltinTarget(_Node):
    """A call of a builtin: one of `BUILTINS`."""

    kind: Literal["builtin"] = "builtin"
    name: str


CallTarget = Annotated[FeatureTarget | LaneTarget | BuiltinTarget, Field(discriminator="kind")]


class Call(_Node):
    """A call; its arguments are evaluated left to right before the call."""

    op: Literal["call"] = "call"
    target: CallTarget
    args: list[Expr] = Field(default_factory=list)


class Unary(_Node):
    """`not operand` or `-operand`."""

    op: Literal["unary"] = "unary"
    operator: UnaryOperator
    operand: Expr


class Binary(_Node):
    """`left operator right`."""

    op: Literal["binary"] = "binary"
    operator: BinaryOperator
    left: Expr
    right: Expr


Expr = Annotated[Const | Ref | Call | Unary | Binary, Field(discriminator="op")]

for _model in (Call, Unary, Binary):
    _model.model_rebuild()

__all__ = [
    "BUILTINS",
    "Binary",
    "BinaryOperator",
    "BuiltinTarget",
    "Call",
    "CallTarget",
    "Const",
    "ConstValue",
    "Expr",
    "FeatureTarget",
    "LaneTarget",
    "Ref",
    "Unary",
    "UnaryOperator",
]


# --- what the operators compute (the orchestrator and the checker's constant folding) ---------


def _true_division(left: Any, right: Any) -> Any:
    return left / right


#: The arithmetic and comparison operators; `and`/`or` short-circuit and are built separately.
BINARY_OPERATIONS: dict[str, Callable[[Any, Any], Any]] = {
    "+": operator.add,
    "-": operator.sub,
    "*": operator.mul,
    "/": _true_division,
    "%": operator.mod,
    "==": operator.eq,
    "!=": operator.ne,
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
}
