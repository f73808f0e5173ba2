# SPDX-License-Identifier: GPL-3.0-or-later
"""haze_mapping against the independent mpmath transcription of the paper (reference.py).

float64: every output within 1e-12 RELATIVE of the reference (exact zeros absolutely), over
random inputs across the domain and the explicit stiff cases of hg_support.stiff_cases().
η and κ are checked (a) as a stage, reference Gulbrandsen at the code's own r, to 1e-12, and
(b) end to end, relative error divided by the condition number 1/(1-r) of η(r), κ(r) (the
float64 rounding of r alone is amplified by it; see hg_support.gulbrandsen_condition).
float32: k_h, β, r (and p) within 1e-5 absolute of the reference of the float32 inputs.

The worst errors seen are printed at the end of the pytest run (conftest.py) and by
measure_errors.py.
"""
import math
from collections import defaultdict

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hg_support as S
import reference as R
from hazy_gloss.core import gulbrandsen_ior, haze_mapping

# ------------------------------------------------------------------------------------------------
# The reference checks itself (independent derivations of the printed formulas)
# ------------------------------------------------------------------------------------------------

_BEZIER_POINTS = [(rc, p, w)
                  for w in (1e-8, 0.25, 1.0, 2.0, 8.0, 1e6, 1e15)
                  for p in (1e-6, 0.1, 0.5, 0.7, 1 - 1e-9)
                  for rc in (0.0, 1e-12, 0.05, 0.5, 0.7, 0.99, 1 - 1e-12, 1.0)]


def _curve(u, p, bh, w):
    """Quadratic rational Bézier C(u) with control points (0,0), (p,β_h), (1,0), weights 1,w,1
    (Appendix, first display), evaluated directly."""
    den = (1 - u) ** 2 + 2 * (1 - u) * u * w + u ** 2
    return ((2 * (1 - u) * u * w * p + u ** 2) / den, 2 * (1 - u) * u * w * bh / den)


def test_reference_bezier_root_is_the_curve_inverse():
    """u of Eqs. 12-14 (printed, minus root) lies in [0, 1], equals the conjugate form
    2 r_c/(b + sqrt Δ), and C_x(u) = r_c; Eq. 15 is C_y(u); the point lies in the control
    triangle (k_h <= β_h min(r_c/p, (1-r_c)/(1-p)), the Eq. 7 bound)."""
    with mpmath.workdps(200):
        for rc, p, w in _BEZIER_POINTS:
            rc_, p_, w_, bh = R.mpf(rc), R.mpf(p), R.mpf(w), mpmath.mpf("0.7")
            u = R.bezier_u(rc_, p_, w_)
            u2 = R.bezier_u(rc_, p_, w_, form="conjugate")
            assert 0 <= u <= 1
            assert abs(u - u2) <= mpmath.mpf(10) ** -150, (rc, p, w, u, u2)
            x, y = _curve(u, p_, bh, w_)
            assert abs(x - rc_) <= mpmath.mpf(10) ** -150, (rc, p, w)
            kh = R.haze_intensity_bezier(rc_, p_, bh, w_)
            assert abs(kh - y) <= mpmath.mpf(10) ** -150
            bound = R.haze_intensity_eq7(rc_, p_, bh)
            assert kh <= bound * (1 + mpmath.mpf(10) ** -150)


def test_reference_bezier_tends_to_eq7():
    """Eq. 7 is the w -> ∞ limit of Eq. 15, with |k_h(w) - k_h7| <= β_h / (2 w sqrt(p(1-p)))."""
    with mpmath.workdps(120):
        for rc, p, _ in _BEZIER_POINTS:
            for w in (1e3, 1e10, 1e40):
                rc_, p_, bh = R.mpf(rc), R.mpf(p), mpmath.mpf("0.7")
                d = abs(R.haze_intensity_bezier(rc_, p_, bh, R.mpf(w))
                        - R.haze_intensity_eq7(rc_, p_, bh))
                assert d <= bh / (2 * w * mpmath.sqrt(p_ * (1 - p_))) * (1 + 1e-30) + 1e-100


