# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/img/layer_tree.png: a material's node tree before and after Make Hazy, drawn from the
nodes' own locations, sizes and links, and the inside of the layer node's group as its labelled
frames in order, each with its node count (matplotlib).

    .venv/bin/python scripts/tree_diagram.py [--out docs/img/layer_tree.png]

The material: a Principled BSDF with image textures on Base Color, Roughness,
Metallic, Coat Weight and a Normal Map.  Needs matplotlib (requirements-dev.txt).
"""
import argparse
import os
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)

import bpy  # noqa: E402

import hazy_gloss  # noqa: E402

HEADER, ROW = 26.0, 22.0  # a node's title bar and socket rows, in node-editor units
COLOURS = {"TEXTURE": "#e8a33d", "SHADER": "#5ba55b", "GROUP": "#3f8f9f", "OUTPUT": "#c0504d",
           "INPUT": "#888888", "CONVERTER": "#4f7fbf", "VECTOR": "#7f5fbf"}


def _kind(n):
    if n.bl_idname in ("ShaderNodeGroup",):
        return "GROUP"
    if n.bl_idname.startswith("ShaderNodeTex"):
        return "TEXTURE"
    if n.bl_idname.startswith("ShaderNodeBsdf") or n.bl_idname in ("ShaderNodeMixShader",
                                                                   "ShaderNodeAddShader"):
        return "SHADER"
    if n.bl_idname in ("ShaderNodeOutputMaterial", "NodeGroupOutput"):
        return "OUTPUT"
    if n.bl_idname == "ShaderNodeNormalMap":
        return "VECTOR"
    if n.bl_idname == "NodeGroupInput":
        return "INPUT"
    return "CONVERTER"


def _shown(sockets):
    return [s for s in sockets if s.enabled and not s.hide and s.name]


def _rows(n):
    """The input rows drawn for a node: all of a small node's, else those fed by computed
    values (the editor folds a BSDF's many inputs into panels; what only passes a group's
    input on is counted, not listed)."""
    ins = _shown(n.inputs)
    if len(ins) <= 12:
        return ins, 0
    fed = [s for s in ins if s.is_linked and s.links[0].from_node.bl_idname != "NodeGroupInput"]
    return fed, len(ins) - len(fed)


def _outs(n):
    outs = _shown(n.outputs)
    return outs if len(outs) <= 12 else []


def _box(n):
    """(x, top, width, height, {socket: y}) of a node as drawn (collapsed nodes are one row;
    its outputs first, then its inputs; a socket not drawn links at the node's middle)."""
    x, top = (n.location_absolute if hasattr(n, "location_absolute") else n.location)
    outs = _outs(n)
    ins, more = _rows(n)
    ys = {}
    if n.hide:
        for s in list(n.outputs) + list(n.inputs):
            ys[s.as_pointer()] = top - HEADER / 2
        return x, top, n.width, HEADER, ys
    y = top - HEADER
    for s in outs:
        ys[s.as_pointer()] = y - ROW / 2
        y -= ROW
    for s in ins:
        ys[s.as_pointer()] = y - ROW / 2
        y -= ROW
    if more or (not outs and n.outputs):
        y -= ROW
    h = top - y + 6.0
    for s in list(n.outputs) + list(n.inputs):
        ys.setdefault(s.as_pointer(), top - h / 2)
    return x, top, n.width, h, ys


def _fit(text, width, per_char=8.5):
    n = max(4, int(width / per_char))
    return text if len(text) <= n else text[:n - 1] + "…"


def draw(ax, tree, title, skip=("NodeFrame", "NodeReroute")):
    from matplotlib.patches import FancyBboxPatch, Rectangle
    from matplotlib.path import Path
    from matplotlib.patches import PathPatch
    boxes = {}
    for n in tree.nodes:
        if n.bl_idname == "NodeFrame":
            continue
        boxes[n.name] = _box(n)
    # frames: the extent of their children
    for f in (n for n in tree.nodes if n.bl_idname == "NodeFrame"):
        kids = [boxes[c.name] for c in tree.nodes if c.parent == f and c.name in boxes]
        if not kids:
            continue
        x0 = min(b[0] for b in kids) - 40
        x1 = max(b[0] + b[2] for b in kids) + 40
        y1 = max(b[1] for b in kids) + 60
        y0 = min(b[1] - b[3] for b in kids) - 40
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor="#f2f2ea", edgecolor="#b8b8a8",
                               zorder=0))
        ax.text(x0 + 12, y1 - 14, _fit(f.label or f.name, x1 - x0 - 24, 10.0), fontsize=6.5,
                va="top", color="#555544", zorder=1)
    for n in tree.nodes:
        if n.bl_idname in skip:
            continue
        x, top, w, h, _ = boxes[n.name]
        c = COLOURS[_kind(n)]
        ax.add_patch(FancyBboxPatch((x, top - h), w, h, boxstyle="round,pad=0,rounding_size=8",
                                    facecolor="#d9d9d9" if n.mute else "#3a3a3a",
                                    edgecolor="#222222", linewidth=0.6, zorder=3,
                                    alpha=0.55 if n.mute else 1.0))
        ax.add_patch(Rectangle((x, top - HEADER), w, HEADER, facecolor=c, edgecolor="none",
                               zorder=4, alpha=0.45 if n.mute else 1.0))
        ax.text(x + 8, top - HEADER / 2, _fit(n.label or n.name, w - 12), fontsize=6.5,
                va="center", color="white", zorder=5)
        if not n.hide:
            ins, more = _rows(n)
            for s in ins:
                y = boxes[n.name][4][s.as_pointer()]
                ax.text(x + 10, y, _fit(s.name, w - 16, 6.0), fontsize=4.5, va="center",
                        color="#dddddd", zorder=5)
            if more:
                ax.text(x + 10, top - h + 6 + ROW / 2, _fit(f"+ {more} inputs", w - 16, 6.0),
                        fontsize=4.5, va="center", color="#aaaaaa", style="italic", zorder=5)
            elif not _outs(n) and n.outputs:
                ax.text(x + 10, top - h + 6 + ROW / 2, _fit(f"{len(_shown(n.outputs))} sockets",
                                                            w - 16, 6.0),
                        fontsize=4.5, va="center", color="#aaaaaa", style="italic", zorder=5)
    for link in tree.links:
        a, b = link.from_node, link.to_node
        if a.name not in boxes or b.name not in boxes or not link.is_valid:
            continue
        xa = boxes[a.name][0] + boxes[a.name][2]
        ya = boxes[a.name][4].get(link.from_socket.as_pointer(), boxes[a.name][1] - HEADER)
        xb = boxes[b.name][0]
        yb = boxes[b.name][4].get(link.to_socket.as_pointer(), boxes[b.name][1] - HEADER)
        d = max(40.0, 0.4 * abs(xb - xa))
        path = Path([(xa, ya), (xa + d, ya), (xb - d, yb), (xb, yb)],
                    [Path.MOVETO, Path.CURVE4, Path.CURVE4, Path.CURVE4])
        faint = b.mute or a.bl_idname == "NodeGroupInput"
        ax.add_patch(PathPatch(path, facecolor="none", edgecolor="#999999" if faint else "#222222",
                               linewidth=0.3 if faint else 0.6, linestyle=":" if b.mute else "-",
                               zorder=2))
    xs = [b[0] for b in boxes.values()] + [b[0] + b[2] for b in boxes.values()]
    ys = [b[1] for b in boxes.values()] + [b[1] - b[3] for b in boxes.values()]
    ax.set_xlim(min(xs) - 80, max(xs) + 80)
    ax.set_ylim(min(ys) - 80, max(ys) + 100)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=9)


