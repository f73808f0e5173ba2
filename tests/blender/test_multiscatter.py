# SPDX-License-Identifier: GPL-3.0-or-later
"""Multiscatter GGX keeps the peak, rendered (issue 13 item 4).

Exact scene (tests/blender/scenes.py): a flat plane, orthographic camera straight down, a sun
of angle 0 along the normal, black world, 1 sample, no denoising, the smallest pixel filter,
no clamps, glossy filter 0, 0 bounces: every pixel is f_r(n, n), the peak.

- api.create_material(kind=..., distribution="MULTI_GGX", haziness=h) for h in 0, 0.3, 0.6,
  0.9: the peak moves by <= 1e-3 (measured and recorded per Blender version);
- the same materials with the single-scatter mapping (distribution "GGX", lobes then switched
  to Multiscatter GGX: what the add-on did before) move it by more (the test can fail);
- the rendered peak equals core.multiscatter's model of it (the factor S and F_ss per node);
- the in-shader group (node math) keeps the single-scatter mapping: its drift is recorded.
"""
import importlib

import bpy
import numpy as np
import pytest

import scenes
from measurements import record

HAZINESS = (0.0, 0.3, 0.6, 0.9)
CASES = {
    "conductor": dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3), edge_tint=(1.0, 0.8, 0.5),
                      roughness=0.4, haze_extent=5.0),
    "conductor_aniso": dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.6, 0.3),
                            edge_tint=(1.0, 0.8, 0.5), roughness=0.5, anisotropy=0.6,
                            haze_extent=(6.0, 2.0)),
    "dielectric": dict(kind="DIELECTRIC", core_reflectivity=(0.04, 0.04, 0.04), roughness=0.4,
                       haze_extent=5.0),
    "legacy": dict(kind="LEGACY", core_reflectivity=(0.6, 0.5, 0.2), roughness=0.4,
                   haze_extent=5.0),
}


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return mod("api"), mod("core.multiscatter"), mod("blender.material")


def peak(mat):
    scenes.setup_render("CYCLES", samples=1, resolution=(4, 4), bounces=0)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.flat_plane_scene(mat, light_dir=(0.0, 0.0), view_dir=(0.0, 0.0))
    img = scenes.render_exr()[..., :3].astype(np.float64)
    assert np.ptp(img.reshape(-1, 3), axis=0).max() <= 1e-6 * img.max()  # every pixel is the peak
    return img[2, 2]


def drift(peaks):
    """max over haziness and channels of |peak(h) / peak(0) - 1|."""
    p = np.asarray(peaks)
    return float(np.abs(p[1:] / p[0] - 1.0).max())


def single_scatter_material(api, material_mod, name, params, haziness):
    """The single-scatter mapping (distribution GGX) drawn with Multiscatter GGX lobes."""
    mat = api.create_material(name, distribution="GGX", haziness=haziness, **params)
    for node in material_mod.ours(mat.node_tree).values():
        if hasattr(node, "distribution") and node.bl_idname != "ShaderNodeGroup":
            node.distribution = "MULTI_GGX"
    return mat


@pytest.mark.parametrize("case", sorted(CASES))
def test_multiscatter_peak_is_invariant(env, case):
    api, ms, material_mod = env
    params = CASES[case]
    corrected, uncorrected = [], []
    for h in HAZINESS:
        mat = api.create_material(f"MS {case} {h}", distribution="MULTI_GGX", haziness=h, **params)
        corrected.append(peak(mat))
        old = single_scatter_material(api, material_mod, f"SS {case} {h}", params, h)
        uncorrected.append(peak(old))
    after, before = drift(corrected), drift(uncorrected)
    record("multiscatter_peak", {case: dict(corrected=after, single_scatter_mapping=before,
                                            peaks=np.asarray(corrected).tolist())})
    assert after <= 1e-3, after
    assert before > 2e-3, before  # the test can fail: the old mapping moves the peak
    assert after < 0.05 * before


@pytest.mark.parametrize("case", ["conductor", "dielectric", "legacy"])
def test_multiscatter_model_matches_cycles(env, case):
    """The rendered peak equals r [(1-β) S_n + β p S_w] D_n(0)/4 of core.multiscatter, with S
    and F_ss computed for the running Blender (4.5's conductor Fresnel included)."""
    api, ms, _ = env
    params = CASES[case]
    worst = 0.0
    for h in (0.0, 0.6):
        mat = api.create_material(f"Model {case} {h}", distribution="MULTI_GGX", haziness=h, **params)
        m = api.map_parameters(api.read_parameters(mat))
        model = ms.peak_factor(params["kind"], m.alpha, m.alpha_wide, m.reflectivity, m.beta,
                               edge_tint=m.edge_tint, halo=h > 0)
        d_n = 1.0 / (np.pi * float(m.alpha[0]) * float(m.alpha[1]))
        rel = peak(mat) / (model * d_n / 4.0) - 1.0
        worst = max(worst, float(np.abs(rel).max()))
    record("multiscatter_peak", {f"{case} model vs render": worst})
    assert worst <= 2e-5, worst


def test_in_shader_group_keeps_single_scatter_mapping(env):
    """The node-math group does not correct for Multiscatter GGX (documented): its drift is the
    single-scatter mapping's (recorded for the report)."""
    api, _, material_mod = env
    figures = {}
    for case in ("conductor", "dielectric", "legacy"):
        params = CASES[case]
        group, lean_ss = [], []
        for h in HAZINESS:
            mat = api.create_material(f"Group {case} {h}", distribution="MULTI_GGX", haziness=h,
                                      shader_mapping=True, **params)
            group.append(peak(mat))
            lean_ss.append(peak(single_scatter_material(api, material_mod, f"SS2 {case} {h}",
                                                        params, h)))
        figures[case] = drift(group)
        assert np.allclose(group, lean_ss, rtol=2e-5, atol=0), case
    record("multiscatter_peak", {"in-shader group": figures})
