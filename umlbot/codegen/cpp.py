"""The C++ generator: one compiled model → `CMakeLists.txt`, `src/model.cpp` and the runtime.

Each swimlane becomes a namespace with its datastores (`umlbot::Datastore` variables), its nodes
as an enum, and one `walk` function: a `switch` over the nodes in a loop, a `case` per node
commented with the node id and its file:line, so a person can follow a lane in the generated code
as in its YAML. Expressions become calls of the runtime's operators (`op_add`, `op_lt` …) that
compute what the interpreter computes (umlbot.compiler.expr, Python semantics); their operands are
evaluated left to right as there. Forks start a thread per flow and joins count arrivals, as
docs/semantics.md says; a virtual lane runs on its caller's thread, with its own activation.

The output is deterministic: lanes, nodes and components in a fixed order, no time stamps.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from umlbot.base.errors import ModelError
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
from umlbot.compiler.expr import (
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
from umlbot.services.orchestrator import heartbeat_period_s, used_components

#: the runtime's files, copied into every project (package data of umlbot.codegen)
RUNTIME_FILES = ("umlbot_runtime.hpp", "umlbot_runtime.cpp")

_INT64 = (-(2**63), 2**63 - 1)

_OPERATORS = {
    "+": "op_add", "-": "op_sub", "*": "op_mul", "/": "op_div", "%": "op_mod",
    "==": "op_eq", "!=": "op_ne", "<": "op_lt", "<=": "op_le", ">": "op_gt", ">=": "op_ge",
}


class GenerateError(ModelError):
    """The model uses something the generator cannot express in C++ (with its file:line)."""


def program_name(model: CompiledModel) -> str:
    """The generated program's file name: `<model name>-orchestrator`."""
    return f"{_slug(model.name)}-orchestrator"


def _slug(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_-]", "_", name) or "model"


def _ident(name: str) -> str:
    """A C++ identifier for a model name (letters, digits, `_`; the rest becomes `_`)."""
    text = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return text if text and not text[0].isdigit() else f"_{text}"


def _cstr(text: str) -> str:
    """A C++ string literal of `text` (UTF-8; octal escapes, which never run into what follows)."""
    out = []
    for byte in text.encode("utf-8"):
        char = chr(byte)
        if char in '"\\?':
            out.append("\\" + char)
        elif 0x20 <= byte < 0x7F:
            out.append(char)
        else:
            out.append(f"\\{byte:03o}")
    return '"' + "".join(out) + '"'


def _comment(text: str) -> str:
    """`text` safe inside a `//` comment (one line, no trailing backslash)."""
    flat = " ".join(text.split())
    return flat.replace("\\", "\\\\")


@dataclass(frozen=True)
class _Names:
    """The C++ names of a model's lanes and nodes."""

    lanes: dict[str, str]
    nodes: dict[str, dict[str, str]]


def _names(model: CompiledModel) -> _Names:
    lanes: dict[str, str] = {}
    taken: set[str] = set()
    for name in sorted(model.lanes):
        ident = f"lane_{_ident(name)}"
        while ident in taken:
            ident += "_"
        taken.add(ident)
        lanes[name] = ident
    nodes: dict[str, dict[str, str]] = {}
    for name, lane in model.lanes.items():
        per: dict[str, str] = {}
        used: set[str] = set()
        for node_id in _node_order(lane):
            ident = f"N_{_ident(node_id)}"
            while ident in used:
                ident += "_"
            used.add(ident)
            per[node_id] = ident
        nodes[name] = per
    return _Names(lanes, nodes)


def _node_order(lane: Lane) -> list[str]:
    """The lane's nodes in reading order: start first, then by line, then by id."""
    return sorted(lane.nodes, key=lambda node_id: (node_id != lane.start, lane.nodes[node_id].line, node_id))


