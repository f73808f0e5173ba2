# SPDX-License-Identifier: GPL-3.0-or-later
"""The layout shows the architecture (issue 12): bpy only under hazy_gloss/blender/, no import
cycles between the package's modules, no symlinks, the shared constants written once."""
import ast
import os
import re
from pathlib import Path

import pytest

import layout_graph

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "hazy_gloss"
BLENDER_MODULES = {"bpy", "mathutils", "bmesh", "bpy_extras", "addon_utils", "bl_operators",
                   "bl_ui", "gpu", "blf", "aud", "idprop", "bl_math", "freestyle", "imbuf"}


def modules():
    for path in sorted(PKG.rglob("*.py")):
        yield path, ".".join(path.relative_to(ROOT).with_suffix("").parts)


def imports(path, module):
    """(absolute module name, line) of every import in ``path`` (function-level included)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    pkg = module.rsplit(".", 1)[0] if path.name != "__init__.py" else module
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name, node.lineno
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")
                base = base[:len(base) - node.level + 1]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = node.module
            yield name, node.lineno
            for a in node.names:  # "from . import x" imports the module x
                yield f"{name}.{a.name}", node.lineno


def test_bpy_only_under_blender():
    offenders = []
    for path, module in modules():
        if module.startswith("hazy_gloss.blender"):
            continue
        for name, line in imports(path, module):
            if name.split(".")[0] in BLENDER_MODULES:
                offenders.append(f"{path.relative_to(ROOT)}:{line} imports {name}")
    assert not offenders, offenders


def test_no_import_cycles_at_module_level():
    """Module-level imports between the package's modules form no cycle (function-level imports
    are how the facade and the CLI reach Blender lazily)."""
    known = {m for _, m in modules()} | {m.rsplit(".", 1)[0] for _, m in modules()}
    graph = {}
    for path, module in modules():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        deps = set()
        pkg = module.rsplit(".", 1)[0] if path.name != "__init__.py" else module
        for node in tree.body:  # module level only
            stmts = [node]
            if isinstance(node, ast.If):  # TYPE_CHECKING blocks and version switches
                stmts = node.body + node.orelse
            for st in stmts:
                if isinstance(st, ast.ImportFrom):
                    base = pkg.split(".")[:len(pkg.split(".")) - st.level + 1] if st.level else []
                    name = ".".join(base + ([st.module] if st.module else [])) if st.level else st.module
                    for a in st.names:
                        full = f"{name}.{a.name}"
                        deps.add(full if full in known else name)
                elif isinstance(st, ast.Import):
                    deps.update(a.name for a in st.names)
        graph[module] = {d for d in deps if d in known and d != module}
    # packages import their __init__: a module's package is not a dependency on itself
    cycles = []
    state = {}

    def visit(m, stack):
        state[m] = 1
        for d in graph.get(m, ()):
            if state.get(d) == 1:
                cycles.append(stack[stack.index(d):] + [d] if d in stack else [m, d])
            elif d not in state:
                visit(d, stack + [d])
        state[m] = 2

    for m in graph:
        if m not in state:
            visit(m, [m])
    real = [c for c in cycles if not all(x == c[0] or x.startswith(c[0] + ".") or
                                          c[0].startswith(x + ".") for x in c)]
    assert not real, real


def test_no_import_cycles_outside_blender():
    """The bpy-free modules import each other without a cycle, function-level imports included
    (tests/pure/layout_graph.py reads every import statement)."""
    g = layout_graph.graph(layout_graph.imports())
    free = {m: {d for d in deps if not d.startswith("hazy_gloss.blender")}
            for m, deps in g.items() if not m.startswith("hazy_gloss.blender")}
    assert not layout_graph.cycles(free)


def test_no_symlinks():
    tracked = [p for p in ROOT.iterdir() if not p.name.startswith(".venv")
               and p.name not in (".git", "out", "dist", "build")]
    links = [str(q.relative_to(ROOT)) for p in tracked
             for q in ([p] + (list(p.rglob("*")) if p.is_dir() and not p.is_symlink() else []))
             if q.is_symlink()]
    assert not links, links


#: Generated data tables (numbers that are data, not constants of the add-on).
DATA_MODULES = ("cie_1931.py", "cycles_ggx_tables.py")


def _uses(tree):
    """(kind, value, line) of the literals that would be copies of shared constants."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, float):
            yield "number", node.value, node.lineno
        elif isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Constant):
            yield "key", node.slice.value, node.lineno
        elif isinstance(node, ast.Compare) and isinstance(node.left, ast.Constant) and \
                any(isinstance(op, (ast.In, ast.NotIn)) for op in node.ops):
            yield "key", node.left.value, node.lineno
        elif isinstance(node, ast.JoinedStr) or (isinstance(node, ast.BinOp) and isinstance(
                node.left, ast.Constant) and isinstance(node.left.value, str)):
            first = node.values[0] if isinstance(node, ast.JoinedStr) and node.values else \
                getattr(node, "left", None)
            if isinstance(first, ast.Constant) and isinstance(first.value, str):
                yield "prefix", first.value, node.lineno


@pytest.mark.parametrize("kind, value, name", [
    ("number", 0.9999, "MAX_HAZINESS"), ("number", 0.004, "MIN_ROUGHNESS"),
    ("number", 0.0101, "MIN_ROUGHNESS_AS"), ("key", "hazy_gloss", "STAMP"),
    ("key", "hazy_gloss_role", "ROLE"), ("prefix", "HG ", "NODE_PREFIX"),
])
def test_constants_written_once(kind, value, name):
    """The shared constants are written in constants.py only (elsewhere they are imported)."""
    hits = []
    for path, module in modules():
        if path.name == "constants.py" or path.name in DATA_MODULES:
            continue
        for k, v, line in _uses(ast.parse(path.read_text(encoding="utf-8"))):
            if k == kind and (v == value if kind != "prefix" else str(v).startswith(value)):
                hits.append(f"{path.relative_to(ROOT)}:{line}")
    assert not hits, f"{name} written outside constants.py: {hits}"
