# SPDX-License-Identifier: GPL-3.0-or-later
"""Multiscatter GGX (core/multiscatter.py) and the peak it keeps, without rendering.

- Tables: Cycles' E(μ = 1, R) and E_avg(R), shipped as data, against an independent
  deterministic quadrature of the GGX single-scatter albedo with height-correlated Smith G
  (ggx_albedo.py), to the tables' own accuracy (Monte Carlo + 6 decimals); Cycles' lookup.
- F_ss: the closed forms against numerical integrals (F82), the exact conductor Fresnel against
  the complex-index textbook formula, 4.5's approximation, the running Blender's version.
- The correction: describe(..., "MULTI_GGX") gives socket values whose normal-incidence peak,
  evaluated from those values alone (F(0) from η, κ / IOR and tint / colours, F_ss from the
  node's rule, S from the tables), equals the haze-free material's to 1e-9 for every kind, over
  a grid that includes the stiff corners; the single-scatter mapping would move it by > 1e-3
  (the test can fail); GGX / Beckmann / Ashikhmin-Shirley never reach the correction.
tests/blender/test_multiscatter.py renders the same claims in Cycles 4.5, 5.2 and 5.3.
"""
import itertools
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import ggx_albedo as Q
from hazy_gloss import constants as K
from hazy_gloss.core.tables import cycles_ggx_tables as T
from hazy_gloss.core import lobes as core_lobes
from hazy_gloss.core import multiscatter as ms
from hazy_gloss.core.conventions import alpha_from_roughness
from hazy_gloss.core.lobes import describe

NODES = np.arange(32) / 31
#: cycles_precompute.cpp clamps the roughness to >= 1e-4
R_NODES = np.maximum(NODES, 1e-4)


# ------------------------------------------------------------------------------------------------
# Tables
# ------------------------------------------------------------------------------------------------


def test_table_albedo_at_normal_incidence_matches_quadrature():
    table = np.asarray(T.E_MU1, np.float32).astype(np.float64)
    quad = np.array([Q.albedo_normal(r * r) for r in R_NODES])
    err = table - quad
    # Monte Carlo (2^23 samples) and 6-decimal rounding: measured max 8.1e-7, rms 3.8e-7
    assert np.abs(err).max() <= 1.2e-6, np.abs(err).max()
    assert np.sqrt(np.mean(err ** 2)) <= 5e-7
    assert np.all(np.diff(table) <= 0)  # rougher lobes lose more energy


def test_table_average_albedo_matches_quadrature():
    quad = np.array([Q.albedo_average(r * r) for r in R_NODES])
    for name in ("EAVG_V4", "EAVG_V53"):
        table = np.asarray(getattr(T, name), np.float32).astype(np.float64)
        err = table - quad
        assert np.abs(err).max() <= 1.2e-6, (name, np.abs(err).max())  # measured 6.5e-7
        assert np.sqrt(np.mean(err ** 2)) <= 5e-7
    gen = np.abs(np.asarray(T.EAVG_V4, np.float64) - np.asarray(T.EAVG_V53, np.float64)).max()
    assert gen <= 1.1e-6


def test_lookup_is_cycles_piecewise_linear():
    table = np.asarray(T.E_MU1, np.float32).astype(np.float64)
    assert np.array_equal(ms.albedo_normal(NODES), table)  # nodes exactly
    mid = (NODES[:-1] + NODES[1:]) / 2
    assert np.allclose(ms.albedo_normal(mid), (table[:-1] + table[1:]) / 2, rtol=0, atol=1e-15)
    assert ms.albedo_normal(1.7) == table[-1] and ms.albedo_normal(-1.0) == table[0]  # saturated
    eavg = np.asarray(T.EAVG_V53, np.float32).astype(np.float64)
    assert np.array_equal(ms.albedo_average(NODES, "5.3"), eavg)
    # the roughness index: (α_x α_y)^¼ after each α is clamped to <= 1
    assert ms.roughness_index(0.25) == pytest.approx(0.5, abs=1e-16)
    assert ms.roughness_index(2.0, 0.25) == pytest.approx(0.25 ** 0.25, abs=1e-16)


