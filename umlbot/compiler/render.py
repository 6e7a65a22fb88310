"""Pictures of a compiled model: the component diagram and the activity diagrams.

Each diagram is written as Mermaid, PlantUML and Graphviz DOT text, and as SVG through Graphviz's
`dot` binary. Activity diagrams use UML shapes: a filled circle for the start, a bull's-eye for an
end, a diamond for a decision, a black bar for a fork or join, and one cluster per swimlane. There
is one activity diagram per activity source file (its swimlanes side by side).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import Literal

from umlbot.base.errors import UmlbotError
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

Format = Literal["mermaid", "plantuml", "dot", "svg"]
FORMATS: tuple[Format, ...] = ("mermaid", "plantuml", "dot", "svg")
SUFFIX: dict[Format, str] = {"mermaid": ".mmd", "plantuml": ".puml", "dot": ".dot", "svg": ".svg"}
DOT_TIMEOUT_S = 60.0


class RenderError(UmlbotError, RuntimeError):
    """A diagram could not be drawn (Graphviz missing or failing)."""


class SvgNotDrawn(RenderError):
    """The SVG diagrams could not be drawn; every other format asked for was written (`written`)."""

    def __init__(self, reason: str, written: list[Path]) -> None:
        super().__init__(f"SVG not drawn: {reason}")
        self.written = written


def diagrams(model: CompiledModel) -> dict[str, list[Lane]]:
    """The activity diagrams: name -> its swimlanes (one diagram per activity source file)."""
    result: dict[str, list[Lane]] = {}
    for lane in sorted(model.lanes.values(), key=lambda x: (x.file, x.line, x.name)):
        result.setdefault(diagram_id(lane.file), []).append(lane)
    return result


def diagram_id(file: str) -> str:
    """The activity diagram of the lanes in one source file: `activity-<file's stem>`."""
    return f"activity-{_slug(PurePosixPath(file).stem or 'activities')}"


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]", "_", text)


def _ident(*parts: str) -> str:
    return "_".join(re.sub(r"\W", "_", p) for p in parts)


def successors(node: Node) -> list[tuple[str, str]]:
    """(target, label) of every outgoing flow; a decision's labels are its guards (`else` last)."""
    if isinstance(node, DecisionNode):
        return [(b.target, b.label) for b in node.branches]
    if isinstance(node, ForkNode):
        return [(t, "") for t in node.targets]
    if isinstance(node, EndNode):
        return []
    return [(node.next, "")]


def _successors(node: Node) -> list[tuple[str, str]]:
    """`successors` with a decision's guards in UML's brackets, as the pictures show them."""
    guarded = isinstance(node, DecisionNode)
    return [(target, f"[{label}]" if guarded else label) for target, label in successors(node)]


def _label(node: Node) -> str:
    if isinstance(node, DatastoreNode):
        return f"«datastore»\n{node.label}"
    if isinstance(node, SendNode | AcceptNode | ActionNode):
        return node.label
    return ""


# --- Graphviz DOT ----------------------------------------------------------------------------------


