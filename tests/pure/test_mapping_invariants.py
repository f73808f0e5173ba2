# SPDX-License-Identifier: GPL-3.0-or-later
"""Properties the haze mapping must satisfy for EVERY valid input (paper §2.3-2.4):

* ranges: β ∈ [0, 1], 0 <= r <= 1, κ >= 0, η > 0, α_w >= α_n, all outputs finite;
* Eq. 6: positivity (1-β) r >= 0, i.e. k̂_h <= r̂_c/p, and energy k̂_h <= (1-r̂_c)/(1-p), both
  to a few ulp; in fact k̂_h <= β_h min(r̂_c/p, (1-r̂_c)/(1-p)) (the Bézier stays in its
  control triangle);
* κ == 0 exactly where g == 0 (dielectric), κ > 0 where g > 0 and r > 0;
* peak invariance (Eq. 3 with P = p): (1-β) r + β r p == r_c per channel;
* the halo keeps the core's chroma: r / r̂ == r_c / r̂_c;
* continuity of k_h in r_c around the branch points (r_c = p, b = 1): no step larger than the
  Lipschitz bound β_h max(1/p, 1/(1-p)) of the control triangle (times the r_c step plus the
  rounding of p itself, 2 ulp: Eq. 7's branch is chosen at the rounded p);
* monotonicity of k_h, β, r̂ in β_h;
* w -> ∞ converges to Eq. 7 with |k_h(w) - k_h(∞)| <= β_h / (2 w sqrt(p(1-p))).
"""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hg_support as S
import reference as R
from hazy_gloss.core import haze_mapping

_FIELDS = ("beta", "reflectivity", "ior", "extinction", "peak_ratio", "peak_complement",
           "halo_intensity", "reflectivity_max", "weight_narrow", "weight_wide", "dielectric_ior")