def test_reference_gulbrandsen_reproduces_reflectivity():
    """Independent check of the Gulbrandsen transcription: the normal-incidence Fresnel
    reflectance of η + iκ, ((η-1)² + κ²)/((η+1)² + κ²), is r; and κ = 0 iff g = 0."""
    for r, g in S.gulbrandsen_stiff_points():
        if r >= 1:
            continue
        with mpmath.workdps(400):
            eta, kap = R.gulbrandsen(R.mpf(r), R.mpf(g))
            f0 = R.gulbrandsen_reflectivity(eta, kap)
            assert abs(f0 - R.mpf(r)) <= mpmath.mpf(10) ** -300 * max(1, 1 / (1 - R.mpf(r))), (r, g)
            assert (kap == 0) == (g == 0 or r == 0)


def test_reference_is_precision_independent():
    """The reference returned at the default precision equals one computed at 4x the digits."""
    cases = S.stiff_cases()[::23]
    for label, kw in cases:
        a = S.reference_for(kw)
        b = S.reference_for(kw, dps=4 * R.DPS)
        for key in a:
            va = a[key] if isinstance(a[key], (list, tuple)) else [a[key]]
            vb = b[key] if isinstance(b[key], (list, tuple)) else [b[key]]
            for x, y in zip(va, vb):
                assert abs(x - y) <= abs(y) * mpmath.mpf(10) ** -40 or x == y, (label, key, x, y)


# ------------------------------------------------------------------------------------------------
# float64: explicit stiff cases
# ------------------------------------------------------------------------------------------------

_STIFF = S.stiff_cases()
_GROUPS = defaultdict(list)
for _label, _kw in _STIFF:
    _GROUPS[_label.split()[0].split("=")[0]].append((_label, _kw))


@pytest.mark.parametrize("group", sorted(_GROUPS))
def test_stiff_cases_float64(group):
    failures = []
    for label, kw in _GROUPS[group]:
        out = haze_mapping(**S.lenient(kw))
        assert out.beta.dtype == np.float64
        ref = S.reference_for(kw)
        try:
            S.check64(out, ref, f"{label} | {S.describe(kw)}", label="float64 stiff")
        except AssertionError as exc:
            failures.append(str(exc))
    assert not failures, f"{len(failures)} of {len(_GROUPS[group])} cases:\n" + "\n".join(failures[:20])


def test_stiff_case_count():
    """The stiff set covers what the brief lists (guard against silently dropping cases)."""
    labels = " ".join(label for label, _ in _STIFF)
    for needle in ("b~1", "b==1", "w=1 ", "w=1e-08", "w=1e+08", "w=1e+15", "w=inf", "rc=0 ",
                   "rc=1e-12", "rc=1 ", "rc=p", "lam=1e-10", "lam=1000000.0", "lam=1000000000000.0",
                   "alpha=1e-12", "bh=1-1e-12"):
        assert needle in labels + " ", needle
    assert len(_STIFF) > 1500


# ------------------------------------------------------------------------------------------------
# float64: random inputs over the domain (hypothesis) and as one texture call
# ------------------------------------------------------------------------------------------------


@settings(max_examples=S.examples(250), deadline=None)
@given(S.mapping_inputs(64))
def test_random_float64(kw):
    out = haze_mapping(**S.lenient(kw))
    ref = S.reference_for(kw)
    S.check64(out, ref, S.describe(kw), label="float64 random")


def _random_texels(rng, n, dist="GGX", aniso=True):
    rc = rng.uniform(0, 1, (n, 3)) * rng.uniform(0, 1, (n, 1))
    rc[rng.uniform(size=n) < 0.05] = 0.0
    rc[rng.uniform(size=n) < 0.05, 0] = 1.0
    g = rng.uniform(0, 1, (n, 3))
    g[rng.uniform(size=n) < 0.3] = 0.0
    ax = 10 ** rng.uniform(-6, 0.3, n)
    ay = 10 ** rng.uniform(-6, 0.3, n) if aniso else ax
    bh = rng.uniform(0, 1, n)
    lx = 10 ** rng.uniform(-6, 6, n)
    ly = 10 ** rng.uniform(-6, 6, n) if aniso else lx
    return rc, g, ax, ay, bh, lx, ly


@pytest.mark.parametrize("dist,w,alpha_max", [("GGX", None, None), ("BECKMANN", 3.0, None),
                                              ("ASHIKHMIN_SHIRLEY", None, None),
                                              ("MULTI_GGX", 0.5, 1.0), ("GGX", math.inf, 1.0)])
