# SPDX-License-Identifier: GPL-3.0-or-later
"""Extract the socket declarations of the BSDF nodes a haze layer wraps, once per Blender.

    bash scripts/setup.sh --no-demo && .venv/bin/python scripts/extract_bsdf_interfaces.py [--check]

writes ``hazy_gloss/core/tables/bsdf_interfaces.json`` (``--check``: compare and exit 1 if it differs).
The layer's node group has the wrapped BSDF's inputs with their names, types, limits, defaults
and panels; Python cannot read a built-in node's declaration (``bl_rna`` holds the socket
type's generic limits), but Blender's own Make Group (Ctrl+G) copies it into the group's
interface.  So each venv of scripts/setup.sh makes a group of a Principled (every subsurface
method), a Metallic and a Glossy BSDF with ``node.group_make`` and prints its interface; this
script collects them per Blender version (major.minor).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from hazy_gloss.core import tables as table_files  # noqa: E402  (the table files' one writer)

OUT = table_files.path("bsdf_interfaces")
VENVS = (".venv45", ".venv52", ".venv")

_PROBE = r'''
import json, bpy
bpy.ops.wm.read_homefile(use_empty=True)
out = {}
mat = bpy.data.materials.new("probe")
if bpy.app.version < (5, 0, 0):
    mat.use_nodes = True
tree = mat.node_tree
win = bpy.context.window_manager.windows[0]
area = win.screen.areas[0]
area.ui_type = "ShaderNodeTree"
space = area.spaces.active
space.node_tree = tree
region = next(r for r in area.regions if r.type == "WINDOW")
variants = [("PRINCIPLED", "ShaderNodeBsdfPrincipled", m) for m in
            ("RANDOM_WALK", "RANDOM_WALK_SKIN", "BURLEY")]
variants += [("METALLIC", "ShaderNodeBsdfMetallic", f) for f in ("F82", "PHYSICAL_CONDUCTOR")]
variants += [("GLOSSY", "ShaderNodeBsdfGlossy", None)]
for kind, idname, method in variants:
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    space.node_tree = tree  # (Make Group enters the group it made)
    node = tree.nodes.new(idname)
    if kind == "PRINCIPLED":
        node.subsurface_method = method
    elif kind == "METALLIC":
        node.fresnel_type = method
    node.select = True
    tree.nodes.active = node
    with bpy.context.temp_override(window=win, area=area, region=region, space_data=space):
        assert bpy.ops.node.group_make() == {"FINISHED"}
    group = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeGroup").node_tree
    items = []
    for it in group.interface.items_tree:
        if it.item_type == "PANEL":
            continue
        if it.in_out != "INPUT":
            continue
        d = dict(name=it.name, type=it.socket_type, hide_value=bool(it.hide_value),
                 panel=it.parent.name if it.parent is not None and it.parent.name else "")
        for attr in ("subtype", "min_value", "max_value"):
            if hasattr(it, attr):
                d[attr] = getattr(it, attr)
        if hasattr(it, "default_value"):
            v = it.default_value
            d["default"] = list(v) if hasattr(v, "__len__") else v
        items.append(d)
    closed = {it.name: bool(it.default_closed) for it in group.interface.items_tree
              if it.item_type == "PANEL"}
    entry = out.setdefault(kind, {"sockets": {}, "panels": closed})
    for d in items:
        entry["sockets"].setdefault(d["name"], d)
print("HG-JSON" + json.dumps({"version": "%d.%d" % bpy.app.version[:2], "nodes": out}))
'''


def probe(venv):
    py = ROOT / venv / "bin" / "python"
    res = subprocess.run([str(py), "-c", _PROBE], capture_output=True, text=True, check=True)
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("HG-JSON"))
    return json.loads(line[len("HG-JSON"):])


def render(tables):
    return table_files.dumps(tables, "scripts/extract_bsdf_interfaces.py: each supported "
                             "Blender's own Make Group on each BSDF node (bpy "
                             + ", ".join(sorted(tables)) + ")", "GPL-3.0-or-later")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true")
    args = ap.parse_args(argv)
    tables = {}
    for venv in VENVS:
        d = probe(venv)
        tables[d["version"]] = d["nodes"]
    text = render(tables)
    if args.check:
        ok = OUT.read_text() == text
        print("bsdf_interfaces.json is up to date" if ok else "bsdf_interfaces.json differs")
        return 0 if ok else 1
    OUT.write_text(text)
    print(f"wrote {OUT.relative_to(ROOT)} ({', '.join(sorted(tables))})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
