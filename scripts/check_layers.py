#!/usr/bin/env python3
"""Check that umlbot's packages stack as docs/architecture.md draws them.

Reads every `import` of the product code (module level, inside functions and under
`TYPE_CHECKING` alike) and fails, naming the file and line, on:

- an import that runs **up a floor** (a lower floor importing a higher one);
- an **import circle** between modules (A imports B imports … imports A), however it is hidden;
- an import that goes **around a front door**: a package whose `__init__` lists its public names
  in `__all__` is used through that `__init__` by every module outside the package;
- a module that is on **no floor**.

Only the product code (`umlbot/`) is read; tests and benchmarks may reach anything. Exit status
0 when all holds, 1 with one `file:line: message` a problem otherwise.

    python scripts/check_layers.py [--graph]   # --graph prints the floors and their modules
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "umlbot"

#: The floors from the ground up: a module may import its own floor and the floors below it.
#: A module belongs to the first floor with a prefix that names it or a package holding it.
FLOORS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("ground", ("umlbot.base", "umlbot.testing")),
    ("compiler", ("umlbot.compiler",)),
    ("bus", ("umlbot.services.bus",)),
    ("services", ("umlbot.services",)),
    ("apps", ("umlbot.monitor", "umlbot.sim", "umlbot.codegen", "umlbot.record", "umlbot.fleet")),
    ("studio", ("umlbot.studio",)),
    ("cli", ("umlbot.commands", "umlbot.cli", "umlbot.__main__")),
)
#: Imports that are allowed although they run up: none today. (importer, imported) module names.
EXCEPTIONS: frozenset[tuple[str, str]] = frozenset()


@dataclass(frozen=True)
class Import:
    """One import statement's edge: `importer` imports `imported` at `path:line`."""

    importer: str
    imported: str
    path: Path
    line: int


def module_files(root: Path) -> dict[str, Path]:
    """Every module of the package by its dotted name (a package by its `__init__`)."""
    modules: dict[str, Path] = {}
    for path in sorted((root / PACKAGE).rglob("*.py")):
        if "node_modules" in path.parts:
            continue
        parts = path.relative_to(root).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        modules[name] = path
    return modules


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The module `name` names, or the nearest package holding it; None outside the package."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def imports_of(module: str, path: Path, modules: dict[str, Path], doors: set[str]) -> list[Import]:
    """The package-internal imports of one module, each resolved to a module of the package.

    `from P import name` where P has a front door (`__all__`) goes through that door: an edge to
    P, whether `name` is a submodule the door loads (lazily, perhaps) or a name it defines."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: list[Import] = []
    for node in ast.walk(tree):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                parts = parts[: len(parts) - node.level + 1]
                base = ".".join([*parts, base] if base else parts)
            # `from a.b import c`: c is the module a.b.c when there is one, else a name of a.b
            for alias in node.names:
                candidate = f"{base}.{alias.name}"
                targets.append(candidate if candidate in modules and base not in doors else base)
        if not isinstance(node, ast.Import | ast.ImportFrom):
            continue
        for target in targets:
            resolved = _resolve(target, modules)
            if resolved is not None and resolved != module:
                found.append(Import(module, resolved, path, node.lineno))
    return found


def floor_of(module: str) -> int | None:
    """The index of the module's floor in FLOORS (None: on no floor). The package's own `__init__`
    (its version and error roots) is on the ground floor: everything may import it."""
    if module == PACKAGE:
        return 0
    for index, (_, prefixes) in enumerate(FLOORS):
        for prefix in prefixes:
            if module == prefix or module.startswith(prefix + "."):
                return index
    return None


def _front_door(module: str, modules: dict[str, Path], doors: set[str]) -> str | None:
    """The innermost package with a front door (`__all__`) that holds `module` below its __init__."""
    parts = module.split(".")
    for cut in range(len(parts) - 1, 0, -1):
        package = ".".join(parts[:cut])
        if package in doors:
            return package
    return None


def has_front_door(path: Path) -> bool:
    """A package `__init__` that lists its public names in `__all__`."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return any(
        isinstance(node, ast.Assign)
        and any(isinstance(target, ast.Name) and target.id == "__all__" for target in node.targets)
        for node in tree.body
    )


def cycles(edges: dict[str, list[Import]]) -> list[list[str]]:
    """The import circles: strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0

    def visit(start: str) -> None:
        nonlocal counter
        # iterative depth-first search: (node, iterator over its successors)
        work = [(start, iter(sorted({e.imported for e in edges.get(start, [])})))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, successors = work[-1]
            for succ in successors:
                if succ not in index:
                    index[succ] = low[succ] = counter
                    counter += 1
                    stack.append(succ)
                    on_stack.add(succ)
                    work.append((succ, iter(sorted({e.imported for e in edges.get(succ, [])}))))
                    break
                if succ in on_stack:
                    low[node] = min(low[node], index[succ])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    component: list[str] = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))

    for module in sorted(edges):
        if module not in index:
            visit(module)
    return found


def check(root: Path) -> list[str]:
    """Every problem as `file:line: message`, in file order."""
    modules = module_files(root)
    doors = {name for name, path in modules.items() if path.name == "__init__.py" and has_front_door(path)}
    edges: dict[str, list[Import]] = defaultdict(list)
    for module, path in modules.items():
        edges[module].extend(imports_of(module, path, modules, doors))
    problems: list[tuple[Path, int, str]] = []
    for module, path in modules.items():
        if floor_of(module) is None:
            problems.append((path, 1, f"{module} is on no floor: add its package to FLOORS"))
    for module in modules:
        for edge in edges[module]:
            low, high = floor_of(edge.importer), floor_of(edge.imported)
            upward = low is not None and high is not None and high > low
            if upward and (edge.importer, edge.imported) not in EXCEPTIONS:
                assert low is not None and high is not None
                problems.append((edge.path, edge.line,
                                 f"{edge.importer} ({FLOORS[low][0]}) imports {edge.imported}, "
                                 f"a floor up ({FLOORS[high][0]})"))
            door = _front_door(edge.imported, modules, doors)
            if door is not None and not (edge.importer == door or edge.importer.startswith(door + ".")):
                problems.append((edge.path, edge.line,
                                 f"{edge.importer} imports {edge.imported} around the front door of "
                                 f"{door}: import it from {door}"))
    for circle in cycles(edges):
        members = set(circle)
        for module in circle:
            for edge in edges[module]:
                if edge.imported in members:
                    problems.append((edge.path, edge.line,
                                     f"import circle: {edge.importer} imports {edge.imported} "
                                     f"(circle of {', '.join(circle)})"))
    problems.sort(key=lambda p: (str(p[0]), p[1], p[2]))
    return [f"{path.relative_to(root)}:{line}: {message}" for path, line, message in problems]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--graph", action="store_true", help="print the floors and their modules")
    parser.add_argument("--root", type=Path, default=ROOT, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.graph:
        modules = module_files(args.root)
        for index, (name, _) in enumerate(FLOORS):
            members = sorted(m for m in modules if floor_of(m) == index)
            print(f"{name} ({len(members)} modules)")
            for member in members:
                print(f"  {member}")
    problems = check(args.root)
    for problem in problems:
        print(problem)
    if problems:
        print(f"check_layers: {len(problems)} problem(s)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
