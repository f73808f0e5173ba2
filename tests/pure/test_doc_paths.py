# SPDX-License-Identifier: GPL-3.0-or-later
"""The names the docs give exist: every backticked dotted name of the package in
README.md and docs/*.md (``hazy_gloss.x.y``, or ``core.x`` / ``api.x`` / ``blender.x.y`` ...
relative to it) is a module, or a name a module defines, found by file existence and ``ast``
(nothing is imported, so no bpy); an operator id ``hazy_gloss.x`` is an operator's
``bl_idname``; every backticked repository file path (``hazy_gloss/...py``, ``core/...py``,
``blender/...py``, ``scripts/...py``, ``benchmarks/...py``, ``tests/...py`` ...) is a file.
Code blocks are not read here (tests/blender/test_docs.py runs the Python ones)."""
from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "hazy_gloss"
DOCS = [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md"))

#: Folders a backticked path may start from: the repository's, and the package's (docs write
#: ``core/mapping.py`` for ``hazy_gloss/core/mapping.py``).
REPO_DIRS = ("hazy_gloss", "scripts", "benchmarks", "tests", "node_groups", "docs")
PKG_DIRS = ("core", "blender", "conversion", "interchange", "utils")
#: Names a backticked dotted name may start from, relative to the package.
PKG_NAMES = ("api", "constants", "core", "blender", "conversion", "interchange", "utils",
             "recomposite")
#: Where a bare file name (a backticked span that is only ``name.py``) may live.
SEARCH = ("hazy_gloss", "scripts", "benchmarks", "tests", "node_groups")

_FENCE = re.compile(r"^```.*?^```[^\n]*$", re.S | re.M)
_SPAN = re.compile(r"`([^`\n]+)`")
_PATH = re.compile(r"(?<![\w./-])((?:%s)/[\w./-]*?\.py)\b" % "|".join(REPO_DIRS + PKG_DIRS))
_DOTTED = re.compile(r"(?<![\w/])(hazy_gloss(?:\.\w+)+\*?)")
_RELATIVE = re.compile(r"^(?:%s)(?:\.\w+)+\*?" % "|".join(PKG_NAMES))
_BARE = re.compile(r"^(\w+\.py)(?:::\w+)?$")


def references(text):
    """[(kind, reference)] of the backticked spans of a Markdown text outside code blocks:
    kind "path", "file" (a bare file name), "name" (dotted, of the package) or "relative"
    (dotted, relative to the package)."""
    out = []
    for span in _SPAN.findall(_FENCE.sub("", text)):
        if "*" in span.replace(".*", "").replace("_*", "") or "<" in span:
            continue  # a pattern (blender/*_ops.py) or a placeholder (<version>)
        for p in _PATH.findall(span):
            out.append(("path", p))
        m = _BARE.match(span)
        if m:
            out.append(("file", m.group(1)))
        for d in _DOTTED.findall(span):
            out.append(("name", d))
        m = _RELATIVE.match(span)
        if m and not m.group(0).endswith(".py"):  # constants.py is a file name
            out.append(("relative", m.group(0)))
    return out


def _module_file(parts):
    base = ROOT.joinpath(*parts)
    for p in (base.with_suffix(".py"), base / "__init__.py"):
        if p.is_file():
            return p
    return None


@functools.lru_cache(maxsize=None)
def _top_level(path):
    """{name: node} of what a module defines at top level (in ``if`` / ``try`` blocks too)."""
    names = {}

    def visit(body):
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                names[node.name] = node
            elif isinstance(node, ast.Assign):
                for t in node.targets:
                    for n in ast.walk(t):
                        if isinstance(n, ast.Name):
                            names[n.id] = node
            elif isinstance(node, (ast.AnnAssign, ast.AugAssign)) and isinstance(node.target, ast.Name):
                names[node.target.id] = node
            elif isinstance(node, (ast.Import, ast.ImportFrom)):
                for a in node.names:
                    names[(a.asname or a.name).split(".")[0]] = node
            elif isinstance(node, ast.If):
                visit(node.body)
                visit(node.orelse)
            elif isinstance(node, ast.Try):
                visit(node.body)
                for h in node.handlers:
                    visit(h.body)
                visit(node.orelse)
                visit(node.finalbody)

    visit(ast.parse(Path(path).read_text(encoding="utf-8")).body)
    return names


def _resolve_in(module_parts, path, rest):
    """Whether ``rest`` (attribute names) is defined in the module at ``path``."""
    if not rest:
        return True
    names = _top_level(str(path))
    head = rest[0]
    if head.endswith("*"):
        return any(n.startswith(head[:-1]) for n in names)
    node = names.get(head)
    if node is None:
        return False
    if len(rest) == 1:
        return True
    if isinstance(node, ast.ClassDef):
        inner = {n.name for n in node.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                             ast.ClassDef))}
        inner |= {t.id for n in node.body if isinstance(n, ast.Assign) for t in n.targets
                  if isinstance(t, ast.Name)}
        inner |= {n.target.id for n in node.body if isinstance(n, ast.AnnAssign)
                  and isinstance(n.target, ast.Name)}
        return rest[1] in inner
    if isinstance(node, ast.ImportFrom):  # follow "from .x import name" / "from . import x"
        pkg = module_parts if path.name == "__init__.py" else module_parts[:-1]
        base = list(pkg[:len(pkg) - node.level + 1]) if node.level else []
        src = base + (node.module.split(".") if node.module else [])
        alias = next(a for a in node.names if (a.asname or a.name) == head)
        return resolve_name(".".join(src + [alias.name] + rest[1:]))
    if isinstance(node, ast.Import):
        return resolve_name(".".join([n for a in node.names if (a.asname or a.name) == head
                                      for n in a.name.split(".")] + rest[1:]))
    return False  # an attribute of a value: not looked into


