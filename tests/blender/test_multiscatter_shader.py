# SPDX-License-Identifier: GPL-3.0-or-later
"""Multiscatter GGX in the shader (core.node_multiscatter through node_math.mapping), rendered.

Exact scene (tests/blender/scenes.py): a flat plane, orthographic camera straight down, a delta
sun along the normal, black world, 1 sample, 0 bounces: every pixel is f_r(n, n), the peak.
Roughness and colour are textures (object-space coordinates through math nodes, so every pixel
of the 8 x 8 frame has its own values and the node math runs in the shader, nothing folded in
Python); haziness 0, 0.3, 0.6, 0.9 over the same textures.

- for every lobe type (Metallic physical conductor, Principled metallic F82-tint with a textured
  Specular Tint, Principled dielectric, Glossy, Principled coat with a textured Coat IOR) the
  peak of every pixel moves by <= 1e-3 from haziness 0 to 0.9; the single-scatter mapping on
  the same lobes moves it by more (the test can fail);
- the in-shader node group (Multiscatter GGX) keeps the peak the same way;
- what Cycles computes from the graph equals Graph.evaluate (float32 numpy) of it.
"""
import importlib
from types import SimpleNamespace

import numpy as np
import pytest

import scenes
from measurements import record

HAZINESS = (0.0, 0.3, 0.6, 0.9)
RES = 8
LOBE_KIND = {"CONDUCTOR": "CONDUCTOR", "F82_TINT": "DIELECTRIC", "DIELECTRIC": "DIELECTRIC",
             "LEGACY": "LEGACY", "COAT": "DIELECTRIC"}


