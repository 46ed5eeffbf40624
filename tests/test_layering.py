"""The Blender package imports one way: down the layer list of docs/architecture.md.

Reads the package's own source with ``ast`` (nothing is imported, so this runs without Blender):

* every module of ``addon/nfield/blender`` sits in exactly one layer of the table in docs/architecture.md,
  and every module the table names exists;
* a module-level import of a sibling module points to the same layer or a lower one;
* no sibling module is imported inside a function (that would hide an upward dependency from the check);
* the import graph (all imports, wherever they are) has no cycle;
* ``nfield.core`` imports neither ``bpy`` nor the Blender layer.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

# Reads sources and docs/architecture.md, runs no native code: left out of the sanitizer job (whose copy of
# tests/ has no docs beside it).
pytestmark = pytest.mark.no_sanitizer
ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "addon" / "nfield" / "blender"
CORE = ROOT / "addon" / "nfield" / "core"
DOC = ROOT / "docs" / "architecture.md"
DOTTED = "nfield.blender"

#: a row of the layer table: "| 3 | `design` | ... |"
LAYER_ROW = re.compile(r"^\|\s*(\d+)\s*\|([^|]*)\|")


def layer_table() -> dict[str, int]:
    """Module name -> layer number, from the table under the heading "Blender layer: import layers"."""
    text = DOC.read_text()
    section = text.split("## Blender layer: import layers", 1)
    assert len(section) == 2, f"{DOC} has no '## Blender layer: import layers' section"
    layers: dict[str, int] = {}
    for line in section[1].split("\n## ", 1)[0].splitlines():
        m = LAYER_ROW.match(line)
        if not m:
            continue
        for name in re.findall(r"`([a-z_]+)`", m.group(2)):
            assert name not in layers, f"module {name} is listed in layers {layers[name]} and {m.group(1)}"
            layers[name] = int(m.group(1))
    assert layers, "the layer table is empty"
    return layers


def modules() -> dict[str, ast.Module]:
    return {p.stem: ast.parse(p.read_text(), filename=str(p)) for p in sorted(PACKAGE.glob("*.py"))}


def _sibling_targets(node, names: set[str]) -> list[str]:
    """Sibling modules an Import / ImportFrom node refers to."""
    out: list[str] = []
    if isinstance(node, ast.ImportFrom):
        base = node.module or ""
        if node.level == 1:
            out = [base.split(".")[0]] if base else [a.name for a in node.names]
        elif node.level == 0 and (base == DOTTED or base.startswith(DOTTED + ".")):
            rest = base[len(DOTTED):].lstrip(".")
            out = [rest.split(".")[0]] if rest else [a.name for a in node.names]
    elif isinstance(node, ast.Import):
        out = [a.name[len(DOTTED) + 1:].split(".")[0] for a in node.names if a.name.startswith(DOTTED + ".")]
    return [t for t in out if t in names]


def imports(tree: ast.Module, names: set[str]) -> tuple[list[tuple[int, str]], list[tuple[int, str]]]:
    """(module-level imports, imports inside functions) of siblings, as (line, module) pairs. Class bodies
    run at import time: their imports count as module-level."""
    top: list[tuple[int, str]] = []
    inner: list[tuple[int, str]] = []

    def visit(node, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                (inner if in_function else top).extend((child.lineno, t) for t in _sibling_targets(child, names))
            visit(child, in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)))

    visit(tree, False)
    return top, inner


def test_every_module_has_a_layer():
    layers, mods = layer_table(), modules()
    missing = sorted(set(mods) - set(layers))
    assert not missing, f"modules not in the layer table of {DOC.name}: {missing}"
    ghosts = sorted(set(layers) - set(mods))
    assert not ghosts, f"the layer table of {DOC.name} names modules that do not exist: {ghosts}"


def test_module_level_imports_point_down():
    layers, mods = layer_table(), modules()
    upward = []
    for name, tree in mods.items():
        top, _ = imports(tree, set(mods))
        for line, target in top:
            if target != name and layers[target] > layers[name]:
                upward.append(f"{name}.py:{line} (layer {layers[name]}) imports {target} (layer {layers[target]})")
    assert not upward, "imports pointing up the layer list:\n" + "\n".join(upward)


def test_no_sibling_imports_inside_functions():
    mods = modules()
    hidden = [f"{name}.py:{line} imports {target} inside a function"
              for name, tree in mods.items() for line, target in imports(tree, set(mods))[1]]
    assert not hidden, "\n".join(hidden)


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(edges[v]):
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

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles():
    mods = modules()
    edges = {}
    for name, tree in mods.items():
        top, inner = imports(tree, set(mods))
        edges[name] = {t for _, t in top + inner if t != name}
    assert not _cycles(edges), f"import cycles in {DOTTED}: {_cycles(edges)}"


def test_cycle_finder_finds_a_cycle():
    """The check above can fail: a three-module loop and a self-contained pair are found, a chain is not."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": {"a"}, "c": {"a"}}) == [["a", "b"]]
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_core_never_imports_blender():
    bad = []
    for p in sorted(CORE.rglob("*.py")):
        for node in ast.walk(ast.parse(p.read_text(), filename=str(p))):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [("." * node.level) + (node.module or "")]
            for n in names:
                if n.split(".")[0] in ("bpy", "bmesh", "mathutils", "gpu") or "blender" in n:
                    bad.append(f"{p.relative_to(ROOT)}:{node.lineno} imports {n}")
    assert not bad, "\n".join(bad)
