# SPDX-License-Identifier: GPL-3.0-or-later
"""The import graph of the hazy_gloss package, read from the source (ast, nothing imported):
every ``import`` and ``from ... import`` statement of every module, function-level ones
included.  tests/pure/test_layout.py checks the layering rule and the absence of cycles on it;
scripts/architecture.py draws docs/architecture.md's diagram from it.

A statement ``from . import x`` imports the module ``x`` when there is one; ``from .m import
name`` imports ``m``.  A module importing its own package (``from .. import constants`` is
``hazy_gloss.constants``, but ``from . import x`` inside ``x``'s package runs the package's
``__init__`` first) is not counted as an edge to that package."""
from __future__ import annotations

import ast
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = "hazy_gloss"


@dataclass(frozen=True)
class Import:
    source: str  # the importing module
    target: str  # the imported module (a module of the package) or a top-level name outside it
    line: int
    function_level: bool  # inside a def (or a class body inside a def)
    internal: bool  # a module of the package


def modules(root=ROOT):
    """{module name: path} of every module of the package (``__init__`` as the package)."""
    out = {}
    for path in sorted((root / PACKAGE).rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _in_function(tree):
    """Line numbers of the import statements inside function bodies."""
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            for sub in ast.walk(node):
                if isinstance(sub, (ast.Import, ast.ImportFrom)):
                    lines.add(sub.lineno)
    return lines


def imports(root=ROOT):
    """Every import of every module of the package, as :class:`Import`."""
    mods = modules(root)
    out = []
    for mod, path in mods.items():
        tree = ast.parse(path.read_text(encoding="utf-8"))
        inside = _in_function(tree)
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[:len(base) - node.level + 1]
                    name = ".".join(base + ([node.module] if node.module else []))
                else:
                    name = node.module
                subs = [f"{name}.{a.name}" for a in node.names if f"{name}.{a.name}" in mods]
                targets = subs
                if len(subs) < len(node.names):  # names of the module itself
                    targets = targets + [name]
            for target in targets:
                internal = target in mods or target.split(".")[0] == PACKAGE
                while internal and target not in mods:  # "import hazy_gloss.x.y" -> the module
                    target = target.rpartition(".")[0]
                if not internal:
                    target = target.split(".")[0]
                if target == mod or (internal and mod.startswith(target + ".")):
                    continue
                out.append(Import(mod, target, node.lineno, node.lineno in inside, internal))
    return out


def graph(found, function_level=True):
    """{module: set of the package's modules it imports}."""
    g = {}
    for imp in found:
        g.setdefault(imp.source, set())
        if imp.internal and (function_level or not imp.function_level):
            g[imp.source].add(imp.target)
    return g


def cycles(g):
    """The strongly connected components of ``g`` with more than one module (Tarjan), each a
    sorted list: every import cycle lies within one."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(g.get(v, ())):
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

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out
