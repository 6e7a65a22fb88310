"""The docs, tested: the examples in README.md and docs/*.md are checked against the code.

Convention for fenced code blocks: an HTML comment `<!-- doc-test: KIND ARGS -->` on the line
right before a fence (invisible on the rendered page) says what the fence is and how it is
checked. Every ```yaml fence of docs/model-format.md must carry one. Kinds:

- `model [run]`: a complete one-file model; it compiles with no error and no warning. With `run`
  it also runs to its end in the orchestrator against mock services on a real broker.
- `nodes`: a fragment of a lane's node list; it compiles inside `wrapped_model` (the reference
  car's components and deployment, a component lane that sets `clearance_cm` and calls the
  virtual lane `Measure`, which stores `center`, `left` and `right`), with a stub action for
  every node id the fragment names but does not define. Inline spans `{id: …}` in
  docs/model-format.md are single nodes and are checked the same way.
- `activity-file`: an activity file, where `[ ... ]` stands for a node list (the test puts
  start → end there); it compiles as `activities/doc.yaml` of a folder model of the car.
- `deployment`: a deployment file, plain or YAML; it compiles as the deployment of a model whose
  components are those it names, each of its implementation's kind.
- `layout DIR`: a folder tree; each file or glob it lists exists under DIR.
- `check-output DIR FILE "OLD" -> "NEW"`: `umlbot check DIR`, run on a copy of DIR where FILE
  has OLD replaced by NEW, prints exactly the fence: the problems on stdout, the summary (the
  fence's last line) on stderr.
- `track [FILE]`: a track file; `umlbot.sim.track.parse_track` loads it, giving the same track as
  FILE when one is named.
- `CallRequest`, `Reply`, `OrchestratorStatus`, `TraceEvent`: each JSON object of the fence (the
  whole fence, else one per line) validates against that envelope of `umlbot.services.bus.envelopes`
  and uses no key the envelope does not declare (`OrchestratorStatus`: no key the orchestrator
  does not publish). `MonitorEvent`: a line of `umlbot monitor --json`
  (`umlbot.monitor.state.MonitorEvent`).

Tables and prose are checked where the code has the same list: node kinds and keys, component
kinds and features, implementations, model keys, error codes, topics, driver settings, command
options (every `umlbot COMMAND --option` in README.md and docs/*.md exists), and relative links.
"""

from __future__ import annotations

import importlib
import inspect
import itertools
import json
import re
import shlex
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any, get_args

import click
import pytest
import yaml
from click.testing import CliRunner
from conftest import BrokerProcess, RawClient
from orchestrator_support import rig
from pydantic import BaseModel

from umlbot import ModelError
from umlbot.base.catalog import resolve_implementation
from umlbot.base.diagnostics import Diagnostics
from umlbot.base.library import BUILTIN, FeatureSpec, check_args
from umlbot.base.yamlsrc import parse_yaml, to_python
from umlbot.cli import COMMANDS, cli
from umlbot.compiler.api import CheckResult, check_model, compile_model
from umlbot.compiler.compiled import dump_compiled
from umlbot.compiler.expr_parser import RBinary, RName, RUnary, parse_expression
from umlbot.compiler.source import MODEL_KEYS, NODE_FIELDS
from umlbot.services.bus import (
    ERROR_CODES,
    CallRequest,
    ExitRequest,
    Heartbeat,
    OrchestratorStatus,
    Reply,
    Status,
    TraceEvent,
)
from umlbot.services.orchestrator.orchestrator import HEARTBEAT_MAX_S
from umlbot.sim import load_track, parse_track

#: umlbot's own implementations and kinds (the docs' tables list these; plugins document theirs).
IMPLEMENTATIONS = {impl.id: impl for impl in BUILTIN.implementations}
KIND_FEATURES = {kind.name: {spec.name: spec for spec in kind.features} for kind in BUILTIN.kinds}

ROOT = Path(__file__).resolve().parent.parent
DOCS = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")])
MODEL_FORMAT = ROOT / "docs" / "model-format.md"
MQTT = ROOT / "docs" / "mqtt.md"
SEMANTICS = ROOT / "docs" / "semantics.md"
SIMULATOR = ROOT / "docs" / "simulator.md"


# --- reading Markdown ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Fence:
    """A fenced code block: its info string, its `doc-test` marker (if any) and its text."""

    path: Path
    line: int  # of the opening fence, 1-based
    info: str
    marker: str | None
    body: str
    section: str  # the heading above it

    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


@dataclass(frozen=True)
class Span:
    """An inline code span outside fences, with its line and the heading above it."""

    path: Path
    line: int
    text: str
    section: str
    source_line: str

    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


FENCE_RE = re.compile(r"^(\s*)(```+)\s*(\S*)\s*$")
MARKER_RE = re.compile(r"^\s*<!-- doc-test: (.*) -->\s*$")
SPAN_RE = re.compile(r"(?<!`)`([^`\n]+)`(?!`)")
HEADING_RE = re.compile(r"^#+ ")


@cache
def parse_markdown(path: Path) -> tuple[tuple[Fence, ...], tuple[Span, ...]]:
    """The fences and the inline code spans of a Markdown file."""
    lines = path.read_text(encoding="utf-8").splitlines()
    found_fences: list[Fence] = []
    found_spans: list[Span] = []
    section = ""
    i = 0
    while i < len(lines):
        line = lines[i]
        opening = FENCE_RE.match(line)
        if opening:
            indent, ticks, info = opening.groups()
            previous = i - 1
            while previous >= 0 and not lines[previous].strip():
                previous -= 1
            marker = MARKER_RE.match(lines[previous]) if previous >= 0 else None
            body: list[str] = []
            j = i + 1
            while j < len(lines) and lines[j].strip() != ticks:
                body.append(lines[j][len(indent):] if lines[j].startswith(indent) else lines[j])
                j += 1
            found_fences.append(Fence(path, i + 1, info, marker.group(1) if marker else None,
                                      "\n".join(body) + "\n", section))
            i = j + 1
            continue
        if HEADING_RE.match(line):
            section = line.strip()
        for span in SPAN_RE.finditer(line):
            found_spans.append(Span(path, i + 1, span.group(1), section, line))
        i += 1
    return tuple(found_fences), tuple(found_spans)


def fences(path: Path) -> tuple[Fence, ...]:
    return parse_markdown(path)[0]


def spans(path: Path) -> tuple[Span, ...]:
    return parse_markdown(path)[1]


def marked(path: Path, kind: str) -> list[Fence]:
    """The fences of `path` whose marker starts with `kind`."""
    return [f for f in fences(path) if f.marker is not None and f.marker.split()[0] == kind]


def section_text(path: Path, heading: str) -> str:
    """The text under the heading that starts with `heading`, up to the next heading of its level."""
    lines = path.read_text(encoding="utf-8").splitlines()
    in_fence = [False] * len(lines)  # a `# comment` in a fence is no heading
    inside = False
    for i, line in enumerate(lines):
        if FENCE_RE.match(line):
            inside = not inside
        in_fence[i] = inside
    start = next(i for i, line in enumerate(lines) if line.startswith(heading) and not in_fence[i])
    level = len(heading) - len(heading.lstrip("#"))
    end = next((i for i in range(start + 1, len(lines)) if not in_fence[i] and HEADING_RE.match(lines[i])
                and len(lines[i]) - len(lines[i].lstrip("#")) <= level), len(lines))
    return "\n".join(lines[start:end])


