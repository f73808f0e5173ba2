# SPDX-License-Identifier: GPL-3.0-or-later
"""Real Cycles renders that prove the paper's claims for the add-on's materials.

Scene: a flat plane, orthographic camera along the normal, a delta sun (angle 0), black world,
Gaussian pixel filter of 0.01 px (samples at the pixel centre), denoising off — each pixel is Strength * f_r(wi, wo) * cos θi exactly.
The analytic reference is tests/blender/analytic.py (an independent numpy evaluation of Eq. 1);
the physical parameters it is given come from hazy_gloss.core (the code under test maps, the
analytic side evaluates the BRDF).
"""
import importlib
import math

import bpy
import numpy as np
import pytest

import analytic
import scenes
from measurements import record





@pytest.fixture
def api(hg, clean_file):
    return importlib.import_module(hg.__name__ + ".api")


def render_plane(mat, light=(0.0, 0.0), strength=1.0, res=(4, 4)):
    scenes.setup_render("CYCLES", samples=1, resolution=res, bounces=0)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    setup = scenes.flat_plane_scene(mat, light_dir=light, strength=strength)
    return scenes.centre(scenes.render_exr()), setup


CASES = {
    "conductor": dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5)),
    "dielectric": dict(kind="DIELECTRIC", core_reflectivity=0.04),
    "legacy": dict(kind="LEGACY", core_reflectivity=(0.6, 0.5, 0.2)),
}


# --------------------------------------------------------------------------------------------
# Peak invariance (Eq. 2 with g_h(n, n) = 0): haziness and extent leave the peak alone.
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("anisotropy", [0.0, 0.7])
@pytest.mark.parametrize("shader_mapping", [False, True])
def test_peak_invariance(api, case, anisotropy, shader_mapping):
    values = []
    # λ = 300 drives α_w past Cycles' α <= 1 clamp; (12, 2) is an anisotropic halo
    for haziness, extent in [(0.0, 5.0), (0.3, 5.0), (0.9, 5.0), (0.9, (12.0, 2.0)), (0.9, 300.0),
                             (0.99, 1.0)]:
        if case == "dielectric" and haziness > 0.5:
            haziness = haziness / 10
        mat = api.create_material("peak", roughness=0.2, anisotropy=anisotropy, haziness=haziness,
                                  haze_extent=extent, shader_mapping=shader_mapping, **CASES[case])
        values.append(render_plane(mat, light=(0.0, 0.0))[0])
    values = np.array(values)
    rel = np.abs(values / values[0] - 1).max()
    record("peak_invariance", {f"{case} aniso={anisotropy} in-shader={shader_mapping}": rel})
    assert values[0].max() > 1.0  # a real highlight, not a black render
    assert rel <= 1e-4, (values, rel)


# --------------------------------------------------------------------------------------------
# Analytic agreement with an independent evaluation of Eq. 1
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("case", ["conductor", "conductor_aniso", "dielectric", "dielectric_aniso",
                                  "legacy", "legacy_aniso", "beckmann", "clamped_wide"])