@pytest.fixture
def mods(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(graph=mod("core.graph"), node_math=mod("core.node_math"),
                           emit=mod("blender.nodes.emit"), builder=mod("blender.nodes.builder"),
                           lobes=mod("blender.nodes.lobes"), compat=mod("blender.compat"),
                           api=mod("api"), material=mod("blender.model.material"))


_math = scenes.math_node
_combine = scenes.combine_xyz


def _textures(tree, lobe):
    """Per-pixel inputs: u, v in [0, 1] across the frame (object coordinates + 1/2)."""
    tc = tree.nodes.new("ShaderNodeTexCoord")
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(tc.outputs["Object"], sep.inputs[0])
    u = _math(tree, "ADD", sep.outputs[0], 0.5)
    v = _math(tree, "ADD", sep.outputs[1], 0.5)
    if lobe == "COAT":  # Coat IOR 1.3 ... 1.8, F0 = ((n-1)/(n+1))², grey; coat roughness 0.05 ... 0.5
        ior = _math(tree, "MULTIPLY_ADD", v, 0.5, 1.3)
        f0 = _math(tree, "POWER", _math(tree, "DIVIDE", _math(tree, "SUBTRACT", ior, 1.0),
                                        _math(tree, "ADD", ior, 1.0)), 2.0)
        return dict(core_reflectivity=_combine(tree, f0, f0, f0),
                    roughness=_math(tree, "MULTIPLY_ADD", u, 0.45, 0.05))
    rough = _math(tree, "MULTIPLY_ADD", u, 0.62, 0.08)
    if lobe == "DIELECTRIC":  # F0 0.02 ... 0.08, coloured
        col = _combine(tree, _math(tree, "MULTIPLY_ADD", v, 0.06, 0.02),
                       _math(tree, "MULTIPLY_ADD", u, 0.03, 0.03), 0.04)
    else:
        col = _combine(tree, _math(tree, "MULTIPLY_ADD", u, 0.6, 0.3),
                       _math(tree, "MULTIPLY_ADD", v, -0.5, 0.85), _math(tree, "MULTIPLY_ADD", u, 0.3, 0.2))
    out = dict(core_reflectivity=col, roughness=rough)
    if lobe == "CONDUCTOR":
        out["edge_tint"] = _combine(tree, 1.0, _math(tree, "MULTIPLY_ADD", v, -0.6, 0.9), 0.5)
    if lobe == "F82_TINT":
        out["tint"] = _combine(tree, 1.0, _math(tree, "MULTIPLY_ADD", v, -0.4, 0.9), 0.6)
    return out


def _principled(tb, name, roughness, distribution="MULTI_GGX"):
    n = tb.node("ShaderNodeBsdfPrincipled", name=name)
    n.distribution = distribution
    tb.feed(n.inputs["Roughness"], roughness)
    return n


def hazy_material(m, name, lobe, haziness, extent=6.0, multiscatter=True):
    """A material drawing Eq. 1 from node math fed with textures: the two lobes of ``lobe``
    mixed by β (Multiscatter GGX nodes), β and r from node_math.mapping(multiscatter=lobe)
    (``multiscatter`` False: the single-scatter mapping on the same lobes)."""
    mat = m.compat.new_material(name)
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out_node = tree.nodes.new("ShaderNodeOutputMaterial")
    tb = m.builder.TreeBuilder(tree)
    tex = _textures(tree, lobe)
    g = m.graph.Graph()
    kind = LOBE_KIND[lobe]
    src = {k: g.input(k, vector=m.node_math.INPUTS[k]) for k in tex if k != "tint"}
    src.update(haziness=haziness, haze_extent_x=extent, haze_extent_y=extent, anisotropy=0.0,
               rotation=0.0, smoothness=1.0)
    src.setdefault("edge_tint", 0.0)
    tint = g.input("tint", vector=True) if "tint" in tex else None
    out = m.node_math.mapping(g, src, kind=kind, anisotropic=False, smooth=False,
                              distribution="MULTI_GGX", multiscatter=lobe if multiscatter else None,
                              tint=tint)
    s = m.emit.emit(tb, g, out, dict(tex))
    narrow = dict(roughness=s["roughness"], anisotropy=None, rotation=None)
    wide = dict(roughness=s["roughness_wide"], anisotropy=None, rotation=None)
    depth = 1 + tb.max_depth
    if lobe in ("CONDUCTOR", "DIELECTRIC", "LEGACY"):
        fresnel = {"CONDUCTOR": dict(ior=s.get("ior"), extinction=s.get("extinction")),
                   "DIELECTRIC": dict(ior=s.get("ior"), specular_tint=s.get("specular_tint")),
                   "LEGACY": dict(colour_narrow=s.get("colour_narrow"), colour_wide=s.get("colour_wide"))}[lobe]
        bsdf = m.lobes.build_lobes(tb, kind, "MULTI_GGX", beta=s["beta"], narrow=narrow, wide=wide,
                                   fresnel=fresnel, shared={}, depth=depth, always_wide=True)
    else:
        pair = []
        for which, lobe_r in (("Narrow", s["roughness"]), ("Wide", s["roughness_wide"])):
            if lobe == "F82_TINT":  # Principled metallic: F0 = Base Color, F82 tint = Specular Tint
                n = _principled(tb, which, lobe_r)
                tb.feed(n.inputs["Metallic"], 1.0)
                tb.feed(n.inputs["Base Color"], s["reflectivity"])
                tb.link(tex["tint"], n.inputs["Specular Tint"])
            else:  # the coat alone: black base, no base specular, Coat IOR from r̂
                n = _principled(tb, which, 0.5, distribution="GGX")
                tb.feed(n.inputs["Base Color"], (0.0, 0.0, 0.0))
                tb.feed(n.inputs["Specular IOR Level"], 0.0)
                tb.feed(n.inputs["Coat Weight"], 1.0)
                tb.feed(n.inputs["Coat IOR"], s["ior"])
                tb.feed(n.inputs["Coat Roughness"], lobe_r)
            pair.append(n)
        mix = tb.node("ShaderNodeMixShader", name="mix")
        tb.feed(mix.inputs[0], s["beta"])
        tb.link(pair[0].outputs[0], mix.inputs[1])
        tb.link(pair[1].outputs[0], mix.inputs[2])
        bsdf = mix.outputs[0]
    tree.links.new(bsdf, out_node.inputs["Surface"])
    return mat


def render(mat, light=(0.0, 0.0)):
    return scenes.render_plane(mat, resolution=(RES, RES), light_dir=light)


def drift(images):
    """max over haziness, pixels and channels of |peak(h) / peak(0) - 1| (pixels that reflect)."""
    ref = images[0]
    keep = ref > 1e-6 * ref.max()
    return float(max(np.abs(np.where(keep, im / np.where(keep, ref, 1.0) - 1.0, 0.0)).max()
                     for im in images[1:]))


@pytest.mark.parametrize("lobe", ["CONDUCTOR", "F82_TINT", "DIELECTRIC", "LEGACY", "COAT"])
def test_textured_peak_is_invariant(mods, lobe):
    corrected = [render(hazy_material(mods, f"MS {lobe} {h}", lobe, h)) for h in HAZINESS]
    single = [render(hazy_material(mods, f"SS {lobe} {h}", lobe, h, multiscatter=False))
              for h in HAZINESS]
    # the textures vary: 8 x 8 distinct texels
    assert len(np.unique(np.round(corrected[0].reshape(-1, 3), 6), axis=0)) >= 32
    after, before = drift(corrected), drift(single)
    record("multiscatter_shader", {lobe: dict(corrected=after, single_scatter_mapping=before)})
    assert after <= 1e-3, after
    assert before > 1e-3, before  # the test can fail: the single-scatter mapping moves the peak
    assert after < 0.2 * before
    # ... and the haze is there: off the peak (light at 24°, half-angle 12°) the halo shows
    off = [render(mats, light=(24.0, 0.0)) for mats in
           (hazy_material(mods, f"Off {lobe} 0", lobe, 0.0), hazy_material(mods, f"Off {lobe} .9", lobe, 0.9))]
    assert np.max(off[1] / np.maximum(off[0], 1e-30)) > 3.0  # the smoother pixels


@pytest.mark.parametrize("kind", ["CONDUCTOR", "DIELECTRIC", "LEGACY"])
def test_group_keeps_the_peak(mods, kind):
    """The in-shader group (api.create_material(shader_mapping=True), Multiscatter GGX) with
    its Roughness and Core Reflectivity linked to textures."""
    images = []
    for h in HAZINESS:
        tint = dict(edge_tint=(1.0, 0.7, 0.5)) if kind == "CONDUCTOR" else {}  # (conductors only)
        mat = mods.api.create_material(f"Group {kind} {h}", kind=kind, distribution="MULTI_GGX",
                                       haziness=h, haze_extent=6.0, shader_mapping=True,
                                       core_reflectivity=0.5, **tint)
        tree = mat.node_tree
        group = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeGroup")
        tex = _textures(tree, kind)
        tree.links.new(tex["roughness"], group.inputs["Roughness"])
        tree.links.new(tex["core_reflectivity"], group.inputs["Core Reflectivity"])
        images.append(render(mat))
    d = drift(images)
    record("multiscatter_shader", {f"group {kind}": d})
    assert d <= 1e-3, d


CASES = [
    dict(core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5), roughness=0.4, haziness=0.6,
         haze_extent_x=5.0, tint=(1.0, 0.8, 0.5)),
    dict(core_reflectivity=(0.04, 0.05, 0.02), edge_tint=(0.2, 0.5, 0.9), roughness=0.2, haziness=0.9,
         haze_extent_x=30.0, tint=(0.6, 0.9, 1.0)),
    dict(core_reflectivity=(0.5, 0.5, 0.5), edge_tint=(0.0, 0.0, 0.0), roughness=0.8, haziness=0.3,
         haze_extent_x=0.5, tint=(1.0, 1.0, 1.0)),
    dict(core_reflectivity=(0.999, 0.2, 0.0), edge_tint=(1.0, 1.0, 1.0), roughness=0.05, haziness=0.9999,
         haze_extent_x=200.0, tint=(0.2, 0.4, 0.8)),
]