def test_energy_scale_limits():
    x = np.linspace(0, 1, 101)
    alpha = x * x
    white = ms.energy_scale(alpha, np.ones(x.shape + (3,)))
    assert np.allclose(white, (1.0 / ms.albedo_normal(x))[:, None], rtol=1e-14, atol=0)
    assert np.all(ms.energy_scale(alpha, np.zeros(x.shape + (3,))) == 1.0)
    s = ms.energy_scale(0.36, np.linspace(0, 1, 50)[:, None] * np.ones(3))
    assert np.all(np.diff(s[:, 0]) > 0)  # more Fresnel, more compensation
    assert ms.energy_scale(0.0, (1.0, 1.0, 1.0))[0] == 1.0


# ------------------------------------------------------------------------------------------------
# F_ss
# ------------------------------------------------------------------------------------------------

_X, _W = np.polynomial.legendre.leggauss(200)
_MU, _WMU = 0.5 * (_X + 1.0), 0.5 * _W


def _average(f):
    """∫_0^1 2μ F(μ) dμ."""
    return float(np.sum(_WMU * 2.0 * _MU * f(_MU)))


def _conductor_textbook(mu, eta, kappa):
    n = eta + 1j * kappa
    cos_t = np.sqrt(1.0 - (1.0 - mu * mu) / (n * n))
    rs = (mu - n * cos_t) / (mu + n * cos_t)
    rp = (n * mu - cos_t) / (n * mu + cos_t)
    return 0.5 * (abs(rs) ** 2 + abs(rp) ** 2)


@pytest.mark.parametrize("eta, kappa", [(0.2, 3.9), (1.1, 2.2), (2.5, 0.0), (0.05, 0.5), (40.0, 9.0)])
def test_conductor_fresnel_exact_and_45(eta, kappa):
    for mu in (1.0, 0.6, 1 / 7, 0.02):
        want = _conductor_textbook(mu, eta, kappa)
        assert ms._fresnel_conductor(mu, eta, kappa) == pytest.approx(want, rel=1e-12, abs=1e-15)
    # 4.5's approximation agrees at normal incidence only
    assert ms._fresnel_conductor(1.0, eta, kappa, exact=False) == pytest.approx(
        _conductor_textbook(1.0, eta, kappa), rel=1e-12)


def test_f82_average_is_the_integral_of_the_f82_model():
    f0 = np.array([0.9, 0.6, 0.04])
    tint = np.array([0.8, 1.0, 0.5])
    fss = ms.fss_f82_tint(f0, tint)
    f = 6 / 7
    b = (f0 + (1 - f0) * f ** 5) * 7 / f ** 6 * (1 - tint)
    for ch in range(3):
        model = lambda mu: f0[ch] + (1 - f0[ch]) * (1 - mu) ** 5 - b[ch] * mu * (1 - mu) ** 6  # noqa: E731
        assert model(1 / 7) == pytest.approx((f0[ch] + (1 - f0[ch]) * f ** 5) * tint[ch], rel=1e-12)
        assert fss[ch] == pytest.approx(_average(model), rel=1e-12, abs=1e-15)
    # white tint: pure Schlick (Cycles sets B = 0 exactly)
    assert np.allclose(ms.fss_f82_tint(f0, 1.0), f0 + (1 - f0) / 21, rtol=0, atol=1e-16)