def test_analytic_agreement(api, hg, case):
    conv = importlib.import_module(hg.__name__ + ".core.conventions")
    params = dict(roughness=0.3, haziness=0.6, haze_extent=4.0)
    dist = "GGX"
    if case == "conductor_aniso":
        params.update(CASES["conductor"], anisotropy=0.6, haze_extent=(6.0, 2.0), rotation=0.0)
    elif case == "beckmann":
        params.update(CASES["conductor"], distribution="BECKMANN")
        dist = "BECKMANN"
    elif case == "dielectric":
        params.update(kind="DIELECTRIC", core_reflectivity=0.05, haziness=0.08)
    elif case == "dielectric_aniso":  # Principled: same anisotropy convention as Metallic
        params.update(kind="DIELECTRIC", core_reflectivity=0.05, haziness=0.08, anisotropy=0.5,
                      haze_extent=(2.0, 7.0), rotation=0.1)
    elif case == "legacy_aniso":  # Glossy: the opposite anisotropy convention
        params.update(CASES["legacy"], anisotropy=0.8, haze_extent=(7.0, 2.0))
    elif case == "clamped_wide":  # α_w hits Cycles' α <= 1 and the 10:1 aspect limit
        params.update(CASES["conductor"], roughness=0.5, anisotropy=0.3, haze_extent=(30.0, 1.0))
    else:
        params.update(CASES[case])
    mat = api.create_material("analytic", **params)
    p = api.read_parameters(mat)
    m = api.map_parameters(p)
    alpha_n = tuple(float(a) for a in conv.alpha_from_roughness(p["roughness"], p["anisotropy"]))
    alpha_w = tuple(float(np.asarray(a)) for a in m.alpha_wide)
    worst = 0.0
    exact_fresnel = not case.startswith(("conductor", "beckmann", "clamped")) or bpy.app.version >= (5, 0, 0)
    for theta, phi in [(0.0, 0.0), (10.0, 0.0), (25.0, 30.0), (40.0, 90.0), (60.0, 200.0)]:
        px, setup = render_plane(mat, light=(theta, phi), strength=1.0)
        wi, wo = setup["wi"], setup["wo"]
        if p["rotation"]:  # express the directions in the rotated tangent frame
            c, s_ = math.cos(2 * math.pi * p["rotation"]), math.sin(2 * math.pi * p["rotation"])
            rot = np.array([[c, s_, 0.0], [-s_, c, 0.0], [0.0, 0.0, 1.0]])
            wi, wo = rot @ wi, rot @ wo
        beta = float(m.beta)
        if case.startswith("legacy"):
            fn = analytic.microfacet_lobe(wi, wo, *alpha_n, distribution=dist)
            fw = analytic.microfacet_lobe(wi, wo, *alpha_w, distribution=dist)
            f = np.asarray(m.weight_narrow) * fn + np.asarray(m.weight_wide) * fw
        elif case.startswith("dielectric"):
            eta = float(m.dielectric_ior)
            f = analytic.two_lobe_brdf(wi, wo, beta=beta, alpha_n=alpha_n, alpha_w=alpha_w,
                                       eta=(eta,) * 3, kappa=(0.0,) * 3, distribution=dist)
        else:
            f = analytic.two_lobe_brdf(wi, wo, beta=beta, alpha_n=alpha_n, alpha_w=alpha_w,
                                       eta=m.ior, kappa=m.extinction, distribution=dist)
        expected = np.asarray(f).reshape(3) * math.cos(math.radians(theta))
        rel = float(np.abs(px / expected - 1).max())
        worst = max(worst, rel)
        tol = 1e-3 if exact_fresnel or theta == 0.0 else 4e-2  # 4.5: approximate conductor Fresnel
        assert rel <= tol, (theta, phi, px, expected)
    record("analytic_agreement", {case: worst})


# --------------------------------------------------------------------------------------------
# Halo behaviour: grows with haziness off the peak; widens with haze extent.
# --------------------------------------------------------------------------------------------
def test_halo_grows_with_haziness(api):
    off_peak = []
    for haziness in (0.0, 0.2, 0.4, 0.6, 0.8, 0.95):
        mat = api.create_material("halo", roughness=0.15, haziness=haziness, haze_extent=5.0,
                                  **CASES["conductor"])
        off_peak.append(render_plane(mat, light=(30.0, 0.0))[0].mean())
    assert np.all(np.diff(off_peak) > 0), off_peak
    record("halo_monotonic", {"off_peak_30deg": off_peak})


def _profile(mat):
    """Radiance along a line of pixels under a point light above the plane's centre: pixel at
    distance x sees the light at θi = atan(x / h); θh = θi / 2 (camera along the normal)."""
    scenes.setup_render("CYCLES", samples=1, resolution=(256, 4), bounces=0)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.flat_plane_scene(mat, light_dir=(0.0, 0.0), strength=0.0, ortho_scale=4.0)
    light = bpy.data.lights.new("HG point", "POINT")
    light.energy = 100.0
    light.shadow_soft_size = 0.0
    lo = bpy.data.objects.new("HG point", light)
    bpy.context.scene.collection.objects.link(lo)
    lo.location = (0.0, 0.0, 1.0)
    img = scenes.render_exr()
    row = img[1:3, :, :3].mean(axis=(0, 2))
    return row[128:]  # centre -> right edge


