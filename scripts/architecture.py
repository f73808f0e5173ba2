# SPDX-License-Identifier: GPL-3.0-or-later
"""Draw docs/architecture.md's diagram from the code: the import graph of the package.

    python scripts/architecture.py [--check]

reads every import statement of ``hazy_gloss`` with tests/pure/layout_graph.py (ast, nothing
imported, no bpy needed), groups the modules by folder (core/, interchange/, utils/, the
top-level bpy-free modules, the entry points) and, under blender/, by layer (its folders,
:data:`ROLES`), collapses the imports to edges between groups, and writes a Mermaid
flowchart between the markers of docs/architecture.md (the text around them is hand-written and
left alone).  A solid arrow: some module-level import; dashed: function-level imports only.
Imports from the entry points and blender/ into the bpy-free part are drawn as one arrow to its
box (they may import any of it); the arrows inside it are drawn group by group.

``--check``: write nothing, exit 1 with a one-line reason when the file differs from what would
be written (tests/pure/test_docs_generated.py runs it).  A module of blender/ outside the layers'
folders goes in an "other" group, named in the diagram and on stderr: move it into its layer.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "pure"))

import generated_doc  # noqa: E402
import layout_graph  # noqa: E402

DOC = ROOT / "docs" / "architecture.md"
BEGIN = "<!-- architecture diagram: begin (scripts/architecture.py) -->"
END = "<!-- architecture diagram: end -->"
SIZE_BEGIN = "<!-- package size: begin (scripts/architecture.py) -->"
SIZE_END = "<!-- package size: end -->"
#: The package when the lean-codebase work began (14be10a, 2026-12-03): Python modules and
#: lines of hazy_gloss/, of hazy_gloss/blender/, and the lines of hand-written image codecs.
#: --check accepts a size table within this fraction of the counts (1 % of 30k lines: 300).
SIZE_TOLERANCE = 0.01
BEFORE = {"commit": "14be10a", "modules": 112, "lines": 30933, "blender_lines": 13784,
          "codec_lines": 1436}
PKG = layout_graph.PACKAGE

#: The layers of hazy_gloss/blender, top down, each a folder (base: blender/compat.py and the
#: package itself).  A module of blender/ outside these is drawn in "other" (and fails the test).
ROLES = {
    "ui": "operators, panels, menus, properties, registration",
    "actions": "what the operators and the API do",
    "model": "hazy materials in Blender: build, read, update; stamps; groups",
    "nodes": "node-tree builders and emitters",
    "base": "Blender versions (compat)",
}
BASE = ("", "compat")

#: The groups of the bpy-free part, by folder; the entry points (the package, the facade, the
#: command line) are a group of their own.  A new folder gets a group of its own.
ENTRY = ("", "api", "__main__")
FREE_FOLDERS = {"core": "the haze mapping, lobes, node math, multiscatter, thin film",
                "conversion": "texture conversion: image files to the mapping's maps",
                "interchange": "MaterialX, USD, other engines",
                "utils": "presets, looks, plots"}

#: Drawing order and subgraphs.
LAYERS = (("entry", "entry points"), ("blender", "blender/: everything that imports bpy"),
          ("free", "bpy-free"))


def group_of(module, packages=()):
    """(layer, group id, group label) of a module of the package (``packages``: the names of
    the package's packages, whose ``__init__`` belongs to their folder)."""
    rel = module[len(PKG) + 1:] if module != PKG else ""
    if rel in ENTRY:
        return "entry", "entry", "hazy_gloss: __init__, api (the facade), __main__ (CLI)"
    parts = rel.split(".")
    if parts[0] == "blender":
        inner = ".".join(parts[1:])
        role = "base" if inner in BASE else parts[1] if len(parts) > 2 or module in packages else None
        if role in ROLES:
            where = "blender/compat.py" if role == "base" else f"blender/{role}/"
            return "blender", role, f"{where}: {ROLES[role]}"
        return "blender", "other", "blender/ other: not in a layer's folder"
    if len(parts) == 1 and module not in packages:
        return "free", "toplevel", "hazy_gloss/*.py: constants, schema, recomposite, node layout"
    folder = parts[0]
    what = FREE_FOLDERS.get(folder, "")
    return "free", folder, f"{folder}/" + (f": {what}" if what else "")


def _short(module, packages):
    rel = module[len(PKG) + 1:] if module != PKG else ""
    parts = [p for p in rel.split(".") if p] + (["__init__"] if module in packages else [])
    if parts[0] == "blender":
        parts = parts[2:] if parts[1:2] in (["nodes"], ["model"], ["actions"], ["ui"]) else parts[1:]
    elif len(parts) > 1:
        parts = parts[1:]
    return ".".join(parts)


def _wrap(names, width=48):
    lines, line = [], ""
    for n in names:
        if line and len(line) + len(n) + 2 > width:
            lines.append(line + ",")
            line = n
        else:
            line = f"{line}, {n}" if line else n
    return lines + [line] if line else lines


def diagram(root=layout_graph.ROOT):
    """(Mermaid text, [modules of blender/ outside the layers' folders])."""
    mods = layout_graph.modules(root)
    found = layout_graph.imports(root)
    packages = {m for m, path in mods.items() if path.name == "__init__.py"}
    where = {m: group_of(m, packages) for m in mods}
    members, labels, layer_of = {}, {}, {}
    for m in sorted(mods):
        layer, gid, label = where[m]
        members.setdefault(gid, []).append(_short(m, packages))
        labels[gid], layer_of[gid] = label, layer
    edges = {}  # (from group, to group) -> True when some import is at module level
    for imp in found:
        if not imp.internal:
            continue
        a, b = where[imp.source][1], where[imp.target][1]
        if where[imp.source][0] != "free" and where[imp.target][0] == "free":
            b = "layer_free"  # into the bpy-free part: one arrow to its box
        if a != b:
            edges[(a, b)] = edges.get((a, b), False) or not imp.function_level
    order = ["entry", "ui", "actions", "model", "nodes", "base", "other",
             "toplevel", "core", "conversion", "interchange", "utils"]
    gids = sorted(members, key=lambda g: (order.index(g) if g in order else len(order), g))
    out = ["```mermaid", "flowchart TB"]
    for layer, title in LAYERS:
        inside = [g for g in gids if layer_of[g] == layer]
        if not inside:
            continue
        out.append(f'  subgraph layer_{layer}["{title}"]')
        for g in inside:
            text = "<br/>".join([f"<b>{labels[g]}</b>"] + _wrap(sorted(members[g])))
            out.append(f'    {g}["{text}"]')
        out.append("  end")
    rank = gids + ["layer_free"]
    for (a, b), module_level in sorted(edges.items(), key=lambda e: (rank.index(e[0][0]),
                                                                      rank.index(e[0][1]))):
        out.append(f"  {a} {'-->' if module_level else '-.->'} {b}")
    out.append("```")
    other = sorted(m for m in mods if where[m][1] == "other")
    return "\n".join(out), other


def size_table(root=ROOT):
    """The package's size now beside :data:`BEFORE` (a Markdown table)."""
    pkg = root / PKG
    files = sorted(pkg.rglob("*.py"))
    lines = {f: len(f.read_text(encoding="utf-8").splitlines()) for f in files}
    blender = sum(n for f, n in lines.items() if (pkg / "blender") in f.parents)
    b = BEFORE
    k = lambda n: f"{n / 1000:.1f}k"  # noqa: E731
    rows = [("Python modules", b["modules"], len(files)),
            ("lines of Python", k(b["lines"]), k(sum(lines.values()))),
            ("of them in blender/", k(b["blender_lines"]), k(blender)),
            ("hand-written image codecs (lines)", k(b["codec_lines"]), 0)]
    out = [f"| | before ({b['commit']}) | now |", "|---|---|---|"]
    out += [f"| {what} | {was} | {now} |" for what, was, now in rows]
    return "\n".join(out)


def render(text, block, size=None):
    """``text`` with ``block`` (and the size table) between their markers (ValueError when
    they are missing)."""
    where = DOC.relative_to(ROOT)
    text = generated_doc.render(text, block, BEGIN, END, where)
    return generated_doc.render(text, size if size is not None else size_table(), SIZE_BEGIN,
                                SIZE_END, where)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true",
                    help="exit 1 when docs/architecture.md differs from what would be written")
    args = ap.parse_args(argv)
    block, other = diagram()
    if other:
        print(f"architecture.py: outside the layers' folders (drawn as 'other'): {', '.join(other)}",
              file=sys.stderr)
    size = size_table()

    def new_text(old):
        kept = _kept_size(old, size) if args.check else size
        return render(old, block, kept)
    return generated_doc.write_or_check(DOC, ROOT, new_text, check=args.check,
                                        script="architecture.py",
                                        source="the import graph and the package's size")


def _numbers(table):
    """The numbers of a size table's "now" column, in order (a "k" multiplies by 1000)."""
    out = []
    for row in table.splitlines()[2:]:
        cell = row.strip().strip("|").split("|")[-1].strip()
        out.append(float(cell[:-1]) * 1000 if cell.endswith("k") else float(cell))
    return out


def _kept_size(old_text, size):
    """For --check: the doc's size table where it is within SIZE_TOLERANCE of ``size`` (an
    edit of a few lines must not fail the test), else ``size``."""
    i, j = old_text.find(SIZE_BEGIN), old_text.find(SIZE_END)
    if i < 0 or j < i:
        return size
    was = old_text[i + len(SIZE_BEGIN):j].strip()
    try:
        a, b = _numbers(was), _numbers(size)
    except ValueError:
        return size
    close = len(a) == len(b) and all(abs(x - y) <= SIZE_TOLERANCE * max(y, 100.0)
                                     for x, y in zip(a, b))
    return was if close else size


if __name__ == "__main__":
    sys.exit(main())
