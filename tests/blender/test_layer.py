# SPDX-License-Identifier: GPL-3.0-or-later
"""Make Hazy as a layer on the artist's own material (issue 13): everything kept, identical at
haziness 0, peaks invariant on every part, metallic maps exact per texel, a hazy coat.

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
    return SimpleNamespace(api=mod("api"), layer=mod("blender.layer"), make=mod("blender.make_hazy"),
                           material=mod("blender.material"), exr=mod("exr"), core=mod("core"),
                           lobes=mod("core.lobes"), ops=mod("blender.operators"), hg=hg)


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


def signature(mat):
    """Nodes (name, type, unlinked input values, settings) and links of a tree."""
    sig = []
    for n in sorted(mat.node_tree.nodes, key=lambda n: n.name):
        vals = []
        for s in n.inputs:
            if not s.is_linked and hasattr(s, "default_value"):
                v = s.default_value
                vals.append((s.identifier, tuple(v) if hasattr(v, "__len__") else v))
        props = tuple(getattr(n, p, None) for p in ("distribution", "subsurface_method", "fresnel_type"))
        sig.append((n.name, n.bl_idname, tuple(vals), props))
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


# --------------------------------------------------------------------------------------------
# 1. Make Hazy keeps everything; haziness 0 is the original
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", list(MATERIALS))
def test_haziness_zero_is_the_original(env, name):
    mat = MATERIALS[name]()
    sig = signature(mat)
    before = render_for(env, name, mat)
    assert before["combined"].max() > 0.005
    make_hazy(env, mat)
    assert env.api.is_hazy(mat)
    p = env.api.read_parameters(mat)
    assert p["layered"] and p["haziness"] == 0.0
    assert signature(mat) == sig  # not one node, link or value changed
    # haze on, then off again: the user's tree comes back exactly
    env.api.update_material(mat, haziness=0.6, haze_extent=(6.0, 3.0))
    on = signature(mat)
    assert on != sig
    env.api.update_material(mat, haziness=0.0)
    assert signature(mat) == sig
    after = render_for(env, name, mat)
    err = rel_diff(before["combined"], after["combined"])
    alpha = float(np.abs(before["alpha"] - after["alpha"]).max())
    b, a = before["combined"], after["combined"]
    record("layer_haziness0", {name: dict(
        max_rel=err, alpha=alpha, peak_before=float(b.max()), peak_after=float(a.max()),
        mean_before=float(b.mean()), mean_after=float(a.mean()),
        transparent_before=float((before["alpha"] < 0.5).mean()),
        transparent_after=float((after["alpha"] < 0.5).mean()))})
    assert err <= 1e-5 and alpha <= 1e-6, (err, alpha)


@pytest.mark.parametrize("name", list(MATERIALS))
def test_haze_keeps_every_input_and_link(env, name):
    """With haze on, every node of the user's is still there with its values and links, and
    every BSDF the layer adds carries the core's inputs except the ones haze changes."""
    mat = MATERIALS[name]()
    user_nodes, user_links = signature(mat)
    make_hazy(env, mat, haziness=0.5, haze_extent=(7.0, 4.0), coat_haziness=0.4)
    tree = mat.node_tree
    core = env.layer.find_core(tree)
    names = {n.name for n in tree.nodes}
    assert {n[0] for n in user_nodes} <= names
    now_links = signature(mat)[1]
    owned = set(env.layer.layer_state(mat)["base"])
    for link in user_links:
        if link[2] == core.name and tree.nodes[link[2]].inputs[link[3]].name in owned:
            continue  # an owned input: the link now feeds the layer's node math
        if link[2] == tree.nodes[link[2]].name and tree.nodes[link[2]].bl_idname.startswith("ShaderNodeOutput") \
                or tree.nodes[link[2]].bl_idname in ("ShaderNodeMixShader", "ShaderNodeAddShader") \
                and link[0] == core.name:
            continue  # where the core went, the layer's last mix goes now
        assert link in now_links, link
    copies = [n for n in tree.nodes if n.bl_idname == core.bl_idname and n != core]
    assert copies
    changed = {"Roughness", "Anisotropic", "Anisotropic Rotation", "Anisotropy", "Rotation",
               "IOR", "Base Color", "Metallic", "Coat IOR", "Coat Roughness", "Color",
               "Extinction"}
    for c in copies:
        for a, b in zip(core.inputs, c.inputs):
            if a.name in changed:
                continue
            if a.is_linked:
                assert b.is_linked and b.links[0].from_socket == a.links[0].from_socket, (c.name, a.name)
            elif hasattr(a, "default_value"):
                va, vb = a.default_value, b.default_value
                assert (tuple(va) if hasattr(va, "__len__") else va) == \
                    (tuple(vb) if hasattr(vb, "__len__") else vb), (c.name, a.name)
        assert c.distribution == core.distribution


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
    # a film on a dielectric reaches r ~ 0.5 at most (0.9 cannot keep the peak: a note says so)
    haziness = 0.3 if "film" in name and "dielectric" in name else 0.9
    env.api.update_material(mat, haziness=haziness, haze_extent=(8.0, 3.0),
                            coat_haziness=0.8 if name == "coat with textured roughness" else 0.0)
    after = render(env, mat, light=(0.0, 0.0), passes=("glossy",))["glossy"]
    err = rel_diff(before, after)
    record("layer_peak", {name: err})
    assert before.max() > 0.05
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
        mix = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeMixShader")
        betas[m] = mix.inputs[0].default_value
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