def _check_invariants(kw, out, eps):
    tol = 8 * eps
    # absolute slack for subnormal results (e.g. β_h = 1.4e-45 in float32): 8 smallest subnormals
    sub = 8 * (2.0 ** -149 if eps == S.EPS32 else 5e-324)
    for f in _FIELDS:
        assert np.all(np.isfinite(getattr(out, f))), f
    for a in out.alpha_wide:
        assert np.all(np.isfinite(a))
    beta = float(out.beta)
    r = np.asarray(out.reflectivity, dtype=float)
    rc = np.asarray(out.core_reflectivity, dtype=float)
    g = np.asarray(out.edge_tint, dtype=float)
    eta = np.asarray(out.ior, dtype=float)
    kap = np.asarray(out.extinction, dtype=float)
    p, q = float(out.peak_ratio), float(out.peak_complement)
    kh = float(out.halo_intensity)
    rc_hat, r_hat = rc.max(), float(out.reflectivity_max)
    bh = float(out.haziness)

    assert 0.0 <= beta <= 1.0
    assert np.all(r >= 0) and np.all(r <= 1)
    assert np.all(kap >= 0)
    assert np.all(eta > 0)
    assert 0 <= p <= 1 and 0 <= q <= 1 and abs(p + q - 1) <= 4 * eps
    # α_w >= α_n, with α_n as the renderer gets it (alpha_max / Ashikhmin-Shirley clamps)
    lo, hi = 0.0, math.inf
    if kw["distribution"] == "ASHIKHMIN_SHIRLEY":
        lo, hi = 1e-4, 1.0
    if kw.get("alpha_max") is not None:
        hi = min(hi, kw["alpha_max"])
    ax, ay = (kw["alpha"] if isinstance(kw["alpha"], tuple) else (kw["alpha"], kw["alpha"]))
    for a_n, a_w in zip((ax, ay), out.alpha_wide):
        a_n = min(max(float(a_n), lo), hi)
        assert float(a_w) >= a_n * (1 - tol), (a_w, a_n)

    # Eq. 6: positivity and energy, and the interpolation bound (β_h times the bound)
    assert kh >= 0
    assert kh * p <= rc_hat * (1 + tol) + sub, ("positivity", kh, rc_hat, p)
    assert kh * q <= (1 - rc_hat) * (1 + tol) + tol * q + sub, ("energy", kh, rc_hat, q)
    bound = min(rc_hat / p if p > 0 else math.inf, (1 - rc_hat) / q if q > 0 else math.inf)
    assert kh <= bh * bound * (1 + tol) + sub, ("k_h <= β_h bound", kh, bh, bound)
    kn = np.asarray(out.weight_narrow, dtype=float)
    kw_ = np.asarray(out.weight_wide, dtype=float)
    assert np.all(kn >= 0) and np.all(kw_ >= 0)
    assert np.all(kn + kw_ <= 1 + tol)  # legacy energy: k_n + k_w = r <= 1

    # κ == 0 exactly where g == 0 (and only there, away from underflow)
    assert np.all(kap[g == 0] == 0.0)
    sig = (g >= 1e-100) & (r >= 1e-100)
    assert np.all(kap[sig] > 0)

    # peak invariance, Eq. 3 at θ_d = 0 with P = p: (1-β) r + β r p == r_c, per channel
    lhs = (1 - beta) * r + beta * r * p
    scale = max(r_hat, 1e-300)
    assert np.all(np.abs(lhs - rc) <= (1e-12 if eps == S.EPS64 else 1e-6) * scale), (lhs, rc)
    # same chroma for halo and core: r r̂_c == r_c r̂
    assert np.all(np.abs(r * rc_hat - rc * r_hat) <= 4 * eps * r_hat * max(rc_hat, 1e-300))
    # dielectric: κ = 0 and η = (1+√r)/(1-√r)
    if np.all(g == 0) and r_hat < 1 - 1e-6:
        r64 = np.asarray(out.reflectivity, dtype=np.float64)  # exact widening of the code's r
        s = np.sqrt(r64)
        # η may come from r before its final rounding (numpy 1.x promotes float32 0-d calls
        # to float64 internally), so allow the conditioning 1/(1-r) of η(r) on top of 16 ulp
        cond = np.maximum(1.0, r64 / (1.0 - r64))
        assert np.all(np.abs(eta - (1 + s) ** 2 / (1 - r64)) <= 16 * eps * cond * eta)


@settings(max_examples=S.examples(300), deadline=None)
@given(S.mapping_inputs(64))
def test_invariants_float64(kw):
    out = haze_mapping(**S.lenient(kw))
    assert out.beta.dtype == np.float64
    _check_invariants(kw, out, S.EPS64)


@settings(max_examples=S.examples(200), deadline=None)
@given(S.mapping_inputs(32))
def test_invariants_float32(kw):
    kw32 = S.to_float32(kw)
    out = haze_mapping(**S.lenient(kw32))
    assert out.beta.dtype == np.float32
    _check_invariants(dict(kw32, alpha_max=kw.get("alpha_max")), out, S.EPS32)


@settings(max_examples=S.examples(80), deadline=None)
@given(S.mapping_inputs(64), st.integers(2, 40))
def test_invariants_texture(kw, n):
    """The same invariants hold texel by texel in a texture call (random arrays)."""
    rng = np.random.default_rng(n)
    rc = rng.uniform(0, 1, (n, 3)) ** rng.uniform(0.2, 5)
    bh = rng.uniform(0, 1, n)
    out = haze_mapping(rc, kw["edge_tint"], kw["alpha"], bh, kw["haze_extent"],
                       distribution=kw["distribution"], smoothness=kw["smoothness"],
                       alpha_max=kw["alpha_max"])
    for i in range(n):
        one = type("T", (), {f: np.asarray(getattr(out, f))[i] for f in _FIELDS + (
            "core_reflectivity", "edge_tint", "haziness")})
        one.alpha_wide = tuple(np.broadcast_to(a, (n,))[i] for a in out.alpha_wide)
        _check_invariants(dict(kw, core_reflectivity=rc[i], haziness=bh[i]), one, S.EPS64)