class _LaneWriter:
    """Writes one lane's walk function."""

    def __init__(self, model: CompiledModel, names: _Names, lane: Lane) -> None:
        self.model = model
        self.names = names
        self.lane = lane
        self.nodes = names.nodes[lane.name]

    def where(self, line: int) -> str:
        return f"{self.lane.file or '<model>'}:{line or self.lane.line}"

    def error(self, message: str, line: int) -> GenerateError:
        return GenerateError(message, self.lane.file or "<model>", line or self.lane.line or 1, 1)

    # --- expressions --------------------------------------------------------------------------

    def expr(self, expr: Expr, line: int) -> str:
        """A C++ expression of type Value computing `expr` (operands left to right)."""
        if isinstance(expr, Const):
            return self.const(expr.value, line)
        if isinstance(expr, Ref):
            return f"{self.names.lanes[expr.lane]}::{_ident(expr.name)}.get()"
        if isinstance(expr, Unary):
            operand = self.expr(expr.operand, line)
            return f"op_not({operand})" if expr.operator == "not" else f"op_neg({operand})"
        if isinstance(expr, Binary):
            left = self.expr(expr.left, line)
            right = self.expr(expr.right, line)
            if expr.operator == "and":
                return f"Value(truthy({left}) && truthy({right}))"
            if expr.operator == "or":
                return f"Value(truthy({left}) || truthy({right}))"
            function = _OPERATORS[expr.operator]
            if _waits(expr.right) and _waits(expr.left):
                # C++ leaves the order of a function's arguments open: the left operand first
                return f"[&] {{ Value left = {left}; return {function}(left, {right}); }}()"
            return f"{function}({left}, {right})"
        if isinstance(expr, Call):
            return self.call(expr, line)
        raise self.error(f"the generator cannot express {expr!r}", line)  # pragma: no cover

    def call(self, call: Call, line: int) -> str:
        target = call.target
        args = [self.expr(arg, line) for arg in call.args]
        if isinstance(target, FeatureTarget):
            array = f"Value::array({{{', '.join(args)}}})" if args else "Value::array()"
            return f"rt.call(act, {_cstr(target.component)}, {_cstr(target.feature)}, {array})"
        if isinstance(target, LaneTarget):
            ns = self.names.lanes[target.lane]
            start = self.names.nodes[target.lane][self.model.lanes[target.lane].start]
            return f"rt.call_lane(act, {_cstr(target.lane)}, {ns}::walk, {ns}::kNodes, {ns}::{start})"
        if isinstance(target, BuiltinTarget):
            if target.name == "Application.exit":
                return "rt.exit_requested()"
            scale = {"usleep": "1e-6", "msleep": "1e-3"}.get(target.name)
            if scale is None:
                raise self.error(f"unknown builtin {target.name!r}", line)
            return f"rt.sleep(act, {args[0] if args else 'Value(0.0)'}, {scale})"
        raise self.error(f"the generator cannot express the call {call!r}", line)  # pragma: no cover

    def const(self, value: object, line: int) -> str:
        if value is None:
            return "Value()"
        if isinstance(value, bool):
            return "Value(true)" if value else "Value(false)"
        if isinstance(value, int):
            if not _INT64[0] <= value <= _INT64[1]:
                raise self.error(f"the integer {value} does not fit in 64 bits: the generated C++ "
                                 "cannot hold it (the interpreter can)", line)
            if value == _INT64[0]:
                return "Value(INT64_MIN)"
            return f"Value({value})" if abs(value) < 2**31 else f"Value(std::int64_t{{{value}}})"
        if isinstance(value, float):
            if not math.isfinite(value):
                raise self.error(f"the number {value!r} has no JSON form: the generated C++ cannot "
                                 "trace it", line)
            text = repr(value)
            return f"Value({text if ('.' in text or 'e' in text) else text + '.0'})"
        if isinstance(value, str):
            return f"Value({_cstr(value)})"
        raise self.error(f"the generator cannot express the constant {value!r}", line)

    # --- nodes ----------------------------------------------------------------------------------

    def goto(self, target: str) -> str:
        return f"prev = node; node = {self.nodes[target]}; continue;"

    def what(self, node: Node) -> str:
        """The comment naming a node: kind, id, label, file:line."""
        what = f"{node.kind} {node.id}"
        if node.label and node.label != node.id:
            what += f": {node.label}"
        return f"{_comment(what)} ({self.where(node.line)})"

    def function_name(self, node: Node) -> str:
        return f"{'choose' if isinstance(node, DecisionNode) else 'do'}_{self.nodes[node.id][2:]}"

    def function(self, node: Node) -> list[str]:
        """The function holding what a node computes (None for the nodes that only route)."""
        line = node.line
        name = self.function_name(node)
        body: list[str]
        if isinstance(node, ActionNode):
            body = [f"return {self.call(node.call, line)};"]
        elif isinstance(node, DatastoreNode):
            body = [f"Value v = {self.expr(node.value, line)};", f"{_ident(node.name)}.set(v);", "return v;"]
        elif isinstance(node, SendNode):
            payload = "Value()" if node.payload is None else self.expr(node.payload, line)
            body = [f"Value v = {payload};", f"rt.send({_cstr(node.signal)}, v);", "return v;"]
        elif isinstance(node, AcceptNode):
            body = [f"Value v = rt.accept(act, {_cstr(node.signal)});"]
            if node.store is not None:
                body.append(f"{_ident(node.store)}.set(v);")
            body.append("return v;")
        elif isinstance(node, DecisionNode):
            body = []
            for branch in node.branches:
                target = self.nodes[branch.target]
                if branch.guard is None:
                    body.append(f"return {target};  // else")
                else:
                    guard = self.expr(branch.guard, branch.line or line)
                    body.append(f"if (truthy({guard})) return {target};")
            if node.branches[-1].guard is not None:
                body.append("return -1;  // no guard holds and there is no else: this flow stops")
        else:
            return []
        returns = "int" if isinstance(node, DecisionNode) else "Value"
        text = "\n".join(body)
        if "rt." in text:
            body.insert(0, "Runtime& rt = runtime();")
        used = re.search(r"(?<![\w:])act\b", text) is not None
        param = "Activation& act" if used else "Activation& /*act*/"
        return [f"// {self.what(node)}", f"static {returns} {name}({param}) {{",
                *(f"  {line_}" for line_ in body), "}", ""]

    def case(self, node: Node) -> list[str]:
        n = self.nodes[node.id]
        lines = [f"      case {n}:  // {self.what(node)}"]
        lines += [f"        {text}" for text in self.route(node, n)]
        return lines

    def route(self, node: Node, n: str) -> list[str]:
        """What the walk does at a node: run its function, then go on."""
        if isinstance(node, StartNode):
            return [f"act.passed({n});", self.goto(node.next)]
        if isinstance(node, EndNode):
            return [f"act.passed({n});", "return Outcome::Ended;"]
        if isinstance(node, ActionNode | DatastoreNode | SendNode | AcceptNode):
            return [f"act.step({n}, {self.function_name(node)});", self.goto(node.next)]
        if isinstance(node, DecisionNode):
            return [f"node = act.decide({n}, {self.function_name(node)});",
                    "if (node < 0) return Outcome::Stopped;  // no guard holds, no else",
                    f"prev = {n};", "continue;"]
        if isinstance(node, ForkNode):
            targets = ", ".join(self.nodes[t] for t in node.targets)
            return [f"return act.fork({n}, {{{targets}}});  // joined at {node.join}"]
        if isinstance(node, JoinNode):
            incoming = ", ".join(self.nodes[t] for t in node.incoming)
            wait = f"if (!act.arrive({n}, prev, {{{incoming}}})) return Outcome::Stopped;"
            return [wait + "  // not the last flow", f"act.passed({n});", self.goto(node.next)]
        raise self.error(f"the generator cannot express a {node.kind} node", node.line)  # pragma: no cover

    def declarations(self) -> list[str]:
        lane = self.lane
        ns = self.names.lanes[lane.name]
        kind = "virtual lane" if lane.virtual else f"component {lane.component or lane.name}"
        out = [f"// lane {lane.name} ({kind}), {self.where(lane.line)}", f"namespace {ns} {{"]
        enum = ", ".join(self.nodes[node_id] for node_id in _node_order(lane))
        out.append(f"enum : int {{ {enum} }};")
        out.append("extern const NodeInfo kNodes[];")
        out.append("Outcome walk(Activation& act, int node, int prev);")
        for store in lane.datastores:
            writers = sorted(
                (n.line, n.id) for n in lane.nodes.values()
                if (isinstance(n, DatastoreNode) and n.name == store)
                or (isinstance(n, AcceptNode) and n.store == store)
            )
            written = ", ".join(f"{node_id} (line {line})" for line, node_id in writers)
            out.append(f"Datastore {_ident(store)}{{{_cstr(store)}}};  // written by {_comment(written)}")
        out.append(f"}}  // namespace {ns}")
        return out

    def definition(self) -> list[str]:
        lane = self.lane
        ns = self.names.lanes[lane.name]
        order = _node_order(lane)
        out = [f"// lane {lane.name}, {self.where(lane.line)}", f"namespace {ns} {{", "",
               "const NodeInfo kNodes[] = {"]
        for node_id in order:
            node = lane.nodes[node_id]
            out.append(f"    {{{_cstr(node.id)}, {_cstr(node.kind)}, {_cstr(node.label or node.id)}}},")
        out += ["};", "", "// what each node computes"]
        for node_id in order:
            out += self.function(lane.nodes[node_id])
        out += ["// the flows: from each node to the next",
                "Outcome walk(Activation& act, int node, int prev) {",
                "  (void)prev;  // only joins read it", "  for (;;) {", "    switch (node) {"]
        for node_id in order:
            out += self.case(lane.nodes[node_id])
        out += ["      default:", "        return Outcome::Stopped;", "    }", "  }", "}", "",
                f"}}  // namespace {ns}"]
        return out


