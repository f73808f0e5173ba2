# SPDX-License-Identifier: GPL-3.0-or-later
"""The body colour under the Principled specular (core/body_colour.py), without rendering.

- Tables (extracted from the bpy wheels): every sampled node of ggx_gen_schlick_ior_s against
  an independent deterministic quadrature of what cycles_precompute.cpp estimates (the mean of
  the remapped dielectric Fresnel over GGX visible normals, horizon-cut), to the tables' own
  accuracy (Monte Carlo with 2^20 samples, 6 decimals); the lookup at the nodes and between them
  (trilinear, Cycles' index maps), both generations (4.5/5.2: 16³ in μ; 5.3: 32³ in √μ).
- The kernel's chain: Specular IOR Level -> η, Specular Tint, the float32 η == 1 rule, the
  channel maximum before (5.3) or after (4.5/5.2) the Multiscatter GGX factor, that factor
  against core.multiscatter at normal view, 4.5's Fresnel-is-zero shortcut.
- Stiff inputs (IOR 1.0001 .. 1e3, ±inf, NaN, roughness 0 and 1, μ 0 and 1): finite, in [0, 1].
- The compensation: its factor, the polynomial and its reported fit error, the clamp and the
  darkening it leaves, the node description (evaluated as the nodes would).
tests/blender/test_body_colour.py renders the same claims in Cycles 4.5, 5.2 and 5.3.
"""
import itertools

import numpy as np
import pytest

import specular_reference as R
from hazy_gloss.core import body_colour as bc
from hazy_gloss.core import multiscatter as ms
from hazy_gloss.core.lobes import describe

VERSIONS = ("4.5", "5.2", "5.3")
GENERATIONS = {"V4": (16, False), "V53": (32, True)}


def _f0(ior):
    return ((ior - 1.0) / (ior + 1.0)) ** 2


# ------------------------------------------------------------------------------------------------
# Tables
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("gen", sorted(GENERATIONS))
def test_table_nodes_match_quadrature(gen):
    """Sampled nodes (the η = 1 slice aside, below) within the Monte Carlo accuracy of the
    generator: measured max 1.6e-5 (V4, all 4096 nodes), 2.2e-5 (V53, 1500 random nodes)."""
    n, sqrt_mu = GENERATIONS[gen]
    table = bc.generation_tables(gen)["ior_s"]
    rng = np.random.default_rng(7)
    nodes = [(i, j, k) for i in range(n) for j in range(n) for k in range(1, n)]
    pick = rng.choice(len(nodes), 700, replace=False)
    err = np.array([table[k, j, i] - R.s_mean(*R.table_node(i, j, k, n, sqrt_mu))
                    for i, j, k in (nodes[p] for p in pick)])
    assert np.abs(err).max() <= 4e-5, np.abs(err).max()
    assert np.sqrt(np.mean(err ** 2)) <= 5e-6


def test_table_eta_one_slice():
    """z = 0 is η = 1 (F = F0 = 0): 4.5/5.2's float32 generator gives exactly 0 there; 5.3's
    is 0 to 1e-5 except at the grazing node μ = 1e-8 (s = 1 for a mirror, falling with
    roughness: η a hair above 1 there).  Cycles reads this slice for IOR within ~1e-2 of 1."""
    assert np.all(bc.generation_tables("V4")["ior_s"][0] == 0.0)
    z0 = bc.generation_tables("V53")["ior_s"][0]
    assert z0[0, 0] == 1.0 and np.all(np.diff(z0[0]) <= 1e-6)
    assert np.abs(z0[1:]).max() <= 1e-5