@functools.lru_cache(maxsize=None)
def _operator_ids():
    ids = set()
    for path in (PKG / "blender").rglob("*.py"):
        ids.update(re.findall(r"bl_idname\s*=\s*[\"']hazy_gloss\.(\w+)[\"']",
                              path.read_text(encoding="utf-8")))
    return ids


def resolve_name(dotted):
    """Whether a dotted name ``hazy_gloss.…`` is a module of the package or a name one
    defines; a trailing ``*`` matches any name with that prefix."""
    parts = dotted.split(".")
    if parts[0] != "hazy_gloss":
        return False
    for i in range(len(parts), 0, -1):
        path = _module_file(parts[:i])
        if path is not None:
            return _resolve_in(tuple(parts[:i]), path, parts[i:])
    return False


def resolve(kind, ref):
    if kind == "path":
        return (ROOT / ref).is_file() or (PKG / ref).is_file()
    if kind == "file":
        return any(next((ROOT / d).rglob(ref), None) is not None for d in SEARCH)
    if kind == "name":
        if resolve_name(ref):
            return True
        parts = ref.split(".")  # an operator id, alone or in bpy.ops.hazy_gloss.x
        return len(parts) == 2 and parts[1] in _operator_ids()
    if kind == "relative":  # hazy_gloss.<ref>, or blender/'s module of that name
        return resolve_name("hazy_gloss." + ref) or resolve_name("hazy_gloss.blender." + ref)
    raise ValueError(kind)


def problems(text):
    """The references of ``text`` that do not resolve, as "kind: reference"."""
    return [f"{kind}: {ref}" for kind, ref in references(text) if not resolve(kind, ref)]


def test_the_checker_fails_on_made_up_names():
    doc = ("The mapping is `hazy_gloss.core.mapping.haze_mapping` in `core/mapping.py`, "
           "read by `scripts/architecture.py` and `tests/pure/test_layout.py`.\n"
           "Made up: `hazy_gloss.core.mapping.no_such_function`, `hazy_gloss.no_such_module`, "
           "`core.no_such_module.f`, `blender/no_such_module.py`, `scripts/no_such_script.py`, "
           "`tests/pure/test_no_such.py`, `no_such_file.py`, "
           "`hazy_gloss.core.lobes.HazyLobes.no_such_attribute`.\n"
           "```python\nimport hazy_gloss.in_a_code_block_not_checked_here\n```\n")
    assert problems(doc) == [
        "name: hazy_gloss.core.mapping.no_such_function", "name: hazy_gloss.no_such_module",
        "relative: core.no_such_module.f", "path: blender/no_such_module.py",
        "path: scripts/no_such_script.py", "path: tests/pure/test_no_such.py",
        "file: no_such_file.py", "name: hazy_gloss.core.lobes.HazyLobes.no_such_attribute"]
    assert len(references(doc)) == 12


def test_the_checker_finds_real_names():
    doc = ("`hazy_gloss.core.inverse_haze_mapping` (re-exported by core/__init__), "
           "`hazy_gloss.constants.EXIT_*`, `api.make_hazy(mat, haziness=0.1)`, "
           "`convert_wiring.wire_material` (blender/model/convert_wiring.py), `hazy_gloss.convert_maps` (an "
           "operator), `bpy.ops.hazy_gloss.setup_recomposite()`, `hazy_gloss.core.lobes.HazyLobes`, "
           "`hazy_gloss/core/thin_film.py`, `blender/*_ops.py` (a pattern, not checked)")
    assert not problems(doc), problems(doc)


@pytest.mark.parametrize("doc", DOCS, ids=[p.name for p in DOCS])
def test_doc_names_and_paths_exist(doc):
    bad = problems(doc.read_text(encoding="utf-8"))
    assert not bad, f"{doc.name} names what does not exist: {bad}"