def _half_width(halo):
    """Pixels from the centre to where the halo term falls below half its maximum."""
    k = int(np.argmax(halo))
    above = np.nonzero(halo[k:] >= halo[k] / 2)[0]
    return k + int(above.max())


def test_halo_widens_with_extent(api):
    base = _profile(api.create_material("h0", roughness=0.15, haziness=0.0, **CASES["conductor"]))
    widths = []
    for extent in (2.0, 4.0, 8.0):
        hazy = _profile(api.create_material("h", roughness=0.15, haziness=0.7, haze_extent=extent,
                                            **CASES["conductor"]))
        widths.append(_half_width(hazy - base))
    assert widths[0] < widths[1] < widths[2], widths
    record("halo_half_width_px", {"extent 2,4,8": widths})


# --------------------------------------------------------------------------------------------
# Energy: white furnace
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("case,haziness,extent", [
    ("conductor", 0.999, 5.0), ("conductor", 0.999, 1000.0), ("conductor", 0.5, (40.0, 1.0)),
    ("dielectric", 0.999, 1000.0), ("legacy", 0.999, 50.0)])
def test_white_furnace(api, case, haziness, extent):
    params = dict(CASES[case])
    params["core_reflectivity"] = 0.95 if case != "dielectric" else 0.04
    if case == "conductor":
        params["edge_tint"] = 1.0
    # the analytic sphere has no UV map: anisotropic lobes take a radial tangent
    mat = api.create_material("furnace", roughness=0.3, haziness=haziness, haze_extent=extent,
                              tangent="RADIAL_Z", **params)
    scenes.setup_render("CYCLES", samples=64, resolution=(32, 32), bounces=2)
    scenes.furnace_sphere_scene(mat, 1.0)
    img = scenes.render_exr()
    mask = img[..., 3] > 0.999
    vals = img[..., :3][mask]
    mean = float(vals.mean())
    noise = float(vals.std() / math.sqrt(vals.size))
    record("white_furnace", {f"{case} βh={haziness} λ={extent}": [mean, noise]})
    assert mask.sum() > 100
    assert mean > (0.3 if case != "dielectric" else 0.02), mean  # a lit sphere, not a black one
    assert mean <= 1.0 + 4 * noise + 3e-3, (mean, noise)  # 4.5's conductor Fresnel is 2-3e-3 high


# --------------------------------------------------------------------------------------------
# In-shader mapping == Python mapping (emit the node graph's internal values)
# --------------------------------------------------------------------------------------------
IN_SHADER_CASES = [
    dict(core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5), roughness=0.1, haziness=0.5, haze_extent=5.0),
    dict(core_reflectivity=(0.02, 0.02, 0.02), edge_tint=0.0, roughness=0.1, haziness=0.1, haze_extent=7.0),
    dict(core_reflectivity=(0.5, 0.12, 0.12), edge_tint=(0.0, 0.85, 1.0), roughness=0.1, haziness=0.99, haze_extent=(10.0, 1.0), anisotropy=0.3),
    dict(core_reflectivity=(0.999, 0.99, 0.98), edge_tint=0.5, roughness=0.5, haziness=0.9, haze_extent=50.0),
    dict(core_reflectivity=(0.3, 0.3, 0.3), edge_tint=0.2, roughness=0.2, haziness=0.7, haze_extent=1e-3),
    dict(core_reflectivity=(0.0277, 0.01, 0.02), edge_tint=0.9, roughness=0.3, haziness=0.6, haze_extent=5.0, smoothness=1.0),
    dict(core_reflectivity=(0.6, 0.2, 0.1), edge_tint=0.3, roughness=0.05, haziness=0.8, haze_extent=(3.0, 9.0), anisotropy=0.9, smoothness=4.0),
    dict(core_reflectivity=(0.04, 0.04, 0.04), edge_tint=0.0, roughness=0.1, haziness=0.5, haze_extent=5.0, smoothness=0.01),
    dict(core_reflectivity=(0.8, 0.8, 0.8), edge_tint=1.0, roughness=0.9, haziness=0.95, haze_extent=3.0, smoothness=1e4),
    dict(core_reflectivity=(1.0, 0.5, 0.2), edge_tint=0.5, roughness=0.2, haziness=0.7, haze_extent=5.0),  # r̂_c = 1
    dict(core_reflectivity=(0.99, 0.9, 0.5), edge_tint=0.3, roughness=0.2, haziness=0.9999, haze_extent=5.0),
    dict(core_reflectivity=(0.7, 0.7, 0.7), edge_tint=0.6, roughness=0.2, haziness=0.999, haze_extent=4.0, smoothness=3.0),
]


