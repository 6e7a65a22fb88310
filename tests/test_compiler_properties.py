"""Property tests: arbitrary input to the expression parser and the model loader gives a result or a
`ModelError`, nothing else, and quickly."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
import yaml
from compiler_support import HEADER
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from umlbot import ModelError
from umlbot.base.diagnostics import Location
from umlbot.compiler.api import check_model, compile_model
from umlbot.compiler.expr_parser import RawExpr, RBinary, RCall, RConst, RName, RUnary, parse_expression

EXPRESSION_CHARS = "ab_xyzAB.()+-*/%<>=!, '\"\\0123456789\t\nandortefls"
YAML_CHARS = "abcdeiklnorstxyz_ABPMS0123456789{}[]:,-&*!|>'\"# \n.()"
FAST = settings(max_examples=300, deadline=2000, suppress_health_check=[HealthCheck.too_slow,
                                                                         HealthCheck.function_scoped_fixture])


@FAST
@given(st.text(max_size=300))
def test_parser_accepts_or_raises_model_error_on_any_text(text: str) -> None:
    try:
        parse_expression(text)
    except ModelError as exc:
        assert exc.line >= 1 and exc.column >= 1


@FAST
@given(st.text(alphabet=EXPRESSION_CHARS, max_size=300))
def test_parser_on_expression_like_text(text: str) -> None:
    try:
        parse_expression(text, Location("f.yaml", 7, 9))
    except ModelError as exc:
        assert exc.file == "f.yaml" and exc.line >= 7


@pytest.mark.parametrize("text", [
    "(" * 10_000 + "1" + ")" * 10_000,
    "-" * 10_000 + "1",
    "not " * 10_000 + "true",
    "1" + " + 1" * 5_000,
    "f(" * 5_000 + ")" * 5_000,
    "a" * 20_000,
])
def test_hostile_expressions_are_refused_quickly(text: str) -> None:
    started = time.monotonic()
    with pytest.raises(ModelError, match=r"nested too deeply|too long"):
        parse_expression(text)
    assert time.monotonic() - started < 1.0


def _names() -> st.SearchStrategy[str]:
    return st.sampled_from(["a", "b", "count", "Pi.x", "Sonar.value", "Motor.enabled"])


def _raw_trees() -> st.SearchStrategy[str]:
    leaves = st.one_of(
        st.integers(0, 10**6).map(str),
        st.floats(0, 1e6, allow_nan=False).map(lambda f: repr(float(f))),
        st.sampled_from(["true", "false", "null", "'text'", '"q\\"uote"']),
        _names(),
    )

    def extend(children: st.SearchStrategy[str]) -> st.SearchStrategy[str]:
        binary = st.tuples(children, st.sampled_from(
            ["+", "-", "*", "/", "%", "==", "!=", "<", "<=", ">", ">=", "and", "or"]), children)
        return st.one_of(
            binary.map(lambda t: f"({t[0]} {t[1]} {t[2]})"),
            children.map(lambda c: f"(not {c})"),
            children.map(lambda c: f"(-{c})"),
            st.tuples(_names(), st.lists(children, max_size=3)).map(lambda t: f"{t[0]}({', '.join(t[1])})"),
        )

    return st.recursive(leaves, extend, max_leaves=20)


def _show(expr: RawExpr) -> str:
    if isinstance(expr, RConst):
        if expr.value is None:
            return "null"
        if isinstance(expr.value, bool):
            return "true" if expr.value else "false"
        if isinstance(expr.value, str):
            return '"' + expr.value.replace("\\", "\\\\").replace('"', '\\"') + '"'
        return repr(expr.value)
    if isinstance(expr, RName):
        return expr.dotted
    if isinstance(expr, RCall):
        return f"{expr.name.dotted}({', '.join(_show(a) for a in expr.args)})"
    if isinstance(expr, RUnary):
        return f"(not {_show(expr.operand)})" if expr.operator == "not" else f"(-{_show(expr.operand)})"
    assert isinstance(expr, RBinary)
    return f"({_show(expr.left)} {expr.operator} {_show(expr.right)})"


@FAST
@given(_raw_trees())
def test_printed_trees_parse_back_to_the_same_tree(text: str) -> None:
    tree = parse_expression(text)
    again = parse_expression(_show(tree))
    assert _show(again) == _show(tree)


@FAST
@given(text=st.text(alphabet=YAML_CHARS, max_size=400))
def test_loader_on_arbitrary_text_gives_only_model_errors(tmp_path: Path, text: str) -> None:
    path = tmp_path / "model.yaml"
    path.write_text(text, encoding="utf-8")
    result = check_model(path)
    assert all(d.location.line >= 1 and d.location.column >= 1 for d in result.diagnostics)
    try:
        compile_model(path)
    except ModelError:
        assert not result.ok


_KEYS = st.sampled_from(["id", "kind", "next", "call", "name", "value", "branches", "if", "then", "else",
                         "targets", "signal", "store", "payload", "lane", "nodes", "x"])
_SCALARS = st.one_of(
    st.sampled_from(["start", "end", "action", "datastore", "decision", "fork", "join", "send", "accept",
                     "a", "b", "end", "Motor.enabled(true)", "msleep(1)", "x + 1", "Pi", "Helper", "true"]),
    st.integers(-5, 5), st.none(), st.booleans())
_TREES = st.recursive(_SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=5), st.dictionaries(_KEYS, inner, max_size=6)), max_leaves=40)


@FAST
@given(lanes=st.lists(_TREES, max_size=4))
def test_checker_on_arbitrary_lane_structures(tmp_path: Path, lanes: list[object]) -> None:
    dumped = yaml.safe_dump(lanes)
    path = tmp_path / "model.yaml"
    path.write_text(HEADER + "\n".join("  " + line for line in dumped.splitlines()) + "\n",
                    encoding="utf-8")
    result = check_model(path)
    try:
        compile_model(path)
    except ModelError:
        assert not result.ok


def test_alias_bomb_is_refused(tmp_path: Path) -> None:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [*a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, *a{i - 1}, "
              f"*a{i - 1}, *a{i - 1}, *a{i - 1}]" for i in range(1, 9)]
    path = tmp_path / "model.yaml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    started = time.monotonic()
    result = check_model(path)
    assert [e.message for e in result.errors] == [
        "document too large: its aliases expand it to more than 500000 YAML nodes (lists, mappings "
        "and scalars)"]
    assert time.monotonic() - started < 10


def test_deep_yaml_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "model.yaml"
    path.write_text("a: " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    result = check_model(path)
    assert len(result.errors) == 1 and not result.ok


@FAST
@given(value=_raw_trees(), guard=_raw_trees(), call=_raw_trees())
def test_checker_on_arbitrary_expressions(tmp_path: Path, value: str, guard: str, call: str) -> None:
    def quoted(text: str) -> str:
        return "'" + text.replace("'", "''") + "'"

    text = HEADER + f"""\
  - lane: Pi
    nodes:
      - {{id: start, kind: start}}
      - {{id: x, kind: datastore, name: x, value: {quoted(value)}}}
      - {{id: a, kind: action, call: {quoted(call)}}}
      - {{id: d, kind: decision, branches: [{{if: {quoted(guard)}, then: end}}, {{else: end}}]}}
      - {{id: end, kind: end}}
"""
    path = tmp_path / "model.yaml"
    path.write_text(text, encoding="utf-8")
    result = check_model(path)
    for diagnostic in result.diagnostics:
        assert diagnostic.location.line in (20, 21, 22), str(diagnostic)