def table_rows(text: str) -> list[list[str]]:
    """The cells of every Markdown table row in `text` (header and separator rows left out)."""
    rows: list[list[str]] = []
    for line in text.splitlines():
        if not line.startswith("|") or re.fullmatch(r"[|\-\s:]+", line):
            continue
        cells = [cell.strip() for cell in re.split(r"(?<!\\)\|", line.strip())[1:-1]]
        rows.append(cells)
    return rows[1:] if rows else rows  # drop the header


def code_spans(text: str) -> list[str]:
    return SPAN_RE.findall(text)


# --- compiling examples ------------------------------------------------------------------------

CAR_COMPONENTS = """\
components:
  RaspberryPI: {kind: system}
  LeftActuator: {kind: actuator}
  RightActuator: {kind: actuator}
  Sensor: {kind: actuator}
  DistanceRead: {kind: sensor}
"""

CAR_DEPLOYMENT = """\
driver: mock
components:
  RaspberryPI: {impl: raspberrypi}
  LeftActuator: {impl: l298n}
  RightActuator: {impl: l298n}
  Sensor: {impl: servo}
  DistanceRead: {impl: hcsr04}
"""

MEASURE_LANE = """\
  - lane: Measure
    nodes:
      - {id: start, kind: start}
      - {id: read_center, kind: datastore, name: center, value: DistanceRead.value()}
      - {id: read_left, kind: datastore, name: left, value: DistanceRead.value()}
      - {id: read_right, kind: datastore, name: right, value: DistanceRead.value()}
      - {id: end, kind: end}
"""

CONTEXT_NODES = """\
      - {id: ctx_clearance, kind: datastore, name: clearance_cm, value: 20}
      - {id: ctx_measure, kind: action, call: Measure}
"""


def read_yaml(text: str) -> Any:
    """YAML as the compiler reads it (YAML 1.2 scalars: `on` and `off` are strings, not booleans)."""
    diagnostics = Diagnostics()
    loaded = to_python(parse_yaml(text, "<doc>", diagnostics))
    assert not diagnostics.has_errors, text
    return loaded


def _node_list(fragment: str) -> list[dict[str, Any]]:
    loaded = read_yaml(fragment)
    nodes = loaded if isinstance(loaded, list) else [loaded]
    assert all(isinstance(node, dict) for node in nodes), fragment
    return nodes


def _referenced(node: dict[str, Any]) -> list[str]:
    names: list[str] = []
    if isinstance(node.get("next"), str):
        names.append(node["next"])
    names.extend(str(t) for t in node.get("targets") or [])
    for branch in node.get("branches") or []:
        names.extend(str(branch[key]) for key in ("then", "else") if key in branch)
    return names


def wrapped_model(fragment: str) -> str:
    """A one-file model of the car whose component lane holds `fragment` (YAML node list text)."""
    nodes = _node_list(fragment)
    defined = {str(node.get("id")) for node in nodes} | {"ctx_clearance", "ctx_measure"}
    text = _dedent(fragment)
    if not text.startswith("-"):  # a single node, `{id: …}`
        text = "- " + text
    indented = "".join("      " + line + "\n" if line.strip() else "\n" for line in text.splitlines())
    has_start = any(node.get("kind") == "start" for node in nodes)
    lane = ""
    if has_start:
        lane += indented + CONTEXT_NODES
    else:
        lane += "      - {id: start, kind: start}\n" + CONTEXT_NODES + indented
        defined.add("start")
    if "end" not in defined:
        lane += "      - {id: end, kind: end}\n"
        defined.add("end")
    missing = sorted({name for node in nodes for name in _referenced(node)} - defined)
    forked = {str(t) for node in nodes if node.get("kind") == "fork" for t in node.get("targets") or []}
    for name in missing:  # a fork's flows meet again at a join
        after = "stub_join" if name in forked else "end"
        lane += f"      - {{id: {name}, kind: action, call: msleep(1), next: {after}}}\n"
    if forked & set(missing):
        lane += "      - {id: stub_join, kind: join, next: end}\n"
    return ("name: doc\n" + CAR_COMPONENTS + "deployment:\n" + _indent(CAR_DEPLOYMENT, 2)
            + "lanes:\n" + MEASURE_LANE + "  - lane: RaspberryPI\n    nodes:\n" + lane)


def _dedent(text: str) -> str:
    lines = [line for line in text.splitlines() if line.strip()]
    width = min(len(line) - len(line.lstrip(" ")) for line in lines)
    return "\n".join(line[width:] for line in text.splitlines()) + "\n"


def _indent(text: str, width: int) -> str:
    return "".join(" " * width + line + "\n" for line in text.splitlines())