def test_table_orientation_and_shape():
    """The tables as the kernel indexes them, [z][y][x] with x the roughness: for a smooth
    lobe s rises towards grazing (y -> 0), in both generations; E is 1 for a mirror at every μ."""
    for gen, (n, _) in GENERATIONS.items():
        t = bc.generation_tables(gen)
        assert t["ior_s"].shape == (n, n, n) and t["e"].shape == (32, 32) and t["eavg"].shape == (32,)
        k = n // 2
        smooth = t["ior_s"][k, :, 1]  # s falls from ~1 at grazing to ~0 face-on
        assert smooth[0] > 0.5 and smooth[-1] < 1e-3 and np.all(np.diff(smooth[n // 4:]) <= 1e-6)
        assert np.all(t["e"][:, 0] >= 0.9999)


@pytest.mark.parametrize("version", ("4.5", "5.3"))
def test_lookup_hits_the_nodes(version):
    """At a node (roughness, view and IOR exactly on it) the estimate is f0 + (1 - f0) s_node."""
    gen = "V53" if version == "5.3" else "V4"
    n, sqrt_mu = GENERATIONS[gen]
    table = bc.generation_tables(gen)["ior_s"]
    for i, j, k in [(3, 5, 7), (n - 1, n - 1, 2), (1, n // 2, n - 2), (n // 3, 1, 1)]:
        r, y, z = i / (n - 1), j / (n - 1), k / (n - 1)
        mu = y * y if sqrt_mu else y
        f0 = z ** 4
        ior = (1 + z * z) / (1 - z * z)
        a = bc.specular_albedo(r * r, r * r, mu, ior, version=version)
        assert a == pytest.approx(f0 + (1 - f0) * table[k, j, i], rel=0, abs=2e-7)


@pytest.mark.parametrize("version", ("4.5", "5.3"))
def test_interpolated_albedo_matches_quadrature(version):
    """Off the nodes, A = f0 + (1 - f0) s against s integrated at the very point: the tables'
    trilinear interpolation error, view angles 0-80°, roughness 0.02-1, IOR 1.05-40 (measured
    over 600 random points: max 6.7e-3 / 5.0e-3 (4.5 / 5.3), rms 5.3e-4 / 2.3e-4)."""
    rng = np.random.default_rng(3)
    r = rng.uniform(0.02, 1.0, 200)
    mu = np.cos(np.radians(rng.uniform(0.0, 80.0, 200)))
    ior = np.exp(rng.uniform(np.log(1.05), np.log(40.0), 200))
    ref = np.array([R.s_mean(m, a * a, e) for m, a, e in zip(mu, r, ior)])
    a_ref = _f0(ior) + (1 - _f0(ior)) * ref
    d = bc.specular_albedo(r * r, r * r, mu, ior, version=version) - a_ref
    assert np.abs(d).max() <= 1e-2
    assert np.sqrt(np.mean(d ** 2)) <= 1e-3


def test_estimate_is_not_the_brdf_albedo():
    """What Cycles subtracts is its energy-conserving estimate, not the single-scatter GGX
    BRDF's albedo: equal for a smooth lobe, the BRDF's smaller for a rough one (about 0.3 x for
    R = 1 face-on at IOR 1.5, where E(1, α = 1) = 0.31)."""
    for r, close in ((0.05, True), (1.0, False)):
        est = bc.specular_albedo(r * r, r * r, 1.0, 1.5)
        brdf = R.brdf_albedo(1.0, r * r, 1.5, _f0(1.5))
        if close:
            assert brdf == pytest.approx(est, rel=1e-3)
        else:
            assert 0.25 < brdf / est < 0.35


# ------------------------------------------------------------------------------------------------
# The kernel's chain
# ------------------------------------------------------------------------------------------------


def test_specular_ior_level_changes_eta_like_the_kernel():
    """Level L != 0.5 scales F0 by 2L and re-derives η from it (F0 clamped to 0.99): the same
    albedo as the IOR with that F0 at level 0.5; level 0 removes the specular (A = 0)."""
    mu = np.linspace(0.0, 1.0, 9)
    for ior, level in [(1.5, 0.25), (1.5, 1.0), (2.4, 0.8), (1.2, 0.05)]:
        f0 = _f0(ior) * 2 * level
        same = (1 + np.sqrt(f0)) / (1 - np.sqrt(f0))
        np.testing.assert_allclose(bc.specular_albedo(0.1, 0.1, mu, ior, level=level),
                                   bc.specular_albedo(0.1, 0.1, mu, same), rtol=1e-12, atol=1e-15)
    assert np.all(bc.specular_albedo(0.1, 0.1, mu, 1.5, level=0.0) == 0.0)
    eta, f0, exists = bc.kernel_specular(40.0, 1.0)  # 2 F0(40) > 0.99: clamped
    assert f0 == pytest.approx(2 * _f0(40.0)) and exists
    assert eta == pytest.approx((1 + np.sqrt(0.99)) / (1 - np.sqrt(0.99)))
    eta, _, _ = bc.kernel_specular(0.5, 0.7)  # IOR < 1 stays below 1
    assert eta < 1.0


def test_no_specular_closure_when_eta_is_one_in_float32():
    """IOR 1 (or within float32 rounding of it) makes no specular closure: A = 0."""
    assert bc.specular_albedo(0.3, 0.3, 0.5, 1.0) == 0.0
    assert bc.specular_albedo(0.3, 0.3, 0.5, 1.0 + 1e-8) == 0.0
    assert bc.specular_albedo(0.3, 0.3, 0.5, 1.0001) > 0.0


def test_specular_tint_and_channel_maximum():
    """Tint scales f0 per channel; 4.5/5.2 and 5.3 (GGX) take the largest channel: one grey A."""
    tint = np.array([1.0, 0.5, 0.0])
    mu = np.array([1.0, 0.5, 0.2])
    for v in VERSIONS:
        a = bc.specular_albedo(0.2, 0.2, mu, 2.0, tint, version=v)
        est = bc.albedo_estimate(0.2, 0.2, mu, 2.0, tint, version=v)
        np.testing.assert_allclose(a, np.repeat(est.max(axis=-1, keepdims=True), 3, -1), rtol=1e-14)
        np.testing.assert_allclose(est[..., 0], bc.specular_albedo(0.2, 0.2, mu, 2.0, version=v))
        s = bc.albedo_estimate(0.2, 0.2, mu[1:], 2.0, 0.0, version=v)  # f0 = 0: est = s
        f0 = _f0(2.0) * 0.5
        np.testing.assert_allclose(est[1:, 1], f0 + (1 - f0) * s, rtol=1e-13)
    big = bc.albedo_estimate(0.2, 0.2, 0.7, 2.0, 100.0)  # f0 tint saturates at 1
    assert big == pytest.approx(1.0)


def test_multiscatter_factor_at_normal_view_matches_core_multiscatter():
    """Multiscatter GGX multiplies the layer albedo by the closure weight's energy factor,
    (1 + F_ms (1 - E)/E) E: at μ = 1 this is S(F_ss) / S(1) of core.multiscatter (its own
    tables and F_ss code)."""
    for v, r, ior, tint in itertools.product(("4.5", "5.3"), (0.2, 0.6, 1.0), (1.3, 2.0, 6.0),
                                             ((1, 1, 1), (1.0, 0.4, 0.1))):
        tint = np.asarray(tint, float)
        a = r * r
        fss = ms.fss_dielectric(ior, specular_tint=tint)
        d_ref = ms.energy_scale(a, fss, version=v) / ms.energy_scale(a, np.ones(3), version=v)
        est = bc.albedo_estimate(a, a, 1.0, ior, tint, version=v)
        got = bc.specular_albedo(a, a, 1.0, ior, tint, distribution="MULTI_GGX", version=v)
        want = d_ref * est.max() if v == "5.3" else np.full(3, (d_ref * est).max())
        np.testing.assert_allclose(got, want, rtol=1e-9)


def test_multiscatter_lowers_the_layer_albedo():
    """The factor is <= 1 (F_ms <= 1): Multiscatter GGX darkens the base less than GGX."""
    r = np.linspace(0.0, 1.0, 11)[:, None, None]
    mu = np.linspace(0.0, 1.0, 11)[None, :, None]
    ior = np.array([1.1, 1.5, 3.0, 40.0])
    for v in VERSIONS:
        g = bc.specular_albedo(r * r, r * r, mu, ior, version=v)
        m = bc.specular_albedo(r * r, r * r, mu, ior, distribution="MULTI_GGX", version=v)
        assert np.all(m <= g + 1e-15)
        assert np.all(m[0] == g[0])  # a mirror loses nothing


def test_versions():
    """4.5 and 5.2 share their tables (and so every A, the shortcut below aside); 5.3's finer
    table differs by up to ~1.3e-2 in A within 0-80° (measured)."""
    r = np.linspace(0.0, 1.0, 21)[:, None, None]
    mu = np.cos(np.radians(np.linspace(0.0, 80.0, 17)))[None, :, None]
    ior = np.array([1.05, 1.5, 2.5, 5.0, 12.0, 40.0])
    a45, a52, a53 = (bc.specular_albedo(r * r, r * r, mu, ior, version=v) for v in VERSIONS)
    assert np.array_equal(a45, a52)
    d = np.abs(a53 - a45)
    assert 1e-3 < d.max() < 2e-2
    assert bc.generation(None) == "V53" and bc.generation((4, 5, 15)) == "V4"


def test_45_skips_the_table_where_the_fresnel_is_zero():
    """4.5 returns 0 where the specular's Fresnel at the view angle is 0 in every channel
    (Specular Tint black, F_dielectric(μ) < F0(η): past the Brewster dip of a large IOR);
    5.2 and 5.3 read the table there.  Face-on (F = F0 exactly, float32 rounding decides) the
    table is taken, as the 4.5 render of tests/blender/test_body_colour.py shows."""
    a45 = bc.specular_albedo(0.16, 0.16, 0.1, 12.0, 0.0, version="4.5")
    a52 = bc.specular_albedo(0.16, 0.16, 0.1, 12.0, 0.0, version="5.2")
    assert a45 == 0.0 and a52 > 1e-4
    for mu in (1.0, 0.7):  # F(μ) >= F0: the table
        a45 = bc.specular_albedo(0.16, 0.16, mu, 1.5, 0.0, version="4.5")
        assert a45 > 1e-4 and a45 == bc.specular_albedo(0.16, 0.16, mu, 1.5, 0.0, version="5.2")


def test_anisotropy_only_through_the_product():
    a = bc.specular_albedo(0.3 / 2.0, 0.3 * 2.0, 0.6, 1.5)
    assert a == bc.specular_albedo(0.3, 0.3, 0.6, 1.5)
    assert bc.specular_albedo(2.0, 3.0, 0.6, 1.5) == bc.specular_albedo(1.0, 1.0, 0.6, 1.5)


def test_broadcasting_and_shapes():
    mu = np.linspace(0, 1, 5)
    assert bc.specular_albedo(0.1, 0.1, mu, 1.5).shape == (5,)
    assert bc.specular_albedo(0.1, 0.1, mu[:, None], [1.5, 2.0]).shape == (5, 2)
    assert bc.specular_albedo(0.1, 0.1, mu[:, None], 1.5, (1.0, 0.5, 0.2)).shape == (5, 1, 3)
    assert bc.specular_albedo(0.1, 0.1, mu, 1.5, np.ones((5, 3))).shape == (5, 3)
    assert np.ndim(bc.specular_albedo(0.1, 0.1, 0.5, 1.5)) == 0
    with pytest.raises(ValueError):
        bc.specular_albedo(0.1, 0.1, 0.5, 1.5, distribution="BECKMANN")


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("distribution", bc.DISTRIBUTIONS)
def test_stiff_inputs_are_finite(version, distribution):
    """IOR 1.0001 .. 1e3 and ±inf, roughness 0 and 1 (and beyond), μ 0 and 1 (and beyond),
    levels 0 .. inf, NaN anywhere: finite, in [0, 1]."""
    vals = dict(alpha=[0.0, 1e-12, 1.0, 5.0, np.nan, np.inf, -1.0],
                mu=[0.0, 1e-9, 1.0, 1.5, -0.5, np.nan, np.inf, -np.inf],
                ior=[1.0001, 1.0, 0.5, 1e-9, 40.0, 1e3, np.inf, -np.inf, np.nan],
                level=[0.0, 0.5, 1.0, 1e6, np.inf, np.nan])
    a = np.asarray(vals["alpha"])[:, None, None, None]
    mu = np.asarray(vals["mu"])[None, :, None, None]
    ior = np.asarray(vals["ior"])[None, None, :, None]
    level = np.asarray(vals["level"])[None, None, None, :]
    with np.errstate(all="raise"):
        for tint in (1.0, (1.0, 0.0, np.nan), (np.inf, 0.5, 0.0)):
            out = bc.specular_albedo(a, a, mu, ior, tint, level, distribution, version)
            assert np.all(np.isfinite(out)) and out.min() >= 0.0 and out.max() <= 1.0
    # the limits: a huge IOR reflects everything, IOR 1.0001 almost nothing face-on
    assert bc.specular_albedo(0.2, 0.2, 0.8, 1e3, version=version) > 0.99
    assert bc.specular_albedo(0.2, 0.2, 0.8, np.inf, version=version) == pytest.approx(1.0)
    assert bc.specular_albedo(0.0, 0.0, 1.0, 1.0001, version=version) < 1e-6
    # NaN reads as the kernel's clamps read it
    assert bc.specular_albedo(np.nan, 0.0, 0.5, 1.5) == bc.specular_albedo(0.0, 0.0, 0.5, 1.5)
    assert bc.specular_albedo(0.1, 0.1, 0.5, 1.5, level=np.nan) == 0.0


def test_facing():
    np.testing.assert_array_equal(bc.facing([1.0, 0.25, 0.0, -0.5]), [0.0, 0.75, 1.0, 0.5])


# ------------------------------------------------------------------------------------------------
# The compensation
# ------------------------------------------------------------------------------------------------


def hazy(ior, roughness, haziness, extent=5.0, distribution="GGX"):
    """(β, α_wide, IOR') of a Principled core as blender/model/layer.py computes them."""
    f0 = _f0(ior)
    d = describe("DIELECTRIC", distribution, core_reflectivity=(f0,) * 3, roughness=roughness,
                 haziness=haziness, haze_extent=extent)
    gain = float(d.mapping.reflectivity_max) / float(np.max(d.mapping.core_reflectivity))
    q = np.sqrt(min(f0 * gain, 1 - 2 ** -23))
    return float(d.beta), float(d.wide.roughness) ** 2, float((1 + q) / (1 - q))


def test_no_haze_no_compensation():
    r = bc.compensation(0.09, 1.5, 1.5, 0.0, 0.5, (0.8, 0.8, 0.8))
    np.testing.assert_allclose(np.asarray(r.coefficients)[:, 0], [1, 0, 0, 0], atol=1e-12)
    assert r.fit_error <= 1e-12 and r.grey and not r.clamped
    assert max(r.darkening_face_on) == 0.0 and max(r.residual_average) == 0.0
    assert r.warning() is None


def test_factor_is_the_ratio_of_body_weights():
    beta, aw, ior_h = hazy(1.5, 0.3, 0.5)
    mu = np.linspace(0.05, 1.0, 20)
    c = bc.factor(0.09, 1.5, ior_h, beta, aw, mu)
    a_n = bc.specular_albedo(0.09, 0.09, mu, 1.5)
    a_nh = bc.specular_albedo(0.09, 0.09, mu, ior_h)
    a_wh = bc.specular_albedo(aw, aw, mu, ior_h)
    want = (1 - a_n) / ((1 - beta) * (1 - a_nh) + beta * (1 - a_wh))
    np.testing.assert_allclose(c, np.repeat(want[:, None], 3, 1), rtol=1e-13)
    assert np.all(c > 1.0)


@pytest.mark.parametrize("version", ("4.5", "5.3"))
def test_fit_error_is_what_it_says(version):
    """The reported fit error bounds |c_fit/c - 1| over 0-80° (checked on a grid 10x finer than
    the fit's), and degree 3 keeps it within 1.5% for typical hazy Principled materials
    (IOR 1.33-2.5, roughness 0.05-0.8, haziness 0.1 and 0.5; measured worst 0.9%, median 0.09%,
    at the smoothest cores, where c falls steeply towards grazing).  Beyond 80° the polynomial is
    extrapolated: the 2μ-weighted rms over the hemisphere stays <= 4.4% (median 0.34%)."""
    errs = []
    for ior, rough, h in itertools.product((1.33, 1.5, 2.5), (0.05, 0.2, 0.5, 0.8), (0.1, 0.5)):
        beta, aw, ior_h = hazy(ior, rough, h)
        res = bc.compensation(rough ** 2, ior, ior_h, beta, aw, version=version)
        mu = np.cos(np.radians(np.linspace(0.0, 80.0, 4001)))
        c = bc.factor(rough ** 2, ior, ior_h, beta, aw, mu, version=version)
        rel = np.abs(res.polynomial(1.0 - mu) / c - 1.0).max()
        assert rel <= res.fit_error * 1.05 + 1e-9, (ior, rough, h, rel, res.fit_error)
        assert res.fit_error <= 0.015, (ior, rough, h, res.fit_error)
        assert res.fit_rms <= 0.05 and res.fit_error_hemisphere >= res.fit_error
        errs.append(res.fit_error)
    assert np.median(errs) <= 4e-3


def test_higher_degree_fits_better():
    beta, aw, ior_h = hazy(1.5, 0.2, 0.5)
    e = [bc.compensation(0.04, 1.5, ior_h, beta, aw, degree=d).fit_error for d in (1, 2, 3, 4, 5)]
    assert all(b <= a * 1.0001 for a, b in zip(e, e[1:])), e
    assert bc.compensation(0.04, 1.5, ior_h, beta, aw, degree=0).degree == 0
    for bad in (-1, 9, 2.5, True):
        with pytest.raises(ValueError):
            bc.compensation(0.04, 1.5, ior_h, beta, aw, degree=bad)
    with pytest.raises(ValueError):
        bc.compensation(0.04, 1.5, ior_h, beta, aw, max_angle=0.0)


def test_darkening_and_the_clamp():
    """Haziness 0.5 darkens the body by half face-on (c(1) = 2) for this material; white 0.8
    cannot be doubled: the clamp leaves 1 - 1/1.6 = 37.5% face-on, and only in the channels
    that clamp; a dark base keeps everything."""
    beta, aw, ior_h = hazy(1.5, 0.3, 0.5)
    white = bc.compensation(0.09, 1.5, ior_h, beta, aw, (0.8, 0.8, 0.8))
    red = bc.compensation(0.09, 1.5, ior_h, beta, aw, (0.8, 0.1, 0.1))
    dark = bc.compensation(0.09, 1.5, ior_h, beta, aw, (0.05, 0.05, 0.05))
    c1 = white.c_face_on[0]
    assert white.darkening_face_on[0] == pytest.approx(1 - 1 / c1, rel=1e-12)
    assert white.residual_face_on[0] == pytest.approx(1 - 1 / (0.8 * c1), rel=1e-12)
    assert white.clamped and red.clamped and not dark.clamped
    assert red.residual_face_on[0] == pytest.approx(white.residual_face_on[0])
    assert red.residual_face_on[1] == 0.0 and abs(red.residual_average[2]) <= 1e-15
    assert max(dark.residual_average) == 0.0 and dark.warning() is None
    assert 0 < white.residual_average[0] < white.darkening_average[0]
    line = white.warning()
    assert line and "\n" not in line and "37.5%" in line
    np.testing.assert_allclose(white.compensated_base(1.0), np.ones(3))
    np.testing.assert_allclose(dark.compensated_base(1.0), 0.05 * np.asarray(dark.polynomial(0.0)))


def test_node_description_evaluates_to_the_polynomial():
    beta, aw, ior_h = hazy(2.0, 0.25, 0.3)
    res = bc.compensation(0.0625, 2.0, ior_h, beta, aw, (0.5, 0.3, 0.2), degree=4)
    d = res.nodes()
    assert d["node_count"] == 7 and len(d["horner"]) == 4
    assert d["facing"]["node"] == "ShaderNodeLayerWeight" and d["facing"]["Blend"] == 0.5
    a = d["coefficients"]
    f = np.linspace(0.0, 1.0, 33)
    p = np.full_like(f, a[-1])
    for step, k in zip(d["horner"], range(len(a) - 2, -1, -1)):
        assert step["operation"] == "MULTIPLY_ADD" and step["inputs"][2] == f"a[{k}]"
        p = p * f + a[k]
    np.testing.assert_allclose(p, res.polynomial(f)[:, 0], rtol=1e-14)
    np.testing.assert_allclose(sum(ak * f ** k for k, ak in enumerate(a)), p, rtol=1e-12)
    folded = d["constant_base"]
    assert folded["node_count"] == 6 and len(folded["horner"]) == 4
    b = np.asarray(folded["coefficients"])
    q = np.broadcast_to(b[-1], (33, 3)).copy()
    for k in range(len(b) - 2, -1, -1):
        q = q * f[:, None] + b[k]
    np.testing.assert_allclose(np.minimum(q, 1.0), res.compensated_base(1.0 - f), rtol=1e-13)


def test_coloured_compensation_only_for_53_multiscatter_with_tint():
    beta, aw, ior_h = hazy(1.5, 0.4, 0.5, distribution="MULTI_GGX")
    args = (0.16, 1.5, ior_h, beta, aw, (0.5, 0.5, 0.5))
    tint = (1.0, 0.6, 0.2)
    assert not bc.compensation(*args, tint=tint, distribution="MULTI_GGX", version="5.3").grey
    assert bc.compensation(*args, tint=tint, distribution="MULTI_GGX", version="4.5").grey
    assert bc.compensation(*args, tint=tint, version="5.3").grey
    res = bc.compensation(*args, tint=tint, distribution="MULTI_GGX", version="5.3")
    desc = res.nodes()
    assert desc["horner"][0]["node"] == "ShaderNodeVectorMath"
    assert all(len(a) == 3 for a in desc["coefficients"])


@pytest.mark.parametrize("version", ("4.5", "5.3"))
def test_compensation_stiff_inputs(version):
    """Vanishing hazy bodies (IOR' 1e3 or inf, β = 1), mirrors, IOR 1.0001, NaN colours: finite
    coefficients and reports, c capped."""
    cases = [(0.0, 1.5, 1e3, 1.0, 0.0), (1.0, 1.0001, 1.0002, 0.5, 1.0), (0.04, 1.5, np.inf, 0.9, 1.0),
             (0.09, 40.0, 1e3, 0.3, 0.8), (0.09, 1.5, 3.0, np.nan, 0.5), (np.nan, 1.5, 3.0, 0.5, np.nan)]
    for alpha, ior, ior_h, beta, aw in cases:
        for base in ((0.8, 0.8, 0.8), (np.nan, np.inf, -1.0), (0.0, 0.0, 0.0)):
            r = bc.compensation(alpha, ior, ior_h, beta, aw, base, version=version)
            vals = np.concatenate([np.ravel(r.coefficients), [r.fit_error, r.fit_rms, r.c_max],
                                   r.residual_face_on, r.residual_average, r.darkening_average])
            assert np.all(np.isfinite(vals)), (alpha, ior, ior_h, beta, aw, base)
            assert r.c_max <= bc.C_LIMIT
            assert all(0.0 <= x <= 1.0 for x in r.residual_average + r.residual_face_on)
