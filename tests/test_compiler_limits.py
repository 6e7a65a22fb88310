"""Bad input at the edges: positions of bad bytes, one error for an unreadable model.yaml, and the
limits (file size, YAML nodes and nesting, expression length, nesting and operator chains) named
in their errors and documented in docs/model-format.md."""

from __future__ import annotations

import asyncio
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner
from compiler_support import HEADER, MAIN, at, check_text, errors_of, position, with_left_out

from umlbot import ModelError
from umlbot.base import files, yamlsrc
from umlbot.cli import cli
from umlbot.compiler import expr_parser
from umlbot.compiler.api import check_model
from umlbot.compiler.compiled import DatastoreNode, DecisionNode, dump_compiled, load_compiled
from umlbot.compiler.expr import Expr
from umlbot.compiler.expr_parser import parse_expression
from umlbot.compiler.source import Unreadable, read_model_folder
from umlbot.services.orchestrator.expressions import ExpressionCompiler

ROOT = Path(__file__).resolve().parent.parent
ROBOT_CAR = ROOT / "models" / "robot_car"


# --- positions -------------------------------------------------------------------------------------


def test_a_bad_byte_is_reported_at_its_line_and_column(tmp_path: Path) -> None:
    path = tmp_path / "model.yaml"
    # line 4: two spaces, "é" (two bytes, one character), then a Latin-1 byte
    path.write_bytes(b"name: t\ncomponents:\n  Pi: {kind: system}\n  \xc3\xa9\xff: x\n")
    result = check_model(path)
    assert [str(d) for d in result.diagnostics] == [
        f"{path}:4:4: error: not UTF-8 text: byte 0xff: invalid start byte"]


def test_a_bad_byte_in_an_activity_file(tmp_path: Path) -> None:
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    activity = model / "activities" / "motion.yaml"
    text = activity.read_bytes()
    line, column = position(text.decode("utf-8"), "TurnLeft")
    activity.write_bytes(text.replace(b"TurnLeft", b"Turn\xe9Left", 1))
    errors = [e for e in errors_of(check_model(model)) if e.location.file == str(activity)]
    assert [at(e) for e in errors] == [(line, column + 4)]
    # main.yaml calls its swimlanes: those checks wait for it
    assert with_left_out("not UTF-8 text: byte 0xe9: invalid continuation byte").fullmatch(errors[0].message)


# --- an unreadable model.yaml is one error -----------------------------------------------------------


def _alias_bomb() -> str:
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 9)]
    return "\n".join(lines) + "\n"


UNREADABLE: dict[str, tuple[bytes, str]] = {
    "too large": (b"# " + b"x" * files.MAX_FILE_BYTES + b"\n",
                  f"file too large ({files.MAX_FILE_BYTES + 3} bytes, at most {files.MAX_FILE_BYTES})"),
    "alias bomb": (_alias_bomb().encode(),
                   f"document too large: its aliases expand it to more than {yamlsrc.MAX_NODES} YAML "
                   "nodes (lists, mappings and scalars)"),
    "nested too deeply": (b"a: " + b"[" * 500 + b"]" * 500 + b"\n",
                          "document nested too deeply (more than 100 levels of lists and mappings)"),
    "not UTF-8": (b"name: car\n\xff\n", "not UTF-8 text: byte 0xff: invalid start byte"),
    "invalid YAML": (b"components: [\n", "invalid YAML: "),
}


@pytest.mark.parametrize("case", sorted(UNREADABLE))
def test_an_unreadable_model_file_is_the_only_problem(tmp_path: Path, case: str) -> None:
    content, message = UNREADABLE[case]
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)  # its activities name the components model.yaml declares
    (model / "model.yaml").write_bytes(content)
    result = check_model(model)
    assert len(result.diagnostics) == 1, [str(d) for d in result.diagnostics]
    only = result.diagnostics[0]
    assert only.severity == "error" and only.location.file == str(model / "model.yaml")
    assert only.message.startswith(message)
    assert result.model is None


def test_an_activity_file_error_is_still_reported_beside_it(tmp_path: Path) -> None:
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    (model / "model.yaml").write_bytes(b"\xff")
    (model / "activities" / "broken.yaml").write_text("lane: [\n", encoding="utf-8")
    files = sorted(Path(d.location.file).name for d in check_model(model).diagnostics)
    assert files == ["broken.yaml", "model.yaml"]


# --- an unreadable activity file or deployment is one error too ---------------------------------------


