"""Every checker message a modeller can meet has a plain form in the page (issue 28 §4); the CLI
keeps its own messages."""

from __future__ import annotations

import ast
import shutil
import subprocess
from pathlib import Path

from robot_run import CAR_MODEL, umlbot_argv

from umlbot.studio.plain import plain_message
from umlbot.studio.workspace import Workspace

REPO = Path(__file__).resolve().parent.parent
#: where the checker's messages are made (the model's files, its YAML, its expressions, its checks)
SOURCES = ["umlbot/compiler/checker.py", "umlbot/compiler/source.py", "umlbot/compiler/expr.py",
           "umlbot/compiler/expr_parser.py", "umlbot/base/yamlsrc.py"]
MAKERS = {"error", "warning", "ModelError", "fail"}


def _template(node: ast.expr) -> str | None:
    """The message a call makes, each part that varies written as "x1"."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(str(v.value) if isinstance(v, ast.Constant) else "x1" for v in node.values)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):
        a, b = _template(node.left), _template(node.right)
        return None if a is None or b is None else a + b
    return None


def checker_messages() -> list[tuple[str, int, str]]:
    found = []
    for rel in SOURCES:
        tree = ast.parse((REPO / rel).read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if not isinstance(node, ast.Call) or not node.args:
                continue
            fn = node.func
            name = fn.attr if isinstance(fn, ast.Attribute) else fn.id if isinstance(fn, ast.Name) else ""
            if name in MAKERS:
                text = _template(node.args[0])
                if text:
                    found.append((rel, node.lineno, text))
    return found


def test_every_message_the_checker_can_make_has_a_plain_form() -> None:
    messages = checker_messages()
    assert len(messages) > 100, len(messages)  # the walk finds the checker's messages
    unknown = [f"{rel}:{line}: {text}" for rel, line, text in messages if plain_message(text) is None]
    assert unknown == [], "\n".join(unknown)


def test_the_plain_forms_speak_of_steps_and_choices_not_of_yaml_keys() -> None:
    said = plain_message("an action 'go' has no outgoing flow: give it 'next' or put a node after it")
    assert said is not None and said.startswith("Connect this step to the next one")
    said = plain_message("a decision 'which' needs 'branches': a list of {if: <guard>, then: <node>} "
                         "and {else: <node>}")
    assert said == "This choice needs at least two ways out: connect it to the next steps."
    assert plain_message("swimlane 'Stop' has no end node") == "Swimlane Stop needs an end: add an end node."
    assert plain_message("something no rule knows") is None
    for _, _, text in checker_messages():  # none of them asks for a YAML key by its name
        plain = plain_message(text) or ""
        assert "'next'" not in plain and "'branches'" not in plain and "{if:" not in plain, (text, plain)


def test_the_page_gets_the_plain_form_and_the_cli_keeps_its_message(tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    motion = folder / "activities" / "motion.yaml"
    motion.write_text(motion.read_text(encoding="utf-8").replace("      - {id: end, kind: end}\n", "", 1),
                      encoding="utf-8")
    (problem,) = [d for d in Workspace(folder).answer()["diagnostics"] if "end node" in d["message"]]
    assert problem["plain"] == "Swimlane MoveForward needs an end: add an end node."
    assert problem["relpath"] == "activities/motion.yaml" and problem["line"] > 0
    check = subprocess.run(umlbot_argv("check", str(folder)), capture_output=True, text=True, timeout=60,
                           check=False)
    assert "swimlane 'MoveForward' has no end node" in check.stdout + check.stderr
    assert "needs an end" not in check.stdout + check.stderr
