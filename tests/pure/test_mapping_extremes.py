# SPDX-License-Identifier: GPL-3.0-or-later
"""Extreme and invalid inputs of the haze mapping.

- a Bézier weight w so small that 1/w overflows (float64 w < ~5.6e-309, float32 < ~2.9e-39) is
  the w -> 0 limit (no haze), not NaN;
- α_n above ``alpha_max`` (or outside Ashikhmin-Shirley's range) is counted, raises in strict
  mode, and the reported α_n is the one the renderer uses, so α_w >= α_n in every output;
- inverse_haze_mapping flags NaN / ±inf / negative inputs in ``clamped`` and ``exact`` and
  never returns NaN;
- property tests over extreme floats (subnormals, ±inf, NaN, the largest finite values) in
  float32 and float64: no NaN or inf in any output, α_w >= α_n, β in [0, 1].
"""
import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hg_support as S
from hazy_gloss.core import haze_mapping, inverse_haze_mapping

NAN, INF = math.nan, math.inf
FIELDS = ("beta", "reflectivity", "ior", "extinction", "peak_ratio", "peak_complement",
          "halo_intensity", "reflectivity_max", "weight_narrow", "weight_wide",
          "dielectric_ior", "core_reflectivity", "edge_tint", "haziness")


def _finite(out):
    for f in FIELDS:
        v = np.asarray(getattr(out, f))
        assert np.all(np.isfinite(v)), (f, v)
    for k in range(2):
        assert np.all(np.isfinite(np.asarray(out.alpha_wide[k]))), out.alpha_wide
        assert np.all(np.isfinite(np.asarray(out.alpha[k]))), out.alpha
        assert np.all(np.asarray(out.alpha_wide[k]) >= np.asarray(out.alpha[k])), (out.alpha,
                                                                                  out.alpha_wide)


# -- 1/w overflow ---------------------------------------------------------------------------------


def test_issue_call_tiny_smoothness_is_finite():
    """A call that gave η, κ, k_n = NaN with clamped == {}: finite now."""
    m = haze_mapping((0.9, 0.6, 0.3), 0.5, 0.01, 0.5, 5.0, smoothness=5e-324)
    _finite(m)
    assert m.clamped == {}
    # the w -> 0 limit: the Bézier collapses onto the r_c axis, no haze at all
    assert float(m.halo_intensity) == 0.0 and float(m.beta) == 0.0
    np.testing.assert_array_equal(m.reflectivity, [0.9, 0.6, 0.3])
    np.testing.assert_array_equal(m.weight_narrow, m.reflectivity)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_tiny_smoothness_is_continuous_across_the_overflow(dtype):
    """w on either side of the value where 1/w overflows gives (almost) the same result, in
    scalar and texture calls, float32 and float64."""
    tiny = np.finfo(dtype).tiny
    ws = np.array([tiny, tiny / 2, tiny / 2 ** 10, 1 / np.finfo(dtype).max,
                   np.nextafter(dtype(0), dtype(1))], dtype=dtype)
    rc = np.array([[0.9, 0.6, 0.3]] * 5 + [[0.05, 0.02, 0.01]] * 5, dtype=dtype)
    w = np.concatenate([ws, ws])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        out = haze_mapping(rc, dtype(0.5), dtype(0.01), dtype(0.5), dtype(5.0), smoothness=w)
    _finite(out)
    assert out.clamped == {}
    for f in ("beta", "reflectivity", "ior", "extinction", "weight_narrow"):
        v = np.asarray(getattr(out, f), dtype=np.float64)
        ref = np.concatenate([np.repeat(v[:1], 5, 0), np.repeat(v[5:6], 5, 0)])
        np.testing.assert_allclose(v, ref, rtol=1e-6, atol=1e-30, err_msg=f)


# -- α_n above alpha_max ------------------------------------------------------------------------


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_alpha_above_alpha_max_is_counted_and_reported_clamped(dtype):
    """Was α_w = 1 < α_n = 2 with clamped == {}."""
    a = np.array([0.2, 2.0, 1.5], dtype=dtype)
    out = haze_mapping(np.full((3, 3), 0.5, dtype), dtype(0.5), (a, np.array([0.2, 0.2, 3.0], dtype)),
                       np.full(3, 0.5, dtype), np.full(3, 2.0, dtype), alpha_max=1.0)
    assert out.clamped.get("alpha > 1 (renderer limit)") == 2, out.clamped
    np.testing.assert_array_equal(out.alpha[0], np.array([0.2, 1.0, 1.0], dtype))
    np.testing.assert_array_equal(out.alpha[1], np.array([0.2, 0.2, 1.0], dtype))
    _finite(out)


