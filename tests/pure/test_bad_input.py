# SPDX-License-Identifier: GPL-3.0-or-later
"""Bad input.

Scalar calls (every input one texel) raise ValueError with a message naming the parameter and
what is wrong.  Texture calls (arrays) never raise for bad VALUES: each bad texel is clamped to
the nearest valid value (NaN -> the lower bound), counted per reason in ``clamped``, and no
output field contains NaN or inf; good texels are bit-identical to a call without the bad ones.
Shape errors and bad options (distribution, alpha_max) raise in both modes.
"""
import math
import re
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import hg_support as S
from hazy_gloss.core import haze_mapping

NAN, INF = math.nan, math.inf
BASE = dict(core_reflectivity=0.5, edge_tint=0.2, alpha=0.1, haziness=0.3, haze_extent=2.0)

# (override, regex the message must match)
SCALAR_BAD = [
    (dict(core_reflectivity=NAN), r"core_reflectivity.*NaN"),
    (dict(core_reflectivity=INF), r"core_reflectivity.*> ?1"),
    (dict(core_reflectivity=-INF), r"core_reflectivity.*< ?0"),
    (dict(core_reflectivity=-0.1), r"core_reflectivity.*< ?0"),
    (dict(core_reflectivity=1.0000001), r"core_reflectivity.*> ?1"),
    (dict(core_reflectivity=(0.5, NAN, 0.2)), r"core_reflectivity.*NaN"),
    (dict(core_reflectivity=(0.5, 0.2, 1.5)), r"core_reflectivity.*> ?1"),
    (dict(edge_tint=NAN), r"edge_tint.*NaN"),
    (dict(edge_tint=INF), r"edge_tint.*> ?1"),
    (dict(edge_tint=-1e-30), r"edge_tint.*< ?0"),
    (dict(edge_tint=2.0), r"edge_tint.*> ?1"),
    (dict(edge_tint=(0.1, 0.2, -0.3)), r"edge_tint.*< ?0"),
    (dict(alpha=-1.0), r"alpha.*< ?0"),
    (dict(alpha=NAN), r"alpha.*NaN"),
    (dict(alpha=INF), r"alpha.*is \+inf"),
    (dict(alpha=(0.1, -0.1)), r"alpha\.y.*< ?0"),
    (dict(alpha=(NAN, 0.1)), r"alpha\.x.*NaN"),
    (dict(haziness=1.0), r"haziness.*>= ?1"),
    (dict(haziness=1.5), r"haziness.*>= ?1"),
    (dict(haziness=INF), r"haziness.*>= ?1"),
    (dict(haziness=NAN), r"haziness.*NaN"),
    (dict(haziness=-0.1), r"haziness.*< ?0"),
    (dict(haziness=-INF), r"haziness.*< ?0"),
    (dict(haze_extent=-1.0), r"haze_extent.*< ?0"),
    (dict(haze_extent=-INF), r"haze_extent.*< ?0"),
    (dict(haze_extent=NAN), r"haze_extent.*NaN"),
    (dict(haze_extent=INF), r"haze_extent.*is \+inf"),
    (dict(haze_extent=(1.0, -5.0)), r"haze_extent\.y.*< ?0"),
    (dict(smoothness=0.0), r"smoothness.*> ?0"),
    (dict(smoothness=-1.0), r"smoothness.*> ?0"),
    (dict(smoothness=-INF), r"smoothness.*> ?0"),
    (dict(smoothness=NAN), r"smoothness.*> ?0"),
    (dict(distribution="PHONG"), r"distribution must be one of"),
    (dict(distribution=""), r"distribution must be one of"),
    (dict(alpha_max=0.0), r"alpha_max"),
    (dict(alpha_max=-1.0), r"alpha_max"),
    (dict(alpha_max=NAN), r"alpha_max"),
    (dict(alpha_max=INF), r"alpha_max"),
    (dict(alpha=(0.1, 0.2, 0.3)), r"alpha.*\(x, y\)"),
    (dict(haze_extent=(1.0,)), r"haze_extent.*\(x, y\)"),
    (dict(core_reflectivity=(0.1, 0.2)), r"core_reflectivity.*\(\.\.\., 3\)"),
    (dict(edge_tint=np.zeros((2, 4))), r"edge_tint.*\(\.\.\., 3\)"),
]