def test_texture_call_float64(dist, w, alpha_max):
    """One vectorised (texture) call: every texel within tolerance of the reference, and equal
    to the scalar call of the same texel."""
    rng = np.random.default_rng(20180507)
    n = 120
    rc, g, ax, ay, bh, lx, ly = _random_texels(rng, n)
    out = haze_mapping(rc, g, (ax, ay), bh, (lx, ly), distribution=dist, smoothness=w,
                       alpha_max=alpha_max)
    # r_c = 1 texels: r = 1, η and κ evaluated at 1 - eps (documented), counted as such
    n_one = int(np.count_nonzero((rc == 1).any(-1)))
    assert set(out.clamped) <= S.RENDERER_REASONS, out.clamped
    assert out.clamped.get("reflectivity at 1 (η, κ use 1 - ε)", 0) == n_one
    failures = []
    for i in range(n):
        kw = dict(core_reflectivity=rc[i], edge_tint=g[i], alpha=(ax[i], ay[i]), haziness=bh[i],
                  haze_extent=(lx[i], ly[i]), distribution=dist, smoothness=w,
                  alpha_max=alpha_max)
        one = haze_mapping(**S.lenient(kw))
        for f in ("beta", "halo_intensity", "peak_ratio", "reflectivity", "ior", "extinction"):
            np.testing.assert_array_equal(np.asarray(getattr(out, f))[i], getattr(one, f), f)
        try:
            S.check64(one, S.reference_for(kw), S.describe(kw), label="float64 texture")
        except AssertionError as exc:
            failures.append(str(exc))
    assert not failures, "\n".join(failures[:10])


# ------------------------------------------------------------------------------------------------
# w = ∞ is Eq. 7 exactly
# ------------------------------------------------------------------------------------------------


@settings(max_examples=S.examples(100), deadline=None)
@given(S.mapping_inputs(64, smooth=False))
def test_w_inf_is_eq7(kw):
    a = haze_mapping(**S.lenient(kw))
    b = haze_mapping(**S.lenient(dict(kw, smoothness=math.inf)))
    for f in ("beta", "halo_intensity", "reflectivity", "ior", "extinction"):
        np.testing.assert_array_equal(getattr(a, f), getattr(b, f), f)


def test_per_texel_smoothness_mixing_inf():
    """A per-texel w array mixing ∞ (Eq. 7) and finite weights equals the per-texel calls."""
    rng = np.random.default_rng(7)
    rc, g, ax, ay, bh, lx, ly = _random_texels(rng, 40)
    w = np.where(rng.uniform(size=40) < 0.5, np.inf, 10 ** rng.uniform(-3, 6, 40))
    out = haze_mapping(rc, g, (ax, ay), bh, (lx, ly), smoothness=w)
    for i in range(40):
        one = haze_mapping(rc[i], g[i], (ax[i], ay[i]), bh[i], (lx[i], ly[i]),
                           smoothness=None if np.isinf(w[i]) else w[i])
        for f in ("beta", "halo_intensity", "reflectivity"):
            np.testing.assert_allclose(np.asarray(getattr(out, f))[i], getattr(one, f),
                                       rtol=1e-15, atol=0, err_msg=f)


# ------------------------------------------------------------------------------------------------
# Gulbrandsen stage: r -> 1 without cancellation in κ, g -> 0
# ------------------------------------------------------------------------------------------------


# r = 1 is outside gulbrandsen_ior's domain (the mapping uses 1 - eps): not a case
@pytest.mark.parametrize("r,g", [(r, g) for r, g in S.gulbrandsen_stiff_points() if r < 1])
def test_gulbrandsen_stage(r, g):
    eta, kap = gulbrandsen_ior(np.float64(r), np.float64(g))
    e_ref, k_ref = R.gulbrandsen_at(r, g)
    e_eta = S.rel_err(eta, e_ref)
    e_kap = S.rel_err(kap, k_ref) if abs(float(k_ref)) > 1e-290 else S.abs_err(kap, k_ref)
    S.WORST.add("float64 gulbrandsen stage", "ior", e_eta, f"r={r!r} g={g!r}")
    S.WORST.add("float64 gulbrandsen stage", "extinction", e_kap, f"r={r!r} g={g!r}")
    assert e_eta <= S.REL64, (eta, e_ref)
    assert e_kap <= S.REL64, (kap, k_ref)
    if g == 0:
        assert kap == 0.0


# ------------------------------------------------------------------------------------------------
# float32
# ------------------------------------------------------------------------------------------------


