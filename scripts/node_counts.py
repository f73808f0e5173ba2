# SPDX-License-Identifier: GPL-3.0-or-later
"""Node counts of lean (constant) vs in-shader-mapping materials, as a Markdown table.

    .venv/bin/python scripts/node_counts.py
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import bpy  # noqa: E402

import hazy_gloss  # noqa: E402


def count(mat):
    """Nodes a render evaluates: the material's nodes plus the group's inner nodes (recursively)."""
    def inner(tree):
        n = 0
        for node in tree.nodes:
            if node.bl_idname in ("NodeGroupInput", "NodeGroupOutput", "NodeFrame", "NodeReroute"):
                continue
            n += 1
            if node.bl_idname == "ShaderNodeGroup" and node.node_tree:
                n += inner(node.node_tree)
        return n
    return inner(mat.node_tree)


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
            lean = count(api.create_material("lean", **p))
            shader = count(api.create_material("shader", shader_mapping=True, **p))
            ms = count(api.create_material("shader ms", shader_mapping=True, distribution="MULTI_GGX", **p))
            rows.append(f"| {kind.lower()} | {label} | {lean} | {shader} | {ms} |")
    print(f"Blender {bpy.app.version_string}; nodes counted include the output node and every node"
          " inside node groups.\n")
    print("| kind | configuration | lean (constants) | in-shader mapping | in-shader, Multiscatter GGX |")
    print("|---|---|---:|---:|---:|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
