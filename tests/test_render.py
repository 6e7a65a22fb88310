"""`umlbot render`: every notation, SVG through Graphviz that parses as XML and names every node."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from click.testing import CliRunner

from umlbot.cli import cli
from umlbot.compiler.api import compile_model
from umlbot.compiler.render import RenderError, SvgNotDrawn, dot_to_svg, render_model, render_texts

ROBOT_CAR = Path(__file__).resolve().parent.parent / "models" / "robot_car"
SVG = "{http://www.w3.org/2000/svg}"


def test_svg_parses_and_contains_every_node_id(tmp_path: Path) -> None:
    model = compile_model(ROBOT_CAR)
    written = render_model(model, tmp_path, ("svg",))
    assert sorted(p.name for p in written) == [
        "activity-main.svg", "activity-measure.svg", "activity-motion.svg", "components.svg"]
    ids: set[str] = set()
    for path in written:
        root = ET.parse(path).getroot()  # noqa: S314 - our own file, written by dot just now
        assert root.tag == f"{SVG}svg"
        ids |= {el.attrib["id"] for el in root.iter() if "id" in el.attrib}
    for lane in model.lanes.values():
        for node_id in lane.nodes:
            assert f"{lane.name}.{node_id}" in ids
    assert set(model.components) <= ids


def test_uml_shapes_in_dot() -> None:
    texts = render_texts(compile_model(ROBOT_CAR), "dot")
    motion = texts["activity-motion.dot"]
    assert isinstance(motion, str)
    assert 'subgraph "cluster_Stop"' in motion
    assert '"Stop.start" [id="Stop.start"' in motion and "shape=circle, style=filled" in motion
    assert "shape=doublecircle" in motion  # the bull's-eye end
    assert 'fillcolor=black, label="", width=1.2, height=0.06' in motion  # fork/join bars
    main = texts["activity-main.dot"]
    assert isinstance(main, str)
    assert "shape=diamond" in main and 'label="[Measure.right > side_cm]"' in main


def test_mermaid_and_plantuml_name_every_node() -> None:
    model = compile_model(ROBOT_CAR)
    mermaid = "".join(str(t) for t in render_texts(model, "mermaid").values())
    plantuml = "".join(str(t) for t in render_texts(model, "plantuml").values())
    assert mermaid.count("flowchart") == 4
    assert plantuml.count("@startuml") == 4 and plantuml.count("@enduml") == 4
    for lane in model.lanes.values():
        assert f"subgraph lane_{lane.name}" in mermaid
        for node_id in lane.nodes:
            assert f"{lane.name}_{node_id}" in mermaid
            if node_id != lane.start:
                assert f"{lane.name}_{node_id}" in plantuml
    assert "<<choice>>" in plantuml and "<<fork>>" in plantuml and "<<join>>" in plantuml


def test_missing_dot_is_a_clear_error(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(RenderError, match=r"Graphviz's 'dot' program was not found on PATH; install "
                                          r"Graphviz \(Debian: apt-get install graphviz\)"):
        dot_to_svg("digraph { a }")


def test_render_command_writes_every_format(tmp_path: Path) -> None:
    out = tmp_path / "pictures"
    result = CliRunner().invoke(cli, ["render", str(ROBOT_CAR), "-o", str(out)])
    assert result.exit_code == 0, result.output
    suffixes = sorted({p.suffix for p in out.iterdir()})
    assert suffixes == [".dot", ".mmd", ".puml", ".svg"]
    assert len(list(out.iterdir())) == 16


def test_render_command_one_format(tmp_path: Path) -> None:
    out = tmp_path / "pictures"
    result = CliRunner().invoke(cli, ["render", str(ROBOT_CAR), "-o", str(out), "--format", "mermaid"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.iterdir()) == [
        "activity-main.mmd", "activity-measure.mmd", "activity-motion.mmd", "components.mmd"]


def test_render_without_dot_writes_the_other_formats_and_exits_3(monkeypatch: pytest.MonkeyPatch,
                                                                tmp_path: Path) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    out = tmp_path / "pictures"
    result = CliRunner().invoke(cli, ["render", str(ROBOT_CAR), "-o", str(out)])
    assert result.exit_code == 3, result.output
    written = sorted(p.name for p in out.iterdir())
    assert len(written) == 12 and {Path(name).suffix for name in written} == {".dot", ".mmd", ".puml"}
    assert sorted(Path(line).name for line in result.stdout.splitlines()) == written
    assert result.stderr.splitlines() == [
        "error: SVG not drawn: Graphviz's 'dot' program was not found on PATH; install Graphviz "
        "(Debian: apt-get install graphviz) or render with --format mermaid, plantuml or dot"]


def test_render_model_writes_svg_last(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    with pytest.raises(SvgNotDrawn) as caught:
        render_model(compile_model(ROBOT_CAR), tmp_path / "d", ("svg", "mermaid"))
    assert [p.name for p in caught.value.written] == [
        "activity-main.mmd", "activity-measure.mmd", "activity-motion.mmd", "components.mmd"]
    assert all(p.is_file() for p in caught.value.written)