def _id(case):
    return re.sub(r"\s+", "", repr(case[0]))[:60]


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("case", SCALAR_BAD, ids=[_id(c) for c in SCALAR_BAD])
def test_scalar_call_raises(case, dtype):
    override, pattern = case
    kw = dict(BASE, **override)
    if dtype is np.float32:  # same call with float32 scalars (numpy scalars are single texels)
        for k in ("core_reflectivity", "edge_tint", "haziness"):
            if not isinstance(kw[k], np.ndarray):
                kw[k] = np.asarray(kw[k], dtype=np.float32)
        for k in ("alpha", "haze_extent"):
            v = kw[k]
            kw[k] = (tuple(np.float32(x) for x in v) if isinstance(v, tuple) else np.float32(v))
    with pytest.raises(ValueError, match=pattern):
        haze_mapping(**kw)


def test_strict_flag_overrides_mode():
    with pytest.raises(ValueError, match="haziness"):
        haze_mapping(np.full((4, 3), 0.5), 0.0, 0.1, np.array([0.1, 0.2, 1.0, 0.3]), 2.0,
                     strict=True)
    out = haze_mapping(0.05, 0.0, 0.1, 1.0, 2.0, strict=False)
    assert out.clamped == {"haziness >= 1": 1}
    assert float(out.haziness) == np.nextafter(1.0, 0.0)


@pytest.mark.parametrize("shapes", [
    dict(core_reflectivity=(4, 3), haziness=(5,)),
    dict(core_reflectivity=(4, 3), edge_tint=(3, 3)),
    dict(alpha=((4,), (5,))),
    dict(haze_extent=((2, 2), (3,))),
    dict(core_reflectivity=(2, 3), smoothness=(3,)),
    dict(haziness=(6,), alpha=(7,)),
])
def test_mismatched_shapes_raise(shapes):
    kw = dict(BASE)
    for key, shp in shapes.items():
        if key in ("alpha", "haze_extent") and isinstance(shp[0], tuple):
            kw[key] = (np.full(shp[0], 0.1), np.full(shp[1], 0.1))
        elif key in ("core_reflectivity", "edge_tint"):
            kw[key] = np.full(shp, 0.3)
        else:
            kw[key] = np.full(shp, 0.3)
    with pytest.raises(ValueError, match="do not broadcast"):
        haze_mapping(**kw)


# ------------------------------------------------------------------------------------------------
# Texture calls: clamp and count
# ------------------------------------------------------------------------------------------------

FIELDS = ("core_reflectivity", "edge_tint", "alpha.x", "alpha.y", "haziness", "haze_extent.x",
          "haze_extent.y", "smoothness")
#: bad values per field: (value, kind) where kind is nan / below / above
BAD_VALUES = {
    "core_reflectivity": [(NAN, "nan"), (-0.25, "below"), (-INF, "below"), (1.5, "above"),
                          (INF, "above")],
    "edge_tint": [(NAN, "nan"), (-1e-3, "below"), (INF, "above"), (1.0 + 2 ** -20, "above")],
    "alpha.x": [(NAN, "nan"), (-1.0, "below"), (-INF, "below"), (INF, "above")],
    "alpha.y": [(NAN, "nan"), (-0.5, "below")],
    "haziness": [(NAN, "nan"), (-0.2, "below"), (1.0, "above"), (3.0, "above"), (INF, "above")],
    "haze_extent.x": [(NAN, "nan"), (-3.0, "below"), (INF, "above")],
    "haze_extent.y": [(NAN, "nan"), (-INF, "below")],
    "smoothness": [(NAN, "nan"), (0.0, "below"), (-2.0, "below"), (-INF, "below")],
}
OUTPUT_FIELDS = ("beta", "reflectivity", "ior", "extinction", "peak_ratio", "peak_complement",
                 "halo_intensity", "reflectivity_max", "weight_narrow", "weight_wide",
                 "dielectric_ior", "core_reflectivity", "edge_tint", "haziness")


def _nearest_valid(field, value, kind, dtype):
    t = np.dtype(dtype).type
    if field == "smoothness":
        return t(np.finfo(dtype).tiny)
    if kind in ("nan", "below"):
        return t(0)
    if field in ("core_reflectivity", "edge_tint"):
        return t(1)
    if field == "haziness":
        return np.nextafter(t(1), t(0))
    return t(np.finfo(dtype).max)