# ------------------------------------------------------------------------------------------------
# Continuity of k_h in r_c around the branch points
# ------------------------------------------------------------------------------------------------


def _branch_points(p, w):
    pts = [p]
    if w is not None and w != 1:
        rstar = (0.5 - w * p) / (1 - w)
        if 0 <= rstar <= 1:
            pts.append(rstar)
    return pts


def _windows(x0, n=40):
    """Dense r_c samples around x0 at scales 1e-2 ... 1e-12 and at consecutive doubles."""
    xs = [x0 + k * h for h in (1e-2, 1e-4, 1e-6, 1e-9, 1e-12) for k in range(-n, n + 1)]
    x = x0
    for _ in range(n):
        x = math.nextafter(x, -math.inf)
    for _ in range(2 * n + 1):
        xs.append(x)
        x = math.nextafter(x, math.inf)
    xs = np.unique(np.clip(np.asarray(xs), 0.0, 1.0))
    return xs


_CONT_CASES = [(lam, w, bh, alpha, dist)
               for dist in ("GGX", "ASHIKHMIN_SHIRLEY")
               for lam in (0.01, 0.41421356, 1.0, 7.0, 300.0, (1.0, 0.0), (0.3, 20.0))
               for w in (0.01, 0.5, 1.0, 2.0, 8.0, 1e4, None)
               for bh, alpha in ((0.3, 0.05), (0.999, 0.2))]


@pytest.mark.parametrize("lam,w,bh,alpha,dist", _CONT_CASES)
def test_continuity_in_core_reflectivity(lam, w, bh, alpha, dist):
    probe = haze_mapping(0.5, 0.0, alpha, bh, lam, distribution=dist)
    p, q = float(probe.peak_ratio), float(probe.peak_complement)
    lip = bh * max(1 / p, 1 / q)
    for x0 in _branch_points(p, w):
        rc = _windows(x0)
        out = haze_mapping(rc[:, None], 0.0, alpha, bh, lam, distribution=dist, smoothness=w)
        kh = np.asarray(out.halo_intensity, dtype=float)
        step = np.abs(np.diff(kh))
        allowed = (lip * (np.diff(rc) * (1 + 1e-9) + 2 * S.EPS64 * p)
                   + 8 * S.EPS64 * np.maximum(kh[1:], kh[:-1]) + 1e-300)
        bad = np.nonzero(step > allowed)[0]
        assert bad.size == 0, (f"jump at r_c={rc[bad[0]]!r}->{rc[bad[0] + 1]!r}: "
                               f"k_h {kh[bad[0]]!r}->{kh[bad[0] + 1]!r}, allowed {allowed[bad[0]]:.3g}")
        # unimodal: k_h rises then falls (ulp-level wiggles aside)
        d = np.diff(kh)
        tiny = 8 * S.EPS64 * np.maximum(kh[1:], kh[:-1]) + 1e-300
        signs = np.sign(np.where(np.abs(d) <= tiny, 0, d))
        signs = signs[signs != 0]
        assert np.count_nonzero(np.diff(signs) != 0) <= 1


@settings(max_examples=S.examples(60), deadline=None)
@given(st.floats(1e-3, 1e3), st.floats(1e-3, 1e5), st.floats(0.01, 0.999),
       st.sampled_from(S.DISTS))