def test_conductor_fss_fits_f82_through_the_node_fresnel():
    eta, kappa = np.array([0.2, 0.9, 1.1]), np.array([3.9, 2.4, 2.2])
    fss = ms.fss_conductor(eta, kappa, "5.3")
    f0 = np.array([_conductor_textbook(1.0, e, k) for e, k in zip(eta, kappa)])
    f82 = np.array([_conductor_textbook(1 / 7, e, k) for e, k in zip(eta, kappa)])
    f = 6 / 7
    b = 7 / f ** 6 * (f0 + (1 - f0) * f ** 5 - f82)
    assert np.allclose(fss, f0 + (1 - f0) / 21 - b / 126, rtol=1e-12)
    # within a few 1e-3 of the true average of the conductor Fresnel (F82 is a fit)
    true = np.array([_average(lambda mu: _conductor_textbook(mu, e, k)) for e, k in zip(eta, kappa)])
    assert np.abs(fss - true).max() < 5e-3
    # 4.5 evaluates the F(1/7) of its approximate Fresnel: a different F_ss (measured 1.9e-4)
    d45 = np.abs(ms.fss_conductor(eta, kappa, "4.5") - fss).max()
    assert 1e-5 < d45 < 1e-3
    assert np.array_equal(ms.fss_conductor(eta, kappa, "5.2"), fss)


def test_dielectric_fss():
    # Kulla-Conty's fit of the average dielectric Fresnel: a few % of the exact integral
    for eta in (1.5, 2.0, 4.0, 10.0, 40.0):
        def fd(mu):
            ct = np.sqrt(1 - (1 - mu * mu) / eta ** 2)
            rs, rp = (mu - eta * ct) / (mu + eta * ct), (eta * mu - ct) / (eta * mu + ct)
            return 0.5 * (rs * rs + rp * rp)
        assert ms._dielectric_fss_fit(eta) == pytest.approx(_average(fd), rel=0.03)
    # generalized Schlick: F_ss = mix(F0 tint, 1, s), s from the fit; s = 0 at IOR 1
    f = ms.single_scatter_albedo("DIELECTRIC", ior=1.5, specular_tint=(1.0, 0.5, 0.0))
    f0 = 0.04
    s = (0.5 / (4.08567 + 1.00071 * 1.5) - f0) / (1 - f0)
    assert np.allclose(f, [f0 + s * (1 - f0), 0.5 * f0 + s * (1 - 0.5 * f0), s], rtol=1e-12)
    assert np.allclose(ms.single_scatter_albedo("DIELECTRIC", ior=1.0, specular_tint=1.0), 0.0)


def test_single_scatter_albedo_dispatch():
    c = (0.3, 0.5, 1.2)
    assert np.array_equal(ms.single_scatter_albedo("CONSTANT", colour=c), c)  # Glossy: no clamp above
    assert np.array_equal(ms.single_scatter_albedo("F82_TINT", f0=c, tint=0.5), ms.fss_f82_tint(c, 0.5))
    # F82 given explicitly: F82-tint is the special case F82 = Schlick(F0, 1/7) · tint
    f0, tint = np.array([0.9, 0.6, 0.3]), np.array([1.0, 0.8, 0.5])
    f82 = (f0 + (1 - f0) * (6 / 7) ** 5) * tint
    assert np.allclose(ms.single_scatter_albedo("F82", f0=f0, f82=f82), ms.fss_f82_tint(f0, tint),
                       rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match="fresnel must be one of"):
        ms.single_scatter_albedo("SCHLICK", f0=c)


