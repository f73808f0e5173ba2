# SPDX-License-Identifier: GPL-3.0-or-later
"""The performance scene: one analytic sphere under a small area light and a procedural
gradient sky (no external files), and the material variants compared in docs/performance.md.

Variants of one material class, all with the same physical values:
- ``lean``       hazy_gloss.api.create_material (two lobes + mix, constants from Python);
- ``in_shader``  the same with shader_mapping=True (the haze mapping as shader nodes);
- ``mix``        a hand-built Mix Shader of two lobes, typed in as a user would (no add-on code);
- ``single``     the core (narrow) lobe alone with the same Fresnel: one Metallic BSDF for
                 conductors, one Principled BSDF for the dielectric (the product's lobe node).
"""
from __future__ import annotations

import math

import bpy
import numpy as np
from mathutils import Vector

import scenes  # tests/blender/scenes.py

CLASSES = {
    "dielectric": dict(kind="DIELECTRIC", core_reflectivity=0.04, roughness=0.12, haziness=0.05,
                       haze_extent=6.0, base_color=(0.05, 0.12, 0.35)),
    "conductor": dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3),
                      edge_tint=(1.0, 0.8, 0.5), roughness=0.15, haziness=0.6, haze_extent=5.0),
    "aniso_conductor": dict(kind="CONDUCTOR", core_reflectivity=(0.95, 0.64, 0.54),
                            edge_tint=(1.0, 0.7, 0.5), roughness=0.15, anisotropy=0.6,
                            haziness=0.7, haze_extent=(8.0, 2.0), tangent="RADIAL_Z"),
}
LABELS = {"dielectric": "dielectric", "conductor": "conductor",
          "aniso_conductor": "anisotropic conductor"}
VARIANTS = ("lean", "in_shader", "mix", "single")
VARIANT_LABELS = {"lean": "hazy (lean)", "in_shader": "hazy (in-shader mapping)",
                  "mix": "hand-built two-lobe mix", "single": "single lobe"}
RESOLUTION = (96, 96)


def gradient_world(zenith=(0.45, 0.6, 1.0), horizon=(1.0, 0.95, 0.85), ground=(0.18, 0.14, 0.1),
                   strength=1.0):
    """A sky from the ray direction: ground below the horizon, horizon -> zenith above it."""
    world = bpy.data.worlds.new("HG Report Sky")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    tree = world.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new("ShaderNodeOutputWorld")
    bg = tree.nodes.new("ShaderNodeBackground")
    coord = tree.nodes.new("ShaderNodeTexCoord")
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(coord.outputs["Generated"], sep.inputs[0])
    # sky: horizon -> zenith with sqrt(z); ground: constant, a sharp horizon line
    up = tree.nodes.new("ShaderNodeMath")
    up.operation = "SQRT"
    up.use_clamp = True
    tree.links.new(sep.outputs["Z"], up.inputs[0])
    sky = tree.nodes.new("ShaderNodeMix")
    sky.data_type = "RGBA"
    sky.inputs["A"].default_value = (*horizon, 1.0)
    sky.inputs["B"].default_value = (*zenith, 1.0)
    tree.links.new(up.outputs[0], sky.inputs["Factor"])
    above = tree.nodes.new("ShaderNodeMath")
    above.operation = "GREATER_THAN"
    above.inputs[1].default_value = 0.0
    tree.links.new(sep.outputs["Z"], above.inputs[0])
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs["A"].default_value = (*ground, 1.0)
    tree.links.new(sky.outputs["Result"], mix.inputs["B"])
    tree.links.new(above.outputs[0], mix.inputs["Factor"])
    tree.links.new(mix.outputs["Result"], bg.inputs["Color"])
    bg.inputs["Strength"].default_value = strength
    tree.links.new(bg.outputs[0], out.inputs["Surface"])
    # The default automatic 1024-px importance map costs ~1 s per render (half a million world
    # evaluations); a smooth sky needs far less.
    if hasattr(world, "cycles"):
        world.cycles.sampling_method = "MANUAL"
        world.cycles.sample_map_resolution = 64
    bpy.context.scene.world = world
    return world


def uv_sphere(name="HG Report Sphere", segments=96, rings=48):
    """A smooth-shaded UV sphere of radius 1 (EEVEE does not render Cycles' analytic point
    spheres, so every engine gets this mesh)."""
    import bmesh
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")  # create_uvsphere fills it only if it exists
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=1.0,
                              calc_uvs=True)
    bm.to_mesh(mesh)
    bm.free()
    assert len(mesh.uv_layers) == 1, "UV sphere without UVs"
    for poly in mesh.polygons:
        poly.use_smooth = True
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def lit_sphere_scene(material, *, light_power=150.0, light_size=1.0):
    """A UV sphere (radius 1) seen by an orthographic camera from 20° above the horizon on the
    -Y side, a small square area light up and to the left-front, the gradient sky.  Film
    transparent: sphere pixels have alpha 1 (the error mask).  Call setup_render / eevee_setup
    first (they reset the world; this sets the sky)."""
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    bpy.context.scene.render.film_transparent = True
    obj = uv_sphere()
    obj.data.materials.append(material)
    cam = scenes._ortho_camera("HG Report Camera", scenes.spherical_direction(70.0, -90.0), 2.3)
    gradient_world()
    light = bpy.data.lights.new("HG Report Area", "AREA")
    light.shape = "SQUARE"
    light.size = light_size
    light.energy = light_power
    lo = bpy.data.objects.new("HG Report Area", light)
    bpy.context.scene.collection.objects.link(lo)
    d = scenes.spherical_direction(50.0, -130.0)
    lo.location = d * 5.0
    lo.rotation_euler = d.to_track_quat("Z", "Y").to_euler()
    return {"sphere": obj, "camera": cam, "light": lo}


