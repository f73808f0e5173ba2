# SPDX-License-Identifier: GPL-3.0-or-later
"""bpy-free checks of the built-in presets (the paper's Table 3 and figure examples) and of the
numpy plots the material panel shows (Figure 3 left: k_h vs r_c; Figure 2: BRDF slice)."""
import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hazy_gloss.core import haze_mapping
from hazy_gloss.utils import plots, presets

ROOT = Path(__file__).resolve().parents[2]
# the render harness' independent microfacet BRDFs (numpy, no bpy, no project code), loaded by
# its path: tests/blender on sys.path would shadow this directory's modules of the same names
_spec = importlib.util.spec_from_file_location("hg_analytic", ROOT / "tests" / "blender" / "analytic.py")
analytic = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(analytic)

# api.PARAMETERS (api imports bpy, so the list is repeated here)
API_PARAMETERS = {"kind", "distribution", "core_reflectivity", "edge_tint", "roughness",
                  "anisotropy", "rotation", "haziness", "haze_extent", "smoothness",
                  "shader_mapping", "base_color", "transmission", "tangent"}

# Table 3 as printed: r_p, g, α_n, β_h, λ_h  (+ the kind the text gives each object)
TABLE3 = {
    "PROBE_A": ((0.02,) * 3, (0.0,) * 3, 0.01, 0.1, (5, 5), "DIELECTRIC"),
    "PROBE_B": ((0.5,) * 3, (1.0,) * 3, 0.01, 0.99, (5, 5), "CONDUCTOR"),
    "FERTILITY": ((0.5, 0.28, 0.1), (0.8, 0.06, 0.03), 0.03, 0.99, (5, 5), "CONDUCTOR"),
    "VASE": ((0.05,) * 3, (0.0,) * 3, 0.01, 0.15, (7, 7), "DIELECTRIC"),
    "TEAPOT": ((0.5, 0.12, 0.12), (0.0, 0.85, 1.0), 0.01, 0.99, (10, 1), "CONDUCTOR"),
}


# --------------------------------------------------------------------------------------------
# Presets
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("pid", sorted(TABLE3))
def test_table3_values_as_printed(pid):
    rc, g, alpha, bh, ext, kind = TABLE3[pid]
    pre = presets.PRESETS[pid]
    assert pre.core_reflectivity == rc and pre.edge_tint == g
    assert pre.alpha == alpha and pre.haziness == bh and pre.haze_extent == ext
    assert pre.kind == kind
    p = presets.parameters(pid)
    # the api's roughness is Blender's R = √α, the paper prints α
    assert p["roughness"] == pytest.approx(math.sqrt(alpha), rel=1e-15)
    assert p["roughness"] ** 2 == pytest.approx(alpha, rel=1e-14)
    assert p["haze_extent"] == ext and p["haziness"] == bh


def test_vase_has_dark_green_base_and_figure_examples():
    vase = presets.PRESETS["VASE"]
    r, g, b = vase.base_color
    assert g > r and g > b and max(vase.base_color) < 0.1  # dark greenish Lambertian base
    fig3d, fig3c = presets.PRESETS["FIG3_DIELECTRIC"], presets.PRESETS["FIG3_CONDUCTOR"]
    assert fig3d.alpha == fig3c.alpha == 0.01 and fig3d.haze_extent == (7, 7) == fig3c.haze_extent
    assert fig3d.core_reflectivity == (0.04,) * 3 and fig3d.kind == "DIELECTRIC"
    assert fig3c.kind == "CONDUCTOR"
    fig4 = presets.PRESETS["FIG4"]
    assert fig4.core_reflectivity == (0.03,) * 3 and fig4.haziness == 0.1
    fig5 = presets.PRESETS["FIG5"]
    assert max(fig5.core_reflectivity) == 0.5 and fig5.alpha == 0.01
    assert fig5.haze_extent == (5.75, 5.75)