def test_version_follows_the_running_blender(monkeypatch):
    monkeypatch.delitem(sys.modules, "bpy", raising=False)
    assert ms.cycles_version() == ms.LATEST
    monkeypatch.setitem(sys.modules, "bpy", SimpleNamespace(app=SimpleNamespace(version=(4, 5, 15))))
    assert ms.cycles_version() == (4, 5)
    eta, kappa = (0.2, 0.9, 1.1), (3.9, 2.4, 2.2)
    assert np.array_equal(ms.fss_conductor(eta, kappa), ms.fss_conductor(eta, kappa, "4.5"))
    d = describe("CONDUCTOR", "MULTI_GGX", core_reflectivity=(0.9, 0.6, 0.4), edge_tint=(1, 0.8, 0.6),
                 roughness=0.4, haziness=0.6, haze_extent=5.0)
    assert d.mapping.multiscatter.version == (4, 5)
    monkeypatch.setitem(sys.modules, "bpy", SimpleNamespace(app=SimpleNamespace(version=(5, 2, 3))))
    d52 = describe("CONDUCTOR", "MULTI_GGX", core_reflectivity=(0.9, 0.6, 0.4), edge_tint=(1, 0.8, 0.6),
                   roughness=0.4, haziness=0.6, haze_extent=5.0)
    assert d52.mapping.multiscatter.version == (5, 2)
    assert not np.array_equal(d.fresnel["ior"], d52.fresnel["ior"])  # 4.5's F_ss differs
    assert ms.cycles_version("5.3") == (5, 3) and ms.cycles_version((6, 1, 0)) == (6, 1)
    with pytest.raises(ValueError, match="not supported"):
        ms.cycles_version((4, 2))


# ------------------------------------------------------------------------------------------------
# The corrected mapping: the peak from the socket values alone
# ------------------------------------------------------------------------------------------------


def _lobe_alpha(kind, lobe):
    """(α_x, α_y) Cycles draws a lobe with (node convention of the kind)."""
    a = 0.0 if lobe.anisotropy is None else np.asarray(lobe.anisotropy, np.float64)
    if kind == "LEGACY":  # Glossy: α_x α_y = R⁴ for any anisotropy (each <= 1 checked below)
        r2 = np.asarray(lobe.roughness, np.float64) ** 2
        s = 1.0 - np.abs(a)
        return r2 * s, r2 / s
    return alpha_from_roughness(lobe.roughness, a)


def rendered_peak(d, version="5.3"):
    """Normal-incidence peak (units of D_n(0)/4) of what describe() tells the nodes to draw."""
    kind, f = d.kind, d.fresnel
    an = _lobe_alpha(kind, d.narrow)
    if kind == "CONDUCTOR":
        eta, kappa = np.asarray(f["ior"], np.float64), np.asarray(f["extinction"], np.float64)
        f0 = ((eta - 1) ** 2 + kappa ** 2) / ((eta + 1) ** 2 + kappa ** 2)
        fss = ms.single_scatter_albedo("CONDUCTOR", ior=eta, extinction=kappa, version=version)
        fss_n = fss_w = fss
        w_n, w_w = f0, f0
    elif kind == "DIELECTRIC":
        eta = np.asarray(f["ior"], np.float64)
        tint = np.asarray(f["specular_tint"], np.float64)
        f0 = np.clip(((eta - 1) / (eta + 1))[..., None] ** 2 * tint, 0, 1)
        fss_n = fss_w = ms.single_scatter_albedo("DIELECTRIC", ior=eta, specular_tint=tint)
        w_n, w_w = f0, f0
    else:
        w_n = np.asarray(f["colour_narrow"], np.float64)
        w_w = np.asarray(f.get("colour_wide", 0.0 * w_n), np.float64)
        fss_n, fss_w = w_n, w_w
    s_n = ms.energy_scale(an, fss_n, version=version)
    if d.wide is None:
        return w_n * s_n
    aw = _lobe_alpha(kind, d.wide)
    p = (np.minimum(an[0], 1) * np.minimum(an[1], 1) / (np.minimum(aw[0], 1) * np.minimum(aw[1], 1)))[..., None]
    s_w = ms.energy_scale(aw, fss_w, version=version)
    if kind == "LEGACY":  # weights in the colours
        return w_n * s_n + w_w * p * s_w
    b = np.asarray(d.beta, np.float64)[..., None]
    return w_n * ((1 - b) * s_n + b * p * s_w)