def _dot_str(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _dot_node(lane: Lane, node: Node) -> str:
    name = _dot_str(f"{lane.name}.{node.id}")
    attrs: dict[str, str] = {"id": name, "tooltip": _dot_str(f"{lane.name}.{node.id} ({node.kind})")}
    if isinstance(node, StartNode):
        attrs.update(shape="circle", style="filled", fillcolor="black", label='""', width="0.25",
                     fixedsize="true")
    elif isinstance(node, EndNode):
        attrs.update(shape="doublecircle", style="filled", fillcolor="black", label='""',
                     width="0.2", fixedsize="true")
    elif isinstance(node, DecisionNode):
        attrs.update(shape="diamond", label='""', width="0.35", height="0.35", fixedsize="true")
    elif isinstance(node, ForkNode | JoinNode):
        attrs.update(shape="box", style="filled", fillcolor="black", label='""', width="1.2",
                     height="0.06", fixedsize="true")
    elif isinstance(node, SendNode):
        attrs.update(shape="cds", label=_dot_str(_label(node)))
    elif isinstance(node, AcceptNode):
        attrs.update(shape="invhouse", label=_dot_str(_label(node)))
    elif isinstance(node, DatastoreNode):
        attrs.update(shape="box", label=_dot_str(_label(node)))
    else:
        attrs.update(shape="box", style="rounded", label=_dot_str(_label(node)))
    body = ", ".join(f"{k}={v}" for k, v in attrs.items())
    return f"    {name} [{body}];"


def activity_dot(name: str, lanes: list[Lane]) -> str:
    """One activity diagram in DOT; each swimlane is a cluster; node names are `Lane.id`."""
    lines = [f"digraph {_dot_str(name)} {{", "  rankdir=TB;",
             '  node [fontname="Helvetica", fontsize=10];', '  edge [fontname="Helvetica", fontsize=9];']
    for lane in lanes:
        kind = "virtual swimlane" if lane.virtual else "swimlane"
        lines.append(f"  subgraph {_dot_str('cluster_' + lane.name)} {{")
        lines.append(f"    label={_dot_str(f'{lane.name} ({kind})')}; style=rounded;")
        lines.extend(_dot_node(lane, node) for node in lane.nodes.values())
        lines.append("  }")
    for lane in lanes:
        for node in lane.nodes.values():
            for target, label in _successors(node):
                attrs = f" [label={_dot_str(label)}]" if label else ""
                lines.append(f"  {_dot_str(f'{lane.name}.{node.id}')} -> "
                             f"{_dot_str(f'{lane.name}.{target}')}{attrs};")
    lines.append("}")
    return "\n".join(lines) + "\n"


def components_dot(model: CompiledModel) -> str:
    """The component diagram in DOT: components with their implementation and ports, and links."""
    lines = [f"digraph {_dot_str(model.name + ' components')} {{", "  rankdir=LR;",
             '  node [fontname="Helvetica", fontsize=10, shape=component];',
             '  edge [fontname="Helvetica", fontsize=9, arrowhead=none];']
    for name, comp in model.components.items():
        ports = "".join(f"\n○ {port}: {feature}" for port, feature in comp.ports.items())
        label = f"«{comp.kind}»\n{name}\n: {comp.impl}{ports}"
        lines.append(f"  {_dot_str(name)} [id={_dot_str(name)}, label={_dot_str(label)}];")
    for link in model.links:
        label = f"{link.source_port} — {link.target_port}"
        lines.append(f"  {_dot_str(link.source_component)} -> {_dot_str(link.target_component)} "
                     f"[id={_dot_str(link.id)}, label={_dot_str(label)}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


# --- Mermaid ---------------------------------------------------------------------------------------


def _mm_str(text: str) -> str:
    return '"' + text.replace('"', "#quot;").replace("\n", "<br/>") + '"'


def activity_mermaid(name: str, lanes: list[Lane]) -> str:
    """One activity diagram as a Mermaid flowchart; each swimlane is a subgraph."""
    lines = ["flowchart TB", "  classDef bar fill:#000,stroke:#000,color:#000;",
             "  classDef start fill:#000,stroke:#000;", "  classDef stop fill:#000,stroke:#000;"]
    for lane in lanes:
        lines.append(f"  subgraph {_ident('lane', lane.name)}[{_mm_str(lane.name)}]")
        for node in lane.nodes.values():
            ident = _ident(lane.name, node.id)
            if isinstance(node, StartNode):
                lines.append(f'    {ident}((" ")):::start')
            elif isinstance(node, EndNode):
                lines.append(f'    {ident}(((" "))):::stop')
            elif isinstance(node, DecisionNode):
                lines.append(f'    {ident}{{" "}}')
            elif isinstance(node, ForkNode | JoinNode):
                lines.append(f'    {ident}[" "]:::bar')
            elif isinstance(node, SendNode):
                lines.append(f"    {ident}>{_mm_str(_label(node))}]")
            elif isinstance(node, DatastoreNode):
                lines.append(f"    {ident}[({_mm_str(_label(node))})]")
            elif isinstance(node, AcceptNode):
                lines.append(f"    {ident}[/{_mm_str(_label(node))}/]")
            else:
                lines.append(f"    {ident}({_mm_str(_label(node))})")
        lines.append("  end")
    for lane in lanes:
        for node in lane.nodes.values():
            for target, label in _successors(node):
                arrow = f"-->|{_mm_str(label)}|" if label else "-->"
                lines.append(f"  {_ident(lane.name, node.id)} {arrow} {_ident(lane.name, target)}")
    return "\n".join(lines) + "\n"


def components_mermaid(model: CompiledModel) -> str:
    """The component diagram as a Mermaid flowchart."""
    lines = ["flowchart LR"]
    for name, comp in model.components.items():
        ports = "".join(f"\n○ {port}: {feature}" for port, feature in comp.ports.items())
        label = f"«{comp.kind}»\n{name}\n: {comp.impl}{ports}"
        lines.append(f"  {_ident(name)}[{_mm_str(label)}]")
    for link in model.links:
        label = f"{link.source_port} — {link.target_port}"
        lines.append(f"  {_ident(link.source_component)} ---|{_mm_str(label)}| "
                     f"{_ident(link.target_component)}")
    return "\n".join(lines) + "\n"


# --- PlantUML --------------------------------------------------------------------------------------


def _pu_str(text: str) -> str:
    return '"' + text.replace('"', "'").replace("\n", "\\n") + '"'


def activity_plantuml(name: str, lanes: list[Lane]) -> str:
    """One activity diagram in PlantUML's state-diagram notation (it allows any graph): `[*]` the
    start, `<<end>>` the bull's-eye, `<<choice>>` the diamond, `<<fork>>`/`<<join>>` the bars, a
    composite state per swimlane."""
    lines = [f"@startuml {_slug(name)}", "hide empty description"]
    for lane in lanes:
        kind = "virtual swimlane" if lane.virtual else "swimlane"
        lines.append(f"state {_pu_str(f'{lane.name} ({kind})')} as {_ident('lane', lane.name)} {{")
        for node in lane.nodes.values():
            ident = _ident(lane.name, node.id)
            if isinstance(node, StartNode):
                continue
            if isinstance(node, EndNode):
                lines.append(f"  state {ident} <<end>>")
            elif isinstance(node, DecisionNode):
                lines.append(f"  state {ident} <<choice>>")
            elif isinstance(node, ForkNode):
                lines.append(f"  state {ident} <<fork>>")
            elif isinstance(node, JoinNode):
                lines.append(f"  state {ident} <<join>>")
            else:
                lines.append(f"  state {_pu_str(_label(node))} as {ident}")
        for node in lane.nodes.values():
            source = "[*]" if isinstance(node, StartNode) else _ident(lane.name, node.id)
            for target, label in _successors(node):
                suffix = f" : {label}" if label else ""
                lines.append(f"  {source} --> {_ident(lane.name, target)}{suffix}")
        lines.append("}")
    lines.append("@enduml")
    return "\n".join(lines) + "\n"


def components_plantuml(model: CompiledModel) -> str:
    """The component diagram in PlantUML."""
    lines = [f"@startuml {_slug(model.name)}-components"]
    for name, comp in model.components.items():
        label = f"«{comp.kind}»\n{name}\n: {comp.impl}"
        lines.append(f"component {_pu_str(label)} as {_ident(name)} {{")
        for port in comp.ports:
            lines.append(f"  port {_ident(name, port)} as {_pu_str(port)}")
        lines.append("}")
    for link in model.links:
        lines.append(f"{_ident(link.source_component, link.source_port)} -- "
                     f"{_ident(link.target_component, link.target_port)} : {link.id}")
    lines.append("@enduml")
    return "\n".join(lines) + "\n"


# --- SVG and files -------------------------------------------------------------------------------


def dot_to_svg(dot_text: str) -> bytes:
    """Lay a DOT graph out as SVG with Graphviz's `dot`; `RenderError` when dot is missing or fails."""
    dot = shutil.which("dot")
    if dot is None:
        raise RenderError("Graphviz's 'dot' program was not found on PATH; install Graphviz "
                          "(Debian: apt-get install graphviz) or render with --format mermaid, "
                          "plantuml or dot")
    try:
        done = subprocess.run([dot, "-Tsvg"], input=dot_text.encode("utf-8"), capture_output=True,
                              timeout=DOT_TIMEOUT_S, check=False)
    except subprocess.TimeoutExpired as exc:
        raise RenderError(f"dot did not finish within {DOT_TIMEOUT_S:g} s") from exc
    except OSError as exc:
        raise RenderError(f"cannot run {dot}: {exc.strerror}") from exc
    if done.returncode != 0:
        raise RenderError(f"dot failed: {done.stderr.decode('utf-8', 'replace').strip()}")
    return done.stdout


def render_texts(model: CompiledModel, fmt: Format) -> dict[str, str | bytes]:
    """Every diagram of the model in one format: file name -> content."""
    makers: dict[Format, tuple[Callable[[CompiledModel], str], Callable[[str, list[Lane]], str]]] = {
        "mermaid": (components_mermaid, activity_mermaid),
        "plantuml": (components_plantuml, activity_plantuml),
        "dot": (components_dot, activity_dot),
        "svg": (components_dot, activity_dot),
    }
    components, activity = makers[fmt]
    texts: dict[str, str] = {"components": components(model)}
    for name, lanes in diagrams(model).items():
        texts[name] = activity(name, lanes)
    suffix = SUFFIX[fmt]
    if fmt == "svg":
        return {name + suffix: dot_to_svg(text) for name, text in texts.items()}
    return {name + suffix: text for name, text in texts.items()}


def render_model(model: CompiledModel, out_dir: str | Path, formats: tuple[Format, ...] = FORMATS
                 ) -> list[Path]:
    """Write the diagrams in `formats` into `out_dir` (created); the paths written, sorted.

    SVG comes last: when Graphviz cannot draw it, `SvgNotDrawn` carries the files of the other
    formats, which are written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    for fmt in sorted(formats, key=lambda f: f == "svg"):
        try:
            texts = render_texts(model, fmt)
        except RenderError as exc:
            raise SvgNotDrawn(str(exc), sorted(written)) from exc
        for name, content in texts.items():
            path = out / name
            if isinstance(content, bytes):
                path.write_bytes(content)
            else:
                path.write_text(content, encoding="utf-8")
            written.append(path)
    return sorted(written)
