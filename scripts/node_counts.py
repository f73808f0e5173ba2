# SPDX-License-Identifier: GPL-3.0-or-later
"""Node counts of lean (constant) vs in-shader-mapping materials, and of haze layers on
Principled materials; writes the tables into docs/node-groups.md (between the "node-counts"
markers) and prints them.

    .venv/bin/python scripts/node_counts.py
"""
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))  # layer_probe

import bpy  # noqa: E402

import hazy_gloss  # noqa: E402
import layer_probe  # noqa: E402


def count(mat):
    """Nodes a render evaluates: the material's nodes plus the group's inner nodes (recursively)."""
    return count_tree(mat.node_tree)


def count_tree(tree):
    """A tree's nodes and its groups' (recursively), frames and group inputs / outputs aside."""
    def inner(tree):
        n = 0
        for node in tree.nodes:
            if node.bl_idname in ("NodeGroupInput", "NodeGroupOutput", "NodeFrame", "NodeReroute"):
                continue
            n += 1
            if node.bl_idname == "ShaderNodeGroup" and node.node_tree:
                n += inner(node.node_tree)
        return n
    return inner(tree)


def layer_rows(api):
    """Nodes a haze layer adds to a Principled material, by material (BSDFs, mixes, math)."""
    import numpy as np
    rows = []

    def principled(**inputs):
        from hazy_gloss.blender import compat
        mat = compat.new_material("layer")
        b = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
        b.distribution = inputs.pop("distribution", "GGX")
        for k, v in inputs.items():
            b.inputs[k].default_value = v
        return mat, b

    def texture(mat, b, name, grey=True):
        img = bpy.data.images.new(name, 4, 4, float_buffer=True)
        img.pixels.foreach_set(np.full(64, 0.3, np.float32))
        t = mat.node_tree.nodes.new("ShaderNodeTexImage")
        t.image = img
        mat.node_tree.links.new(t.outputs["Color"], b.inputs[name])

    cases = []
    mat, b = principled(**{"Base Color": (0.5, 0.1, 0.05, 1.0)})
    cases.append(("plastic", mat, dict(haziness=0.1)))
    mat, b = principled(**{"Base Color": (0.5, 0.1, 0.05, 1.0)})
    cases.append(("plastic, Keep Body Colour", mat, dict(haziness=0.1, keep_body_colour=True)))
    mat, b = principled(**{"Metallic": 1.0})
    cases.append(("metal", mat, dict(haziness=0.5)))
    mat, b = principled(**{"Metallic": 1.0, "Anisotropic": 0.5})
    cases.append(("metal, anisotropic halo", mat, dict(haziness=0.5, haze_extent=(8.0, 2.0))))
    mat, b = principled(**{"Metallic": 1.0, "Coat Weight": 1.0})
    cases.append(("car paint (metal, hazy coat)", mat, dict(haziness=0.3, coat_haziness=0.4)))
    mat, b = principled()
    texture(mat, b, "Metallic")
    cases.append(("metallic map", mat, dict(haziness=0.5)))
    mat, b = principled()
    texture(mat, b, "Roughness")
    cases.append(("plastic, roughness map", mat, dict(haziness=0.1)))
    mat, b = principled(**{"Metallic": 1.0})
    texture(mat, b, "Base Color")
    texture(mat, b, "Roughness")
    cases.append(("metal, base colour + roughness maps", mat, dict(haziness=0.5)))
    mat, b = principled(distribution="MULTI_GGX", **{"Metallic": 1.0})
    texture(mat, b, "Roughness")
    cases.append(("metal, roughness map, Multiscatter GGX", mat, dict(haziness=0.5)))
    from hazy_gloss.blender.model import layer, layer_values
    for label, mat, haze in cases:
        top = len(mat.node_tree.nodes)
        api.make_hazy(mat, **haze)
        node = layer.layer_node(mat)
        from hazy_gloss.core import layer_graph
        slots = len(layer_graph.slots_of(layer_values.graph_of(node).cycles))  # (and one for EEVEE)
        kept, exact = layer_probe.rendered_slots(layer_values, node)
        rows.append(f"| {label} | {top} | {len(mat.node_tree.nodes) - top} | {node.node_tree.name} | "
                    f"{count_tree(node.node_tree)} | {slots} | {kept}{'' if exact else ' (at most)'} |")
    return rows


def main():
    hazy_gloss.register()
    from hazy_gloss import api
    rows = []
    base = dict(core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5), roughness=0.2,
                haziness=0.5, haze_extent=5.0)
    for kind in ("CONDUCTOR", "DIELECTRIC", "LEGACY"):
        for label, extra in (("isotropic", {}), ("haze 0", dict(haziness=0.0)),
                             ("anisotropic", dict(anisotropy=0.5, haze_extent=(8.0, 2.0))),
                             ("smooth (Bézier)", dict(smoothness=2.0)),
                             ("anisotropic + smooth", dict(anisotropy=0.5, haze_extent=(8.0, 2.0), smoothness=2.0))):
            p = dict(base, kind=kind, **extra)
            if kind != "CONDUCTOR":  # (a dielectric or legacy material has no edge tint)
                p.pop("edge_tint")
            lean = count(api.create_material("lean", **p))
            shader = count(api.create_material("shader", shader_mapping=True, **p))
            ms = count(api.create_material("shader ms", shader_mapping=True, distribution="MULTI_GGX", **p))
            rows.append(f"| {kind.lower()} | {label} | {lean} | {shader} | {ms} |")
    lines = [f"Blender {bpy.app.version_string}; nodes counted include the output node and every "
             "node inside node groups.", "",
             "| kind | configuration | lean (constants) | in-shader mapping | in-shader, Multiscatter GGX |",
             "|---|---|---:|---:|---:|"] + rows
    lines += ["", "A haze layer (Make Hazy) on a Principled material: the nodes its tree gains (the "
              "layer node; the BSDF stays beside it, muted), the group the layer node uses (shared "
              "by every material of its configuration), its nodes (sub-groups included), its BSDF "
              "slots and how many of them Cycles renders for these values (a Mix whose factor "
              "folds to 0 or 1 drops its other side; the group has one more, folded, for EEVEE):", "",
              "| material | its nodes | added | group | nodes in the group | BSDF slots | rendered |",
              "|---|---:|---:|---|---:|---:|---:|"] + layer_rows(api)
    text = "\n".join(lines)
    print(text)
    doc = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs",
                       "node-groups.md")
    with open(doc, encoding="utf-8") as fh:
        old = fh.read()
    a, b = "<!-- node-counts -->", "<!-- /node-counts -->"
    if a in old and b in old:
        new = old[:old.index(a) + len(a)] + "\n" + text + "\n" + old[old.index(b):]
        with open(doc, "w", encoding="utf-8") as fh:
            fh.write(new)


if __name__ == "__main__":
    main()