def _drift(kind, params, haziness, distribution="MULTI_GGX", dtype=None, version="5.3"):
    d = describe(kind, distribution, haziness=haziness, strict=False, dtype=dtype, **params)
    d0 = describe(kind, distribution, haziness=0.0 * np.asarray(haziness), strict=False,
                  dtype=dtype, **params)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = rendered_peak(d, version) / rendered_peak(d0, version) - 1.0
    rc = np.broadcast_to(np.asarray(params["core_reflectivity"]), rel.shape)
    return np.where(rc > 0, rel, 0.0), d


CASES = {
    "CONDUCTOR": dict(core_reflectivity=(0.9, 0.6, 0.4), edge_tint=(1.0, 0.8, 0.6)),
    "DIELECTRIC": dict(core_reflectivity=(0.04, 0.03, 0.02)),
    "LEGACY": dict(core_reflectivity=(0.9, 0.6, 0.4)),
}


@pytest.mark.parametrize("kind", K.KINDS)
@pytest.mark.parametrize("smoothness", [None, 2.0])
def test_peak_invariant_under_multiscatter(kind, smoothness, monkeypatch):
    monkeypatch.delitem(sys.modules, "bpy", raising=False)  # the tables of 5.3
    worst, worst_ggx = 0.0, 0.0
    for rough, extent, bh in itertools.product((0.05, 0.2, 0.4, 0.6, 0.9), (0.5, 3.0, 7.0),
                                               (0.3, 0.6, 0.9, K.MAX_HAZINESS)):
        params = dict(CASES[kind], roughness=rough, haze_extent=extent, smoothness=smoothness)
        rel, d = _drift(kind, params, bh)
        assert d.mapping.multiscatter.residual <= 1e-9
        worst = max(worst, float(np.abs(rel).max()))
        # the single-scatter mapping drawn with Multiscatter lobes (what the add-on did before)
        d_ss = describe(kind, "GGX", haziness=bh, **params)
        d0 = describe(kind, "GGX", haziness=0.0, **params)
        worst_ggx = max(worst_ggx, float(np.abs(rendered_peak(d_ss) / rendered_peak(d0) - 1).max()))
    assert worst <= 1e-9, worst
    assert worst_ggx > 3e-3, worst_ggx  # evidence the test can fail


@pytest.mark.parametrize("kind", K.KINDS)
def test_peak_invariant_on_textures_float32(kind, monkeypatch):
    """Whole textures (vectorised, float32 like the converter), anisotropic, stiff values."""
    monkeypatch.delitem(sys.modules, "bpy", raising=False)
    rng = np.random.default_rng(7)
    n = 4000
    f32 = np.float32
    rc = rng.uniform(0, 1, (n, 3)).astype(f32)
    rc[:200] = rng.choice([0.0, 1e-6, 0.999, 1.0], (200, 3)).astype(f32)
    params = dict(core_reflectivity=rc, edge_tint=rng.uniform(0, 1, (n, 3)).astype(f32),
                  roughness=rng.uniform(0.004, 1.0, n).astype(f32),
                  anisotropy=np.where(rng.random(n) < 0.5, 0, rng.uniform(0, 1, n)).astype(f32),
                  rotation=rng.random(n).astype(f32),
                  haze_extent=(10 ** rng.uniform(-2, 3, n)).astype(f32))
    bh = rng.uniform(0, K.MAX_HAZINESS, n).astype(f32)
    bh[:100] = f32(K.MAX_HAZINESS)
    d = describe(kind, "MULTI_GGX", haziness=bh, strict=False, **params)
    assert d.beta.dtype == np.float32
    for v in [d.beta, d.mapping.reflectivity] + list(d.fresnel.values()):
        assert np.asarray(v).dtype == np.float32 and np.all(np.isfinite(v))
    assert d.mapping.multiscatter.residual <= 1e-8
    # the socket values rounded to float32 (η, κ, IOR near r = 0 and r = 1 are ill-conditioned
    # there: kept out)
    rel, _ = _drift(kind, params, bh, dtype=np.float32)
    r = np.asarray(d.mapping.reflectivity, np.float64)
    keep = (rc >= 1e-3) & (r < 1 - 1e-4).all(-1)[:, None]
    assert np.abs(np.where(keep, rel, 0)).max() <= 2e-6
    # a texture and a single material give the same description
    i = 4321 % n
    one = describe(kind, "MULTI_GGX", haziness=float(bh[i]), core_reflectivity=tuple(map(float, rc[i])),
                   edge_tint=tuple(map(float, params["edge_tint"][i])), roughness=float(params["roughness"][i]),
                   anisotropy=float(params["anisotropy"][i]), rotation=float(params["rotation"][i]),
                   haze_extent=float(params["haze_extent"][i]), anisotropic=True, dtype=np.float32)
    assert float(one.beta) == pytest.approx(float(d.beta[i]), abs=2e-6)


