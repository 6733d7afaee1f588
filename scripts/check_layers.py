"""Check chekhov's layering: no import cycle between its modules and no import pointing up.

    python scripts/check_layers.py            # exit status 1 and one line per problem

Every ``import`` / ``from … import`` in ``src/chekhov`` counts, those inside functions too (a
cycle through a function-level import still ties the two modules together; only the moment it
bites differs), and those under ``if TYPE_CHECKING:`` too (two modules that need each other's
types are one concept split in two: move the shared type below both).
``from chekhov.pkg import name`` counts as an import of the submodule
``chekhov.pkg.name`` when that is a module, else of the package ``chekhov.pkg``. Importing a
submodule is not counted as importing its package's ``__init__``.

Layers (docs/architecture.md), lowest first; a module may import from its own layer or below:

    0  top-level modules (errors, atomic, paths, trajectory, timing, …), robot/, scene/
    1  collision/
    2  world.py, cases.py (and its private modules, _case_*.py)
    3  trajopt/, roadmap/
    4  planners/
    5  execute/ (the reactive executive)
    6  bench/, viewer/ (and neither imports the other)
    7  cli/
    8  chekhov/__init__.py (the flat public API)
"""

from __future__ import annotations

import ast
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = "chekhov"
# first component under chekhov (a subpackage or a top-level module) -> layer
LAYERS = {"collision": 1, "world": 2, "cases": 2, "_case_file": 2, "_case_sampling": 2,
          "_case_tasks": 2, "_case_generate": 2, "trajopt": 3, "roadmap": 3, "planners": 4,
          "execute": 5, "bench": 6, "viewer": 6, "cli": 7}
# same layer, yet neither may import the other
SIDEWAYS = {("bench", "viewer"), ("viewer", "bench")}


def module_name(path: Path, src: Path = SRC) -> str:
    """``src/chekhov/bench/cases.py`` -> ``chekhov.bench.cases`` (``__init__`` -> package)."""
    parts = list(path.relative_to(src).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules(src: Path = SRC) -> dict[str, Path]:
    """Every module of the package: dotted name -> file."""
    return {module_name(p, src): p for p in sorted((src / PACKAGE).rglob("*.py"))}


def _resolve_from(node: ast.ImportFrom, importer: str, is_package: bool) -> str:
    """The absolute module a ``from`` import names (relative imports resolved)."""
    if node.level == 0:
        return node.module or ""
    base = importer.split(".")
    base = base if is_package else base[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


class Import(NamedTuple):
    """One import of a chekhov module: what, on which line, and whether only for typing."""

    target: str
    line: int
    type_only: bool


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def _import_nodes(node: ast.AST, type_only: bool = False
                  ) -> Iterator[tuple[ast.Import | ast.ImportFrom, bool]]:
    """Every import statement under ``node`` (functions included), with whether it sits in
    an ``if TYPE_CHECKING:`` body."""
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.Import | ast.ImportFrom):
            yield child, type_only
        elif isinstance(child, ast.If) and _is_type_checking(child):
            for stmt in child.body:
                yield from _import_nodes(ast.Module(body=[stmt], type_ignores=[]), True)
            for stmt in child.orelse:
                yield from _import_nodes(ast.Module(body=[stmt], type_ignores=[]), type_only)
        else:
            yield from _import_nodes(child, type_only)


def imports_of(name: str, path: Path, known: set[str]) -> list[Import]:
    """Every import of another chekhov module in ``path``, functions included; one entry per
    (target, line)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    out: dict[tuple[str, int], Import] = {}
    for node, type_only in _import_nodes(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        else:
            base = _resolve_from(node, name, path.name == "__init__.py")
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base
                       for a in node.names]
        for t in targets:
            if (t == PACKAGE or t.startswith(PACKAGE + ".")) and t != name:
                out.setdefault((t, node.lineno), Import(t, node.lineno, type_only))
    return list(out.values())


def component(module: str) -> str:
    """``chekhov.bench.cases`` -> ``bench``; the package itself -> ``""``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def layer(module: str) -> int:
    """The layer of a module (see the module docstring)."""
    if module == PACKAGE:
        return 8
    return LAYERS.get(component(module), 0)


def upward_imports(graph: dict[str, list[Import]], files: dict[str, Path]
                   ) -> list[str]:
    """One line per import that points to a higher layer or sideways between bench and
    viewer."""
    out = []
    for mod, imports in graph.items():
        for imp in imports:
            up = layer(imp.target) > layer(mod)
            if up or (component(mod), component(imp.target)) in SIDEWAYS:
                out.append(f"{files[mod]}:{imp.line}: {'upward' if up else 'sideways'} import: "
                           f"{mod} (layer {layer(mod)}) imports {imp.target} "
                           f"(layer {layer(imp.target)})")
    return out


def cycles(graph: dict[str, list[Import]]) -> list[list[str]]:
    """The import cycles: strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted({i.target for i in graph.get(v, [])}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def problems(src: Path = SRC) -> list[str]:
    """Every cycle and upward import, one line each (empty when the layering holds)."""
    files = modules(src)
    known = set(files)
    graph = {m: [i for i in imports_of(m, p, known) if i.target in known]
             for m, p in files.items()}
    out = upward_imports(graph, files)
    out += [f"import cycle: {' <-> '.join(c)}" for c in cycles(graph)]
    return out


def main() -> int:
    sys.setrecursionlimit(10_000)
    found = problems()
    for line in found:
        print(line)
    if found:
        print(f"{len(found)} layering problem(s)", file=sys.stderr)
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main())