def _check32_call(kw, label):
    out = haze_mapping(**S.lenient(kw))
    for f in ("beta", "reflectivity", "ior", "extinction", "halo_intensity", "peak_ratio",
              "reflectivity_max", "weight_narrow", "weight_wide", "dielectric_ior"):
        assert np.asarray(getattr(out, f)).dtype == np.float32, f
    assert all(np.asarray(a).dtype == np.float32 for a in out.alpha_wide)
    ref = S.reference_for(kw, eps=S.EPS32)
    return out, ref


@settings(max_examples=S.examples(200), deadline=None)
@given(S.mapping_inputs(32))
def test_random_float32(kw):
    kw = S.to_float32(kw)
    out, ref = _check32_call(kw, "float32 random")
    S.check32(out, ref, S.describe(kw), label="float32 random")


def test_stiff_cases_float32():
    """The float64 stiff set, with the inputs rounded to float32 (reference of those float32
    inputs)."""
    failures = []
    for label, kw in _STIFF[::2]:
        kw = S.to_float32(kw)
        out, ref = _check32_call(kw, label)
        try:
            S.check32(out, ref, f"{label} | {S.describe(kw)}", label="float32 stiff")
        except AssertionError as exc:
            failures.append(str(exc))
    assert not failures, "\n".join(failures[:20])


@pytest.mark.parametrize("w", [None, 0.5, 2.0, 64.0])
def test_float32_texture_call(w):
    rng = np.random.default_rng(32)
    n = 60
    rc, g, ax, ay, bh, lx, ly = (np.asarray(a, dtype=np.float32) for a in _random_texels(rng, n))
    out = haze_mapping(rc, g, (ax, ay), bh, (lx, ly), smoothness=None if w is None else np.float32(w))
    assert out.beta.dtype == np.float32 and out.reflectivity.dtype == np.float32
    for i in range(n):
        ref = R.haze_mapping(rc[i], g[i], (ax[i], ay[i]), bh[i], (lx[i], ly[i]), smoothness=w,
                             eps=S.EPS32)
        sub = type("T", (), {f: np.asarray(getattr(out, f))[i]
                             for f in ("halo_intensity", "beta", "peak_ratio", "reflectivity")})
        S.check32(sub, ref, f"texel {i} w={w}", label="float32 texture")


# ------------------------------------------------------------------------------------------------
# Eq. 7 branch selection as p -> 1 (regression tests)
# ------------------------------------------------------------------------------------------------
#
# Before 274b5d0, mapping.haze_intensity selected the Eq. 7 branch with ``rc <= p`` on the
# ROUNDED p while the energy branch used the accurate complement q = 1 - p: for λ_h -> 0 and r̂_c
# within ulps of p the wrong branch was taken (k_h off by ~ulp/(1-p): 4.8e-3 relative at
# λ_h = 1e-14 in float64, 4e-3 absolute at λ_h = 1e-5 in float32), and at r̂_c = 1 with p
# rounded to 1 it returned k_h = β_h although Eq. 6 (energy) forces k_h = 0; k_h could exceed
# the positivity bound r̂_c/p.  These tests pin the fix over every float within 8 ulp of p.


def near_p_values(lam, dtype=np.float64, alpha=0.01):
    """The floats within 8 ulp of p(λ_h) (isotropic GGX), and 1."""
    t = dtype
    p = R.haze_mapping(0.5, 0.0, t(alpha), 0.5, t(lam))["peak_ratio"]
    start = t(float(p))
    vals = {t(1.0)}
    for k in range(-8, 9):
        rc = start
        for _ in range(abs(k)):
            rc = np.nextafter(rc, t(1) if k > 0 else t(0))
        if 0 <= rc <= 1:
            vals.add(rc)
    return sorted(vals)


@pytest.mark.parametrize("w", [None, math.inf, 2.0])
@pytest.mark.parametrize("dtype,lam", [(np.float64, lam) for lam in
                                       (1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 1e-14, 1e-17)]
                         + [(np.float32, lam) for lam in (1e-1, 1e-3, 1e-5, 1e-7, 1e-10)])