@pytest.mark.parametrize("smoothness", [None, 0.5, 2.0, 1e6])
def test_without_energy_factor_it_is_the_papers_mapping(smoothness, monkeypatch):
    """With S = 1 (E = 1 everywhere) the construction is exactly Eq. 7 / Eqs. 12-15: β_h keeps
    the paper's meaning, the largest halo is the paper's bound."""
    monkeypatch.setattr(ms, "_E_MU1", np.ones(32))
    from hazy_gloss.core import haze_mapping
    rng = np.random.default_rng(3)
    n = 3000
    rc = rng.uniform(0, 1, (n, 3))
    rc[:300] = rng.choice([0.0, 1e-6, 0.5, 0.999, 1.0], (300, 3))
    alpha = rng.uniform(1e-4, 1.0, n)
    m = haze_mapping(rc, rng.uniform(0, 1, (n, 3)), alpha, rng.uniform(0, K.MAX_HAZINESS, n),
                     10 ** rng.uniform(-3, 2, n), distribution="MULTI_GGX", alpha_max=1.0,
                     smoothness=smoothness, strict=False)
    grey = haze_mapping(rc[:, :1].repeat(3, -1), 0.0, alpha, rng.uniform(0, K.MAX_HAZINESS, n),
                        10 ** rng.uniform(-3, 2, n), distribution="MULTI_GGX", alpha_max=1.0,
                        smoothness=smoothness, strict=False)
    for lobe in ms.LOBES:
        if lobe == "COAT":  # the coat's F0 is grey
            m = grey
        c = ms.correct_mapping(m, lobe, tint=(1.0, 0.8, 0.5))
        assert np.allclose(c.beta, m.beta, rtol=0, atol=1e-9), lobe
        assert np.allclose(c.reflectivity, m.reflectivity, rtol=0, atol=1e-9), lobe
        assert np.allclose(c.halo_intensity, m.halo_intensity, rtol=0, atol=1e-9), lobe


@pytest.mark.parametrize("kind", K.KINDS)
def test_bounds_hold_everywhere(kind, monkeypatch):
    """β <= 1 and r <= 1 in every channel (no clamping needed) on stiff corners: the halo on
    the core (λ_h -> 0, where Glossy lobes, whose F_ss is their own colour, lose compensation
    when split), r_c -> 1, β_h -> 1, rough lobes, per-channel edge tints."""
    monkeypatch.delitem(sys.modules, "bpy", raising=False)
    grid = list(itertools.product(
        [(0.0,) * 3, (0.04, 0.03, 0.02), (0.9, 0.6, 0.4), (0.95, 0.95, 0.3), (0.999,) * 3, (1.0, 0.5, 0.2)],
        [(0.0,) * 3, (0.5, 0.9, 0.2), (1.0,) * 3], [0.004, 0.2, 0.6, 1.0], [0.0, 1e-3, 0.2, 5.0, 1e3],
        [1e-7, 0.5, 0.9, K.MAX_HAZINESS]))
    rc, g = np.array([c[0] for c in grid]), np.array([c[1] for c in grid])
    params = dict(core_reflectivity=rc, edge_tint=g, roughness=np.array([c[2] for c in grid]),
                  haze_extent=np.array([c[3] for c in grid]))
    rel, d = _drift(kind, params, np.array([c[4] for c in grid]))
    m = d.mapping
    assert not [reason for reason in m.clamped if "Multiscatter" in reason], m.clamped
    assert np.all((m.beta >= 0) & (m.beta <= 1)) and np.all((m.reflectivity >= 0) & (m.reflectivity <= 1))
    assert m.multiscatter.residual <= 1e-8
    keep = rc >= 1e-3
    assert np.abs(np.where(keep, rel, 0)).max() <= 1e-8
    # monotone in haziness, like the paper's mapping: more haze, more halo weight
    rel2, d2 = _drift(kind, params, np.minimum(np.array([c[4] for c in grid]) + 0.05, K.MAX_HAZINESS))
    assert np.all(d2.mapping.halo_intensity >= m.halo_intensity - 1e-12)


