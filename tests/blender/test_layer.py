# SPDX-License-Identifier: GPL-3.0-or-later
"""Make Hazy as one node on the artist's own material (issues 13, 20): the layer node has the
BSDF's inputs, values, links and panels; identical at haziness 0; peaks invariant on every part;
metallic maps exact per texel; a hazy coat; Remove Haze gives the exact tree back.

Scenes are exact: a plane, an orthographic camera, a delta sun, 1 sample, no bounces (Cycles
then evaluates each pixel's BSDF once, deterministically), except subsurface (random walk:
compared at noise level)."""
import importlib
import math
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import analytic
import scenes
from measurements import record


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(api=mod("api"), layer=mod("blender.model.layer"), make=mod("blender.actions.make_hazy"),
                           layer_values=mod("blender.model.layer_values"),
                           layer_notes=mod("blender.model.layer_notes"), material=mod("blender.model.material"), exr=mod("conversion.imagecheck"), core=mod("core"),
                           lobes=mod("core.lobes"), reports=mod("blender.ui.reports"), hg=hg)


# --------------------------------------------------------------------------------------------
# The artist's materials
# --------------------------------------------------------------------------------------------


def principled(name, **inputs):
    mat = scenes.new_material(name)
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.distribution = inputs.pop("distribution", "GGX")
    for k, v in inputs.items():
        bsdf.inputs[k].default_value = v
    return mat, bsdf


def image(name, pixels, non_color=True):
    h, w = pixels.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True, is_data=non_color)
    img.pixels.foreach_set(np.ascontiguousarray(pixels, dtype=np.float32).ravel())
    return img


def window_image(tree, img):
    """An image texture over the camera frame (Window coordinates, Closest): texel (i, j) covers
    the same pixels in every render of the same resolution."""
    coord = tree.nodes.new("ShaderNodeTexCoord")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation, tex.extension = img, "Closest", "EXTEND"
    tree.links.new(coord.outputs["Window"], tex.inputs["Vector"])
    return tex


def grey(values):
    v = np.asarray(values, float)
    return np.concatenate([np.repeat(v[..., None], 3, -1), np.ones(v.shape + (1,))], -1)


METALLIC_MAP = np.array([[0.0, 1.0, 0.25, 0.5], [0.75, 0.1, 0.9, 0.0],
                         [1.0, 0.33, 0.0, 0.6], [0.05, 1.0, 0.4, 0.95]])


def rusty_metal():
    """A noise texture into Metallic (the issue's first material)."""
    mat, b = principled("Rusty Metal", **{"Base Color": (0.75, 0.45, 0.3, 1.0), "Roughness": 0.3})
    tree = mat.node_tree
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    tree.links.new(noise.outputs["Fac"], b.inputs["Metallic"])
    return mat


def metallic_map(name="Metallic Map", **extra):
    mat, b = principled(name, **{"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.25,
                                 "IOR": 1.6, **extra})
    tex = window_image(mat.node_tree, image("metallic", grey(METALLIC_MAP)))
    mat.node_tree.links.new(tex.outputs["Color"], b.inputs["Metallic"])
    return mat


def car_paint():
    mat, b = principled("Car Paint", **{"Metallic": 1.0, "Base Color": (0.6, 0.05, 0.05, 1.0),
                                        "Roughness": 0.35, "Coat Weight": 1.0,
                                        "Coat Roughness": 0.03, "Coat IOR": 1.5})
    return mat


def leaf():
    mat, b = principled("Leaf", **{"Base Color": (0.1, 0.4, 0.05, 1.0), "Roughness": 0.4})
    a = np.indices((4, 4)).sum(0) % 2
    px = np.concatenate([np.ones((4, 4, 3)), a[..., None].astype(float)], -1)
    tex = window_image(mat.node_tree, image("cutout", px))
    mat.node_tree.links.new(tex.outputs["Alpha"], b.inputs["Alpha"])
    return mat


def emissive_plastic():
    mat, _ = principled("Emissive Plastic", **{"Base Color": (0.3, 0.1, 0.05, 1.0), "Roughness": 0.2,
                                               "Emission Color": (1.0, 0.5, 0.2, 1.0),
                                               "Emission Strength": 2.0})
    return mat


def skin():
    mat, _ = principled("Skin", **{"Base Color": (0.8, 0.5, 0.4, 1.0), "Roughness": 0.45,
                                   "Subsurface Weight": 0.3, "Subsurface Scale": 0.05})
    return mat


def fabric():
    mat, _ = principled("Fabric", **{"Base Color": (0.2, 0.2, 0.5, 1.0), "Roughness": 0.6,
                                     "Sheen Weight": 1.0, "Sheen Roughness": 0.4})
    return mat


def thin_film_metal():
    mat, _ = principled("Thin Film Metal", **{"Metallic": 1.0, "Base Color": (0.8, 0.8, 0.8, 1.0),
                                              "Roughness": 0.2, "Thin Film Thickness": 450.0,
                                              "Thin Film IOR": 1.33})
    return mat