def _make_texture(rng, n, dtype, n_bad, with_smoothness):
    rc = rng.uniform(0, 1, (n, 3)).astype(dtype)
    g = (rng.uniform(0, 1, (n, 3)) * (rng.uniform(size=(n, 1)) < 0.5)).astype(dtype)
    ax = (10 ** rng.uniform(-4, 0, n)).astype(dtype)
    ay = (10 ** rng.uniform(-4, 0, n)).astype(dtype)
    bh = rng.uniform(0, 1, n).astype(dtype)
    lx = (10 ** rng.uniform(-2, 3, n)).astype(dtype)
    ly = (10 ** rng.uniform(-2, 3, n)).astype(dtype)
    w = (10 ** rng.uniform(-2, 3, n)).astype(dtype) if with_smoothness else None
    arrays = {"core_reflectivity": rc, "edge_tint": g, "alpha.x": ax, "alpha.y": ay,
              "haziness": bh, "haze_extent.x": lx, "haze_extent.y": ly, "smoothness": w}
    fields = [f for f in FIELDS if arrays[f] is not None]
    # disjoint bad texels: each bad texel has exactly one bad value in one field (one channel)
    idx = rng.permutation(n)[: n_bad * len(fields)].reshape(len(fields), n_bad)
    bad = {}
    for fi, field in enumerate(fields):
        entries = []
        for j, i in enumerate(idx[fi]):
            value, kind = BAD_VALUES[field][j % len(BAD_VALUES[field])]
            if field in ("core_reflectivity", "edge_tint"):
                c = int(rng.integers(3))
                arrays[field][i, c] = value
            else:
                c = None
                arrays[field][i] = value
            entries.append((int(i), c, value, kind))
        bad[field] = entries
    return arrays, bad


def _call(arrays, dtype, **opts):
    a = arrays
    return haze_mapping(a["core_reflectivity"], a["edge_tint"], (a["alpha.x"], a["alpha.y"]),
                        a["haziness"], (a["haze_extent.x"], a["haze_extent.y"]),
                        smoothness=a["smoothness"], **opts)


def _reason_count(clamped, field, kind):
    total = 0
    for reason, count in clamped.items():
        if field == "smoothness":
            if reason.startswith("smoothness"):
                total += count if kind == "any" else 0
            continue
        if not re.match(re.escape(field) + r"\b(?![.])", reason):
            continue
        k = "nan" if "NaN" in reason else ("below" if "<" in reason else "above")
        if kind in ("any", k):
            total += count
    return total


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("opts", [dict(), dict(distribution="BECKMANN", alpha_max=1.0),
                                  dict(smooth=True), dict(smooth=True, distribution="ASHIKHMIN_SHIRLEY"),
                                  dict(smooth=True, alpha_max=0.5, distribution="MULTI_GGX")])
@pytest.mark.parametrize("seed", [0, 1])
def test_texture_clamps_and_counts(dtype, opts, seed):
    opts = dict(opts)
    smooth = opts.pop("smooth", False)
    rng = np.random.default_rng(seed)
    n, n_bad = 240, 9
    arrays, bad = _make_texture(rng, n, dtype, n_bad, smooth)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no numpy warnings leak out either
        out = _call(arrays, dtype, **opts)

    # 1. no NaN / inf anywhere, dtype preserved
    for f in OUTPUT_FIELDS:
        v = np.asarray(getattr(out, f))
        assert v.dtype == dtype, f
        assert np.all(np.isfinite(v)), f
    for pair in (out.alpha, out.alpha_wide, out.haze_extent):
        for v in pair:
            assert np.all(np.isfinite(v))

    # 2. counts per field and per kind equal the number of bad texels
    for field, entries in bad.items():
        assert _reason_count(out.clamped, field, "any") == len(entries), (field, out.clamped)
        if field != "smoothness":
            for kind in ("nan", "below", "above"):
                expected = sum(1 for e in entries if e[3] == kind)
                assert _reason_count(out.clamped, field, kind) == expected, (field, kind,
                                                                              out.clamped)
    assert len(out.warnings) == len(out.clamped)
    for msg, (reason, count) in zip(out.warnings, out.clamped.items()):
        assert reason in msg and str(count) in msg

    # 3. bad texels clamped to the nearest valid value (reported back in the inputs used)
    used = {"core_reflectivity": out.core_reflectivity, "edge_tint": out.edge_tint,
            "haziness": out.haziness, "haze_extent.x": out.haze_extent[0],
            "haze_extent.y": out.haze_extent[1]}
    if opts.get("distribution") != "ASHIKHMIN_SHIRLEY" and opts.get("alpha_max") is None:
        # (with a renderer limit the reported α_n is the limited one: tests/pure/test_mapping_extremes.py)
        used["alpha.x"], used["alpha.y"] = out.alpha
    clamped_inputs = {k: (None if v is None else np.array(v)) for k, v in arrays.items()}
    for field, entries in bad.items():
        for i, c, value, kind in entries:
            expect = _nearest_valid(field, value, kind, dtype)
            if field in used:
                got = np.asarray(used[field])[i] if c is None else np.asarray(used[field])[i, c]
                assert got == expect, (field, value, got, expect)
            if c is None:
                clamped_inputs[field][i] = expect
            else:
                clamped_inputs[field][i, c] = expect

    # 4. the whole result equals a call on the clamped inputs (so clamping is all that happened)
    again = _call(clamped_inputs, dtype, **opts)
    for f in OUTPUT_FIELDS:
        np.testing.assert_array_equal(getattr(again, f), getattr(out, f), err_msg=f)

    # 5. good texels bit-identical to a call without the bad ones
    bad_idx = sorted({e[0] for entries in bad.values() for e in entries})
    good = np.setdiff1d(np.arange(n), bad_idx)
    only_good = {k: (None if v is None else v[good]) for k, v in arrays.items()}
    ref = _call(only_good, dtype, **opts)
    for f in OUTPUT_FIELDS:
        np.testing.assert_array_equal(np.asarray(getattr(out, f))[good], getattr(ref, f),
                                      err_msg=f)
    for k in range(2):
        np.testing.assert_array_equal(np.broadcast_to(out.alpha_wide[k], (n,))[good],
                                      ref.alpha_wide[k])
    assert set(ref.clamped) <= S.RENDERER_REASONS, ref.clamped