def test_no_halo_and_haziness_zero_are_untouched():
    for kind in K.KINDS:
        d = describe(kind, "MULTI_GGX", **CASES[kind], roughness=0.4, haziness=0.0, haze_extent=5)
        assert d.wide is None and d.mapping.multiscatter is None
        assert d.mapping.reflectivity == pytest.approx(np.asarray(CASES[kind]["core_reflectivity"]))


def test_other_distributions_never_reach_the_correction(monkeypatch):
    """GGX, Beckmann, Ashikhmin-Shirley: describe() is the single-scatter mapping, unchanged."""
    def boom(*a, **k):
        raise AssertionError("correct_mapping called")
    monkeypatch.setattr(core_lobes, "correct_mapping", boom)
    for kind, dists in K.NODE_DISTRIBUTIONS.items():
        for dist in dists:
            if dist == "MULTI_GGX":
                continue
            d = describe(kind, dist, **CASES[kind], roughness=0.3, haziness=0.5, haze_extent=5)
            assert d.mapping.multiscatter is None
    with pytest.raises(AssertionError, match="correct_mapping called"):
        describe("LEGACY", "MULTI_GGX", **CASES["LEGACY"], roughness=0.3, haziness=0.5, haze_extent=5)


def test_f82_tint_lobes_for_principled_metals(monkeypatch):
    """The lobe type a layered Principled material needs: metallic lobes with Base Color r and
    a fixed Specular Tint; the fixed point keeps their peak too."""
    monkeypatch.delitem(sys.modules, "bpy", raising=False)
    from hazy_gloss.core import haze_mapping
    rc, tint = np.array([0.9, 0.6, 0.3]), np.array([1.0, 0.8, 0.5])
    for rough, bh in itertools.product((0.2, 0.5), (0.3, 0.9)):
        a = rough ** 2
        m = haze_mapping(rc, 0.0, a, bh, 5.0, distribution="MULTI_GGX", alpha_max=1.0, max_aspect=10.0)
        c = ms.correct_mapping(m, "F82_TINT", tint=tint)
        hazy = ms.peak_factor("F82_TINT", c.alpha, c.alpha_wide, c.reflectivity, c.beta, tint=tint)
        ref = ms.peak_factor("F82_TINT", a, a, rc, 0.0, tint=tint, halo=False)
        assert np.abs(hazy / ref - 1).max() <= 1e-12
        old = ms.peak_factor("F82_TINT", m.alpha, m.alpha_wide, m.reflectivity, m.beta, tint=tint)
        assert np.abs(old / ref - 1).max() > 1e-5


# ------------------------------------------------------------------------------------------------
# The Principled coat: exact dielectric Fresnel, always Multiscatter GGX's factor
# ------------------------------------------------------------------------------------------------