def _emit_values(m, lobe, params, outputs):
    """A material emitting up to three graph outputs (scalars into the lanes, or one vector):
    every input a socket (Value / Combine XYZ nodes), so Cycles evaluates the whole graph."""
    mat = m.compat.new_material("emit")
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out_node = tree.nodes.new("ShaderNodeOutputMaterial")
    tb = m.builder.TreeBuilder(tree)
    values = dict(params, anisotropy=0.0, rotation=0.0, haze_extent_y=params["haze_extent_x"],
                  smoothness=1.0)
    sources = {}
    for name, v in values.items():
        if isinstance(v, tuple):
            sources[name] = _combine(tree, *v)
        else:
            n = tree.nodes.new("ShaderNodeValue")
            n.outputs[0].default_value = v
            sources[name] = n.outputs[0]
    g = m.graph.Graph()
    src = {k: g.input(k, vector=m.node_math.INPUTS[k]) for k in m.node_math.INPUTS}
    res = m.node_math.mapping(g, src, kind=LOBE_KIND[lobe], anisotropic=False, smooth=False,
                              distribution="MULTI_GGX", multiscatter=lobe,
                              tint=g.input("tint", vector=True))
    exprs = [res[o] for o in outputs]
    s = m.emit.emit(tb, g, exprs, sources)
    colour = s[0] if len(s) == 1 else _combine(tree, *s, *([0.0] * (3 - len(s))))
    em = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(colour, em.inputs["Color"])
    em.inputs["Strength"].default_value = 1.0
    tree.links.new(em.outputs[0], out_node.inputs["Surface"])
    inputs = {k: np.asarray(v, np.float32) for k, v in values.items()}
    want = m.graph.evaluate(exprs, inputs)
    want = np.asarray(want[0], np.float64) if len(exprs) == 1 else np.array([float(w) for w in want])
    return mat, want


@pytest.mark.parametrize("lobe", ["CONDUCTOR", "F82_TINT", "DIELECTRIC", "LEGACY", "COAT"])
def test_cycles_evaluates_the_graph_as_numpy(mods, lobe):
    """Graph.evaluate (float32 numpy, Blender's node semantics, the Color Ramp as Cycles bakes
    it) equals what Cycles computes, for the Multiscatter graph of each lobe type."""
    worst = 0.0
    for params in CASES:
        if lobe == "COAT":
            params = dict(params, core_reflectivity=(params["core_reflectivity"][1],) * 3)
        solved = "halo_max" if lobe == "LEGACY" else "halo_intensity"  # (Glossy: its k̂_max)
        for outputs in (("beta", "reflectivity_max", solved), ("reflectivity",)):
            mat, want = _emit_values(mods, lobe, params, outputs)
            got = scenes.render_plane(mat, resolution=(2, 2), light_dir=(0.0, 0.0),
                                      strength=0.0)[0, 0, :len(want)]
            err = float(np.max(np.abs(got - want)))
            worst = max(worst, err)
            assert err <= 2e-5, (lobe, params, outputs, got, want)
    record("multiscatter_shader", {f"graph vs Cycles {lobe}": worst})