def _emit(hg, params, output):
    """A material whose surface emits one value of the mapping's node math (core.node_math,
    emitted by blender.nodes.emit).  Every input enters as a socket (as a texture would), so
    nothing is folded in Python: the render checks Blender's node semantics."""
    builder = importlib.import_module(hg.__name__ + ".blender.nodes.builder")
    emit = importlib.import_module(hg.__name__ + ".blender.nodes.emit")
    node_math = importlib.import_module(hg.__name__ + ".core.node_math")
    graph = importlib.import_module(hg.__name__ + ".core.graph")
    compat = importlib.import_module(hg.__name__ + ".blender.compat")
    mat = compat.new_material("emit")
    tree = mat.node_tree
    for n in list(tree.nodes):
        if n.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(n)
    out = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"][0]
    tb = builder.TreeBuilder(tree)
    aniso = params.get("anisotropy", 0.0) > 0 or isinstance(params["haze_extent"], tuple)
    lx, ly = params["haze_extent"] if isinstance(params["haze_extent"], tuple) else (params["haze_extent"],) * 2
    rgb = lambda c: (c,) * 3 if not isinstance(c, tuple) else c  # noqa: E731
    values = dict(core_reflectivity=rgb(params["core_reflectivity"]), edge_tint=rgb(params["edge_tint"]),
                  roughness=params["roughness"], anisotropy=params.get("anisotropy", 0.0), rotation=0.0,
                  haziness=params["haziness"], haze_extent_x=lx, haze_extent_y=ly,
                  smoothness=params.get("smoothness") or 1.0)
    sources = {}
    for name, v in values.items():
        if isinstance(v, tuple):
            n = tb.node("ShaderNodeCombineXYZ")
            for i in range(3):
                n.inputs[i].default_value = v[i]
        else:
            n = tb.node("ShaderNodeValue")
            n.outputs[0].default_value = v
        sources[name] = n.outputs[0]
    g = graph.Graph()
    src = {k: g.input(k, vector=node_math.INPUTS[k]) for k in sources}
    m = node_math.mapping(g, src, kind="CONDUCTOR", anisotropic=aniso,
                          smooth=params.get("smoothness") is not None)
    expr = m[output] if output not in ("alpha_wide_x", "alpha_wide_y") else m["alpha_wide"][output[-1] == "y"]
    value = emit.emit(tb, g, expr, sources)
    em = tb.node("ShaderNodeEmission")
    tb.feed(em.inputs["Strength"], 1.0)
    if value.type == "VALUE":
        comb = tb.node("ShaderNodeCombineXYZ")
        for i in range(3):
            tree.links.new(value, comb.inputs[i])
        value = comb.outputs[0]
    tree.links.new(value, em.inputs["Color"])
    tree.links.new(em.outputs[0], out.inputs["Surface"])
    return mat


