"""The house's layout: parley_core's imports form no cycle, the input stages import no
evaluator, and no module outgrows one role (400 lines, the numba kernels excepted)."""

from __future__ import annotations

import ast
from pathlib import Path

import parley_core

PACKAGE = Path(parley_core.__file__).parent
LONGEST = 400
EXEMPT = {"parley_core.quotient.kernels"}  # one role: the compiled loops, each documented
INPUT_STAGES = ("parley_core.model", "parley_core.family.augment", "parley_core.family.usermodel", "parley_core.prism")
EVALUATION = ("parley_core.evaluate", "parley_core.quotient", "parley_core.search", "parley_core.pipeline")


def _modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        found[name] = path
    return found


def _graph() -> dict[str, set[str]]:
    """Module -> the parley_core modules it imports, anywhere in it (functions included),
    as written: importing a sub-module is an edge to it, not to its parent packages."""
    modules = _modules()
    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, path in modules.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text())):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    base = ".".join(
                        package.split(".")[: len(package.split(".")) - node.level + 1] + ([base] if base else [])
                    )
                targets = [
                    f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base for alias in node.names
                ]
            for target in targets:
                if target in modules and target != name:
                    graph[name].add(target)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def _reach(graph: dict[str, set[str]], start: str) -> set[str]:
    seen, todo = set(), [start]
    while todo:
        for w in graph[todo.pop()]:
            if w not in seen:
                seen.add(w)
                todo.append(w)
    return seen


def test_the_import_graph_has_no_cycle():
    graph = _graph()
    assert graph["parley_core.pipeline"] >= {
        "parley_core.family.augment",
        "parley_core.search",
    }  # the walk sees imports
    assert _cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_the_input_stages_import_no_evaluator():
    graph = _graph()
    for module in graph:
        if module.startswith(INPUT_STAGES):
            reached = _reach(graph, module)
            assert not [m for m in reached if m.startswith(EVALUATION)], module


def test_no_module_is_longer_than_one_role_needs():
    long = {
        name: len(path.read_text().splitlines())
        for name, path in _modules().items()
        if name not in EXEMPT and len(path.read_text().splitlines()) > LONGEST
    }
    assert long == {}