def _waits(expr: Expr) -> bool:
    """True when evaluating `expr` calls something (a feature, a lane, a sleep)."""
    if isinstance(expr, Call):
        return not (isinstance(expr.target, BuiltinTarget) and expr.target.name == "Application.exit") or any(
            _waits(a) for a in expr.args)
    if isinstance(expr, Unary):
        return _waits(expr.operand)
    if isinstance(expr, Binary):
        return _waits(expr.left) or _waits(expr.right)
    return False


def render_cpp(model: CompiledModel, source: str = "") -> str:
    """The text of `src/model.cpp` for `model` (`source`: how the model was named, for the header)."""
    names = _names(model)
    writers = [_LaneWriter(model, names, model.lanes[name]) for name in sorted(model.lanes)]
    out = [
        f"// The swimlanes of model {_comment(model.name)}, generated by `umlbot generate cpp`"
        + (f" from {_comment(source)}" if source else "") + ".",
        f"// Source hash {model.source_hash}. Do not edit: change the model and generate again.",
        "// Each lane is a namespace: its datastores, its nodes, and `walk`, which runs a flow from a node",
        "// until it ends, stops (a join waiting, a decision without a match) or forks. The runtime",
        "// (runtime/umlbot_runtime.hpp) does MQTT, the trace, the status and the fail-safe stops.",
        "#include <cstdint>",
        "",
        '#include "umlbot_runtime.hpp"',
        "",
        "using namespace umlbot;",
        "",
        "// --- declarations: every lane's nodes and datastores (lanes read each other's) ---",
        "",
    ]
    for writer in writers:
        out += writer.declarations()
        out.append("")
    out += ["// --- the lanes ---", ""]
    for writer in writers:
        out += writer.definition()
        out.append("")
    out += _model_info(model, names)
    return "\n".join(out) + "\n"