def test_layer_follows_edits_of_the_core(env):
    """Edit the user's BSDF after Make Hazy (as in the node editor): the depsgraph handler
    reruns the layer, which then renders what Make Hazy on the edited material renders."""
    mat = car_paint()
    make_hazy(env, mat, haziness=0.6, coat_haziness=0.3)
    view = dict(light=(35.0, 0.0), view=(10.0, 180.0))
    render(env, mat, **view)  # the material is in use: edits reach the depsgraph
    core = env.layer.find_core(mat.node_tree)
    calls = []
    real = env.layer.apply
    env.layer.apply = lambda *a, **k: calls.append(1) or real(*a, **k)
    try:
        _edit(core)
        bpy.context.view_layer.update()
        bpy.context.view_layer.update()  # nothing changed since: no second rerun
    finally:
        env.layer.apply = real
    assert len(calls) == 1, calls
    got = render(env, mat, **view)["combined"]
    fresh = car_paint()
    _edit(next(n for n in fresh.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"))
    make_hazy(env, fresh, haziness=0.6, coat_haziness=0.3)
    want = render(env, fresh, **view)["combined"]
    assert rel_diff(got, want) <= 1e-6


def test_edit_of_an_owned_input_is_adopted(env):
    """The user types a new IOR into the core while haze is on: it becomes the user's IOR
    (what Remove Haze restores), not something the layer overwrites."""
    mat, bsdf = principled("Plastic", **{"Base Color": (0.3, 0.3, 0.3, 1.0), "Roughness": 0.3})
    make_hazy(env, mat, haziness=0.3)
    hazy_ior = bsdf.inputs["IOR"].default_value
    assert hazy_ior > 1.6
    bsdf.inputs["IOR"].default_value = 1.33
    assert env.api.sync_haze(mat)
    assert env.layer.layer_state(mat)["base"]["IOR"] == {"value": pytest.approx(1.33)}
    assert bsdf.inputs["IOR"].default_value > 1.33  # the layer raises the new IOR
    env.api.remove_haze(mat)
    assert bsdf.inputs["IOR"].default_value == pytest.approx(1.33)
    assert not env.api.is_hazy(mat)
    assert [n.name for n in mat.node_tree.nodes if env.material.is_ours(n)] == []


def test_remove_haze_restores_links(env):
    mat = metallic_map()
    sig = signature(mat)
    make_hazy(env, mat, haziness=0.5)
    assert signature(mat) != sig
    assert bpy.ops.hazy_gloss.remove_haze(material=mat.name) == {"FINISHED"}
    assert signature(mat) == sig
    assert bpy.ops.hazy_gloss.remove_haze(material=mat.name) == {"CANCELLED"}


# --------------------------------------------------------------------------------------------
# What cannot be kept is refused with the reason, touching nothing
# --------------------------------------------------------------------------------------------


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
    # an animated input haze has to set: refused when haze would take it over
    mat, b = principled("Animated IOR", **{"Roughness": 0.3})
    b.inputs["IOR"].keyframe_insert("default_value", frame=1)
    api.make_hazy(mat)
    sig = signature(mat)
    with pytest.raises(ValueError, match="IOR of “Principled BSDF” is animated"):
        api.update_material(mat, haziness=0.4)
    assert signature(mat) == sig and env.api.read_parameters(mat)["haziness"] == 0.0


def test_picks_the_bsdf_and_names_the_others(env):
    mat, b = principled("Two BSDFs", **{"Roughness": 0.3})
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(b.outputs[0], mix.inputs[1])
    tree.links.new(glossy.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    env.ops.last_reports.clear()
    assert bpy.ops.hazy_gloss.make_hazy(material=mat.name) == {"FINISHED"}
    warn = " ".join(m for level, m in env.ops.last_reports if level == "WARNING")
    assert "not hazed" in warn and "Glossy BSDF" in warn
    assert env.layer.find_core(tree).name == "Principled BSDF"
    env.api.remove_haze(mat)
    env.api.make_hazy(mat, node=glossy.name, haziness=0.3)
    assert env.layer.find_core(tree) == glossy
    assert env.api.read_parameters(mat)["kind"] == "LEGACY"


# --------------------------------------------------------------------------------------------
# 5. Keep body colour
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("view", [(0.0, 0.0), (40.0, 180.0), (70.0, 180.0)])
def test_keep_body_colour(env, view):
    """Haze raises a dielectric's reflectivity, which darkens the diffuse under it; Keep Body
    Colour brightens the base colour by c(μ) so the diffuse pass stays what it was (to the
    fit's error), where the base has room to get brighter."""
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
    assert residual <= 1.5e-2, residual
    # the peak is untouched by the compensation (specular only)
    peak = lambda m: render(env, m, (0.0, 0.0), passes=("glossy",))["glossy"]  # noqa: E731
    assert rel_diff(peak(hazy), peak(kept)) <= 1e-5


def test_keep_body_colour_says_what_it_cannot_keep(env):
    mat, _ = principled("White", **{"Base Color": (0.9, 0.9, 0.9, 1.0), "Roughness": 0.3})
    make_hazy(env, mat, haziness=0.5, keep_body_colour=True)
    notes = " ".join(env.layer.summary(mat)["plan"].notes)
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
