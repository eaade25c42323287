"""The engine's modules import one another without a circle (issue 29): every import counts,
at the top of a module or inside a function, at the granularity of modules (importing
``photic.scene.checks`` is an edge to that module, not to the ``photic.scene`` package). A
circle is reported with its modules."""
from __future__ import annotations

import ast
from pathlib import Path

import photic

ROOT = Path(photic.__file__).resolve().parent
ADDON = Path(__file__).resolve().parents[1] / "blender_addon"


def modules(root: Path = ROOT, package: str = "photic") -> dict[str, Path]:
    out = {}
    for f in root.rglob("*.py"):
        parts = f.relative_to(root).with_suffix("").parts
        name = ".".join((package,) + parts)
        out[name.removesuffix(".__init__")] = f
    return out


def import_graph(root: Path = ROOT, package: str = "photic") -> dict[str, set[str]]:
    mods = modules(root, package)
    graph = {m: set() for m in mods}
    for m, f in mods.items():
        package = m if f.name == "__init__.py" else m.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(f.read_text())):
            targets = []
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([base] if base else []))
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            graph[m].update(t for t in targets if t in mods and t != m)
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_engine_has_no_import_circles():
    graph = import_graph()
    assert "photic.scene.checks" in graph and "photic.scene.model" in graph
    assert circles(graph) == []


def test_the_add_on_has_no_import_circles():
    """(export and natural_waters imported each other; what both need is export_values.)"""
    graph = import_graph(ADDON, "photic_blender")
    assert "photic_blender.export_values" in graph
    assert circles(graph) == []


def test_the_checker_finds_a_circle():
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