#: A frame's colour by the part its label names (the text before the colon).
PART_COLOURS = {"Coat": "#d9e7f2", "Dielectric part": "#e6f0dc", "Metal part": "#f2e4d4",
                "EEVEE": "#ece4f2"}


def draw_frames(ax, tree, title, columns=4):
    """The group as an artist reads it: its labelled frames in the editor's left-to-right order,
    wrapped into rows, each with its node count (450 nodes drawn one by one do not read)."""
    import textwrap
    from matplotlib.patches import FancyBboxPatch

    def x_of(n):
        return (n.location_absolute if hasattr(n, "location_absolute") else n.location)[0]
    frames = sorted((n for n in tree.nodes if n.bl_idname == "NodeFrame"), key=x_of)
    w, h, gap = 10.0, 3.2, 1.0
    rows = (len(frames) + columns - 1) // columns
    for i, f in enumerate(frames):
        r, c = divmod(i, columns)
        x, y = c * (w + gap), -r * (h + gap)
        label = f.label or f.name
        part = label.split(":")[0]
        kids = sum(1 for n in tree.nodes if n.parent == f)
        ax.add_patch(FancyBboxPatch((x, y - h), w, h, boxstyle="round,pad=0,rounding_size=0.3",
                                    facecolor=PART_COLOURS.get(part, "#f2f2ea"),
                                    edgecolor="#888877", linewidth=0.8))
        ax.text(x + 0.3, y - 0.35, f"{i + 1}. " + "\n".join(textwrap.wrap(label, 34)),
                fontsize=7.5, va="top", color="#222222")
        ax.text(x + w - 0.3, y - h + 0.3, f"{kids} nodes", fontsize=7, ha="right",
                va="bottom", color="#555555")
    ax.set_xlim(-gap, columns * (w + gap))
    ax.set_ylim(-rows * (h + gap), gap)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=9)