def test_eq7_branch_selection_near_p_one(dtype, lam, w):
    t = dtype
    failures = []
    for rc in near_p_values(lam, t):
        for bh in (0.5, 0.999):
            kw = dict(core_reflectivity=rc, edge_tint=t(0.35), alpha=t(0.01), haziness=t(bh),
                      haze_extent=t(lam), smoothness=None if w is None else t(w))
            out = haze_mapping(**kw)
            ref = R.haze_mapping(rc, t(0.35), t(0.01), t(bh), t(lam), smoothness=w,
                                 eps=S.EPS32 if t is np.float32 else S.EPS64)
            where = f"near p: {S.describe(kw)}"
            if t is np.float64:
                errs = {f: S.rel_err(getattr(out, f), ref[f]) for f in ("halo_intensity", "beta")}
                tol = S.REL64
            else:
                errs = {f: S.abs_err(getattr(out, f), ref[f]) for f in ("halo_intensity", "beta")}
                tol = S.ABS32
            for f, e in errs.items():
                S.WORST.add(f"{np.dtype(t).name} Eq.7 branch near p->1", f, e, where)
            # Eq. 6 positivity: k_h <= β_h r_c / p (exact p of the reference)
            kh = R.mpf(float(out.halo_intensity))
            bound = R.mpf(t(bh)) * R.mpf(rc) / ref["peak_ratio"]
            if kh > bound * (1 + 8 * (S.EPS32 if t is np.float32 else S.EPS64)):
                errs["positivity"] = float(kh / bound - 1)
                tol = min(tol, 0.0)
            if max(errs.values()) > tol:
                failures.append(f"{where}: code k_h={float(out.halo_intensity)!r} "
                                f"β={float(out.beta)!r}; reference k_h="
                                f"{mpmath.nstr(ref['halo_intensity'], 17)} "
                                f"β={mpmath.nstr(ref['beta'], 17)}; {errs}")
    assert not failures, "\n".join(failures[:10])


# ------------------------------------------------------------------------------------------------
# alpha_max when α_w exceeds it by less than half an ulp (disagreement with the reference)
# ------------------------------------------------------------------------------------------------

_F32 = np.float32
_ALPHA_MAX_CASES = [
    # α_n = alpha_max = 1, λ_h tiny: exact α_w = 1 + λ > 1 is limited to 1 = α_n, so p = 1,
    # q = 0 and Eq. 7 gives k_h = β_h r_c (as the code itself does for λ_h = 0 and λ_h = 1);
    # mapping.py rounds α_w to 1, sees no limiting (wx > hi is False) and keeps the unlimited
    # spread λ sqrt(α_x α_y) for 1 - p: q = 2e-8, energy branch, k_h = 0.
    ("f32 rc=1 alpha=1 lam=1e-8", dict(core_reflectivity=_F32(1.0), edge_tint=_F32(0.0),
                                       alpha=_F32(1.0), haziness=_F32(0.5),
                                       haze_extent=_F32(1e-8), alpha_max=1.0), "halo_intensity"),
    ("f64 rc=1 alpha=1 lam=1e-20", dict(core_reflectivity=1.0, edge_tint=0.0, alpha=1.0,
                                        haziness=0.5, haze_extent=1e-20, alpha_max=1.0),
     "halo_intensity"),
    # found by hypothesis: 1 - p is 50% off (x axis limited to α_n = 1 but its spread kept)
    ("f64 alpha=(1, .5) lam=1e-20 q", dict(core_reflectivity=0.0, edge_tint=0.0,
                                           alpha=(1.0, 0.5), haziness=0.0, haze_extent=1e-20,
                                           alpha_max=1.0), "peak_complement"),
    ("f32 alpha=(1, .5) lam=3e-8 Bezier", dict(core_reflectivity=_F32(0.99999994),
                                               edge_tint=_F32(0.0), alpha=(_F32(1.0), _F32(0.5)),
                                               haziness=_F32(0.5), haze_extent=_F32(3e-8),
                                               alpha_max=1.0, smoothness=_F32(2.0)),
     "peak_complement"),
]


@pytest.mark.parametrize("case", _ALPHA_MAX_CASES, ids=[c[0] for c in _ALPHA_MAX_CASES])
def test_alpha_max_within_half_ulp(case):
    name, kw, field = case
    is32 = isinstance(kw["haziness"], np.floating) and kw["haziness"].dtype == np.float32
    out = haze_mapping(**kw)
    ref = S.reference_for(dict(kw, distribution="GGX"), eps=S.EPS32 if is32 else S.EPS64)
    errs = {f: S.rel_err(getattr(out, f), ref[f])
            for f in ("halo_intensity", "beta", "peak_complement")}
    assert errs[field] <= (S.ABS32 if is32 else S.REL64), (
        f"{name}: {S.describe(kw)}: code {field}={float(getattr(out, field))!r}, reference "
        f"{mpmath.nstr(ref[field], 17)}; errors {errs}")