def test_every_preset_maps_and_is_complete():
    ids = [i for i, _, _ in presets.enum_items()]
    assert len(ids) == len(set(ids)) == len(presets.PRESETS)
    for pid, name, desc in presets.enum_items():
        p = presets.parameters(pid)
        assert set(p) <= API_PARAMETERS, set(p) - API_PARAMETERS
        # every perceptual parameter is set, so a preset fully defines the look
        assert API_PARAMETERS - set(p) == {"shader_mapping", "tangent"}
        assert presets.PRESETS[pid].source in desc and name
        # valid for the renderer's mapping (strict: raises on any invalid value)
        m = haze_mapping(p["core_reflectivity"], p["edge_tint"], p["roughness"] ** 2,
                         p["haziness"], p["haze_extent"], alpha_max=1.0, max_aspect=10.0,
                         strict=True)
        assert 0.0 <= float(m.beta) <= 1.0
    with pytest.raises(KeyError, match="PROBE_A"):
        presets.parameters("NOPE")


DIAMOND_R = ((2.417 - 1) / (2.417 + 1)) ** 2  # 0.172, the most reflective common dielectric


def test_dielectric_presets_reflectivity():
    """Haze raises a dielectric's global reflectivity r (Eq. 5): with the paper's rule of thumb
    β_h <= 0.1, r ≈ r_c + β_h (1 - r_c) stays below diamond's 0.172 (no warning in the panel);
    the Vase of Table 3 uses β_h = 0.15 with λ_h = 7 and reaches r = 0.1925 (η = 2.56), beyond
    any common dielectric: the panel's "looks like a metal" warning fires for it, as the
    Discussion says."""
    assert DIAMOND_R == pytest.approx(0.172, abs=1e-3)
    for pid, pre in presets.PRESETS.items():
        if pre.kind != "DIELECTRIC":
            continue
        m = plots.mapping_for(pre.parameters())
        r = float(m.reflectivity_max)
        if pid == "VASE":
            # p = (1/(1+7))² = 1/64, k_h = 0.15 (1 - 0.05)/(1 - p), r = r_c + (1 - p) k_h
            assert r == pytest.approx(0.05 + 0.15 * 0.95, rel=1e-12)
            assert r > DIAMOND_R
        else:
            assert pre.haziness <= 0.1 and r < DIAMOND_R, (pid, r)


# --------------------------------------------------------------------------------------------
# Plots
# --------------------------------------------------------------------------------------------


def _closest(img, colour):
    """Distance of every pixel's RGB to ``colour``."""
    return np.linalg.norm(img[..., :3] - np.asarray(colour[:3], dtype=np.float32), axis=-1)


def test_haze_plot_geometry():
    """Figure 3 left: bounds P and E meet at (p, 1); the β_h curve and the current point sit
    where Eq. 7 puts them; row 0 is the bottom row (Blender's pixel order)."""
    size = 200
    p, bh, rc = 0.3, 0.6, 0.7
    img = plots.haze_plot(rc, p, bh, size=(size, size))
    assert img.shape == (size, size, 4) and img.dtype == np.float32
    assert np.all(np.isfinite(img)) and img.min() >= 0 and img.max() <= 1
    canvas = plots.Canvas(size, size, xlim=(0.0, 1.0), ylim=(0.0, 1.08))

    def row_of_colour(x, colour):
        """Centre (in continuous pixel coordinates) of the stroke of ``colour`` in the column
        at data x, and how close its best pixel is to the colour."""
        d = _closest(img[:, int(canvas.px(x))], colour)
        rows = np.nonzero(d < 0.2)[0]
        return (rows.mean() + 0.5 if rows.size else -1.0), float(d.min())

    # P bound at r_c = p/2 is k_h = 1/2; E bound at r_c = (1+p)/2 is k_h = 1/2
    for x in (p / 2, (1 + p) / 2):
        row, dist = row_of_colour(x, plots.COLOURS["bound"])
        assert dist < 0.15 and abs(row - canvas.py(0.5)) <= 1.5, (x, row, canvas.py(0.5))
    # the β_h curve (Eq. 7) at r_c = 0.9: k_h = β_h (1 - 0.9) / (1 - p)
    row, dist = row_of_colour(0.9, plots.COLOURS["curve"])
    assert dist < 0.15 and abs(row - canvas.py(bh * 0.1 / (1 - p))) <= 1.5
    # the current point: k̂_h = β_h (1 - r_c) / (1 - p)
    kh = bh * (1 - rc) / (1 - p)
    r, c = int(canvas.py(kh)), int(canvas.px(rc))
    assert _closest(img[r - 1:r + 2, c - 1:c + 2], plots.COLOURS["point"]).min() < 0.05
    # orientation: the point is in the lower half of the picture when k_h < 0.5
    assert kh < 0.5 and r < size // 2


