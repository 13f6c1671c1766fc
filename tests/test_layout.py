"""The house's layout: parley_core's rooms sit in layers whose imports point one way (down),
with no cycle; the input stages import no evaluator; and no function outgrows one screen
(:data:`LONGEST` lines of body, the compiled numba kernels and a short list of named
exceptions excepted)."""

from __future__ import annotations

import ast
from pathlib import Path

import parley_core

PACKAGE = Path(parley_core.__file__).parent

LAYERS = [  # a module may import its own layer's earlier rooms and anything in an earlier layer
    ["errors", "files", "progress", "tables", "docstrings", "model", "constraints", "boxes", "metrics"],  # 1 base
    ["prism", "urc", "views", "plugin"],  # 2 languages and contracts
    ["quotient", "evaluate", "family"],  # 3 engine
    ["search", "verify", "optimality", "robust"],  # 4 methods
    ["pipeline"],  # 5 one run
    ["rundir", "experiment", "simulation", "testing"],  # 6 products
    ["api", "cli", "guard", "__main__"],  # 7 faces
]
TOP_LEVEL_MODULES = 15
"""At most this many modules at the top of parley_core besides its packages."""

LONGEST = 80
"""Lines of a function's body (after its docstring)."""
LONG = {
    # function -> why it is longer than LONGEST; an entry that no longer needs to be here fails the test
    "parley_core.rundir.page.render": "one Bokeh document, built view by view; its parts share the data sources",
    "parley_core.simulation.drift.simulate_drift": "one mission loop whose state (beliefs, switches) is per episode",
    "parley_core.simulation.storm.simulate": "one sampling loop over Storm's simulator, per objective kind",
    "parley_core.rundir.policy_grid.grids": "the grid figures and their slice menus share one filter",
    "parley_core.simulation.validate.validate": "checks a run directory against its case study, then runs the jobs",
    "parley_core.search.polish.polish": "one polishing loop: score, expand, evaluate, merge",
    "parley_core.quotient.bounds.RelaxedObjectives.__init__": "the relaxation's arrays, built once per family",
}
INPUT_STAGES = (
    "parley_core.model",
    "parley_core.family.augment",
    "parley_core.family.usermodel",
    "parley_core.prism",
)
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


def _rank(module: str) -> tuple[int, int]:
    if module == "parley_core":  # the package's face: layers 1-2 only, so `import parley_core` stays light
        return 1, len(LAYERS[1])
    top = module.removeprefix("parley_core.").split(".")[0]
    for i, layer in enumerate(LAYERS):
        if top in layer:
            return i, layer.index(top)
    raise AssertionError(f"{module} is in no layer: add its room to LAYERS in tests/test_layout.py")


def test_the_import_graph_has_no_cycle():
    graph = _graph()
    assert graph["parley_core.pipeline"] >= {
        "parley_core.family.prepare",
        "parley_core.search",
    }  # the walk sees imports
    assert _cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_imports_point_down_the_layers():
    upward = [
        f"{module} -> {target}"
        for module, targets in sorted(_graph().items())
        for target in sorted(targets)
        if module.split(".")[1:2] != target.split(".")[1:2] and not _rank(target) < _rank(module)
    ]
    assert upward == []


def test_the_layer_rule_sees_an_upward_import():
    assert _rank("parley_core.pipeline") > _rank("parley_core.search.run")
    assert not _rank("parley_core.api.runs") < _rank("parley_core.rundir.write")  # the writer may not import the API
    assert _rank("parley_core") < _rank("parley_core.quotient")  # the package's face stays below the engine


def test_every_room_is_in_a_layer_and_the_top_level_is_small():
    rooms = {p.stem for p in PACKAGE.glob("*.py") if p.stem != "__init__"} | {
        p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()
    }
    assert rooms - {room for layer in LAYERS for room in layer} == set()
    assert len([p for p in PACKAGE.glob("*.py") if p.stem != "__init__"]) <= TOP_LEVEL_MODULES


def test_the_input_stages_import_no_evaluator():
    graph = _graph()
    for module in graph:
        if module.startswith(INPUT_STAGES):
            reached = _reach(graph, module)
            assert not [m for m in reached if m.startswith(EVALUATION)], module


def _functions():
    """(qualified name, lines of body after the docstring, whether numba compiles it) per function."""
    for module, path in _modules().items():
        tree = ast.parse(path.read_text())
        todo: list[tuple[str, ast.AST]] = [(module, tree)]
        while todo:
            prefix, node = todo.pop()
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.ClassDef):
                    todo.append((f"{prefix}.{child.name}", child))
                elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    body = child.body
                    if isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                        body = body[1:] or body
                    compiled = any("njit" in ast.unparse(d) for d in child.decorator_list)
                    yield f"{prefix}.{child.name}", child.end_lineno - body[0].lineno + 1, compiled
                    todo.append((f"{prefix}.{child.name}", child))


def test_no_function_is_longer_than_one_screen():
    long = {name for name, lines, compiled in _functions() if lines > LONGEST and not compiled}
    assert long - set(LONG) == set(), "split these, or name them in LONG with the reason"
    assert set(LONG) - long == set(), "these are short now: take them out of LONG"