def multiscatter_metal():
    mat, _ = principled("Multiscatter Metal", distribution="MULTI_GGX",
                        **{"Metallic": 1.0, "Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.3})
    return mat


def glass():
    mat, _ = principled("Glass", **{"Transmission Weight": 1.0, "Roughness": 0.5, "IOR": 1.45})
    return mat


def tinted_anisotropic():
    """Specular tint, anisotropy with a UV tangent and a normal map: what stays the user's."""
    mat, b = principled("Brushed Plastic", **{"Base Color": (0.05, 0.1, 0.3, 1.0), "Roughness": 0.3,
                                              "Specular Tint": (1.0, 0.7, 0.4, 1.0),
                                              "Anisotropic": 0.6, "Anisotropic Rotation": 0.1})
    tree = mat.node_tree
    t = tree.nodes.new("ShaderNodeTangent")
    t.direction_type = "UV_MAP"
    tree.links.new(t.outputs[0], b.inputs["Tangent"])
    nm = tree.nodes.new("ShaderNodeNormalMap")
    nm.inputs["Strength"].default_value = 0.3
    tree.links.new(nm.outputs[0], b.inputs["Normal"])
    return mat


def in_a_mix():
    mat, b = principled("Mixed", **{"Base Color": (0.2, 0.05, 0.05, 1.0), "Roughness": 0.15})
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    em = tree.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (0.1, 0.3, 0.1, 1.0)
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = 0.3
    tree.links.new(b.outputs[0], mix.inputs[1])
    tree.links.new(em.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def metallic_node(fresnel):
    mat = scenes.new_material(f"Metallic {fresnel}")
    tree = mat.node_tree
    for n in list(tree.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(n)
    out = tree.nodes[0]
    n = tree.nodes.new("ShaderNodeBsdfMetallic")
    n.distribution, n.fresnel_type = "GGX", fresnel
    n.inputs["Roughness"].default_value = 0.25
    if fresnel == "F82":
        n.inputs["Base Color"].default_value = (0.95, 0.64, 0.54, 1.0)
        n.inputs["Edge Tint"].default_value = (0.99, 0.9, 0.7, 1.0)
    else:
        n.inputs["IOR"].default_value = (0.27, 0.68, 1.32)
        n.inputs["Extinction"].default_value = (3.61, 2.63, 2.29)
    tree.links.new(n.outputs[0], out.inputs["Surface"])
    return mat


def glossy_node():
    mat = metallic_node("F82")
    tree = mat.node_tree
    tree.nodes.remove(next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfMetallic"))
    n = tree.nodes.new("ShaderNodeBsdfGlossy")
    n.distribution = "GGX"
    n.inputs["Color"].default_value = (0.8, 0.6, 0.3, 1.0)
    n.inputs["Roughness"].default_value = 0.3
    tree.links.new(n.outputs[0], tree.nodes[0].inputs["Surface"])
    mat.name = "Glossy"
    return mat


MATERIALS = {
    "rusty metal (noise into Metallic)": rusty_metal,
    "metallic map": metallic_map,
    "car paint (metal + coat)": car_paint,
    "leaf (alpha texture)": leaf,
    "emissive plastic": emissive_plastic,
    "skin (subsurface)": skin,
    "fabric (sheen)": fabric,
    "metal with thin film": thin_film_metal,
    "metal, Multiscatter GGX": multiscatter_metal,
    "glass (transmission)": glass,
    "tinted anisotropic plastic": tinted_anisotropic,
    "plastic in a Mix Shader": in_a_mix,
    "Metallic BSDF (F82)": lambda: metallic_node("F82"),
    "Metallic BSDF (physical)": lambda: metallic_node("PHYSICAL_CONDUCTOR"),
    "Glossy BSDF": glossy_node,
}


# --------------------------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------------------------

NOISY = {"skin (subsurface)", "glass (transmission)"}


def render(env, mat, light=(30.0, 0.0), view=(0.0, 0.0), res=(8, 8), passes=("combined",),
           samples=1, bounces=0, transparent=False):
    scenes.setup_render("CYCLES", samples=samples, resolution=res, bounces=bounces)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.flat_plane_scene(mat, light_dir=light, view_dir=view)
    bpy.context.scene.render.film_transparent = transparent
    return scenes.render_passes(env.exr.read_exr, passes)


def render_for(env, name, mat, **kw):
    if name in NOISY:  # random walk / refraction need bounces; compared at noise level
        kw.update(samples=16, bounces=4)
    return render(env, mat, transparent=True, **kw)


def signature(mat, locations=False):
    """Nodes (name, type, unlinked input values, settings[, label, location, parent, hide,
    mute, width]) and links of a tree."""
    sig = []
    for n in sorted(mat.node_tree.nodes, key=lambda n: n.name):
        vals = []
        for s in n.inputs:
            if not s.is_linked and hasattr(s, "default_value"):
                v = s.default_value
                vals.append((s.identifier, tuple(v) if hasattr(v, "__len__") else v))
        props = tuple(getattr(n, p, None) for p in ("distribution", "subsurface_method", "fresnel_type"))
        row = (n.name, n.bl_idname, tuple(vals), props)
        if locations:
            row += (n.label, tuple(round(x, 3) for x in n.location),
                    n.parent.name if n.parent else None, n.hide, n.mute, round(n.width, 3))
        sig.append(row)
    links = sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                   for l in mat.node_tree.links)
    return sig, links


def rel_diff(a, b, scale=None):
    scale = scale if scale is not None else max(float(np.abs(a).max()), 1e-6)
    return float(np.abs(a - b).max()) / scale


def make_hazy(env, mat, **haze):
    assert bpy.ops.hazy_gloss.make_hazy(material=mat.name) == {"FINISHED"}
    if haze:
        env.api.update_material(mat, **haze)


def bsdf_of(mat):
    return next(n for n in mat.node_tree.nodes
                if n.bl_idname in env_core_types() and not n.get("hazy_gloss_original"))


def env_core_types():
    return ("ShaderNodeBsdfPrincipled", "ShaderNodeBsdfMetallic", "ShaderNodeBsdfGlossy",
            "ShaderNodeBsdfAnisotropic")


def inputs_of(node):
    """{name: ("link", from node, from socket) | ("value", v)} of a node's enabled inputs."""
    out = {}
    for s in node.inputs:
        if not getattr(s, "enabled", True) or not s.name:
            continue
        if s.is_linked:
            out[s.name] = ("link", s.links[0].from_node.name, s.links[0].from_socket.identifier)
        elif hasattr(s, "default_value"):
            v = s.default_value
            out[s.name] = ("value", tuple(round(float(x), 6) for x in v) if hasattr(v, "__len__")
                           else round(float(v), 6))
    return out


# --------------------------------------------------------------------------------------------
# 1. One node: the BSDF's sockets, values, links and panels, and a Haze panel
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(MATERIALS))
def test_make_hazy_is_one_node_with_the_bsdfs_inputs(env, name):
    """After Make Hazy the tree has at most 3 more nodes; the layer node takes the BSDF's name
    and place, has every input of it (names, values, links) in the BSDF's panels, and a Haze
    panel; the BSDF itself is kept beside it, untouched but for its name and links."""
    mat = MATERIALS[name]()
    core = bsdf_of(mat)
    want = inputs_of(core)
    name0, loc0 = core.name, tuple(core.location)
    n_before = len(mat.node_tree.nodes)
    make_hazy(env, mat)
    tree = mat.node_tree
    assert len(tree.nodes) - n_before <= 3, [n.name for n in tree.nodes]
    node = tree.nodes[name0]
    assert node.bl_idname == "ShaderNodeGroup" and tuple(node.location) == loc0
    got = inputs_of(node)
    for k, v in want.items():
        assert got.get(k) == v, (k, got.get(k), v)
    haze = {it.name for it in node.node_tree.interface.items_tree
            if it.item_type == "SOCKET" and it.in_out == "INPUT" and it.parent is not None
            and it.parent.name == "Haze"}
    assert {"Haziness", "Haze Extent X", "Haze Extent Y"} <= haze
    # the BSDF's own panels: every socket of the group sits in the panel Make Group (Ctrl+G)
    # gives it (Blender's own declaration)
    panels = {it.name: (it.parent.name if it.parent is not None else "")
              for it in node.node_tree.interface.items_tree if it.item_type == "SOCKET"
              and it.in_out == "INPUT"}
    kind = env.layer.core_type(core)
    decl = importlib.import_module(f"{env.hg.__name__}.core.tables.bsdf_interfaces").TABLES
    table = decl[f"{bpy.app.version[0]}.{bpy.app.version[1]}"][kind]["sockets"]
    for k in want:
        assert panels[k] == table[k]["panel"], (k, panels[k], table[k]["panel"])
    # the kept BSDF: collapsed, muted, off the output, its values and links as they were (the
    # layer node's inputs are fed by the same sockets)
    kept = env.layer.original_node(mat)
    assert kept == core and kept.mute and kept.hide and not kept.outputs[0].is_linked
    for s in kept.inputs:
        if s.is_linked:
            assert [l.from_socket for l in node.inputs[s.name].links] == \
                [l.from_socket for l in s.links], s.name


@pytest.mark.parametrize("name", list(MATERIALS))
def test_haziness_zero_is_the_original(env, name):
    mat = MATERIALS[name]()
    before = render_for(env, name, mat)
    assert before["combined"].max() > 0.005
    make_hazy(env, mat)
    assert env.api.is_hazy(mat)
    p = env.api.read_parameters(mat)
    assert p["layered"] and p["haziness"] == 0.0
    after = render_for(env, name, mat)
    b, a = before["combined"], after["combined"]
    err = float(np.abs(a - b).max()) if name not in NOISY else rel_diff(a, b)
    alpha = float(np.abs(after["alpha"] - before["alpha"]).max())
    record("layer_haziness0", {name: dict(
        max_abs_diff=err, peak_before=float(b.max()), peak_after=float(a.max()),
        mean_before=float(b.mean()), mean_after=float(a.mean()),
        transparent_before=float((before["alpha"] < 0.5).mean()),
        transparent_after=float((after["alpha"] < 0.5).mean()))})
    if name in NOISY:
        assert err <= 1e-5 and alpha <= 1e-6, (err, alpha)
    else:
        assert err == 0.0 and alpha == 0.0, (err, alpha)


@pytest.mark.parametrize("name", list(MATERIALS))
def test_remove_haze_gives_the_exact_tree_back(env, name):
    """Make Hazy, change haze, Remove Haze: names, types, values, links, labels, locations,
    frames, collapse and mute states as before."""
    mat = MATERIALS[name]()
    frame = mat.node_tree.nodes.new("NodeFrame")
    frame.name = "User frame"
    core = bsdf_of(mat)
    core.parent = frame
    core.label = "My BSDF"
    sig = signature(mat, locations=True)
    make_hazy(env, mat, haziness=0.5, coat_haziness=0.3)
    assert signature(mat, locations=True) != sig
    assert bpy.ops.hazy_gloss.remove_haze(material=mat.name) == {"FINISHED"}
    assert signature(mat, locations=True) == sig
    assert not env.api.is_hazy(mat)
    assert bpy.ops.hazy_gloss.remove_haze(material=mat.name) == {"CANCELLED"}


def test_remove_haze_keeps_what_the_artist_changed_since(env):
    """Values typed into the layer node and links made to it go back to the BSDF."""
    mat = metallic_map()
    make_hazy(env, mat, haziness=0.5)
    node = env.layer.layer_node(mat)
    node.inputs["Roughness"].default_value = 0.42
    noise = mat.node_tree.nodes.new("ShaderNodeTexNoise")
    mat.node_tree.links.new(noise.outputs["Fac"], node.inputs["Coat Weight"])
    env.api.remove_haze(mat)
    core = bsdf_of(mat)
    assert core.inputs["Roughness"].default_value == pytest.approx(0.42)
    assert core.inputs["Coat Weight"].links[0].from_node == noise
    assert core.inputs["Metallic"].is_linked  # the metallic map, as before


#: A node's height on screen at UI scale 1, for the overlap check: 32 px of header and 22 per
#: row (Blender's widget unit is 20 px, sockets are drawn a little apart), its own controls
#: as rows (Math: operation and Clamp; Mix: type, factor mode, clamp; a Color Ramp's widget and
#: an image's selector take several), an unlinked vector input as its label and x, y, z.
_CONTROL_ROWS = {"ShaderNodeMath": 2, "ShaderNodeVectorMath": 1, "ShaderNodeMix": 3,
                 "ShaderNodeClamp": 1, "ShaderNodeSeparateColor": 1, "ShaderNodeCombineColor": 1,
                 "ShaderNodeValToRGB": 5, "ShaderNodeTexEnvironment": 5,
                 "ShaderNodeBsdfPrincipled": 5, "ShaderNodeBsdfMetallic": 2,
                 "ShaderNodeBsdfGlossy": 1}


def _screen_rect(node):
    rows = _CONTROL_ROWS.get(node.bl_idname, 0)
    rows += sum(1 for o in node.outputs if o.enabled and not o.hide)
    for i in node.inputs:
        if i.enabled and not i.hide and not (i.hide_value and not i.is_linked):
            rows += 4 if (i.type == "VECTOR" and not i.is_linked) else 1
    x, y = node.location_absolute if hasattr(node, "location_absolute") else node.location
    return node.name, x, y, node.width, 32.0 + 22.0 * rows


def test_layer_groups_are_shared_and_readable(env):
    """Materials that use the same parts share one group, others get their own; inside, every
    node sits in a labelled frame of at most 80 nodes that names its equations, no two nodes
    (and no two frames) overlap, and every socket of the group is named for what it carries."""
    a, b = car_paint(), car_paint()
    make_hazy(env, a)
    make_hazy(env, b)
    ga, gb = env.layer.layer_node(a).node_tree, env.layer.layer_node(b).node_tree
    assert ga == gb
    c = metallic_map()  # a metallic map needs both parts: another group
    make_hazy(env, c)
    gc = env.layer.layer_node(c).node_tree
    assert gc != ga
    for ng in (ga, gc):
        frames = [n for n in ng.nodes if n.bl_idname == "NodeFrame"]
        members = {f.name: [n for n in ng.nodes if n.parent == f] for f in frames}
        assert frames and all(f.label for f in frames), ng.name
        assert all(len(m) <= 80 for m in members.values()), \
            {f: len(m) for f, m in members.items() if len(m) > 80}
        assert all(("Eq." in f.label or "Table" in f.label or ":" in f.label) for f in frames), \
            [f.label for f in frames]
        loose = [n.name for n in ng.nodes if n.parent is None and n.bl_idname != "NodeFrame"]
        assert not loose, loose[:5]
        from bl_ext.test_repo.hazy_gloss import node_layout
        rects = [_screen_rect(n) for n in ng.nodes if n.bl_idname != "NodeFrame"]
        assert not node_layout.overlaps(rects), node_layout.overlaps(rects)[:5]
        boxes = []
        for f, m in members.items():
            rs = [_screen_rect(n) for n in m]
            left = min(r[1] for r in rs) - 20
            top = max(r[2] for r in rs) + 40
            right = max(r[1] + r[3] for r in rs) + 20
            bottom = min(r[2] - r[4] for r in rs) - 20
            boxes.append((f, left, top, right - left, top - bottom))
        assert not node_layout.overlaps(boxes), node_layout.overlaps(boxes)[:3]
        names = [item.name for item in ng.interface.items_tree if item.item_type == "SOCKET"]
        assert all(names) and not any(n.lower().startswith("value") for n in names), names


# --------------------------------------------------------------------------------------------
# Peak invariance (Eq. 2: g_h(n, n) = 0), on the glossy pass
# --------------------------------------------------------------------------------------------

PEAK = {
    "rusty metal (noise into Metallic)": rusty_metal,
    "metallic map": metallic_map,
    "car paint (metal + coat)": car_paint,
    "metal with thin film": thin_film_metal,
    "tinted anisotropic plastic": tinted_anisotropic,
    "Metallic BSDF (F82)": lambda: metallic_node("F82"),
    "Metallic BSDF (physical)": lambda: metallic_node("PHYSICAL_CONDUCTOR"),
    "Glossy BSDF": glossy_node,
    "dielectric": lambda: principled("Dielectric", **{"Base Color": (0.3, 0.3, 0.3, 1.0),
                                                     "Roughness": 0.2})[0],
    "textured roughness dielectric": lambda: textured_roughness(),
    "metal, Multiscatter GGX": multiscatter_metal,
    "Metallic BSDF (F82) with thin film": lambda: metallic_film(),
    "dielectric with thin film": lambda: principled(
        "Film Dielectric", **{"Base Color": (0.05, 0.05, 0.05, 1.0), "Roughness": 0.25,
                              "Thin Film Thickness": 320.0, "Thin Film IOR": 1.6})[0],
    "textured roughness dielectric, Multiscatter GGX": lambda: textured_roughness("MULTI_GGX"),
    "textured metal, Multiscatter GGX": lambda: textured_metal("MULTI_GGX"),
    "coat with textured roughness": lambda: textured_coat(),
    "dielectric, Multiscatter GGX": lambda: principled(
        "MS Dielectric", distribution="MULTI_GGX", **{"Base Color": (0.3, 0.3, 0.3, 1.0),
                                                       "Roughness": 0.3})[0],
}


def metallic_film():
    mat = metallic_node("F82")
    n = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfMetallic")
    if "Thin Film Thickness" not in n.inputs:
        pytest.skip("the Metallic BSDF has no thin film before Blender 5.0")
    n.inputs["Thin Film Thickness"].default_value = 380.0
    n.inputs["Thin Film IOR"].default_value = 1.45
    return mat


def textured_roughness(distribution="GGX"):
    mat, b = principled("Textured Roughness", distribution=distribution,
                        **{"Base Color": (0.5, 0.2, 0.1, 1.0), "IOR": 1.5})
    rng = np.random.default_rng(4)
    tex = window_image(mat.node_tree, image("rough", grey(rng.uniform(0.1, 0.5, (4, 4)))))
    mat.node_tree.links.new(tex.outputs["Color"], b.inputs["Roughness"])
    return mat


def textured_metal(distribution="GGX"):
    mat, b = principled("Textured Metal", distribution=distribution, **{"Metallic": 1.0})
    rng = np.random.default_rng(5)
    px = np.concatenate([rng.uniform(0.3, 0.95, (4, 4, 3)), np.ones((4, 4, 1))], -1)
    col = window_image(mat.node_tree, image("metal colour", px))
    rough = window_image(mat.node_tree, image("metal rough", grey(rng.uniform(0.15, 0.5, (4, 4)))))
    mat.node_tree.links.new(col.outputs["Color"], b.inputs["Base Color"])
    mat.node_tree.links.new(rough.outputs["Color"], b.inputs["Roughness"])
    return mat


def textured_coat():
    """Only the coat reflects; its roughness is a texture (node math for the coat's haze)."""
    mat, b = principled("Textured Coat", **{"Base Color": (0.0, 0.0, 0.0, 1.0),
                                            "Specular IOR Level": 0.0, "Coat Weight": 1.0,
                                            "Coat IOR": 1.5})
    rng = np.random.default_rng(6)
    tex = window_image(mat.node_tree, image("coat rough", grey(rng.uniform(0.05, 0.3, (4, 4)))))
    mat.node_tree.links.new(tex.outputs["Color"], b.inputs["Coat Roughness"])
    return mat


@pytest.mark.parametrize("name", list(PEAK))
def test_peak_is_invariant(env, name):
    """Light, view and normal aligned: every pixel is the peak.  Haziness 0.9 leaves the
    specular peak (glossy pass) where it was, part by part (the car paint's coat is not hazed
    here: a hazier coat reflects more and so lets less reach the base, see the coat test)."""
    mat = PEAK[name]()
    tangent_free = "anisotropic" not in name  # a normal map tilts the normal off the peak
    if not tangent_free:
        nm = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeNormalMap")
        mat.node_tree.nodes.remove(nm)
    make_hazy(env, mat)
    before = render(env, mat, light=(0.0, 0.0), passes=("glossy",))["glossy"]
    # the tint reaches F0 = 1 at most: a filmed dielectric's r̂ at 0.9 is out of its reach
    haziness = 0.3 if "film" in name and "dielectric" in name else 0.9
    env.api.update_material(mat, haziness=haziness, haze_extent=(8.0, 3.0),
                            coat_haziness=0.8 if name == "coat with textured roughness" else 0.0)
    after = render(env, mat, light=(0.0, 0.0), passes=("glossy",))["glossy"]
    err = rel_diff(before, after)
    record("layer_peak", {name: err})
    assert before.max() > 0.05
    if "film" in name and "dielectric" not in name:
        # a film's interference on a metal is not linear in F0: the peak moves, by what the
        # layer says (a dielectric's film is in the node math: its peak holds below)
        said = env.layer_notes.film_peak_change(env.layer.layer_node(mat))
        ch = np.abs(after[4, 4] - before[4, 4]).argmax()
        moved = float(after[4, 4, ch] / before[4, 4, ch] - 1.0)
        record("layer_film_peak", {name: dict(measured=moved, said=said)})
        assert said is not None and abs(moved - said) <= 0.05 * abs(said) + 2e-5, (moved, said)
        if abs(said) > 1e-5:
            assert any("thin film" in n and "%" in n for n in env.layer.notes(mat))
            return
        # no film on this part (4.5's Principled metal): the peak holds like any other
        assert not any("thin film" in n for n in env.layer.notes(mat))
    assert err <= 1e-5, err


def test_haze_shows_off_peak(env):
    """The halo is there: off the peak, haziness brightens the glossy pass."""
    mat = multiscatter_metal()
    make_hazy(env, mat)
    view = ((50.0, 0.0), (0.0, 0.0))
    before = render(env, mat, *view, passes=("glossy",))["glossy"]
    env.api.update_material(mat, haziness=0.8)
    after = render(env, mat, *view, passes=("glossy",))["glossy"]
    assert after.mean() > 1.3 * before.mean(), (before.mean(), after.mean())


# --------------------------------------------------------------------------------------------
# 2. Metallic maps are exact per texel
# --------------------------------------------------------------------------------------------


def test_metallic_map_is_exact_per_texel(env):
    """A metallic map gives, at every texel, the pure metal and the pure dielectric hazy
    materials mixed by the map; each part has its own β."""
    haze = dict(haziness=0.6, haze_extent=(6.0, 6.0))
    views = [((30.0, 0.0), (0.0, 0.0)), ((0.0, 0.0), (0.0, 0.0)), ((50.0, 20.0), (20.0, 200.0))]
    mixed = metallic_map()
    make_hazy(env, mixed, **haze)
    pure = {}
    for m in (0.0, 1.0):
        mat, _ = principled(f"Pure {m}", **{"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.25,
                                            "IOR": 1.6, "Metallic": m})
        make_hazy(env, mat, **haze)
        pure[m] = mat
    betas = {}
    for m, mat in pure.items():
        vals, _ = env.layer_values.values(env.layer.layer_node(mat))
        betas[m] = vals["beta metal" if m else "beta dielectric"]
    assert abs(betas[0.0] - betas[1.0]) > 0.05, betas  # each part has its own haze mapping
    m = np.repeat(np.repeat(METALLIC_MAP, 2, 0), 2, 1)[..., None]
    worst = 0.0
    for light, view in views:
        got = render(env, mixed, light, view)["combined"]
        d = render(env, pure[0.0], light, view)["combined"]
        k = render(env, pure[1.0], light, view)["combined"]
        want = (1.0 - m) * d + m * k
        err = rel_diff(got, want)
        worst = max(worst, err)
    record("layer_metallic_map", {"max_rel_vs_pure_parts": worst, "beta": betas})
    assert worst <= 1e-5, worst


# --------------------------------------------------------------------------------------------
# Against an independent BRDF: the layered metal is Eq. 1 with Principled's F82 Fresnel
# --------------------------------------------------------------------------------------------


def schlick(cos_d, f0):
    return f0 + (1.0 - f0) * (1.0 - cos_d)[..., None] ** 5


@pytest.mark.parametrize("light,view", [((30.0, 0.0), (0.0, 0.0)), ((45.0, 30.0), (30.0, 200.0)),
                                        ((60.0, 0.0), (10.0, 180.0))])
def test_layered_metal_matches_eq1(env, light, view):
    """A hazy Principled metal (specular tint white: F82 reduces to Schlick) against Eq. 1
    evaluated in numpy from the mapping's β, α_n, α_w and r."""
    rc = np.array([0.9, 0.6, 0.3])
    mat, _ = principled("Metal", **{"Metallic": 1.0, "Base Color": tuple(rc) + (1.0,),
                                    "Roughness": 0.3})
    make_hazy(env, mat, haziness=0.7, haze_extent=5.0)
    d = env.lobes.describe("DIELECTRIC", "GGX", core_reflectivity=tuple(rc), roughness=0.3,
                           haziness=0.7, haze_extent=5.0)
    m = d.mapping
    img = render(env, mat, light, view)["combined"]
    wi, wo = analytic.direction(*light), analytic.direction(*view)
    h = analytic.half_vector(wi, wo)
    cos_d = np.clip(np.dot(h, wi), 0.0, 1.0)
    lobe = lambda a: analytic.microfacet_lobe(wi, wo, a[0], a[1], "GGX")  # noqa: E731
    f = ((1.0 - m.beta) * lobe(m.alpha) + m.beta * lobe(m.alpha_wide)) * \
        schlick(np.asarray(cos_d), np.asarray(m.reflectivity))
    want = f * wi[2]
    got = img[4, 4]
    err = float(np.abs(got - want).max() / np.abs(want).max())
    record("layer_vs_eq1", {f"metal light={light} view={view}": err})
    assert err <= 2e-5, (got, want)


# --------------------------------------------------------------------------------------------
# 3. Hazy coat
# --------------------------------------------------------------------------------------------


def test_coat_peak_is_invariant_and_independent(env):
    """Only the coat reflects (black base, no base specular): its peak holds under coat haze;
    the base's haze does not touch the coat."""
    mat, _ = principled("Coat Only", **{"Base Color": (0.0, 0.0, 0.0, 1.0), "Specular IOR Level": 0.0,
                                        "Coat Weight": 1.0, "Coat Roughness": 0.1, "Coat IOR": 1.5,
                                        "Roughness": 0.3})
    make_hazy(env, mat)
    peak = dict(light=(0.0, 0.0), passes=("glossy",))
    off = dict(light=(20.0, 0.0), passes=("glossy",))
    p0 = render(env, mat, **peak)["glossy"]
    o0 = render(env, mat, **off)["glossy"]
    env.api.update_material(mat, coat_haziness=0.8, coat_haze_extent=6.0)
    p1 = render(env, mat, **peak)["glossy"]
    o1 = render(env, mat, **off)["glossy"]
    err = rel_diff(p0, p1)
    record("layer_coat", {"coat peak": err, "coat halo gain off peak": float(o1.mean() / o0.mean())})
    assert p0.max() > 0.05 and err <= 1e-5, err
    assert o1.mean() > 1.5 * o0.mean()
    # base haze changes nothing here: the base reflects nothing
    env.api.update_material(mat, haziness=0.9)
    p2 = render(env, mat, **peak)["glossy"]
    assert rel_diff(p1, p2) <= 1e-5


# --------------------------------------------------------------------------------------------
# The layer follows the user's edits of the core; Remove Haze gives the material back
# --------------------------------------------------------------------------------------------


def _edit(bsdf):
    bsdf.inputs["Base Color"].default_value = (0.2, 0.5, 0.7, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.45
    bsdf.inputs["Sheen Weight"].default_value = 0.5
    bsdf.inputs["Metallic"].default_value = 0.4


def test_edits_of_the_layer_node_render_without_python(env):
    """Edit the layer node's BSDF inputs (as in the node editor): no Python runs (the group
    computes the haze from them) and the material renders what Make Hazy on the edited
    material renders."""
    mat = car_paint()
    make_hazy(env, mat, haziness=0.6, coat_haziness=0.3)
    view = dict(light=(35.0, 0.0), view=(10.0, 180.0))
    render(env, mat, **view)  # the material is in use: edits reach the depsgraph
    node = env.layer.layer_node(mat)
    calls = []
    real = env.layer.apply
    env.layer.apply = lambda *a, **k: calls.append(1) or real(*a, **k)
    try:
        _edit(node)
        bpy.context.view_layer.update()
        got = render(env, mat, **view)["combined"]
    finally:
        env.layer.apply = real
    assert calls == []
    fresh = car_paint()
    _edit(bsdf_of(fresh))
    make_hazy(env, fresh, haziness=0.6, coat_haziness=0.3)
    want = render(env, fresh, **view)["combined"]
    assert rel_diff(got, want) == 0.0


# --------------------------------------------------------------------------------------------
# What cannot be kept is refused with the reason, touching nothing
# --------------------------------------------------------------------------------------------



def test_a_part_the_group_lacks_renders_plain(env):
    """Edited where Hazy Gloss does not run (its handler off, as on a farm or in a Blender
    without it), an input that needs a part the group lacks renders that part plain: Metallic
    0.4 on a metal layer's group leaves the base without haze (the coat, whose part is there,
    keeps its haze), and the notes say so.  The reference is the same edit made hazy with base
    haziness 0: the parts mixed by the metallic map as Cycles mixes them."""
    from bl_ext.test_repo.hazy_gloss.blender.actions import sync
    mat = car_paint()
    make_hazy(env, mat, haziness=0.6, coat_haziness=0.3)
    view = dict(light=(35.0, 0.0), view=(10.0, 180.0))
    render(env, mat, **view)
    node = env.layer.layer_node(mat)
    before = node.node_tree
    off = ((bpy.app.handlers.depsgraph_update_post, sync.on_depsgraph_update),
           (bpy.app.handlers.frame_change_pre, sync.parts_on_frame_change))
    for handlers, fn in off:
        handlers.remove(fn)
    try:
        _edit(node)
        bpy.context.view_layer.update()
        assert node.node_tree == before
        got = render(env, mat, **view)["combined"]
        assert node.node_tree == before
        notes = env.layer.notes(mat, quick=False)
    finally:
        for handlers, fn in off:
            handlers.append(fn)
    assert any("no dielectric part" in n for n in notes), notes
    fresh = car_paint()
    _edit(bsdf_of(fresh))
    make_hazy(env, fresh, haziness=0.0, coat_haziness=0.3)
    want = render(env, fresh, **view)["combined"]
    assert np.all(np.isfinite(got))
    assert rel_diff(got, want) <= 1e-5, rel_diff(got, want)
    sync.sync(mat)  # the add-on back: the layer moves to the group with the part
    assert env.layer.layer_node(mat).node_tree != before
    assert not env.layer.notes(mat, quick=False) or \
        not any("part" in n for n in env.layer.notes(mat, quick=False))

def test_refuses_what_it_cannot_keep(env):
    api = env.api
    # the BSDF inside a node group (shared by other materials)
    mat, b = principled("Grouped")
    tree = mat.node_tree
    group = bpy.data.node_groups.new("Shared Look", "ShaderNodeTree")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    inner = group.nodes.new("ShaderNodeBsdfPrincipled")
    gout = group.nodes.new("NodeGroupOutput")
    group.links.new(inner.outputs[0], gout.inputs[0])
    gnode = tree.nodes.new("ShaderNodeGroup")
    gnode.node_tree = group
    tree.nodes.remove(b)
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    tree.links.new(gnode.outputs[0], out.inputs["Surface"])
    sig = signature(mat)
    with pytest.raises(ValueError, match="inside the node group “Group”.*ungroup"):
        api.make_hazy(mat, haziness=0.5)
    assert signature(mat) == sig and not api.is_hazy(mat)


def test_a_bsdf_feeding_a_shader_mixing_group_is_found(env):
    """A node group of the artist's that mixes the shader it is given (Group Input -> Mix Shader
    with a Transparent BSDF -> Group Output): the Principled feeding it is the material's BSDF
    (Make Hazy refused it as "inside the node group", which holds no BSDF)."""
    mat, b = principled("Mixed in a group", **{"Roughness": 0.3})
    tree = mat.node_tree
    group = bpy.data.node_groups.new("Mixer", "ShaderNodeTree")
    group.interface.new_socket("Shader", in_out="INPUT", socket_type="NodeSocketShader")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    gin, gout = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    mix, clear = group.nodes.new("ShaderNodeMixShader"), group.nodes.new("ShaderNodeBsdfTransparent")
    group.links.new(gin.outputs[0], mix.inputs[1])
    group.links.new(clear.outputs[0], mix.inputs[2])
    group.links.new(mix.outputs[0], gout.inputs[0])
    gnode = tree.nodes.new("ShaderNodeGroup")
    gnode.node_tree = group
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    tree.links.new(b.outputs[0], gnode.inputs[0])
    tree.links.new(gnode.outputs[0], out.inputs["Surface"])
    env.api.make_hazy(mat, haziness=0.5)
    node = env.layer.layer_node(mat)
    assert node is not None and node.outputs[0].links[0].to_node == gnode
    assert not any("connected" in n for n in env.api.read_parameters(mat)["notes"])


def test_make_hazy_on_a_hazy_material_names_a_missing_node(env):
    """node= naming no BSDF on a hazy material: "no ... BSDF named" (it said "Remove Haze first
    to put it on “Nope”", as if that could work)."""
    mat, _ = principled("Named", **{"Roughness": 0.3})
    env.api.make_hazy(mat, haziness=0.4)
    for name in ("Nope", "Material Output"):
        with pytest.raises(ValueError, match=f"has no Principled, Metallic or Glossy BSDF named “{name}”"):
            env.api.make_hazy(mat, haziness=0.5, node=name)
    assert env.api.read_parameters(mat)["haziness"] == pytest.approx(0.4)


def test_picks_the_bsdf_and_names_the_others(env):
    mat, b = principled("Two BSDFs", **{"Roughness": 0.3})
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(b.outputs[0], mix.inputs[1])
    tree.links.new(glossy.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    env.reports.last_reports.clear()
    assert bpy.ops.hazy_gloss.make_hazy(material=mat.name) == {"FINISHED"}
    warn = " ".join(m for level, m in env.reports.last_reports if level == "WARNING")
    assert "not hazed" in warn and "Glossy BSDF" in warn
    assert env.layer.layer_node(mat).name == "Principled BSDF"
    env.api.remove_haze(mat)
    env.api.make_hazy(mat, node=glossy.name, haziness=0.3)
    assert env.layer.layer_node(mat).name == "Glossy BSDF"
    assert env.api.read_parameters(mat)["kind"] == "LEGACY"


# --------------------------------------------------------------------------------------------
# 5. Keep body colour
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("view", [(0.0, 0.0), (40.0, 180.0), (70.0, 180.0)])
def test_keep_body_colour(env, view):
    """Haze raises a dielectric's reflectivity, which darkens the diffuse under it; Keep Body
    Colour brightens the base colour by c(μ) — computed in the layer's group from Cycles' own
    albedo tables, per shading point — so the diffuse pass stays what it was, where the base
    has room to get brighter."""
    def plastic():
        return principled("Red Plastic", **{"Base Color": (0.5, 0.1, 0.05, 1.0), "Roughness": 0.3})[0]
    light = (30.0, 0.0)
    orig = render(env, plastic(), light, view, passes=("diffuse",))["diffuse"]
    hazy = plastic()
    make_hazy(env, hazy, haziness=0.3)
    dark = render(env, hazy, light, view, passes=("diffuse",))["diffuse"]
    kept = plastic()
    make_hazy(env, kept, haziness=0.3, keep_body_colour=True)
    keep = render(env, kept, light, view, passes=("diffuse",))["diffuse"]
    darkening = 1.0 - float(dark[4, 4, 0] / orig[4, 4, 0])
    residual = float(np.abs(keep[4, 4] / orig[4, 4] - 1.0).max())
    record("layer_body_colour", {f"view {view[0]:g}": dict(darkening=darkening, kept=residual)})
    assert darkening > 0.03, darkening
    assert residual <= 1e-5, residual
    # the peak is untouched by the compensation (specular only)
    peak = lambda m: render(env, m, (0.0, 0.0), passes=("glossy",))["glossy"]  # noqa: E731
    assert rel_diff(peak(hazy), peak(kept)) <= 1e-5


def test_keep_body_colour_says_what_it_cannot_keep(env):
    mat, _ = principled("White", **{"Base Color": (0.9, 0.9, 0.9, 1.0), "Roughness": 0.3})
    make_hazy(env, mat, haziness=0.5, keep_body_colour=True)
    notes = " ".join(env.layer.notes(mat))
    assert "too bright to keep" in notes and "darker" in notes


@pytest.mark.parametrize("name", ["emissive plastic", "leaf (alpha texture)", "fabric (sheen)"])
def test_what_haze_does_not_touch_renders_as_before(env, name):
    """With haze on, the emission pass and the alpha (cut-out) are exactly the original's."""
    mat = MATERIALS[name]()
    before = render(env, mat, passes=("combined", "emission"), transparent=True)
    make_hazy(env, mat, haziness=0.5, haze_extent=6.0)
    after = render(env, mat, passes=("combined", "emission"), transparent=True)
    emission = float(np.abs(before["emission"] - after["emission"]).max())
    alpha = float(np.abs(before["alpha"] - after["alpha"]).max())
    record("layer_untouched", {name: dict(emission=emission, alpha=alpha)})
    assert emission <= 1e-6 * max(1.0, float(before["emission"].max())) and alpha == 0.0


def test_haze_panel_is_the_schemas(env):
    """The layer group's Haze panel holds schema.layer_sockets of its BSDF, each socket with
    the schema's name, default, limits and tooltip (hazy_gloss.schema.HAZE_SOCKETS)."""
    schema = importlib.import_module(f"{env.hg.__name__}.schema")
    for name in ("car paint (metal + coat)", "metal with thin film"):
        mat = MATERIALS[name]()
        make_hazy(env, mat)
        node = env.layer.layer_node(mat)
        kind = env.layer_values.group_config(node).get("bsdf")
        want = [schema.HAZE_SOCKETS[k] for k in schema.layer_sockets(kind, False)]
        got = [(it.name, it.default_value, it.min_value, it.max_value, it.description)
               for it in node.node_tree.interface.items_tree
               if it.item_type == "SOCKET" and it.in_out == "INPUT" and it.parent is not None
               and it.parent.name == "Haze"]
        f32 = np.float32
        assert [(n, f32(d), f32(lo), f32(hi), t) for n, d, lo, hi, t in want] == \
            [(n, f32(d), f32(lo), f32(hi), t) for n, d, lo, hi, t in got], kind


def test_a_colour_just_under_one_says_how_little_haze_shows(env):
    """Silver (Base Color 0.97) at haziness 0.9 on a metal: Eq. 6's energy bound leaves the
    halo a small share of the reflection.  The note gives that share and what Reflectivity Cap
    0.9 gives, each the paper's Eq. 7 β (float64, here), and the peak drop 1 - 0.9/0.97."""
    rc, bh, rough, ext = 0.97, 0.9, 0.3, 5.0
    mat, _ = principled("Silver", **{"Metallic": 1.0, "Base Color": (rc, 0.96, 0.95, 1.0),
                                     "Roughness": rough})
    make_hazy(env, mat, haziness=bh, haze_extent=ext)
    notes = [n for n in env.layer.notes(mat, quick=False) if n.startswith("little haze shows")]
    assert len(notes) == 1, env.layer.notes(mat, quick=False)

    def eq7_beta(r):  # energy side (r > p): β = β_h (1 - r) / ((1 - p)(r + β_h (1 - r)))
        a = rough ** 2
        p = (a / (a * (1 + ext))) ** 2
        assert r > p
        return bh * (1 - r) / ((1 - p) * (r + bh * (1 - r)))
    now, capped = eq7_beta(rc), eq7_beta(0.9)
    assert now < 0.05 * bh
    assert f"leaves the halo {100 * now:.1f}% of the reflection" in notes[0], notes[0]
    assert f"Reflectivity Cap 0.9 gives it {100 * capped:.0f}%" in notes[0], notes[0]
    assert f"drops by {100 * (1 - 0.9 / rc):.1f}%" in notes[0], notes[0]
    env.api.update_material(mat, reflectivity_cap=0.9)
    assert not [n for n in env.layer.notes(mat, quick=False) if n.startswith("little haze")]


def test_notes_evaluate_the_group_only_where_a_note_reads_a_value(env, monkeypatch):
    """The notes read the group's values (β, r, the coat's IOR) only for inputs they judge: a
    silver whose Base Color, Metallic and Specular Tint are linked has nothing to judge (its
    metal's colour and its dielectric's F0 vary) and costs no evaluation; the same silver with
    constant inputs evaluates and says how little haze shows."""
    calls = []
    evaluate = env.layer_values.evaluate

    def counted(*a, **k):
        calls.append(a[1])
        return evaluate(*a, **k)
    monkeypatch.setattr(env.layer_values, "evaluate", counted)
    inputs = {"Metallic": 1.0, "Base Color": (0.97, 0.96, 0.95, 1.0), "Roughness": 0.3}
    linked, bsdf = principled("Linked silver", **inputs)
    tree = linked.node_tree
    for name, node in (("Base Color", "ShaderNodeRGB"), ("Metallic", "ShaderNodeValue"),
                       ("Specular Tint", "ShaderNodeRGB")):
        src = tree.nodes.new(node)
        src.outputs[0].default_value = bsdf.inputs[name].default_value
        tree.links.new(src.outputs[0], bsdf.inputs[name])
    make_hazy(env, linked, haziness=0.9, haze_extent=5.0)
    calls.clear()
    assert not [n for n in env.layer.notes(linked, quick=False) if "haze shows" in n]
    assert calls == []
    plain, _ = principled("Silver", **inputs)
    make_hazy(env, plain, haziness=0.9, haze_extent=5.0)
    calls.clear()
    assert [n for n in env.layer.notes(plain, quick=False) if n.startswith("little haze shows")]
    assert calls


@pytest.mark.parametrize("haziness", [0.6, 0.9])
@pytest.mark.parametrize("thickness", [250.0, 400.0])
def test_a_high_index_film_on_a_dielectric_keeps_the_peak(env, haziness, thickness):
    """A film of IOR 2 on a dielectric over black under Multiscatter GGX: the film's F(0)
    differs per channel, and so does each channel's energy factor; every channel keeps its
    peak (it moved by 0.2-0.4 % when one gain raised them all)."""
    mat, _ = principled("Film IOR 2", distribution="MULTI_GGX",
                        **{"Base Color": (0.0, 0.0, 0.0, 1.0), "Roughness": 0.25,
                           "Thin Film Thickness": thickness, "Thin Film IOR": 2.0})
    make_hazy(env, mat)
    before = render(env, mat, light=(0.0, 0.0), passes=("glossy",))["glossy"]
    env.api.update_material(mat, haziness=haziness, haze_extent=5.0)
    after = render(env, mat, light=(0.0, 0.0), passes=("glossy",))["glossy"]
    assert before[4, 4, :3].min() > 0.01
    err = float(np.abs(after[4, 4, :3] / before[4, 4, :3] - 1.0).max())
    record("layer_film_ior2_peak", {f"{thickness} {haziness}": err})
    # 1e-5 in 5.x; 4.5's film F is read from a table of its Gaussian fit (1.5e-5 in F): the
    # budget of an approximation, 1e-4
    assert err <= (1e-5 if bpy.app.version >= (5, 0, 0) else 1e-4), err
