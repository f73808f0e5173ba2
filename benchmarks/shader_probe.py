# SPDX-License-Identifier: GPL-3.0-or-later
"""Evaluate the in-shader haze mapping (core/node_math.py emitted as nodes) in Cycles, one case per
pixel: the graph's outputs are rendered as emission on a plane seen by an orthographic camera
(the approach of tests/blender/test_render_claims.py::_emit), its inputs come from float32 Image
Textures (Closest), so each pixel reads one texel: many cases per render, float32 throughout as
Cycles computes.
"""
from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Vector

import scenes

#: Emission packs: name -> graph outputs (a scalar fills one channel; a colour fills three).
PACKS = {
    "scalars": ("beta", "halo_intensity", "peak_ratio"),
    "alpha_wide": ("alpha_wide_x", "alpha_wide_y", None),
    "reflectivity": ("reflectivity",),
    "ior": ("ior",),
    "extinction": ("extinction",),
}


def _image(name, rgb):
    """A float32 Non-Color image of shape (k, k, 3) (row 0 = bottom)."""
    k = rgb.shape[0]
    img = bpy.data.images.new(name, k, k, alpha=False, float_buffer=True, is_data=True)
    rgba = np.concatenate([rgb, np.ones((k, k, 1), np.float32)], axis=-1).astype(np.float32)
    img.pixels.foreach_set(rgba.ravel())
    img.update()
    return img


def _scene(k):
    scenes.setup_render("CYCLES", samples=1, resolution=(k, k), bounces=0)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    plane = bpy.data.objects.new("HG probe plane", scenes._plane_mesh("HG probe plane", 1.0))
    bpy.context.scene.collection.objects.link(plane)
    scenes._ortho_camera("HG probe camera", Vector((0.0, 0.0, 1.0)), 1.0)
    return plane


def probe(cases, *, anisotropic, smooth, distribution="GGX", packs=PACKS, return_raw=False):
    """cases: dict of float32 arrays over N cases: core_reflectivity (N, 3), edge_tint (N, 3),
    roughness, anisotropy, haziness, haze_extent_x, haze_extent_y, smoothness (N,).
    Returns {output name: array (N,) or (N, 3)} as Cycles computed them."""
    from hazy_gloss.blender.nodes.builder import TreeBuilder
    from hazy_gloss.blender.nodes.emit import emit
    from hazy_gloss.core import node_math
    from hazy_gloss.core.graph import Graph

    n = len(cases["roughness"])
    k = max(4, int(math.ceil(math.sqrt(n))))  # Blender renders at least 4x4

    def grid(a, channels):
        a = np.asarray(a, np.float32).reshape(n, channels)
        full = np.repeat(a[:1], k * k, axis=0)
        full[:n] = a
        return full.reshape(k, k, channels)

    z = np.zeros(n, np.float32)
    w = cases.get("smoothness")
    imgs = {
        "rc": _image("HG probe rc", grid(cases["core_reflectivity"], 3)),
        "g": _image("HG probe g", grid(cases["edge_tint"], 3)),
        "s1": _image("HG probe s1", grid(np.stack([cases["roughness"], cases["haziness"],
                                                   cases["haze_extent_x"]], -1), 3)),
        "s2": _image("HG probe s2", grid(np.stack([cases["haze_extent_y"], cases["anisotropy"],
                                                   z if w is None else w], -1), 3)),
    }
    plane = _scene(k)
    mat = bpy.data.materials.new("HG probe")
    tree = mat.node_tree
    for nd in list(tree.nodes):
        if nd.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(nd)
    out = next(nd for nd in tree.nodes if nd.bl_idname == "ShaderNodeOutputMaterial")
    tb = TreeBuilder(tree)
    tex = {}
    for key, img in imgs.items():
        t = tb.node("ShaderNodeTexImage")
        t.image = img
        t.interpolation = "Closest"
        t.extension = "EXTEND"
        tex[key] = t.outputs["Color"]
    g = Graph()
    t = {key: g.input(key, vector=True) for key in tex}
    s1, s2 = g.separate(t["s1"]), g.separate(t["s2"])
    src = dict(core_reflectivity=t["rc"], edge_tint=t["g"], roughness=s1[0], anisotropy=s2[1],
               rotation=0.0, haziness=s1[1], haze_extent_x=s1[2], haze_extent_y=s2[0],
               smoothness=s2[2] if smooth else None)
    mx = node_math.mapping(g, src, kind="CONDUCTOR", anisotropic=anisotropic, smooth=smooth,
                           distribution=distribution)
    mx["alpha_wide_x"], mx["alpha_wide_y"] = mx.pop("alpha_wide")
    m = emit(tb, g, mx, tex)
    for key, sock in tex.items():  # the texel values as Cycles reads them
        m[f"texel_{key}"] = sock
    em = tb.node("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 1.0
    tree.links.new(em.outputs[0], out.inputs["Surface"])
    plane.data.materials.append(mat)
    result = {}
    for pack, names in packs.items():
        if len(names) == 1:
            value = m[names[0]]
        else:
            comb = tb.node("ShaderNodeCombineXYZ")
            for i, name in enumerate(names):
                if name is not None:
                    tree.links.new(m[name], comb.inputs[i])
            value = comb.outputs[0]
        tree.links.new(value, em.inputs["Color"])
        img = scenes.render_exr()[..., :3].reshape(k * k, 3)[:n].astype(np.float64)
        if len(names) == 1:
            result[names[0]] = img
        else:
            for i, name in enumerate(names):
                if name is not None:
                    result[name] = img[:, i]
    for img in imgs.values():
        bpy.data.images.remove(img)
    bpy.data.materials.remove(mat)
    return result