def test_in_shader_mapping_equals_python(api, hg):
    worst = {}
    f32 = lambda v: tuple(f32(x) for x in v) if isinstance(v, tuple) else float(np.float32(v))
    for params in IN_SHADER_CASES:
        # the shader receives float32 inputs: map exactly those values (in float64)
        params = {k: f32(v) for k, v in params.items()}
        p = api.normalise_parameters(dict(kind="CONDUCTOR", **params))
        m = api.map_parameters(p)
        want = {"beta": float(m.beta), "peak_ratio": float(m.peak_ratio),
                "halo_intensity": float(m.halo_intensity),
                "alpha_wide_x": float(np.asarray(m.alpha_wide[0])),
                "alpha_wide_y": float(np.asarray(m.alpha_wide[1])),
                "reflectivity": np.asarray(m.reflectivity), "ior": np.asarray(m.ior),
                "extinction": np.asarray(m.extinction)}
        for output, expected in want.items():
            got = render_plane(_emit(hg, params, output), res=(2, 2))[0]
            expected = np.broadcast_to(np.asarray(expected, dtype=np.float64), (3,))
            # relative where values are large (η, κ grow like 1/(1-r)), absolute otherwise
            if output in ("ior", "extinction"):
                # r = 1 (a perfect mirror): both sides cap 1 - r at their own ε (2^-52 vs 2^-23);
                # what matters is that the index is huge, i.e. F = 1 - O(1/η) everywhere
                mirror = np.asarray(m.reflectivity) >= 1.0 - 2.0 ** -23
                if output == "ior":
                    assert np.all(got[mirror] >= 1e6), got
                got, expected = got[~mirror], expected[~mirror]
            err = float(np.max(np.abs(got - expected) / np.maximum(1.0, np.abs(expected)), initial=0.0))
            worst[output] = max(worst.get(output, 0.0), err)
            # η, κ ~ 1/(1-r) are relative; the graph computes 1 - r without cancellation too
            assert err <= 1e-5, (params, output, got, expected)
    record("in_shader_vs_python", worst)


# --------------------------------------------------------------------------------------------
# Spatially varying haziness: a ramp texture changes the halo, not the peak.
# --------------------------------------------------------------------------------------------
def test_haziness_ramp_changes_halo_not_peak(api):
    mat = api.create_material("ramp", roughness=0.2, haziness=0.5, haze_extent=6.0,
                              shader_mapping=True, **CASES["conductor"])
    tree = mat.node_tree
    group = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeGroup")
    coord = tree.nodes.new("ShaderNodeTexCoord")
    grad = tree.nodes.new("ShaderNodeTexGradient")  # linear in object x
    scale = tree.nodes.new("ShaderNodeMapping")
    scale.inputs["Scale"].default_value = (0.19, 1.0, 1.0)  # plane spans x in [-size/2, size/2]
    scale.inputs["Location"].default_value = (0.5, 0.0, 0.0)
    tree.links.new(coord.outputs["Object"], scale.inputs["Vector"])
    tree.links.new(scale.outputs[0], grad.inputs["Vector"])
    ramp = tree.nodes.new("ShaderNodeMath")
    ramp.operation = "MULTIPLY"
    ramp.inputs[1].default_value = 0.95
    tree.links.new(grad.outputs["Fac"], ramp.inputs[0])
    tree.links.new(ramp.outputs[0], group.inputs["Haziness"])

    def row(light):
        scenes.setup_render("CYCLES", samples=1, resolution=(32, 2), bounces=0)
        for o in list(bpy.data.objects):
            bpy.data.objects.remove(o)
        scenes.flat_plane_scene(mat, light_dir=light, strength=1.0, ortho_scale=4.0)
        return scenes.render_exr()[0, :, :3].mean(axis=-1)

    peak = row((0.0, 0.0))
    halo = row((35.0, 0.0))
    assert np.abs(peak / peak.mean() - 1).max() <= 1e-4, peak
    assert np.all(np.diff(halo) > 0), halo  # haziness grows left -> right
    assert halo[-1] > 2 * halo[0]
    record("spatial_haziness", {"peak_rel_spread": float(np.abs(peak / peak.mean() - 1).max()),
                                "halo_ratio_right_left": float(halo[-1] / halo[0])})