def test_alpha_above_alpha_max_raises_in_strict_mode():
    with pytest.raises(ValueError, match=r"alpha\.x > 1 \(renderer limit"):
        haze_mapping(0.5, 0.5, 2.0, 0.5, 5.0, alpha_max=1.0)
    with pytest.raises(ValueError, match=r"alpha\.y > 0\.5"):
        haze_mapping(0.5, 0.5, (0.1, 0.6), 0.5, 5.0, alpha_max=0.5, strict=True)
    # exactly at the limit is valid
    m = haze_mapping(0.5, 0.5, 1.0, 0.5, 5.0, alpha_max=1.0)
    assert float(m.alpha_wide[0]) == 1.0 == float(m.alpha[0]) and m.clamped == {
        "alpha_wide > 1 (renderer limit)": 1}


def test_ashikhmin_shirley_range_is_counted():
    out = haze_mapping(np.full((3, 3), 0.5), 0.0, np.array([1e-6, 0.3, 1.7]), np.full(3, 0.5),
                       np.full(3, 2.0), distribution="ASHIKHMIN_SHIRLEY")
    assert out.clamped.get("alpha < 0.0001 (renderer limit)") == 1, out.clamped
    assert out.clamped.get("alpha > 1 (renderer limit)") == 1, out.clamped
    _finite(out)
    with pytest.raises(ValueError, match="alpha.x > 1"):
        haze_mapping(0.5, 0.0, 1.7, 0.5, 2.0, distribution="ASHIKHMIN_SHIRLEY")


# -- inverse: invalid physical inputs -------------------------------------------------------------


BAD = [NAN, INF, -INF, -1.0]


def _inv_finite(inv):
    for v in (inv.core_reflectivity, inv.edge_tint, inv.haziness, *inv.haze_extent, *inv.alpha):
        assert np.all(np.isfinite(np.asarray(v))), (inv.core_reflectivity, inv.edge_tint,
                                                    inv.haziness, inv.haze_extent, inv.alpha)
    assert np.all((inv.haziness >= 0) & (inv.haziness < 1))
    for v in inv.haze_extent + inv.alpha:
        assert np.all(np.asarray(v) >= 0)


@pytest.mark.parametrize("bad", BAD)
@pytest.mark.parametrize("field", ["beta", "alpha", "alpha_wide", "reflectivity", "ior",
                                   "extinction"])
def test_inverse_flags_invalid_inputs(field, bad):
    kw = dict(beta=0.4, alpha=0.1, alpha_wide=0.3, ior=1.8, extinction=0.6)
    if field == "reflectivity":
        kw.pop("ior"), kw.pop("extinction")
    kw[field] = bad
    inv = inverse_haze_mapping(**kw)
    _inv_finite(inv)
    assert not bool(inv.exact) and not bool(inv.unique), (field, bad, inv.clamped)
    assert any(field.split("_")[0] in r or field in r for r in inv.clamped), (field, inv.clamped)


def test_inverse_negative_extinction_is_flagged():
    """κ enters only squared, so κ < 0 used to map back as exact."""
    inv = inverse_haze_mapping(0.3, 0.1, 0.3, ior=1.8, extinction=-0.6)
    assert not bool(inv.exact) and "extinction" in " ".join(inv.clamped)


def test_inverse_texture_mixes_good_and_bad():
    beta = np.array([0.4, NAN, 0.4, 0.4, 0.4])
    alpha = np.array([0.1, 0.1, -1.0, 0.1, 0.1])
    wide = np.array([0.3, 0.3, 0.3, INF, 0.3])
    ior = np.array([1.8, 1.8, 1.8, 1.8, NAN])[:, None] * np.ones(3)
    inv = inverse_haze_mapping(beta, alpha, wide, ior=ior, extinction=0.6)
    _inv_finite(inv)
    assert inv.exact.tolist() == [True, False, False, False, False], inv.clamped
    ref = inverse_haze_mapping(0.4, 0.1, 0.3, ior=1.8, extinction=0.6)
    assert float(inv.haziness[0]) == float(ref.haziness)