def _model_info(model: CompiledModel, names: _Names) -> list[str]:
    stops = [(name, call.feature, call.args) for name, component in sorted(model.components.items())
             for call in component.safe_stop]
    required = sorted(used_components(model) | {name for name, _, _ in stops})
    accepted = sorted({node.signal for lane in model.lanes.values() for node in lane.nodes.values()
                       if isinstance(node, AcceptNode)})
    writer = _LaneWriter(model, names, next(iter(model.lanes.values()))) if model.lanes else None
    out = ["// --- the model: what the runtime needs to run it ---", "",
           "const ModelInfo kModel{",
           f"    {_cstr(model.name)},",
           f"    {_cstr(model.source_hash)},",
           f"    {model.call_timeout_s!r},  // call_timeout_s",
           f"    {heartbeat_period_s(model)!r},  // heartbeat period, s",
           "    {" + ", ".join(_cstr(name) for name in required) + "},  // must be online",
           "    {"]
    for name, feature, args in stops:
        values = ", ".join(writer.const(arg, 0) for arg in args) if writer else ""
        out.append(f"        {{{_cstr(name)}, {_cstr(feature)}, Value::array({{{values}}})}},  // safe stop")
    out.append("    },")
    out.append("    {" + ", ".join(_cstr(name) for name in accepted) + "},  // signals accepted")
    out.append("    {  // component lanes, started at once")
    for name in sorted(n for n, lane in model.lanes.items() if not lane.virtual):
        ns = names.lanes[name]
        start = names.nodes[name][model.lanes[name].start]
        out.append(f"        {{{_cstr(name)}, {ns}::walk, {ns}::kNodes, {ns}::{start}}},")
    out += ["    },", "};", "", "int main(int argc, char** argv) { return run_main(argc, argv, kModel); }"]
    return out


