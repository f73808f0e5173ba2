# SPDX-License-Identifier: GPL-3.0-or-later
"""Node counts of lean (constant) vs in-shader-mapping materials, and of haze layers on
Principled materials (checked against the most their groups may hold, LIMITS); writes the
tables into docs/node-groups.md (between the "node-counts" markers) and prints them.

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


#: The most nodes (nested groups expanded) a layer's group holds, by the materials it is for.
LIMITS = {"plastic": 250, "metal": 250, "textured plastic": 250, "car paint": 450,
          "every feature": 700}


def layer_rows(api):
    """A haze layer on Principled materials with the Principled's default distribution
    (Multiscatter GGX): the nodes its group holds, the math Cycles runs per shading point for
    the material's links, its BSDF slots."""
    import numpy as np
    rows = []

    def principled(**inputs):
        from hazy_gloss.blender import compat
        mat = compat.new_material("layer")
        b = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
        if "distribution" in inputs:
            b.distribution = inputs.pop("distribution")
        for k, v in inputs.items():
            b.inputs[k].default_value = v
        return mat, b

    def texture(mat, b, name):
        img = bpy.data.images.new(name, 4, 4, float_buffer=True)
        img.pixels.foreach_set(np.full(64, 0.3, np.float32))
        t = mat.node_tree.nodes.new("ShaderNodeTexImage")
        t.image = img
        mat.node_tree.links.new(t.outputs["Color"], b.inputs[name])

    cases = []
    mat, b = principled(**{"Base Color": (0.5, 0.1, 0.05, 1.0)})
    cases.append(("plastic", mat, dict(haziness=0.1)))
    mat, b = principled()
    texture(mat, b, "Base Color")
    texture(mat, b, "Roughness")
    cases.append(("textured plastic", mat, dict(haziness=0.3)))
    mat, b = principled(distribution="GGX")
    texture(mat, b, "Base Color")
    texture(mat, b, "Roughness")
    cases.append(("textured plastic, GGX", mat, dict(haziness=0.3)))
    mat, b = principled(**{"Base Color": (0.5, 0.1, 0.05, 1.0)})
    cases.append(("plastic, Keep Body Colour", mat, dict(haziness=0.1, keep_body_colour=True)))
    mat, b = principled(**{"Metallic": 1.0})
    cases.append(("metal", mat, dict(haziness=0.5)))
    mat, b = principled(**{"Metallic": 1.0})
    texture(mat, b, "Base Color")
    texture(mat, b, "Roughness")
    cases.append(("textured metal", mat, dict(haziness=0.5)))
    mat, b = principled(**{"Metallic": 1.0, "Anisotropic": 0.5})
    cases.append(("metal, anisotropic halo", mat, dict(haziness=0.5, haze_extent=(8.0, 2.0))))
    mat, b = principled()
    texture(mat, b, "Metallic")
    cases.append(("metallic map", mat, dict(haziness=0.5)))
    mat, b = principled(**{"Metallic": 1.0, "Coat Weight": 1.0})
    cases.append(("car paint", mat, dict(haziness=0.3, coat_haziness=0.4)))
    mat, b = principled(**{"Coat Weight": 1.0, "Thin Film Thickness": 300.0,
                           "Transmission Weight": 0.5, "Sheen Weight": 0.5, "Anisotropic": 0.5})
    cases.append(("every feature", mat, dict(haziness=0.3, coat_haziness=0.4)))
    from hazy_gloss.blender.model import layer, layer_values
    from hazy_gloss.core import layer_graph
    for label, mat, haze in cases:
        api.make_hazy(mat, **haze)
        node = layer.layer_node(mat)
        slots = len(layer_graph.slots_of(layer_values.graph_of(node).cycles))
        n = layer_probe.count_nodes(node.node_tree)
        limit = LIMITS.get(label)
        rows.append(f"| {label} | {node.node_tree.name} | {n}"
                    f"{f' (<= {limit})' if limit else ''} | {layer_values.varying_math(node)} | "
                    f"{slots} |")
        assert limit is None or n <= limit, (label, n, limit)
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
    lines += ["", "A haze layer (Make Hazy adds one node to the material's tree) on Principled "
              "materials with the Principled's default distribution, Multiscatter GGX: the group "
              "the layer node uses (shared by every material of its configuration, which names the "
              "parts it holds), every node in it (frames and group inputs included), the math "
              "nodes Cycles runs at every shading point for the material's links (the rest folds "
              "into constants when it compiles the shader) and the BSDF copies it mixes:", "",
              "| material | group | nodes in the group | math per shading point | BSDF copies |",
              "|---|---|---:|---:|---:|"] + layer_rows(api)
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