@settings(max_examples=S.examples(60), deadline=None)
@given(st.lists(st.sampled_from([NAN, INF, -INF, -1.0, -1e-300, 0.0, 0.5, 1.0, 1.0 + 1e-12, 2.0,
                                 1e300]), min_size=7, max_size=7),
       st.sampled_from([np.float64, np.float32]), st.booleans())
def test_texture_any_garbage_is_finite(vals, dtype, smooth):
    """Whatever mix of garbage texels (every field bad at once), the texture call returns finite
    outputs of the right dtype, counts at least one clamp per bad texel and lets no numpy
    RuntimeWarning out."""
    rc, g, ax, ay, bh, lx, ly = vals

    def arr(*x):
        with np.errstate(over="ignore"):  # 1e300 -> inf in float32 is the intended garbage
            return np.asarray(x, dtype=dtype)

    args = (arr([rc, 0.5, 0.1], [0.2, 0.2, 0.2]), arr([g], [0.0]), (arr(ax, 0.1), arr(ay, 0.1)),
            arr(bh, 0.3), (arr(lx, 2.0), arr(ly, 2.0)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        out = haze_mapping(*args, smoothness=arr(-1.0, 2.0) if smooth else None)
    assert not caught, [str(w.message) for w in caught]
    for f in OUTPUT_FIELDS:
        v = np.asarray(getattr(out, f))
        assert v.dtype == dtype and np.all(np.isfinite(v)), f
    for v in out.alpha_wide:
        assert np.all(np.isfinite(v))
    with np.errstate(invalid="ignore"):
        c = lambda x: arr(x)[0]  # noqa: E731
        n_bad_inputs = sum(1 for x, lo, hi in ((rc, 0, 1), (g, 0, 1), (ax, 0, np.inf),
                                               (ay, 0, np.inf), (lx, 0, np.inf), (ly, 0, np.inf))
                           if not (lo <= c(x) <= hi) or not np.isfinite(c(x)))
        n_bad_inputs += 0 if (0 <= c(bh) < 1) else 1
    counted = sum(c for r, c in out.clamped.items()
                  if not r.startswith(("alpha_wide", "reflectivity at 1", "smoothness")))
    assert counted == n_bad_inputs, (vals, out.clamped)
    if smooth:
        assert out.clamped.get("smoothness <= 0 or NaN") == 1


def test_texture_no_numpy_warnings_leak():
    args = (np.array([[0.5] * 3, [0.2] * 3]), 0.0, (np.array([np.inf, 0.1]), np.array([np.inf, 0.1])),
            np.array([0.3, 0.3]), (np.array([np.inf, 2.0]), np.array([np.inf, 2.0])))
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        out = haze_mapping(*args)
    assert all(np.all(np.isfinite(getattr(out, f))) for f in OUTPUT_FIELDS)