def test_haze_plot_smooth_curve_stays_below_eq7():
    """The Bézier (Eqs. 12-15) lies in the triangle under the Eq. 7 lines (Figure 3 grey)."""
    size = 160
    sharp = plots.haze_plot(0.5, 0.3, 0.8, size=(size, size))
    smooth = plots.haze_plot(0.5, 0.3, 0.8, smoothness=1.0, size=(size, size))
    canvas = plots.Canvas(size, size, xlim=(0.0, 1.0), ylim=(0.0, 1.08))
    col = int(canvas.px(0.3))  # the kink of Eq. 7 at r_c = p
    top_sharp = np.argmin(_closest(sharp[:, col], plots.COLOURS["curve"]))
    top_smooth = np.argmin(_closest(smooth[:, col], plots.COLOURS["curve"]))
    assert top_smooth < top_sharp - 3


def _mapping(kind="CONDUCTOR", **kw):
    p = dict(kind=kind, core_reflectivity=(0.6, 0.4, 0.2), roughness=0.2, anisotropy=0.0,
             haziness=0.7, haze_extent=6.0)
    if kind == "CONDUCTOR":  # (an edge tint on another kind is refused, not ignored)
        p["edge_tint"] = (0.9, 0.7, 0.5)
    p.update(kw)
    return plots.mapping_for(p), p


@pytest.mark.parametrize("kind", ["CONDUCTOR", "DIELECTRIC", "LEGACY"])
@pytest.mark.parametrize("theta_i", [0.0, 35.0])
def test_brdf_slice_is_eq2(kind, theta_i):
    """The slice's lobes are Eq. 1's, evaluated independently (tests/blender/analytic.py: GGX,
    height-correlated Smith G2, exact Fresnel at h·wi); core + halo = total (Eq. 2 = Eq. 1);
    the halo vanishes at the peak for θ_i = 0."""
    m, _ = _mapping(kind, core_reflectivity=0.04 if kind == "DIELECTRIC" else (0.6, 0.4, 0.2),
                    haziness=0.1 if kind == "DIELECTRIC" else 0.7)
    s = plots.brdf_slice(m, kind, theta_i=theta_i, samples=401)
    ch = s["channel"]
    ti = math.radians(theta_i)
    wi = np.array([math.sin(ti), 0.0, math.cos(ti)])
    to = np.radians(s["theta_o"])
    wo = np.stack([np.sin(to), np.zeros_like(to), np.cos(to)], axis=-1)
    a_n = [float(np.asarray(a)) for a in m.alpha]
    a_w = [float(np.asarray(a)) for a in m.alpha_wide]
    f_n = analytic.microfacet_lobe(wi, wo, *a_n)
    f_w = analytic.microfacet_lobe(wi, wo, *a_w)
    h = analytic.half_vector(wi, wo)
    cos_d = np.sum(h * wi, axis=-1)
    if kind == "CONDUCTOR":
        fr = analytic.conductor_fresnel(cos_d, float(np.asarray(m.ior).reshape(3)[ch]),
                                        float(np.asarray(m.extinction).reshape(3)[ch]))
    elif kind == "DIELECTRIC":
        fr = analytic.dielectric_fresnel(cos_d, float(np.asarray(m.dielectric_ior)))
    else:  # no Fresnel: k_n + k_w = r
        fr = float(np.asarray(m.reflectivity).reshape(3)[ch])
    beta = float(np.asarray(m.beta))
    np.testing.assert_allclose(s["narrow"], (1.0 - beta) * fr * f_n, rtol=1e-12, atol=0)
    np.testing.assert_allclose(s["wide"], beta * fr * f_w, rtol=1e-12, atol=0)
    np.testing.assert_allclose(s["total"], ((1.0 - beta) * f_n + beta * f_w) * fr, rtol=1e-12,
                               atol=0)
    np.testing.assert_allclose(s["core"] + s["halo"], s["total"], rtol=1e-12, atol=0)
    if theta_i == 0.0:
        mirror = np.argmin(np.abs(s["theta_o"]))
        assert s["theta_o"][mirror] == pytest.approx(0.0, abs=1e-9)
        assert abs(s["halo"][mirror]) <= 1e-12 * s["total"][mirror]
        assert np.all(s["halo"] >= -1e-12 * s["total"].max())  # g_h >= 0 at normal incidence