# --------------------------------------------------------------------------------------------
# Materials
# --------------------------------------------------------------------------------------------


def empty_material(name):
    """A new material holding only its Material Output: (material, tree, output node)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(n)
    out = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"), None)
    if out is None:
        out = tree.nodes.new("ShaderNodeOutputMaterial")
    return mat, tree, out


def physical(api, params):
    """The physical values of Eq. 1 for ``params`` in node conventions (api.lobes_for: the one
    description the add-on builds from), for the hand-built equivalents."""
    p = api.normalise_parameters(dict(params))
    d = api.lobes_for(p)
    m = d.mapping
    wide = d.wide if d.wide is not None else d.narrow
    rc = np.asarray(p["core_reflectivity"])
    return dict(
        p=p, m=m, kind=p["kind"], beta=float(m.beta), roughness=d.narrow.roughness,
        anisotropy=p["anisotropy"], rotation=p["rotation"],
        roughness_wide=float(wide.roughness),
        anisotropy_wide=float(wide.anisotropy) if wide.anisotropy is not None else 0.0,
        rotation_wide=float(wide.rotation) if wide.rotation is not None else p["rotation"],
        ior=tuple(float(x) for x in m.ior), extinction=tuple(float(x) for x in m.extinction),
        dielectric_ior=float(m.dielectric_ior),
        tint=tuple(float(x) for x in (rc / rc.max() if rc.max() > 0 else np.ones(3))),
        base_color=p["base_color"], alpha=tuple(float(a) for a in m.alpha),
        alpha_wide=tuple(float(np.asarray(a)) for a in m.alpha_wide),
        anisotropic=d.anisotropic,
        tangent_axis=p["tangent"][-1] if p["tangent"] != "UV_MAP" else None)


def _hand_lobe(tree, ph, roughness, anisotropy, rotation, tangent):
    if ph["kind"] == "CONDUCTOR":
        n = tree.nodes.new("ShaderNodeBsdfMetallic")
        n.distribution = "GGX"
        n.fresnel_type = "PHYSICAL_CONDUCTOR"
        n.inputs["IOR"].default_value = ph["ior"]
        n.inputs["Extinction"].default_value = ph["extinction"]
        a_name, r_name = "Anisotropy", "Rotation"
    else:
        n = tree.nodes.new("ShaderNodeBsdfPrincipled")
        n.distribution = "GGX"
        n.inputs["Base Color"].default_value = (*ph["base_color"], 1.0)
        n.inputs["Metallic"].default_value = 0.0
        n.inputs["IOR"].default_value = ph["dielectric_ior"]
        n.inputs["Specular IOR Level"].default_value = 0.5
        n.inputs["Specular Tint"].default_value = (*ph["tint"], 1.0)
        a_name, r_name = "Anisotropic", "Anisotropic Rotation"
    n.inputs["Roughness"].default_value = roughness
    if ph["anisotropic"]:
        n.inputs[a_name].default_value = anisotropy
        n.inputs[r_name].default_value = rotation
        tree.links.new(tangent, n.inputs["Tangent"])
    return n


def hand_built(api, params, variant, name=None):
    """``mix`` (two lobes + Mix Shader by β) or ``single`` (the narrow lobe alone), typed in
    from the physical values without the add-on's tree code."""
    ph = physical(api, params)
    mat, tree, out = empty_material(name or f"{variant} {ph['kind']}")
    tangent = None
    if ph["anisotropic"]:
        t = tree.nodes.new("ShaderNodeTangent")
        t.direction_type = "RADIAL"
        t.axis = ph["tangent_axis"] or "Z"
        tangent = t.outputs[0]
    narrow = _hand_lobe(tree, ph, ph["roughness"], ph["anisotropy"], ph["rotation"], tangent)
    if variant == "single":
        tree.links.new(narrow.outputs[0], out.inputs["Surface"])
        return mat
    wide = _hand_lobe(tree, ph, ph["roughness_wide"], ph["anisotropy_wide"], ph["rotation_wide"],
                      tangent)
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = ph["beta"]
    tree.links.new(narrow.outputs[0], mix.inputs[1])
    tree.links.new(wide.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def make_variant(api, cls, variant):
    params = dict(CLASSES[cls])
    if variant == "lean":
        return api.create_material(f"{cls} lean", **params)
    if variant == "in_shader":
        return api.create_material(f"{cls} in-shader", shader_mapping=True, **params)
    return hand_built(api, params, variant, name=f"{cls} {variant}")


def assign(info, material):
    """Put ``material`` on the scene's sphere."""
    obj = info["sphere"]
    obj.data.materials.clear()
    obj.data.materials.append(material)


def rel_rmse(img, ref):
    """RMSE over the sphere pixels (alpha of the reference > 0.999), RGB, relative to the mean of
    the reference there."""
    mask = ref[..., 3] > 0.999
    d = img[..., :3][mask].astype(np.float64) - ref[..., :3][mask].astype(np.float64)
    return float(math.sqrt(np.mean(d * d)) / np.mean(ref[..., :3][mask]))