def test_continuity_random_parameters(lam, w, bh, dist):
    probe = haze_mapping(0.5, 0.0, 0.05, bh, lam, distribution=dist)
    p, q = float(probe.peak_ratio), float(probe.peak_complement)
    lip = bh * max(1 / p, 1 / q)
    for x0 in _branch_points(p, w):
        rc = _windows(x0, n=15)
        kh = np.asarray(haze_mapping(rc[:, None], 0.0, 0.05, bh, lam, distribution=dist,
                                     smoothness=w).halo_intensity, dtype=float)
        allowed = (lip * (np.diff(rc) * (1 + 1e-9) + 2 * S.EPS64 * p)
                   + 8 * S.EPS64 * np.maximum(kh[1:], kh[:-1]) + 1e-300)
        assert np.all(np.abs(np.diff(kh)) <= allowed)


# ------------------------------------------------------------------------------------------------
# Monotonicity in β_h; w -> ∞
# ------------------------------------------------------------------------------------------------


@settings(max_examples=S.examples(100), deadline=None)
@given(S.mapping_inputs(64))
def test_monotone_in_haziness(kw):
    bh = np.unique(np.concatenate([np.linspace(0, 1, 64, endpoint=False),
                                   1 - np.logspace(-1, -15, 30), [float(kw["haziness"])]]))
    out = haze_mapping(kw["core_reflectivity"], kw["edge_tint"], kw["alpha"], bh,
                       kw["haze_extent"], distribution=kw["distribution"],
                       smoothness=kw["smoothness"], alpha_max=kw["alpha_max"])
    for f in ("halo_intensity", "beta", "reflectivity_max"):
        v = np.asarray(getattr(out, f), dtype=float)
        assert np.all(np.diff(v) >= -4 * S.EPS64 * v[1:]), f


@pytest.mark.parametrize("dist", S.DISTS)
@pytest.mark.parametrize("lam", [1e-3, 0.5, 7.0, 1e4])
def test_bezier_tends_to_eq7(dist, lam):
    rc = np.concatenate([np.linspace(0, 1, 201), [1e-12, 1 - 1e-12]])[:, None]
    bh = 0.8
    eq7 = haze_mapping(rc, 0.0, 0.03, bh, lam, distribution=dist)
    kh7 = np.asarray(eq7.halo_intensity, dtype=float)
    p, q = float(eq7.peak_ratio.flat[0]), float(eq7.peak_complement.flat[0])
    prev = None
    for k in range(0, 17):
        w = 10.0 ** k
        kh = np.asarray(haze_mapping(rc, 0.0, 0.03, bh, lam, distribution=dist,
                                     smoothness=w).halo_intensity, dtype=float)
        dev = np.abs(kh - kh7)
        bound = bh / (2 * w * math.sqrt(p * q)) + 8 * S.EPS64
        assert np.all(dev <= bound), (w, dev.max(), bound)
        if prev is not None:
            assert dev.max() <= prev + 8 * S.EPS64  # converges monotonically in w
        prev = dev.max()
    inf = haze_mapping(rc, 0.0, 0.03, bh, lam, distribution=dist, smoothness=math.inf)
    np.testing.assert_array_equal(inf.halo_intensity, eq7.halo_intensity)
    np.testing.assert_array_equal(inf.beta, eq7.beta)


def test_bezier_below_eq7_and_reference_limits():
    """The Bézier k_h never exceeds Eq. 7 (it stays inside the control triangle) — checked on
    the reference too, so the property is the paper's and not an artefact of the code."""
    for w in (0.1, 1.0, 3.0, 50.0):
        for lam in (0.2, 3.0):
            rc = np.linspace(0, 1, 101)[:, None]
            a = np.asarray(haze_mapping(rc, 0.0, 0.05, 0.6, lam, smoothness=w).halo_intensity)
            b = np.asarray(haze_mapping(rc, 0.0, 0.05, 0.6, lam).halo_intensity)
            assert np.all(a <= b * (1 + 8 * S.EPS64))
            for x in rc[::10, 0]:
                ra = R.haze_mapping(x, 0.0, 0.05, 0.6, lam, smoothness=w)["halo_intensity"]
                rb = R.haze_mapping(x, 0.0, 0.05, 0.6, lam)["halo_intensity"]
                assert ra <= rb
