"""The package's import graph: layers that point one way (issue 29).

Read from the source with ``ast`` (nothing is imported): every module of ``python/hcvt``
belongs to one layer of :data:`LAYERS`; it may import its own layer and those below, never
one above; no two modules import each other, directly or around a circle (type-only
imports count: they are arrows a reader follows too); no module takes another's private
name; and no import statement stands inside a function (third-party packages imported on
first use go through :func:`hcvt.lazy.load`).
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "hcvt"

#: Bottom to top. A module is in the layer of its longest listed prefix.
LAYERS: list[tuple[str, ...]] = [
    ("hcvt.core_results", "hcvt._core", "hcvt.errors", "hcvt.lazy"),
    ("hcvt.density", "hcvt.geometry", "hcvt.draw"),
    ("hcvt.mesh",),
    ("hcvt.io",),
    ("hcvt.diagram",),
    ("hcvt.optimise", "hcvt.transport"),
    ("hcvt.seeding",),
    ("hcvt.surface",),
    ("hcvt.distributed",),
    ("hcvt.api",),
    ("hcvt.export", "hcvt.plot", "hcvt.accessor"),
    ("hcvt",),  # the public face: __init__'s names
    ("hcvt.cli", "hcvt.experiments"),  # its users
]


def modules() -> dict[str, Path]:
    """Every module of the package by dotted name (packages by their ``__init__``)."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    out["hcvt._core"] = PACKAGE / "_core.pyi"
    return out


MODULES = modules()


def layer(module: str) -> int:
    best, rank = -1, None
    for i, names in enumerate(LAYERS):
        for name in names:
            if (module == name or module.startswith(name + ".")) and len(name) > best:
                best, rank = len(name), i
    if rank is None:
        raise AssertionError(f"{module} is in no layer of tests/test_layers.py")
    return rank


def _resolve(name: str) -> str | None:
    """The package module that ``name`` (a module or a name in one) comes from."""
    while name and name not in MODULES:
        name = name.rpartition(".")[0]
    return name or None


def _is_type_checking(node: ast.If) -> bool:
    return isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING"


def _imports(tree: ast.Module) -> Iterator[tuple[ast.Import | ast.ImportFrom, bool]]:
    """Every import statement, and whether it stands at module level (or under a
    module-level ``if TYPE_CHECKING:``)."""
    top = set()
    for node in tree.body:
        if isinstance(node, ast.If) and _is_type_checking(node):
            top.update(id(n) for n in node.body)
        top.add(id(node))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import | ast.ImportFrom):
            yield node, id(node) in top


def edges(module: str) -> Iterator[tuple[str, str, ast.stmt]]:
    """(imported package module, names taken from it, the statement) for ``module``."""
    path = MODULES[module]
    if path.suffix == ".pyi":
        return
    tree = ast.parse(path.read_text())
    for node, _ in _imports(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if (target := _resolve(alias.name)) and alias.name.startswith("hcvt"):
                    yield target, "", node
        elif node.module and node.module.startswith("hcvt") and node.level == 0:
            for alias in node.names:
                full = f"{node.module}.{alias.name}"
                if full in MODULES:
                    yield full, "", node
                elif target := _resolve(node.module):
                    yield target, alias.name, node


GRAPH = {m: {t for t, _, _ in edges(m) if t != m} for m in MODULES}


def test_every_module_has_a_layer():
    for module in MODULES:
        layer(module)


@pytest.mark.parametrize("module", sorted(MODULES))
def test_imports_point_down(module):
    up = [t for t in GRAPH[module] if layer(t) > layer(module)]
    assert not up, f"{module} (layer {layer(module)}) imports a higher layer: {up}"


def test_no_cycles():
    # Tarjan's strongly connected components, iteratively small enough to recurse.
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(GRAPH[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(GRAPH):
        if v not in index:
            visit(v)
    # A package's __init__ re-exports its modules, which import their siblings by full
    # path through it: that is not a circle of code, so packages are left out.
    packages = {m for m, p in MODULES.items() if p.name == "__init__.py"}
    cycles = [c for c in cycles if not set(c) & packages or len(set(c) - packages) > 1]
    assert not cycles, f"import cycles: {cycles}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_private_name_across_modules(module):
    taken = [
        f"{target}.{name}"
        for target, name, _ in edges(module)
        if name.startswith("_") and target != module
    ]
    if MODULES[module].suffix == ".py":
        tree = ast.parse(MODULES[module].read_text())
        aliases = {
            (a.asname or a.name.rpartition(".")[2]): f"{n.module}.{a.name}"
            for n in ast.walk(tree)
            if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith("hcvt")
            for a in n.names
            if f"{n.module}.{a.name}" in MODULES and a.name != "_core"
        }
        taken += [
            f"{aliases[n.value.id]}.{n.attr}"
            for n in ast.walk(tree)
            if isinstance(n, ast.Attribute)
            and isinstance(n.value, ast.Name)
            and n.value.id in aliases
            and n.attr.startswith("_")
            and not n.attr.startswith("__")
        ]
    assert not taken, f"{module} takes private names of other modules: {taken}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_import_inside_a_function(module):
    if MODULES[module].suffix != ".py":
        return
    tree = ast.parse(MODULES[module].read_text())
    inner = [ast.unparse(node) for node, top in _imports(tree) if not top]
    assert not inner, f"{module} imports inside a function (use hcvt.lazy.load): {inner}"


def test_the_check_sees_an_upward_import():
    # The graph is read, not assumed: the top imports the bottom, never the reverse.
    assert "hcvt.errors" in GRAPH["hcvt.geometry.domain"]
    assert layer("hcvt.cli") > layer("hcvt.diagram") > layer("hcvt.geometry.domain")