def textured_material(name):
    """The drawn material: image textures on Base Color, Roughness, Metallic, Coat Weight and
    a Normal Map into a Principled BSDF."""
    import numpy as np
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    b = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    b.location, out.location = (-100.0, 300.0), (300.0, 300.0)
    for i, sock in enumerate(("Base Color", "Roughness", "Metallic", "Coat Weight", "Normal")):
        img = bpy.data.images.new(f"{name} {sock}", 8, 8, is_data=sock != "Base Color")
        img.pixels.foreach_set(np.full(8 * 8 * 4, 0.5, np.float32))
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image, tex.label = img, sock.lower().replace(" ", "_") + ".png"
        tex.location = (-700.0, 300.0 - 280.0 * i)
        if sock == "Normal":
            nm = tree.nodes.new("ShaderNodeNormalMap")
            nm.location = (-380.0, 300.0 - 280.0 * i)
            tree.links.new(tex.outputs["Color"], nm.inputs["Color"])
            tree.links.new(nm.outputs["Normal"], b.inputs["Normal"])
        else:
            tree.links.new(tex.outputs["Color"], b.inputs[sock])
    return mat


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(REPO, "docs", "img", "layer_tree.png"))
    args = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    bpy.ops.wm.read_homefile(use_empty=True)
    try:
        hazy_gloss.register()
    except ValueError:
        pass
    from hazy_gloss import api
    from hazy_gloss.blender.model import layer
    before = textured_material("Before")
    after = textured_material("After")
    api.make_hazy(after, haziness=0.4, coat_haziness=0.3)
    group = layer.layer_node(after).node_tree
    fig = plt.figure(figsize=(13, 11), dpi=150)
    grid = fig.add_gridspec(2, 2, height_ratios=[1.0, 1.35])
    draw(fig.add_subplot(grid[0, 0]), before.node_tree,
         f"Before: {len(before.node_tree.nodes)} nodes")
    draw(fig.add_subplot(grid[0, 1]), after.node_tree,
         f"After Make Hazy: {len(after.node_tree.nodes)} nodes (the layer node in the BSDF's "
         "place; the BSDF kept, muted)")
    total = sum(1 for n in group.nodes if n.bl_idname != "NodeFrame")
    draw_frames(fig.add_subplot(grid[1, :]), group,
                f"Inside the layer node: group “{group.name}”, {total} nodes in its frames, "
                "left to right in the node editor\n(shared by every material of its "
                "configuration; Tab into the node to see each frame's nodes)")
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
    fig.savefig(args.out)
    print(f"wrote {args.out}: {len(before.node_tree.nodes)} -> {len(after.node_tree.nodes)} nodes, "
          f"group {group.name!r} with {len(group.nodes)} nodes")


if __name__ == "__main__":
    main(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:])