def _write(tmp_path: Path, text: str, name: str = "doc.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def _check_file(tmp_path: Path, text: str, name: str = "doc.yaml") -> CheckResult:
    return check_model(_write(tmp_path, text, name))


def _problems(result: CheckResult) -> list[str]:
    return [f"{d.location.line}:{d.location.column}: {d.severity}: {d.message}" for d in result.diagnostics]


def _errors(result: CheckResult) -> list[str]:
    return [f"{d.location.line}:{d.location.column}: {d.message}" for d in result.errors]


def test_every_yaml_example_of_the_model_format_is_marked() -> None:
    unmarked = [f.where() for f in fences(MODEL_FORMAT) if f.info == "yaml" and f.marker is None]
    assert unmarked == []
    kinds = {f.marker.split()[0] for f in fences(MODEL_FORMAT) if f.marker}
    assert kinds == {"model", "nodes", "activity-file", "deployment", "layout", "check-output"}


@pytest.mark.parametrize("fence", marked(MODEL_FORMAT, "model"), ids=Fence.where)
def test_complete_model_examples_compile_cleanly(fence: Fence, tmp_path: Path) -> None:
    result = _check_file(tmp_path, fence.body)
    assert _problems(result) == []
    assert result.model is not None


@pytest.mark.parametrize("fence", marked(MODEL_FORMAT, "nodes"), ids=Fence.where)
def test_node_fragments_compile_in_a_wrapper(fence: Fence, tmp_path: Path) -> None:
    result = _check_file(tmp_path, wrapped_model(fence.body))
    assert _errors(result) == [], wrapped_model(fence.body)


NODE_SPANS = [s for s in spans(MODEL_FORMAT) if s.text.startswith("{id:") and "kind:" in s.text]


def test_the_node_table_shows_every_kind_with_its_keys() -> None:
    rows = [row for row in table_rows(section_text(MODEL_FORMAT, "## Swimlanes"))
            if row[0].strip("`") in NODE_FIELDS]
    documented: dict[str, tuple[str, ...]] = {}
    for kind_cell, keys_cell, example_cell in rows:
        kind = kind_cell.strip("`")
        keys = tuple(k.strip("`") for k in re.findall(r"`(\w+)`", keys_cell))
        documented[kind] = keys
        examples = code_spans(example_cell)
        if kind != "decision":  # "see below": the decision fence
            assert len(examples) == 1, example_cell
            node = read_yaml(examples[0])
            assert node["kind"] == kind
            assert set(node) - {"id", "kind"} <= set(keys), examples[0]
    assert documented == NODE_FIELDS


@pytest.mark.parametrize("span", NODE_SPANS, ids=Span.where)
def test_single_node_examples_compile_in_a_wrapper(span: Span, tmp_path: Path) -> None:
    result = _check_file(tmp_path, wrapped_model(span.text))
    assert _errors(result) == [], wrapped_model(span.text)


def _folder_model(root: Path, components: dict[str, str], deployment: str, deployment_name: str,
                  activities: dict[str, str]) -> Path:
    (root / "activities").mkdir(parents=True)
    lines = "".join(f"  {name}: {{kind: {kind}}}\n" for name, kind in components.items())
    (root / "model.yaml").write_text(f"name: doc\ncomponents:\n{lines}", encoding="utf-8")
    (root / deployment_name).write_text(deployment, encoding="utf-8")
    for name, text in activities.items():
        (root / "activities" / name).write_text(text, encoding="utf-8")
    return root


@pytest.mark.parametrize("fence", marked(MODEL_FORMAT, "activity-file"), ids=Fence.where)
def test_activity_file_examples_compile(fence: Fence, tmp_path: Path) -> None:
    text = fence.body.replace("[ ... ]", "[{id: start, kind: start}, {id: end, kind: end}]")
    components = {name: spec["kind"] for name, spec in read_yaml(CAR_COMPONENTS)["components"].items()}
    path = _folder_model(tmp_path / "doc", components, CAR_DEPLOYMENT, "deployment.yaml",
                         {"doc.yaml": text})
    result = check_model(path)
    assert _errors(result) == []
    assert result.model is not None
    lanes = read_yaml(text)
    names = [lanes["lane"]] if "lane" in lanes else [lane["lane"] for lane in lanes["lanes"]]
    assert sorted(names) == sorted(result.model.lanes)


@pytest.mark.parametrize("fence", marked(MODEL_FORMAT, "deployment"), ids=Fence.where)
def test_deployment_examples_compile(fence: Fence, tmp_path: Path) -> None:
    loaded = read_yaml(fence.body)
    if isinstance(loaded, dict):
        entries = {name: entry["impl"] for name, entry in loaded["components"].items()}
        name = "deployment.yaml"
    else:
        entries = dict(line.split("=", 1) for line in fence.body.splitlines() if line.strip())
        name = "deployment.txt"
    components: dict[str, str] = {}
    for component, impl_id in entries.items():
        impl = resolve_implementation(impl_id)
        assert impl is not None, impl_id
        components[component] = impl.kind
    first = next(iter(components))
    main = f"lane: {first}\nnodes: [{{id: start, kind: start}}, {{id: end, kind: end}}]\n"
    path = _folder_model(tmp_path / "doc", components, fence.body, name, {"main.yaml": main})
    result = check_model(path)
    assert _errors(result) == []
    assert result.model is not None
    assert {c: comp.impl for c, comp in result.model.components.items()} == {
        c: resolve_implementation(i).id for c, i in entries.items()  # type: ignore[union-attr]
    }


def test_the_implementation_table_is_the_library() -> None:
    rows = [row for row in table_rows(section_text(MODEL_FORMAT, "## The deployment")) if len(row) == 5]
    documented = {}
    for impl_cell, alias_cell, kind, service, features in rows:
        impl = IMPLEMENTATIONS[impl_cell.strip("`")]
        assert alias_cell.strip("`") in impl.aliases
        assert (kind, service) == (impl.kind, impl.service)
        names = re.findall(r"([A-Za-z]+)(?: \((\d+)\.\.(\d+)\))?", features)
        documented[impl.id] = [name for name, _, _ in names]
        for name, low, high in names:
            if low:
                (param,) = impl.features[name].params
                assert (param.minimum, param.maximum) == (int(low), int(high))
    assert documented == {i.id: list(i.features) for i in IMPLEMENTATIONS.values()}


SIGNATURE_RE = re.compile(r"^(\w+)\((.*)\)(?: -> (\w+))?$")


def _signature(spec: FeatureSpec) -> str:
    """`name(param: type low..high, …) -> returns` as the docs write a feature."""
    params = []
    for param in spec.params:
        text = f"{param.name}: {param.type}"
        if param.minimum is not None and param.maximum is not None:
            text += f" {param.minimum:g}..{param.maximum:g}"
        params.append(text)
    returns = "" if spec.returns == "none" else f" -> {spec.returns}"
    return f"{spec.name}({', '.join(params)}){returns}"


def test_the_kinds_table_is_the_library() -> None:
    rows = table_rows(section_text(MODEL_FORMAT, "## `model.yaml`"))
    rows = [row for row in rows if row[0] in KIND_FEATURES]
    documented = {kind: code_spans(features) for kind, features in rows}
    assert documented == {kind: [_signature(spec) for spec in specs.values()]
                          for kind, specs in KIND_FEATURES.items()}


def test_the_model_keys_table_is_what_the_loader_reads() -> None:
    rows = table_rows(section_text(MODEL_FORMAT, "## `model.yaml`"))
    keys = [row[0].strip("`") for row in rows if row[0].startswith("`")]
    assert keys == list(MODEL_KEYS)


def test_the_compiled_file_holds_what_the_docs_list(tmp_path: Path) -> None:
    (fence,) = marked(MODEL_FORMAT, "model")
    model = compile_model(_write(tmp_path, fence.body))
    data = json.loads(dump_compiled(model))
    text = section_text(MODEL_FORMAT, "## The compiled model file").replace("\n", " ")
    listed = re.search(r"It holds (.*?)\. The robot", text)
    assert listed is not None
    documented = [name for name in code_spans(listed.group(1)) if re.fullmatch(r"[a-z_]+", name)]
    assert sorted(documented) == sorted(data)
    assert data["format_version"] == int(re.search(r"`format_version` \((\d+)\)", text).group(1))  # type: ignore[union-attr]


def test_the_reference_car_is_as_described() -> None:
    text = section_text(MODEL_FORMAT, "## The reference robot car")
    result = check_model(ROOT / "models" / "robot_car")
    assert result.model is not None and result.source is not None
    components = result.model.components
    described = re.search(r"Components: (.*?)\n\n", text, re.S)
    assert described is not None
    assert sorted(code_spans(described.group(1))) == sorted(components)
    assert components["RaspberryPI"].kind == "system"
    flat = re.sub(r"\s+", " ", text)
    pins = re.search(r"inputs (\d+)/(\d+) and (\d+)/(\d+)", flat)
    assert pins is not None
    left, right = components["LeftActuator"].settings, components["RightActuator"].settings
    assert [left["in1"], left["in2"], right["in1"], right["in2"]] == [int(p) for p in pins.groups()]
    assert components["Sensor"].impl == "servo" and f"GPIO {components['Sensor'].settings['gpio']}" in flat
    sonar = components["DistanceRead"]
    assert f"trigger {sonar.settings['trigger']}, echo {sonar.settings['echo']}" in flat
    # each bullet names an activity file and the lanes in it
    files: dict[str, set[str]] = {}
    for lane in result.source.lanes:
        files.setdefault(lane.file, set()).add(lane.name)
    for bullet in re.findall(r"^- `(activities/[\w.]+)`: (.*?)(?=^- |\Z)", text, re.S | re.M):
        file, description = bullet
        lanes = files.pop(file)
        named = {span for span in code_spans(description) if span in lanes}
        assert named == lanes, file
    assert files == {}
    main = next(lane for lane in result.source.lanes if lane.file == "activities/main.yaml")
    datastores = [to_python(n.fields) for n in main.nodes if n.kind == "datastore"]
    clearance = next(d["value"] for d in datastores if d["name"] == "clearance_cm")
    assert f"({clearance} cm)" in flat


@pytest.mark.parametrize("fence", marked(MODEL_FORMAT, "layout"), ids=Fence.where)
def test_layout_examples_exist(fence: Fence) -> None:
    base = ROOT / fence.marker.split()[1]  # type: ignore[union-attr]
    listed = [line.split("#")[0].strip() for line in fence.body.splitlines()[1:]]
    for entry in filter(None, listed):
        assert list(base.glob(entry)), f"{entry} is not in {base}"


@pytest.mark.parametrize("fence", marked(MODEL_FORMAT, "check-output"), ids=Fence.where)
def test_check_output_example_is_what_check_prints(
    fence: Fence, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _, folder, file, old, arrow, new = shlex.split(fence.marker or "")
    assert arrow == "->"
    shutil.copytree(ROOT / folder, tmp_path / folder)
    edited = tmp_path / folder / file
    text = edited.read_text(encoding="utf-8")
    assert text.count(old) == 1
    edited.write_text(text.replace(old, new), encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(cli, ["check", folder])
    expected = fence.body.splitlines()
    assert result.exit_code == 1
    assert result.stdout.splitlines() == expected[:-1]
    assert result.stderr.splitlines()[-1] == expected[-1]


# --- running the complete example --------------------------------------------------------------


RUNNABLE = [f for f in marked(MODEL_FORMAT, "model") if "run" in (f.marker or "").split()]


@pytest.mark.parametrize("fence", RUNNABLE, ids=Fence.where)
def test_complete_example_runs_against_mock_services(
    fence: Fence, broker: BrokerProcess, raw_client: Any, tmp_path: Path
) -> None:
    result = _check_file(tmp_path, fence.body)
    assert result.model is not None
    lanes = read_yaml(fence.body)["lanes"]
    with rig(broker.url, result.model) as running:
        code, _ = running.run(timeout=15.0)
        assert code == 0
        for lane in lanes:
            written = [node["id"] for node in lane["nodes"]]
            assert running.nodes(lane["lane"]) == written  # a sequence: every node once, in order
        for component, comp in result.model.components.items():
            if comp.service == "motor":
                commands = [c for c in running.driver(component).commands if c[0] == "set_enabled"]
                assert ("set_enabled", (True,)) in commands
                assert commands[-1] == ("set_enabled", (False,))  # and stopped at the end
        sleeps = [e for e in running.trace(kind="action") if str(e.get("detail", "")).startswith("msleep(")]
        for event in sleeps:
            asked_ms = float(str(event["detail"])[len("msleep("):-1])
            assert event["duration_ms"] >= asked_ms * 0.95
        # the orchestrator's retained status has the keys docs/semantics.md shows
        client: RawClient = raw_client(broker)
        client.subscribe(f"umlbot/{running.robot}/orchestrator/status")
        published = json.loads(client.get(timeout=5.0).payload)
    (status_fence,) = marked(SEMANTICS, "OrchestratorStatus")
    documented = json.loads(status_fence.body)
    assert published["state"] == "stopped"
    assert set(published) - {"reason"} == set(documented) - {"reason"}


# --- expressions ---------------------------------------------------------------------------------


def _operator_parses(operator: str) -> bool:
    for text in (f"a {operator} b", f"{operator} a"):
        try:
            tree = parse_expression(text)
        except ModelError:
            continue  # not this form of the operator: try the next
        if isinstance(tree, RBinary | RUnary) and tree.operator == operator:
            return True
    return False


def _parses(text: str) -> bool:
    try:
        parse_expression(text)
    except ModelError:
        return False
    return True


EXPRESSION_ROWS = table_rows(section_text(MODEL_FORMAT, "## Expressions"))


@pytest.mark.parametrize("row", EXPRESSION_ROWS, ids=lambda row: row[0])
def test_expressions_in_the_table_parse(row: list[str]) -> None:
    examples = code_spans(row[1])
    assert examples
    for example in examples:
        tokens = example.split()
        if all(_operator_parses(token) for token in tokens):
            continue  # a list of operators, each a working operator
        if all(token.startswith("\\") for token in tokens):  # a list of string escapes
            for escape in tokens:
                assert any(_parses(f"{quote}x{escape}{quote}") for quote in "'\""), escape
            continue
        tree = parse_expression(example)  # raises ModelError when the example does not parse
        if isinstance(tree, RName) and len(tree.parts) == 1:  # a bare name is a datastore read
            assert row[0] == "datastores", f"{example!r} is no {row[0]}"


def test_precedence_is_as_documented() -> None:
    sentence = re.search(r"Precedence, loosest first: (.*?)\. ", section_text(MODEL_FORMAT, "## Expressions"),
                         re.S)
    assert sentence is not None
    parts = sentence.group(1).split(", ")
    assert parts[3] == "comparisons" and parts[-1] == "unary `-`"
    levels = [code_spans(part) for part in parts[:-1]]
    levels[3] = ["=="]
    binary = [level[0].split()[0] for level in levels if level != ["not"]]
    assert binary == ["or", "and", "==", "+", "*"]
    # every binary level binds looser than the next one
    for loose, tight in itertools.pairwise(binary):
        tree = parse_expression(f"a {loose} b {tight} c")
        assert isinstance(tree, RBinary) and tree.operator == loose, (loose, tight)
        tree = parse_expression(f"a {tight} b {loose} c")
        assert isinstance(tree, RBinary) and tree.operator == loose, (loose, tight)
    # `not` sits between `and` and the comparisons; unary minus binds tightest
    tree = parse_expression("not a == b and c")
    assert isinstance(tree, RBinary) and tree.operator == "and"
    assert isinstance(tree.left, RUnary) and isinstance(tree.left.operand, RBinary)
    tree = parse_expression("-a * b")
    assert isinstance(tree, RBinary) and isinstance(tree.left, RUnary)


def test_calls_named_in_the_docs_parse() -> None:
    """`Component.feature(args)`-shaped spans anywhere in the docs are valid expressions."""
    named = [s for path in DOCS for s in spans(path)
             if re.fullmatch(r"[A-Z]\w*\.\w+\(.*\)|(?:usleep|msleep)\(\w*\)", s.text)]
    assert len(named) >= 5
    assert [f"{s.where()}: {s.text}" for s in named if not _parses(s.text)] == []


# --- the simulator's track format ----------------------------------------------------------------


def test_track_example_loads() -> None:
    (fence,) = marked(SIMULATOR, "track")
    track = parse_track(fence.body, "docs/simulator.md")
    raw = yaml.safe_load(fence.body)
    assert track.name == raw["name"]
    assert len(track.walls) == len(raw["walls"])
    bundled = (fence.marker or "").split()[1:]  # the example is that bundled track
    if bundled:
        assert track == load_track(ROOT / bundled[0])


def test_bundled_tracks_table_lists_the_bundled_tracks() -> None:
    rows = table_rows(section_text(SIMULATOR, "## Track files"))
    documented = sorted(row[0].strip("`") for row in rows)
    assert documented == sorted(p.stem for p in (ROOT / "models" / "tracks").glob("*.yaml"))


# --- MQTT payloads -------------------------------------------------------------------------------

ENVELOPES: dict[str, type[BaseModel]] = {
    "CallRequest": CallRequest,
    "Reply": Reply,
    "OrchestratorStatus": OrchestratorStatus,
    "TraceEvent": TraceEvent,
}
#: what the orchestrator publishes beyond OrchestratorStatus's fields (the model allows extras).
ORCHESTRATOR_STATUS_EXTRAS = {"robot", "source_hash", "since"}


def _json_objects(body: str) -> list[dict[str, Any]]:
    try:
        return [json.loads(body)]
    except json.JSONDecodeError:
        return [json.loads(line) for line in body.splitlines() if line.strip()]


def _validate(model: type[BaseModel], payload: dict[str, Any]) -> BaseModel:
    allowed = set(model.model_fields)
    if model is OrchestratorStatus:
        allowed |= ORCHESTRATOR_STATUS_EXTRAS
    assert set(payload) <= allowed, f"{model.__name__} has no {sorted(set(payload) - allowed)}"
    return model.model_validate(payload)


JSON_FENCES = [f for path in DOCS for f in fences(path) if f.marker in ENVELOPES]


def test_every_envelope_has_a_marked_example() -> None:
    assert {f.marker for f in JSON_FENCES} == set(ENVELOPES)


@pytest.mark.parametrize("fence", JSON_FENCES, ids=Fence.where)
def test_json_examples_validate(fence: Fence) -> None:
    objects = _json_objects(fence.body)
    assert objects
    for payload in objects:
        _validate(ENVELOPES[fence.marker or ""], payload)


def test_reply_examples_are_what_the_server_answers() -> None:
    (fence,) = marked(MQTT, "Reply")
    failure = [Reply.model_validate(obj) for obj in _json_objects(fence.body) if not obj["ok"]]
    assert failure and failure[0].error is not None
    with pytest.raises(Exception) as raised:  # the server's own argument check
        check_args(IMPLEMENTATIONS["l298n"].features["dutycycle"], [150])
    assert (raised.value.code, raised.value.message) == (  # type: ignore[attr-defined]
        failure[0].error.code, failure[0].error.message)
    # `umlbot call Sensor.angle 200   # stderr: out_of_range: degrees=200 is outside 0..180 °`
    shown = re.search(r"Sensor\.angle 200 .*# stderr: (\w+): (.*)$", MQTT.read_text(encoding="utf-8"), re.M)
    assert shown is not None
    with pytest.raises(Exception) as raised:
        check_args(IMPLEMENTATIONS["servo"].features["angle"], [200])
    assert (raised.value.code, raised.value.message) == shown.groups()  # type: ignore[attr-defined]


def test_topic_table_payloads_validate() -> None:
    by_topic = {code_spans(row[0])[0]: row for row in table_rows(section_text(MQTT, "## Topics"))}
    status_row = by_topic["umlbot/<robot>/<Component>/status"]
    online, offline = (json.loads(s) for s in code_spans(status_row[2]))
    status = _validate(Status, online)
    assert isinstance(status, Status) and status.impl is not None
    assert status.features == sorted(IMPLEMENTATIONS[status.impl].features)
    assert _validate(Status, offline).model_dump(exclude_defaults=True) == {"state": "offline"}

    assert isinstance(json.loads(code_spans(by_topic["umlbot/<robot>/<Component>/state"][2])[0]), dict)

    orchestrator_row = by_topic["umlbot/<robot>/orchestrator/status"][2]
    example, *states = code_spans(orchestrator_row)
    _validate(OrchestratorStatus, json.loads(example))
    assert states == list(get_args(OrchestratorStatus.model_fields["state"].annotation))

    trace_keys = re.findall(r'"(\w+)"', code_spans(by_topic["umlbot/<robot>/orchestrator/trace"][2])[0])
    assert trace_keys == list(TraceEvent.model_fields)

    _validate(ExitRequest, json.loads(code_spans(by_topic["umlbot/<robot>/orchestrator/exit"][2])[0]))

    heartbeat_row = by_topic["umlbot/<robot>/orchestrator/heartbeat"][2]
    beat = _validate(Heartbeat, json.loads(code_spans(heartbeat_row)[0]))
    assert isinstance(beat, Heartbeat) and beat.period_s == HEARTBEAT_MAX_S
    assert beat.reply_to.startswith("umlbot/car/_reply/umlbot-orchestrator-calls-"), "the calls' reply topic"


def test_broker_url_examples_parse(tmp_path: Path) -> None:
    from umlbot.services.bus import BrokerSettings

    rows = table_rows(section_text(MQTT, "## Connecting"))
    assert len(rows) >= 5
    for url_cell, meaning in rows:
        (url,) = code_spans(url_cell)

        def local(match: re.Match[str]) -> str:  # file parameters must name existing files
            made = tmp_path / Path(match.group(2)).name
            made.write_text("", encoding="utf-8")
            return f"{match.group(1)}={made}"

        settings = BrokerSettings.from_url(re.sub(r"\b(ca|cert|key)=([^&]+)", local, url))
        default_port = re.search(r"default port (\d+)", meaning)
        if default_port:
            assert settings.port == int(default_port.group(1)), url
        default_keepalive = re.search(r"keep-alive in seconds \(default (\d+)\)", meaning)
        if default_keepalive:
            assert BrokerSettings.from_url("mqtt://host").keepalive_s == int(default_keepalive.group(1))
            assert settings.keepalive_s == int(re.search(r"keepalive=(\d+)", url).group(1))  # type: ignore[union-attr]
        if "user name and password" in meaning:
            assert settings.username == "user"
        if "insecure" in url:
            assert settings.insecure
        if "protocol=5" in url:
            assert settings.protocol == "5"


def test_error_codes_are_the_stable_codes() -> None:
    rows = table_rows(section_text(MQTT, "## Calls"))
    documented = [code_spans(row[0])[0] for row in rows]
    assert documented == list(ERROR_CODES)


# --- commands and options ------------------------------------------------------------------------


@cache
def command_of(name: str) -> click.Command:
    """The command as `umlbot` serves it (with the options every command gets: --log-level …)."""
    from umlbot.cli import with_log_options

    module = importlib.import_module(f"umlbot.commands.{name.replace('-', '_')}")
    command: click.Command = module.command
    return with_log_options(command)


def options_of(command: click.Command) -> dict[str, click.Parameter]:
    found: dict[str, click.Parameter] = {"-h": click.Option(["-h"], is_flag=True),
                                         "--help": click.Option(["--help"], is_flag=True)}
    for param in command.params:
        if isinstance(param, click.Option):
            for name in (*param.opts, *param.secondary_opts):
                found[name] = param
    return found


STOP_TOKENS = {"#", "|", "&", "&&", "||", ">", ">>", "2>", ";", "<"}
OPTION_RE = re.compile(r"^(--?[A-Za-z][\w-]*)")


def _takes_value(param: click.Parameter) -> bool:
    return isinstance(param, click.Option) and not param.is_flag and not param.count


def _check_invocation(tokens: list[str], where: str, problems: list[str]) -> None:
    """Check `umlbot [group options] COMMAND args…` (tokens start after `umlbot`)."""
    group = options_of(cli)
    i = 0
    while i < len(tokens) and tokens[i].startswith("-"):
        name = tokens[i].split("=")[0]
        if name not in group:
            problems.append(f"{where}: umlbot has no option {name}")
            return
        i += 2 if _takes_value(group[name]) and "=" not in tokens[i] else 1
    if i >= len(tokens):
        return
    name = tokens[i]
    if name not in COMMANDS:
        if re.fullmatch(r"[a-z][a-z-]*", name):
            problems.append(f"{where}: umlbot has no command {name!r}")
        return
    command = command_of(name)
    rest = tokens[i + 1:]
    if isinstance(command, click.Group) and rest and rest[0] in command.commands:  # calibrate stereo
        command, rest = command.commands[rest[0]], rest[1:]
    options = options_of(command)
    for k, token in enumerate(rest):
        if token in STOP_TOKENS or token.startswith(("#", "(", "`")):
            break
        match = OPTION_RE.match(token.strip("[]"))
        if not match:
            continue
        option = match.group(1)
        param = options.get(option)
        if param is None:
            problems.append(f"{where}: umlbot {name} has no option {option}")
            continue
        if isinstance(param.type, click.Choice) and k + 1 < len(rest):
            value = rest[k + 1].strip("[]")
            if re.fullmatch(r"[a-z0-9|]+", value):
                for choice in value.split("|"):
                    if choice not in param.type.choices:
                        problems.append(f"{where}: umlbot {name} {option} has no choice {choice!r}")


def _command_lines(path: Path) -> Iterator[tuple[str, str]]:
    """(where, text) of every inline span and every line of a shell or plain fence."""
    for span in spans(path):
        yield span.where(), span.text
    for fence in fences(path):
        if fence.info in ("", "sh", "bash", "console"):
            lines = fence.body.splitlines()
            offset = 0
            while offset < len(lines):
                start = offset
                line = lines[offset]
                while line.endswith("\\") and offset + 1 < len(lines):  # a continued command
                    offset += 1
                    line = line[:-1] + " " + lines[offset].strip()
                yield f"{fence.path.relative_to(ROOT)}:{fence.line + 1 + start}", line
                offset += 1


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_umlbot_invocations_use_existing_commands_and_options(path: Path) -> None:
    problems: list[str] = []
    for where, text in _command_lines(path):
        tokens = text.split()
        comment = next((i for i, token in enumerate(tokens) if token.startswith("#")), len(tokens))
        tokens = tokens[:comment]
        for i, token in enumerate(tokens):
            if token == "umlbot" or token.endswith("/bin/umlbot"):
                _check_invocation(tokens[i + 1:], where, problems)
        # `check -W`, `render --format svg`: a command name and its option in one span
        if tokens and tokens[0] in COMMANDS and len(tokens) > 1 and tokens[1].startswith("-"):
            _check_invocation(tokens, where, problems)
    assert problems == []


#: Prose that documents one command's options: (file, heading it starts with or "" for the whole
#: file) -> the commands that must all have every option a code span there starts with.
OPTION_SECTIONS: dict[tuple[str, str], tuple[str, ...]] = {
    ("docs/model-format.md", "# The model format"): ("check", "compile", "render"),
    ("docs/semantics.md", ""): ("run",),
    ("docs/monitor.md", ""): ("monitor",),
    ("docs/studio.md", "## Options"): ("studio",),
    ("docs/services.md", "# Hardware services"): ("service",),
    ("docs/services.md", "## Drivers"): ("service",),
    ("docs/simulator.md", "## Command"): ("sim",),
    ("docs/mqtt.md", "## The embedded broker"): ("broker",),
    ("docs/mqtt.md", "## One call from the shell"): ("call",),
    ("docs/security.md", "## The embedded broker"): ("broker",),
}
#: Spans in those sections that name another command's option on purpose.
OPTION_EXCEPTIONS = {
    # "use the broker that is already there with `--broker mqtt://host:port`" (other commands)
    ("docs/mqtt.md", "--broker mqtt://host:port"),
}


@pytest.mark.parametrize("key", list(OPTION_SECTIONS), ids=lambda key: f"{key[0]} {key[1]}")
def test_documented_options_exist(key: tuple[str, str]) -> None:
    file, heading = key
    path = ROOT / file
    chosen = [s for s in spans(path) if not heading or s.section.startswith(heading)]
    named = [s for s in chosen if s.text.startswith("-") and (file, s.text) not in OPTION_EXCEPTIONS]
    assert named, "the section names no option any more: update OPTION_SECTIONS"
    problems = []
    for span in named:
        option = OPTION_RE.match(span.text)
        assert option is not None, span.text
        for command in OPTION_SECTIONS[key]:
            if option.group(1) not in options_of(command_of(command)):
                problems.append(f"{span.where()}: umlbot {command} has no option {option.group(1)}")
    assert problems == []


#: Options of other programs the docs show, by program.
OTHER_PROGRAMS_OPTIONS = {
    "systemctl": {"--now"},
    "journalctl": {"--since"},
    "mosquitto_sub": {"--cafile"},
    "debootstrap": {"--variant"},
    "systemd-nspawn": {"--boot", "--system-call-filter", "--private-network"},
    "the generated C++ program (umlbot generate cpp)": {"--sim-clock"},
    "ld": {"--gc-sections"},
}


@cache
def options_of_scripts() -> dict[str, frozenset[str]]:
    """The options of the project's scripts (deploy/install.sh, scripts/*.sh, deploy/*.py, bench/*.py)
    by path."""
    found: dict[str, frozenset[str]] = {}
    for shell in [ROOT / "deploy" / "install.sh", *(ROOT / "scripts").glob("*.sh")]:
        text = shell.read_text(encoding="utf-8")
        found[str(shell.relative_to(ROOT))] = frozenset(
            re.findall(r"^\s*(?:-h\|)?(--[\w-]+)\)", text, re.M))
    for script in [*(ROOT / "deploy").glob("*.py"), *(ROOT / "bench").glob("*.py")]:
        options = re.findall(r'add_argument\(\s*"(--[\w-]+)"', script.read_text(encoding="utf-8"))
        found[str(script.relative_to(ROOT))] = frozenset({*options, "-h", "--help"})
    return found


def _script_options() -> set[str]:
    return {option for options in options_of_scripts().values() for option in options}


def _script_named(token: str) -> str | None:
    for script in options_of_scripts():
        if token == script or token.endswith("/" + script) or token == Path(script).name:
            return script
    return None


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_script_invocations_use_existing_options(path: Path) -> None:
    problems = []
    for where, text in _command_lines(path):
        tokens = text.split()
        for i, token in enumerate(tokens):
            script = _script_named(token)
            if script is None:
                continue
            for option_token in tokens[i + 1:]:
                if option_token in STOP_TOKENS or option_token.startswith(("#", "(")):
                    break
                match = OPTION_RE.match(option_token.strip("[]"))
                if match and match.group(1) not in options_of_scripts()[script]:
                    problems.append(f"{where}: {script} has no option {match.group(1)}")
    assert problems == []


#: "Options: …" paragraphs about a script: (file, heading) -> the script.
SCRIPT_OPTION_PARAGRAPHS = {
    ("docs/deploy-pi.md", "## 4. Install"): "deploy/install.sh",
    ("docs/performance.md", "## RPC"): "bench/rpc.py",
    ("docs/performance.md", "## Orchestrator"): "bench/orchestrator.py",
    ("docs/performance.md", "## Memory"): "bench/memory.py",
    ("docs/performance.md", "## Chaos"): "bench/chaos.py",
    ("docs/performance.md", "## Sim"): "bench/sim.py",
}


@pytest.mark.parametrize("key", list(SCRIPT_OPTION_PARAGRAPHS), ids=lambda key: f"{key[0]} {key[1]}")
def test_script_option_paragraphs_name_existing_options(key: tuple[str, str]) -> None:
    text = section_text(ROOT / key[0], key[1])
    paragraph = re.search(r"Options: (.*?)(?:\n\n|\Z)", text, re.S)
    assert paragraph is not None
    named = [OPTION_RE.match(span) for span in code_spans(paragraph.group(1)) if span.startswith("--")]
    assert len(named) >= 3
    script = SCRIPT_OPTION_PARAGRAPHS[key]
    missing = [m.group(1) for m in named if m and m.group(1) not in options_of_scripts()[script]]
    assert missing == []


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_option_named_anywhere_exists_somewhere(path: Path) -> None:
    known = set(options_of(cli)) | _script_options()
    for name in COMMANDS:
        command = command_of(name)
        known |= set(options_of(command))
        for sub in command.commands.values() if isinstance(command, click.Group) else ():
            known |= set(options_of(sub))
    for options in OTHER_PROGRAMS_OPTIONS.values():
        known |= options
    named = {(where, option) for where, text in _command_lines(path)
             for option in re.findall(r"(?<![\w-])(--[a-z][\w-]*)", text)}
    assert sorted(f"{where}: {option}" for where, option in named if option not in known) == []


def test_the_sim_options_table_has_the_defaults() -> None:
    options = options_of(command_of("sim"))
    checked = 0
    for cells in table_rows(section_text(SIMULATOR, "## Command")):
        for span, default in zip(code_spans(cells[0]), cells[1].split(" / "), strict=False):
            param = options[span.split()[0]]
            if isinstance(param.default, int | float) and not isinstance(param.default, bool):
                assert float(default) == param.default, span
                checked += 1
    assert checked >= 4


def test_commands_that_connect_take_a_ca_file() -> None:
    text = section_text(MQTT, "## Connecting")
    claim = re.search(r"The commands that connect, (.*?) also take `--ca-file`", text.replace("\n", " "))
    assert claim is not None
    connecting = sorted(name for name in COMMANDS if "--broker" in options_of(command_of(name)))
    with_ca = sorted(name for name in connecting if "--ca-file" in options_of(command_of(name)))
    assert sorted(code_spans(claim.group(1))) == with_ca


def test_the_command_tables_list_every_command() -> None:
    for path in (ROOT / "README.md",):
        rows = table_rows(section_text(path, "## Commands"))
        documented = [code_spans(row[0])[0].split()[1] for row in rows]
        assert documented == list(COMMANDS)


def test_the_examples_are_found() -> None:
    """The parametrised tests above run on something: an empty list would silently test nothing."""
    assert RUNNABLE and NODE_SPANS and EXPRESSION_ROWS and JSON_FENCES
    for kind in ("model", "nodes", "activity-file", "deployment", "layout", "check-output"):
        assert marked(MODEL_FORMAT, kind), kind


# --- links ---------------------------------------------------------------------------------------

LINK_RE = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_point_to_existing_files(path: Path) -> None:
    text = path.read_text(encoding="utf-8")
    for fence in fences(path):
        text = text.replace(fence.body, "")
    targets = [t for t in LINK_RE.findall(text) if not re.match(r"[a-z]+:", t) and not t.startswith("#")]
    missing = [t for t in targets if not (path.parent / t.split("#")[0]).exists()]
    assert missing == []
    if path.name == "README.md":
        assert len(targets) >= len(list((ROOT / "docs").glob("*.md")))  # every doc page is linked


REPO_PATH_RE = re.compile(r"^(?:models|deploy|services|umlbot|compiler|bench|docs|tests)/[\w./@*-]*$")


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_repository_paths_in_code_spans_exist(path: Path) -> None:
    named = [s for s in spans(path) if REPO_PATH_RE.match(s.text)]
    missing = [f"{s.where()}: {s.text}" for s in named if not list(ROOT.glob(s.text.rstrip("/")))]
    assert missing == []


PYTHON_NAME_RE = re.compile(r"^((?:umlbot|compiler|services)(?:\.\w+)+)(?:\(.*\))?(?: -> \w+)?$")
#: `umlbot.target`, `umlbot.acl`, …: files and systemd units, not Python names.
FILE_SUFFIXES = {"target", "acl", "passwd", "env", "conf", "service"}


def _resolves(dotted: str) -> bool:
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            found: object = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            if not hasattr(found, attr):
                return False
            found = getattr(found, attr)
        return True
    return False


@pytest.mark.parametrize("path", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_python_names_in_code_spans_exist(path: Path) -> None:
    from umlbot.base.plugins import COMPONENTS_GROUP, DRIVERS_GROUP

    named = [(s, m.group(1)) for s in spans(path) if (m := PYTHON_NAME_RE.match(s.text))]
    named = [(s, name) for s, name in named if name.rsplit(".", 1)[1] not in FILE_SUFFIXES]
    named = [(s, name) for s, name in named if name not in (COMPONENTS_GROUP, DRIVERS_GROUP)]  # entry points
    assert [f"{s.where()}: {name}" for s, name in named if not _resolves(name)] == []


PYTHON_FENCES = [f for path in DOCS for f in fences(path) if f.info == "python"]


@pytest.mark.parametrize("fence", PYTHON_FENCES, ids=Fence.where)
def test_python_examples_import_what_exists(fence: Fence) -> None:
    imports = re.findall(r"^from ([\w.]+) import (.+)$", fence.body, re.M)
    assert imports, "a Python example without imports: nothing to check"
    for module_name, names in imports:
        module = importlib.import_module(module_name)
        for name in names.split(","):
            assert hasattr(module, name.strip()), f"{module_name} has no {name.strip()}"


def _parameters(function: Any) -> list[str]:
    return [name for name in inspect.signature(function).parameters if name != "self"]


def test_python_api_signatures_are_as_documented() -> None:
    from umlbot.services.host import ServiceHost
    from umlbot.services.orchestrator import Orchestrator

    options = section_text(SEMANTICS, "## Running the orchestrator from Python").replace("\n", " ")
    listed = re.search(r"Options: (.*?)\. `run\(\)`", options)
    assert listed is not None
    keywords = code_spans(listed.group(1))
    # the options are the keyword parameters after (model, settings, robot=…, clock=…)
    assert sorted(keywords) == sorted(_parameters(Orchestrator.__init__)[4:])

    shown = re.search(r"`(ServiceHost\(.*?\))`", (ROOT / "docs" / "services.md").read_text(encoding="utf-8")
                      .replace("\n", " "))
    assert shown is not None
    documented = re.sub(r"\s+", " ", shown.group(1))
    signature = inspect.signature(ServiceHost.__init__)
    params = [p for p in signature.parameters.values() if p.name != "self"]
    actual = []
    for param in params:
        if param.kind is inspect.Parameter.KEYWORD_ONLY and "*" not in actual:
            actual.append("*")
        actual.append(param.name if param.default is inspect.Parameter.empty
                      else f"{param.name}={param.default!r}")
    assert documented == f"ServiceHost({', '.join(actual)})"


def test_make_sim_is_as_documented() -> None:
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    variables = dict(re.findall(r"^(\w+)\s*\??=\s*(\S+)", makefile, re.M))
    recipe = re.search(r"^sim:.*\n((?:\t.*\n)+)", makefile, re.M)
    assert recipe is not None
    command = "umlbot sim models/robot_car --track $(TRACK) --speed $(SPEED) --plot $(OUT)/sim.png"
    assert command in recipe.group(1)
    readme = (ROOT / "README.md").read_text(encoding="utf-8").replace("\n", " ")
    said = re.search(r"`make sim` drives the reference robot car \(`(.*?)`\) through `(.*?)` at ten times "
                     r"real speed and writes the picture of the run to `(.*?)`", readme)
    assert said is not None
    assert said.groups() == ("models/robot_car", variables["TRACK"], f"{variables['OUT']}/sim.png")
    assert variables["SPEED"] == "10"
    for name in re.findall(r"`make sim ((?:\w+=\S+ ?)+)`", readme)[0].split():
        assert name.split("=")[0] in variables


def _settings_tables() -> dict[str, list[list[str]]]:
    """The settings tables of docs/services.md by their bold title's first word."""
    text = section_text(ROOT / "docs" / "services.md", "### Settings")
    tables: dict[str, list[list[str]]] = {}
    for title, body in re.findall(r"^\*\*(.+?)\*\*.*?\n(.*?)(?=^\*\*|\Z)", text, re.S | re.M):
        tables[title.split()[0]] = table_rows(body)
    return tables


def _default_shown(field: Any) -> str:
    if field.is_required():
        return "required"
    default = field.get_default(call_default_factory=True)
    if default is None:
        return "none"
    if isinstance(default, bool):
        return str(default).lower()
    if isinstance(default, float | int):
        return f"{default:g}"
    if isinstance(default, str):
        return default
    return json.dumps(default)


def _same_default(shown: str, expected: str) -> bool:
    shown, expected = shown.strip("`"), expected.strip("`")
    try:
        return float(shown) == float(expected)
    except ValueError:
        return shown == expected


def test_driver_settings_tables_are_the_settings_models() -> None:
    from umlbot.services.gpio import GpioSettings
    from umlbot.services.gpio.mock import MockGpioSettings
    from umlbot.services.motor import L298NSettings
    from umlbot.services.servo import ServoSettings
    from umlbot.services.servo.mock import MockServoSettings
    from umlbot.services.sonar import HCSR04Settings
    from umlbot.services.sonar.mock import MockSonarSettings

    models: dict[str, type[BaseModel]] = {"L298N": L298NSettings, "HC-SR04": HCSR04Settings,
                                          "Servo": ServoSettings, "Raspberry": GpioSettings}
    tables = _settings_tables()
    assert set(models) | {"Mock"} == set(tables)
    #: documented elsewhere (`host`/`port`/`chip`: "the settings `host`/`port`", "the setting
    #: `chip`" in the driver table) or internal.
    not_in_tables = {"host", "port", "chip", "reserved_pins"}
    for title, model in models.items():
        rows = {code_spans(row[0])[0]: row[1] for row in tables[title]}
        assert set(rows) == set(model.model_fields) - not_in_tables, title
        for key, shown in rows.items():
            expected = _default_shown(model.model_fields[key])
            if expected == "none" and shown == "all":  # gpio `pins`: none = every pin
                continue
            assert _same_default(shown, expected), f"{title} {key}: {shown} != {expected}"
    mock_fields = {**MockSonarSettings.model_fields, **MockGpioSettings.model_fields,
                   **MockServoSettings.model_fields}
    for key_cell, _kinds, shown, _meaning in tables["Mock"]:
        key = code_spans(key_cell)[0]
        assert key in mock_fields, key
        expected = _default_shown(mock_fields[key])
        assert _same_default(shown, expected), f"mock {key}: {shown} != {expected}"


def test_monitor_json_events_are_as_documented() -> None:
    from umlbot.monitor import MonitorEvent

    monitor = ROOT / "docs" / "monitor.md"
    rows = table_rows(section_text(monitor, "## `--json`"))
    documented: dict[str, list[str]] = {}
    for type_cell, _when, fields_cell in rows:
        documented[code_spans(type_cell)[0]] = [f for f in code_spans(fields_cell) if re.fullmatch(r"\w+", f)]
    assert list(documented) == list(get_args(MonitorEvent.model_fields["type"].annotation))
    common = re.search(r"Every line also has (.*?)\. Example", section_text(monitor, "## `--json`"), re.S)
    assert common is not None
    common_fields = [f for f in code_spans(common.group(1)) if f in MonitorEvent.model_fields]
    assert common_fields == ["type", "time", "robot", "topic"]
    named = set(common_fields) | {field for fields in documented.values() for field in fields}
    assert named == set(MonitorEvent.model_fields)
    (fence,) = marked(monitor, "MonitorEvent")
    for payload in _json_objects(fence.body):
        event = MonitorEvent.model_validate(payload)  # extra="forbid": no undeclared key
        assert set(payload) <= {"type", "time", "robot", "topic", *documented[event.type]}