@pytest.mark.parametrize("name", ["measure.yaml", "main.yaml"])
@pytest.mark.parametrize("case", sorted(UNREADABLE))
def test_an_unreadable_activity_file_is_the_only_problem(tmp_path: Path, case: str, name: str) -> None:
    content, message = UNREADABLE[case]
    model = tmp_path / "car"
    # main.yaml calls the swimlanes Measure and Glance of measure.yaml: without measure.yaml they
    # are unknown, without main.yaml they are never called and its datastores unknown
    shutil.copytree(ROBOT_CAR, model)
    activity = model / "activities" / name
    activity.write_bytes(content)
    result = CliRunner().invoke(cli, ["check", str(model)])
    assert result.exit_code == 1
    lines = result.stdout.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{activity}:"), lines
    assert f": error: {message}" in lines[0]
    assert result.stderr == f"{model}: 1 error(s), 0 warning(s)\n"


def test_an_activity_path_that_cannot_be_read_is_the_only_problem(tmp_path: Path) -> None:
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    activity = model / "activities" / "measure.yaml"
    activity.unlink()
    activity.mkdir()  # read even by root: not a file
    result = CliRunner().invoke(cli, ["check", str(model)])
    lines = result.stdout.splitlines()
    expected = with_left_out(f"{activity}:1:1: error: cannot read: Is a directory")
    assert len(lines) == 1 and expected.fullmatch(lines[0])


@pytest.mark.parametrize("name", ["model.yaml", "deployment.yaml"])
def test_a_folder_under_a_model_file_name_is_unreadable_not_missing(tmp_path: Path, name: str) -> None:
    # before: a folder named model.yaml gave "not a model: no model.yaml in this folder" at the
    # model's folder, and one named deployment.yaml was passed over for deployment.txt
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    (model / name).unlink()
    (model / name).mkdir()
    expected = with_left_out(f"{model / name}:1:1: error: cannot read: Is a directory")
    result = CliRunner().invoke(cli, ["check", str(model)])
    lines = result.stdout.splitlines()
    assert result.exit_code == 1 and len(lines) == 1 and expected.fullmatch(lines[0])
    # the studio's way: the folder's files read first, then checked from memory
    read = read_model_folder(model)
    assert read[name] == Unreadable("cannot read: Is a directory")
    assert [str(d) for d in check_model(model, files=read).diagnostics] == lines


def test_a_fifo_in_place_of_an_activity_file_is_refused_without_waiting(tmp_path: Path) -> None:
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    activity = model / "activities" / "measure.yaml"
    activity.unlink()
    os.mkfifo(activity)  # opening it to read would wait for a writer for ever
    argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "check", str(model)]
    result = subprocess.run(argv, capture_output=True, text=True, timeout=60, check=False)
    lines = result.stdout.splitlines()
    expected = with_left_out(f"{activity}:1:1: error: not a regular file (a FIFO)")
    assert len(lines) == 1 and expected.fullmatch(lines[0])
    assert result.returncode == 1


def test_without_the_unreadable_file_its_swimlanes_are_missing(tmp_path: Path) -> None:
    # the errors the test above keeps out are real when the file is simply not there
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    (model / "activities" / "measure.yaml").unlink()
    assert "unknown swimlane or builtin 'Measure'" in CliRunner().invoke(cli, ["check", str(model)]).stdout


@pytest.mark.parametrize("content, message", [
    (b"driver: pigpio\n\xff\n", "2:1: error: not UTF-8 text: byte 0xff: invalid start byte"),
    (b"driver: [\n", "2:1: error: invalid YAML: "),
    (b"", "1:1: error: empty deployment"),
    (b"- a list\n", "1:1: error: a deployment is a mapping with 'components'"),
])
def test_an_unreadable_deployment_is_the_only_problem(tmp_path: Path, content: bytes,
                                                      message: str) -> None:
    model = tmp_path / "car"
    shutil.copytree(ROBOT_CAR, model)
    (model / "deployment.yaml").write_bytes(content)
    lines = CliRunner().invoke(cli, ["check", str(model)]).stdout.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{model / 'deployment.yaml'}:{message}"), lines


# --- YAML limits ---------------------------------------------------------------------------------------


def test_a_large_file_without_aliases_names_the_node_limit(tmp_path: Path) -> None:
    text = "values: [" + "1, " * yamlsrc.MAX_NODES + "1]\n"
    result = check_text(tmp_path, text)
    assert [e.message for e in result.errors] == [
        f"document too large: more than {yamlsrc.MAX_NODES} YAML nodes (lists, mappings and scalars); "
        "split it into more files"]


def test_yaml_just_inside_the_nesting_limit_is_read(tmp_path: Path) -> None:
    depth = yamlsrc.MAX_DEPTH - 1  # the top-level mapping is one level
    result = check_text(tmp_path, HEADER + MAIN + "x: " + "[" * depth + "]" * depth + "\n")
    assert [e.message for e in result.errors] == [
        "unknown key 'x' in model (expected: name, call_timeout_s, components, links, lanes, deployment)"]


# --- expressions: chains are not nesting ---------------------------------------------------------------