@pytest.mark.parametrize("w", [NAN, -1.0, 0.0, 5e-324])
def test_inverse_bad_or_tiny_smoothness(w):
    inv = inverse_haze_mapping(np.array([0.0, 0.3]), 0.1, 0.3, reflectivity=0.5, smoothness=w)
    _inv_finite(inv)
    if w == 5e-324:  # the w -> 0 limit: no haze is reachable, β = 0 is
        assert inv.exact.tolist() == [True, False]
    else:
        assert not inv.exact.any() and "smoothness" in " ".join(inv.clamped)


# -- properties over extreme floats ---------------------------------------------------------------


def _floats(width):
    return st.one_of(st.floats(width=width, allow_nan=True, allow_infinity=True,
                               allow_subnormal=True),
                     st.sampled_from([0.0, -0.0, 1.0, 0.5, 1e-300, 5e-324, 1e-45, 1e-38,
                                      np.finfo(np.float32).max, np.finfo(np.float64).max]),
                     st.floats(0, 1, width=width))


def _extreme_args(draw, width):
    f = _floats(width)
    return dict(rc=[draw(f) for _ in range(3)], g=draw(f), ax=draw(f), ay=draw(f), bh=draw(f),
                lx=draw(f), ly=draw(f), w=draw(st.one_of(st.none(), f)),
                dist=draw(st.sampled_from(S.DISTS)),
                alpha_max=draw(st.sampled_from([None, 1.0, 0.5])),
                max_aspect=draw(st.sampled_from([None, 10.0])))


@st.composite
def extreme64(draw):
    return _extreme_args(draw, 64)


@st.composite
def extreme32(draw):
    return _extreme_args(draw, 32)


def _run(a, dtype, strict):
    """One texel: a scalar call (strict; 0-d values) or a one-texel texture call."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # casts to float32 overflow on purpose;
        # outputs are checked, not warnings
        shape = () if strict else (1,)

        def arr(x):
            return np.broadcast_to(np.asarray(x, dtype=dtype), shape)

        rc = np.broadcast_to(np.asarray(a["rc"], dtype=dtype), shape + (3,))
        args = (rc, arr(a["g"]), (arr(a["ax"]), arr(a["ay"])), arr(a["bh"]),
                (arr(a["lx"]), arr(a["ly"])))
        w = None if a["w"] is None else arr(a["w"])
        return haze_mapping(*args, smoothness=w, distribution=a["dist"], alpha_max=a["alpha_max"],
                            max_aspect=a["max_aspect"], strict=strict)


def _props(out):
    _finite(out)
    assert np.all((out.beta >= 0) & (out.beta <= 1))
    assert np.all(out.reflectivity <= 1) and np.all(out.extinction >= 0) and np.all(out.ior > 0)


@settings(max_examples=S.examples(400), deadline=None)
@given(extreme64())
def test_extreme_floats_texture_float64(a):
    _props(_run(a, np.float64, False))


@settings(max_examples=S.examples(400), deadline=None)
@given(extreme32())
def test_extreme_floats_texture_float32(a):
    out = _run(a, np.float32, False)
    _props(out)
    assert out.beta.dtype == np.float32


@settings(max_examples=S.examples(300), deadline=None)
@given(st.one_of(extreme64(), extreme32()), st.sampled_from([np.float64, np.float32]))
def test_extreme_floats_scalar_raise_or_finite(a, dtype):
    try:
        out = _run(a, dtype, True)
    except ValueError as exc:
        assert "\n" not in str(exc)
        return
    _props(out)
    assert out.clamped == {} or all(r.startswith(("alpha_wide", "reflectivity at 1"))
                                    for r in out.clamped), out.clamped


@settings(max_examples=S.examples(300), deadline=None)
@given(st.lists(_floats(64), min_size=6, max_size=6), st.sampled_from([np.float64, np.float32]),
       st.booleans(), st.sampled_from([None, 1e-3, 5e-324, 1.0]))
def test_inverse_extreme_floats_never_nan(vals, dtype, fresnel, w):
    b, ax, ay, wx, wy, r = vals
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # 1e300 -> inf in float32 is intended
        arr = lambda x: np.asarray([x], dtype=dtype)  # noqa: E731
        kw = dict(ior=arr([r] * 3), extinction=arr([ax] * 3)) if fresnel else \
            dict(reflectivity=arr([r] * 3))
        inv = inverse_haze_mapping(arr(b), (arr(ax), arr(ay)), (arr(wx), arr(wy)),
                                       smoothness=w, **kw)
    _inv_finite(inv)
    if inv.exact.all():  # exact means the forward mapping reproduces the input
        assert all(math.isfinite(x) for x in (b, ax, ay, wx, wy, r))