def _coat_peak(ior, alpha, version="5.3"):
    """A coat's normal-incidence peak (units of 1/(4 π α²)... per unit D(0)/4) from its socket
    values alone: F0 = ((η-1)/(η+1))², F_ss = Kulla-Conty's fit as typed from
    kernel/closure/bsdf_util.h (fresnel_dielectric_Fss, η >= 1 branch), S from the tables."""
    eta = np.maximum(np.asarray(ior, np.float64), 1.0)
    f0 = ((eta - 1) / (eta + 1)) ** 2
    fss = (eta - 1.0) / (4.08567 + 1.00071 * eta)
    return f0 * ms.energy_scale(alpha, np.stack([fss] * 3, -1), version=version)[..., 0]


def test_coat_fss_is_the_kernels_fit():
    eta = np.array([1.0, 1.5, 2.0, 18.78, 1e4])
    want = (eta - 1.0) / (4.08567 + 1.00071 * eta)
    assert np.allclose(ms.single_scatter_albedo("DIELECTRIC_EXACT", ior=eta), want, rtol=1e-15, atol=0)
    assert ms.fss_dielectric_exact(0.5) == 0.0  # Cycles clamps the Coat IOR to >= 1
    # unlike the Principled specular (generalized Schlick, s saturated), not kept >= F0
    assert ms.fss_dielectric_exact(1e5) < ((1e5 - 1) / (1e5 + 1)) ** 2


@pytest.mark.parametrize("version", ["4.5", "5.2", "5.3"])
def test_coat_keeps_the_peak(version):
    """The measured case (Coat Roughness 0.1, Coat IOR 1.5, haziness 0.8, extent 6): the single
    scatter mapping (Coat IOR' 18.78, β 0.970, wide R 0.2646) renders the peak 1.8e-3 high;
    correct_mapping(m, "COAT") keeps it, evaluated from the Coat IOR and β alone."""
    f0 = ((1.5 - 1) / 2.5) ** 2
    worst = 0.0
    for rough, bh, ext in itertools.product((0.1, 0.3, 0.7), (0.3, 0.8, 0.9, K.MAX_HAZINESS), (0.5, 6.0, 50.0)):
        d = describe("DIELECTRIC", "GGX", core_reflectivity=(f0,) * 3, roughness=rough, haziness=bh,
                     haze_extent=ext)
        m = d.mapping
        c = ms.correct_mapping(m, "COAT", version=version)
        a_n, a_w = float(c.alpha[0]), float(c.alpha_wide[0])
        ref = _coat_peak(1.5, a_n, version)
        p = (a_n / min(a_w, 1.0)) ** 2
        beta = float(c.beta)
        hazy = (1 - beta) * _coat_peak(c.dielectric_ior, a_n, version) + \
            beta * p * _coat_peak(c.dielectric_ior, a_w, version)
        worst = max(worst, abs(hazy / ref - 1))
        assert 0 <= beta <= 1 and np.ptp(c.reflectivity) == 0  # one Coat IOR
        if (rough, bh, ext) == (0.1, 0.8, 6.0):
            assert float(m.dielectric_ior) == pytest.approx(18.78, abs=5e-3)
            assert float(m.beta) == pytest.approx(0.970, abs=5e-4)
            assert float(d.wide.roughness) == pytest.approx(0.2646, abs=1e-4)
            p_ss = (float(m.alpha[0]) / float(m.alpha_wide[0])) ** 2
            old = (1 - float(m.beta)) * _coat_peak(m.dielectric_ior, a_n, version) + \
                float(m.beta) * p_ss * _coat_peak(m.dielectric_ior, float(m.alpha_wide[0]), version)
            assert old / ref - 1 == pytest.approx(1.8e-3, abs=5e-5)  # the measured symptom
    assert worst <= 1e-12, worst


def test_coat_needs_a_grey_core():
    d = describe("DIELECTRIC", "GGX", core_reflectivity=(0.04, 0.03, 0.04), roughness=0.1,
                 haziness=0.5, haze_extent=5.0)
    with pytest.raises(ValueError, match="grey"):
        ms.correct_mapping(d.mapping, "COAT")