def render_cmake(model: CompiledModel) -> str:
    """The project's CMakeLists.txt."""
    program = program_name(model)
    return f"""# Generated by `umlbot generate cpp` for model {_comment(model.name)}. Build:
#   cmake -S . -B out -G Ninja && cmake --build out
# Needs g++ (C++17), cmake, ninja-build, libmosquitto-dev and nlohmann-json3-dev.
cmake_minimum_required(VERSION 3.16)
project({_ident(model.name)}_orchestrator LANGUAGES CXX)

set(CMAKE_CXX_STANDARD 17)
set(CMAKE_CXX_STANDARD_REQUIRED ON)
set(CMAKE_CXX_EXTENSIONS OFF)
if(NOT CMAKE_BUILD_TYPE)
  set(CMAKE_BUILD_TYPE Release)
endif()

find_package(Threads REQUIRED)
find_package(nlohmann_json 3.2 REQUIRED)
find_path(MOSQUITTO_INCLUDE_DIR mosquitto.h REQUIRED)
find_library(MOSQUITTO_LIBRARY mosquitto REQUIRED)

add_executable({program} src/model.cpp runtime/umlbot_runtime.cpp)
target_include_directories({program} PRIVATE runtime ${{MOSQUITTO_INCLUDE_DIR}})
target_link_libraries({program} PRIVATE nlohmann_json::nlohmann_json ${{MOSQUITTO_LIBRARY}} Threads::Threads)
target_compile_options({program} PRIVATE -Wall -Wextra)
# libstdc++ linked in: only the parts the program uses are mapped, not the whole shared library
# (~1.4 MB less resident memory); the program then needs only libmosquitto at run time
option(UMLBOT_STATIC_LIBSTDCXX "Link libstdc++ and libgcc statically" ON)
if(UMLBOT_STATIC_LIBSTDCXX AND CMAKE_CXX_COMPILER_ID MATCHES "GNU|Clang")
  target_link_options({program} PRIVATE -static-libstdc++ -static-libgcc -Wl,--as-needed -Wl,--gc-sections)
endif()
install(TARGETS {program} RUNTIME DESTINATION bin)
"""


def project_files(model: CompiledModel, source: str = "") -> dict[str, bytes]:
    """Every file of the project, relative path → bytes (sorted, deterministic)."""
    files = {
        "CMakeLists.txt": render_cmake(model).encode("utf-8"),
        "src/model.cpp": render_cpp(model, source).encode("utf-8"),
    }
    runtime = resources.files("umlbot.codegen") / "runtime"
    for name in RUNTIME_FILES:
        files[f"runtime/{name}"] = (runtime / name).read_bytes()
    return dict(sorted(files.items()))


def generate_cpp(model: CompiledModel, out_dir: str | Path, source: str = "") -> list[Path]:
    """Write the project into `out_dir` (made as needed); files already equal are left untouched
    (so a build after generating again recompiles only what changed). Returns the files written."""
    root = Path(out_dir)
    written: list[Path] = []
    for relative, data in project_files(model, source).items():
        path = root / relative
        if path.exists() and path.read_bytes() == data:
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        written.append(path)
    return written