def test_brdf_slice_peak_independent_of_haze_and_analytic():
    """The paper's point: haziness and extent leave the peak alone.  At normal incidence the
    peak is r_c f_n(n, n) = r_c / (4 π α²) (GGX, G = 1, F(0) = r)."""
    peaks = []
    for bh, ext in [(0.0, 5.0), (0.5, 5.0), (0.9, 2.0), (0.99, 12.0)]:
        m, p = _mapping(haziness=bh, haze_extent=ext)
        peaks.append(plots.brdf_at(m, "CONDUCTOR", 0.0, [0.0])["total"][0])
    alpha = 0.2 ** 2
    expected = 0.6 / (4.0 * np.pi * alpha * alpha)
    np.testing.assert_allclose(peaks, expected, rtol=1e-12)


def test_brdf_slice_anisotropic_halo_along_tangent():
    """The slice runs along the tangent: a halo stretched along x is wider than one along y."""
    mx, _ = _mapping(haze_extent=(12.0, 1.0))
    my, _ = _mapping(haze_extent=(1.0, 12.0))
    angles = np.array([15.0])
    assert plots.brdf_at(mx, "CONDUCTOR", 0.0, angles)["halo"][0] > \
        5 * plots.brdf_at(my, "CONDUCTOR", 0.0, angles)["halo"][0]


@pytest.mark.parametrize("log", [True, False])
def test_brdf_plot_draws_three_curves(log):
    m, _ = _mapping()
    img = plots.brdf_plot(m, "CONDUCTOR", size=(160, 160), log=log)
    assert img.shape == (160, 160, 4) and img.dtype == np.float32 and np.all(np.isfinite(img))
    for name in ("total", "core", "halo"):
        assert _closest(img, plots.COLOURS[name]).min() < 0.05, name
    # symmetric slice at normal incidence: the picture is (nearly) mirror-symmetric
    diff = np.abs(img - img[:, ::-1]).mean()
    assert diff < 0.01


def test_srgb_to_linear():
    out = plots.srgb_to_linear(np.array([[0.0, 0.04045, 0.5, 0.7], [1.0, 1.0, 1.0, 0.2]]))
    np.testing.assert_allclose(out[0, :3], [0.0, 0.04045 / 12.92, 0.21404114], rtol=1e-6)
    assert out[0, 3] == pytest.approx(0.7) and out[1, 3] == pytest.approx(0.2)
    np.testing.assert_allclose(out[1, :3], 1.0, rtol=1e-6)


def test_modules_do_not_import_bpy():
    code = ("import sys; sys.path.insert(0, %r); import hazy_gloss.utils.plots, "
            "hazy_gloss.utils.presets; assert 'bpy' not in sys.modules; print('ok')" % str(ROOT))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "ok" in out.stdout, out.stderr