def _model_with_value(expr: str, guard: str = "true") -> str:
    return HEADER + MAIN + f"""\
  - lane: Motor
    nodes:
      - {{id: start, kind: start}}
      - {{id: s, kind: datastore, name: x, value: "{expr}"}}
      - id: d
        kind: decision
        branches:
          - {{if: "{guard}", then: end}}
          - {{else: end}}
      - {{id: end, kind: end}}
"""


def _evaluate(expr: Expr) -> object:
    evaluator = ExpressionCompiler({"Motor": {"x": 0}}, _NoRuntime()).compile(expr)
    return asyncio.run(evaluator.run())


class _NoRuntime:
    exit_requested = False

    async def call_feature(self, component: str, feature: str, args: list[object]) -> object:
        raise AssertionError("no feature is called")

    async def call_lane(self, lane: str) -> None:
        raise AssertionError("no lane is called")

    async def sleep(self, seconds: float) -> None:
        raise AssertionError("nothing sleeps")


def test_a_flat_sum_of_101_terms_compiles_loads_and_runs(tmp_path: Path) -> None:
    result = check_text(tmp_path, _model_with_value(" + ".join(str(i) for i in range(1, 102))))
    assert result.model is not None, [str(d) for d in result.diagnostics]
    loaded = load_compiled(dump_compiled(result.model))
    node = loaded.lanes["Motor"].nodes["s"]
    assert isinstance(node, DatastoreNode)
    assert _evaluate(node.value) == sum(range(1, 102))


def test_the_longest_chain_in_a_guard_compiles_loads_and_runs(tmp_path: Path) -> None:
    guard = "x" + " + 1" * (expr_parser.MAX_TREE_HEIGHT - 1) + " > 0"  # `>` over a chain of `+`
    result = check_text(tmp_path, _model_with_value("0", guard))
    assert result.model is not None, [str(d) for d in result.diagnostics]
    node = load_compiled(dump_compiled(result.model)).lanes["Motor"].nodes["d"]
    assert isinstance(node, DecisionNode) and node.branches[0].guard is not None
    assert _evaluate(node.branches[0].guard) is True


def test_one_operator_more_than_the_chain_limit_is_refused() -> None:
    text = "1" + " + 1" * (expr_parser.MAX_TREE_HEIGHT + 1)
    with pytest.raises(ModelError) as caught:
        parse_expression(text)
    assert caught.value.message.startswith(
        f"expression tree too high: more than {expr_parser.MAX_TREE_HEIGHT} operators one inside "
        "another (a + b + c has 2, and so has (a + b) * c")
    parse_expression("1" + " + 1" * expr_parser.MAX_TREE_HEIGHT)


def test_nested_chains_none_over_the_limit_are_refused_for_the_tree_height() -> None:
    chain = " + 1" * (expr_parser.MAX_TREE_HEIGHT - 1)  # 199 operators: one such chain is fine
    parse_expression("1" + chain)
    text = "1"
    for _ in range(10):
        text = f"({text}{chain})"
    with pytest.raises(ModelError) as caught:
        parse_expression(text)
    message = caught.value.message
    assert message.startswith(f"expression tree too high: more than {expr_parser.MAX_TREE_HEIGHT} "
                              "operators one inside another")
    assert "in a row" not in message and "split it with a datastore" in message


def test_real_nesting_beyond_the_limit_is_refused_at_the_first_level_too_many() -> None:
    levels = expr_parser.MAX_DEPTH
    parse_expression("(" * levels + "1" + ")" * levels)
    with pytest.raises(ModelError) as caught:
        parse_expression("(" * (levels + 1) + "1" + ")" * (levels + 1))
    assert caught.value.message == f"expression nested too deeply (more than {levels} levels)"
    assert caught.value.column == levels + 2  # just after the parenthesis one level too deep
    with pytest.raises(ModelError, match="nested too deeply"):
        parse_expression("-" * (levels + 1) + "1")


# --- the documented limits are the code's ----------------------------------------------------------


def test_the_limits_table_matches_the_code() -> None:
    text = (ROOT / "docs" / "model-format.md").read_text(encoding="utf-8")
    section = text.split("### Limits", 1)[1].split("\n## ", 1)[0]
    rows = {row.split("|")[1].strip(): row.split("|")[2] for row in section.splitlines()
            if row.startswith("| ") and not row.startswith("| what")}
    numbers = {what: int(re.sub(r"[ ,]", "", re.match(r"\s*([\d ]+)", cell).group(1)))  # type: ignore[union-attr]
               for what, cell in rows.items()}
    assert numbers == {
        "a source file": files.MAX_FILE_BYTES,
        "one YAML document": yamlsrc.MAX_NODES,
        "YAML nesting": yamlsrc.MAX_DEPTH,
        "an expression": expr_parser.MAX_LENGTH,
        "expression nesting": expr_parser.MAX_DEPTH,
        "operators one inside another": expr_parser.MAX_TREE_HEIGHT,
    }
