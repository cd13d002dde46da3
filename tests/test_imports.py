"""The import graph of warp_lamp/: no circle among its modules, and the benchmarks out of the library's way.

The graph is read from the source with :mod:`ast`, not by importing. Its edges are the imports a module makes when
it is imported: the statements at module level and in class bodies, and those under ``if``/``try``/``with`` there.
An import inside a function runs only when the function does, so it cannot break an import, but a circle through
one is the same knot for a reader; the second test holds the whole graph, function-local imports included, to the
same rule. ``import a.b.c`` and ``from a.b import c`` (``c`` a submodule) are edges to ``a.b.c``; ``from a.b import
name`` is an edge to the package ``a.b`` (its ``__init__``). A package's ``__init__`` importing its own submodules
is how a package re-exports; the edge from a submodule to its parent package, which Python imports first, is not
counted (it would make every re-exporting package a circle).
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "warp_lamp"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _imports(tree: ast.AST, *, function_local: bool) -> list[ast.Import | ast.ImportFrom]:
    """The import statements of a module; those inside functions only with ``function_local``."""
    found = []

    def walk(node):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.Import | ast.ImportFrom):
                found.append(child)
            elif isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda):
                if function_local:
                    walk(child)
            else:
                walk(child)

    walk(tree)
    return found


def import_graph(*, function_local: bool) -> dict[str, set[str]]:
    """Edges module -> the warp_lamp modules it imports."""
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        edges = set()
        for node in _imports(ast.parse(path.read_text(), filename=str(path)), function_local=function_local):
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            else:
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")
                    anchor = anchor[: len(anchor) - (node.level - 1)]
                    base = ".".join([*anchor, base] if base else anchor)
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
            for target in targets:
                while target and target not in modules:  # import a.b.c where only a.b is ours: a.b
                    target = target.rpartition(".")[0]
                if target and target != name and not name.startswith(target + "."):
                    edges.add(target)
        graph[name] = edges
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One circle of the graph as a list of modules (first repeated last), or None."""
    state = dict.fromkeys(graph, 0)  # 0 new, 1 on the path, 2 done
    path: list[str] = []

    def visit(node):
        state[node] = 1
        path.append(node)
        for nxt in sorted(graph[node]):
            if state[nxt] == 1:
                return [*path[path.index(nxt) :], nxt]
            if state[nxt] == 0 and (cycle := visit(nxt)):
                return cycle
        path.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if state[node] == 0 and (cycle := visit(node)):
            return cycle
    return None


def test_find_cycle_finds_a_planted_circle():
    """The cycle finder is not vacuous: it reports a three-module circle and passes a chain."""
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_graph_sees_the_library():
    """The parser reads real edges: the lamp imports its kernels and the benchmark's speed module its modes."""
    graph = import_graph(function_local=False)
    assert "warp_lamp.kernels.lamp" in graph["warp_lamp.lamp"]
    assert "warp_lamp.bench.modes" in graph["warp_lamp.bench.speed"]
    assert "warp_lamp.bench.common" in graph["warp_lamp.bench.modes"]


@pytest.mark.parametrize("function_local", [False, True], ids=["module-level", "with-function-local"])
def test_no_import_circle(function_local):
    """No circle among warp_lamp's modules, neither at import time nor through imports inside functions."""
    assert find_cycle(import_graph(function_local=function_local)) is None


def test_library_does_not_import_benchmarks_and_kernels_import_nothing_above():
    """Only the command line reaches warp_lamp.bench; warp_lamp/kernels/ imports no module above it."""
    graph = import_graph(function_local=True)
    for name, edges in graph.items():
        if not name.startswith("warp_lamp.bench") and name != "warp_lamp.cli":
            assert not any(e.startswith("warp_lamp.bench") for e in edges), name
        if name.startswith("warp_lamp.kernels"):
            assert all(e.startswith("warp_lamp.kernels") for e in edges), (name, edges)
