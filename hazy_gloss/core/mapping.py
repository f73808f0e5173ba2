# SPDX-License-Identifier: GPL-3.0-or-later
"""The haze mapping of Barla, Pacanowski & Vangorp 2018 ("A Composite BRDF Model for Hazy
Gloss"), perceptual -> physical and back, in numpy (no bpy).

Every function broadcasts: colours are shaped (..., 3) (a scalar means grey), scalar maps (...).
The computation runs in float32 when every array input is float32, else in float64.

Equation numbers refer to the paper.  Where the implementation deviates from a printed formula
the comment says why; docs/mapping.md derives each stable form.  The result types and the
input handling are in core/mapping_io.py.
"""
from __future__ import annotations

import math

import numpy as np

from .. import constants as K

# HazeMapping and PerceptualParameters live in mapping_io (split off this module), re-exported.
from .mapping_io import HazeMapping, PerceptualParameters, colour_array, xy_pair, Validator, working_dtype

__all__ = ("DISTRIBUTIONS", "HazeMapping", "PerceptualParameters", "haze_mapping",
           "inverse_haze_mapping", "wide_roughness", "peak_ratio", "haze_intensity",
           "gulbrandsen_ior", "gulbrandsen_inverse", "dielectric_ior", "haze_terms")

#: Lobe distributions the add-on offers, spelled as Blender's node enums (constants'
#: vocabulary).
DISTRIBUTIONS = K.DISTRIBUTIONS

#: Cycles clamps Ashikhmin-Shirley roughness to [1e-4, 1] (bsdf_ashikhmin_shirley_setup).
_AS_ALPHA_RANGE = (1e-4, 1.0)


# --------------------------------------------------------------------------------------------
# Building blocks (each usable on its own; all broadcast)
# --------------------------------------------------------------------------------------------


def wide_roughness(alpha_x, alpha_y, extent_x, extent_y):
    """Eq. 8: α_w = α_n + λ_h sqrt(α_n^x α_n^y), per axis.  Returns (α_w^x, α_w^y, g) with
    g = sqrt(α_n^x α_n^y) (computed as a product of square roots: no underflow)."""
    g = np.sqrt(alpha_x) * np.sqrt(alpha_y)
    with np.errstate(over="ignore"):
        wx = alpha_x + extent_x * g
        wy = alpha_y + extent_y * g
    big = np.finfo(np.result_type(wx)).max
    return np.minimum(wx, big), np.minimum(wy, big), g


def _axis_ratio(an, aw, spread, distribution):
    """Peak ratio along one axis and its complement (p_axis, 1 - p_axis), both accurate.

    ``spread`` = α_w - α_n computed without cancellation by the caller."""
    with np.errstate(divide="ignore", invalid="ignore"):
        if distribution == "ASHIKHMIN_SHIRLEY":
            # Cycles: n = 2/α² - 2, peak ∝ sqrt((n_x+1)(n_y+1)), n+1 = (2-α²)/α²  (Table 2 AS row).
            p2 = (an * an * (2.0 - aw * aw)) / (aw * aw * (2.0 - an * an))
            one_minus_p2 = 2.0 * spread * (aw + an) / (aw * aw * (2.0 - an * an))
            px = np.sqrt(p2)
            qx = one_minus_p2 / (1.0 + px)
        else:
            # GGX / Beckmann: D(0) = 1/(π α_x α_y)  (Table 2, Cook-Torrance/Ward rows).
            px = an / aw
            qx = spread / aw
    return px, qx


def peak_ratio(alpha_x, alpha_y, alpha_wide_x, alpha_wide_y, distribution="GGX"):
    """p = f_w(n,n) / f_n(n,n) from the roughnesses the renderer uses (Table 2).

    Returns (p, 1 - p), the complement computed without cancellation (p -> 1 as λ_h -> 0)."""
    px, qx = _axis_ratio(alpha_x, alpha_wide_x, alpha_wide_x - alpha_x, distribution)
    py, qy = _axis_ratio(alpha_y, alpha_wide_y, alpha_wide_y - alpha_y, distribution)
    return px * py, qx + px * qy


def haze_intensity(core_max, p, q, haziness, smoothness=None):
    """k̂_h from r̂_c, p (and q = 1-p), β_h: Eq. 7, or the rational Bézier of Eqs. 12-15.

    Returns (k̂_h, β) where β = k̂_h / r̂ (Eq. 4) is computed in a form that has no 0/0 at
    r̂_c = 0 (its limit there is β_h / (p + (1-p) β_h)).

    The Bézier is evaluated through the conic's implicit equation (docs/mapping.md):
        t = 2 r_c (1 - r_c) / (r_c q + p (1 - r_c) + hypot(r_c - p, sqrt(r_c (1 - r_c)) / w)),
        k_h = β_h t.
    Deviation from the paper: Eqs. 12-14 invert for u with a root that is 0/0 at b = 1 and a
    Taylor window; this closed form is the same root with no division by b - 1 and no
    cancellation anywhere, and reduces exactly to Eq. 7 at w = ∞.
    """
    kh, beta, _, _ = haze_terms(core_max, p, q, haziness, smoothness)
    return kh, beta


def haze_terms(core_max, p, q, haziness, smoothness=None):
    """(k̂_h, β, 1 - r̂, 1 - β), the last two without cancellation as r̂ -> 1 or β -> 1
    (see docs/mapping.md §6)."""
    rc = core_max
    omr = 1.0 - rc
    dtype = np.result_type(rc)
    zero = dtype.type(0)
    omb = 1.0 - haziness  # exact for β_h >= 1/2
    # r̂_c - p without cancellation: near 1 subtract the complements instead.
    d = np.where(p <= 0.5, rc - p, q - omr)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if smoothness is None or np.all(np.isinf(smoothness)):
            lower = _on_positivity_side(rc, omr, p, q)
            # Eq. 7, branch by branch; σ = r̂_c / k̂_h·β_h is the per-branch "cost" of a unit of haze.
            kh = np.where(lower, haziness * rc / np.where(p > 0, p, 1),
                          haziness * omr / np.where(q > 0, q, 1))
            sigma = np.where(lower, p, rc * q / omr)
            den = sigma + q * haziness
            beta = np.where(den > 0, haziness / den, zero)
            # 1 - r̂ = (1 - r̂_c) - (1-p) k̂_h, rearranged into non-negative terms per branch:
            #   energy side  (1 - r̂_c)(1 - β_h);  positivity side ((p - r̂_c) + r̂_c (1-p)(1 - β_h)) / p
            omr_hat = np.where(lower, np.where(p > 0, (np.maximum(-d, 0) + rc * q * omb) / p,
                                               omr - q * kh),
                               omr * omb)
            # 1 - β = (σ - p β_h)/(σ + (1-p) β_h): p (1-β_h)/(p + (1-p) β_h) on the positivity
            # side, ((r̂_c - p) + p (1-r̂_c)(1-β_h)) / ((1-p)(r̂_c + β_h (1-r̂_c))) on the energy side
            den_lo = p + q * haziness
            omb_lo = np.where(den_lo > 0, p * omb / den_lo, zero)
            den_up = q * (rc + haziness * omr)
            omb_up = np.where(den_up > 0, (np.maximum(d, 0) + p * omr * omb) / den_up, dtype.type(1))
            one_minus_beta = np.where(lower, omb_lo, omb_up)
        else:
            m = 1.0 / np.asarray(smoothness, dtype=dtype)
            # Deviation: a w so small that 1/w overflows (float64 w < ~5.6e-309, float32 < ~2.9e-39)
            # is the w -> 0 limit of Eqs. 12-15, t = 0 (no haze): exact to rounding, t ~ 2w√(r_c(1-r_c)).
            lim0 = np.isinf(m)
            if np.any(lim0):
                m = np.where(lim0, dtype.type(1), m)  # finite stand-in; lim0 texels set below
            s = np.sqrt(rc * omr)
            ms = np.where(s > 0, m * s, zero)
            hyp = np.hypot(d, ms)
            den = rc * q + p * omr + hyp
            t = np.where(den > 0, 2.0 * rc * omr / den, zero)
            t = np.where(lim0, zero, t)
            kh = haziness * t
            two_omr_bh = 2.0 * omr * haziness
            den_b = den + q * two_omr_bh
            beta = np.where(den_b > 0, two_omr_bh / den_b, np.where(omr > 0, dtype.type(1), zero))
            beta = np.where(lim0, zero, beta)
            # 1 - r̂ = c_0 + (1-p) t (1 - β_h) with c_0 = (1-u)²/d the Bézier weight of (0, 0);
            # when c_0 is the smaller of c_0, c_2 use the conic t² = 4 w² c_0 c_2 (no cancellation)
            c0 = omr - q * t
            c2 = rc - p * t
            c0 = np.where((c0 < c2) & (c2 > 0), (m * t) ** 2 / (4.0 * c2), c0)
            omr_hat = np.maximum(c0, 0) + q * t * omb
            # 1 - β = ((r̂_c - p) + hyp + 2p(1-r̂_c)(1-β_h)) / (den + 2(1-p)β_h(1-r̂_c)), with
            # (r̂_c - p) + hypot(r̂_c - p, m s) = (m s)² / (hyp - (r̂_c - p)) when r̂_c < p
            d_hyp = np.where(d >= 0, d + hyp, np.where(hyp - d > 0, ms * ms / (hyp - d), zero))
            one_minus_beta = np.where(den_b > 0, (d_hyp + 2.0 * p * omr * omb) / den_b,
                                      1.0 - beta)
            if np.any(lim0):  # no halo: 1 - r̂ = 1 - r̂_c, 1 - β = 1
                omr_hat = np.where(lim0, omr, omr_hat)
                one_minus_beta = np.where(lim0, dtype.type(1), one_minus_beta)
            if np.any(np.isinf(smoothness)):  # mixed per-texel w with some w = ∞: Eq. 7 there
                kh7, beta7, omr7, omb7 = haze_terms(rc, p, q, haziness, None)
                inf = np.isinf(smoothness)
                kh = np.where(inf, kh7, kh)
                beta = np.where(inf, beta7, beta)
                omr_hat = np.where(inf, omr7, omr_hat)
                one_minus_beta = np.where(inf, omb7, one_minus_beta)
    return (kh.astype(dtype, copy=False), np.clip(beta, 0, 1).astype(dtype, copy=False),
            np.clip(omr_hat, 0, 1).astype(dtype, copy=False),
            np.clip(one_minus_beta, 0, 1).astype(dtype, copy=False))


def _on_positivity_side(rc, omr, p, q):
    """r̂_c <= p, decided with the accurate complements when p > 1/2 (as 1 - r̂_c >= 1 - p): the
    rounded p can equal 1 while r̂_c = 1 is already on the energy side (λ_h -> 0)."""
    return np.where(p <= 0.5, rc <= p, omr >= q)


def gulbrandsen_ior(reflectivity, edge_tint, one_minus_r=None):
    """Gulbrandsen 2014, "Artist Friendly Metallic Fresnel": (r, g) -> (η, κ), per channel.

    Printed form: η = g (1-r)/(1+r) + (1-g)(1+√r)/(1-√r), κ = sqrt((r(η+1)² - (η-1)²)/(1-r)).
    Deviation: κ is rewritten (docs/mapping.md) as
        κ = 2√r sqrt( g/(1+r) · ( g/(1+r) + 2 (1-g) / (1-√r)² ) ),
    a sum of non-negative terms: the printed numerator cancels catastrophically as r -> 1.
    1 - √r is computed as (1-r)/(1+√r).  r must be < 1 (the caller limits it); pass
    ``one_minus_r`` when 1 - r is known more accurately than by subtraction (r -> 1)."""
    r = reflectivity
    g = edge_tint
    s = np.sqrt(r)
    omr = 1.0 - r if one_minus_r is None else one_minus_r
    ops = 1.0 + s
    one_minus_s = omr / ops
    n_dielectric = ops / one_minus_s
    n_metal = omr / (1.0 + r)
    eta = g * n_metal + (1.0 - g) * n_dielectric
    gr = g / (1.0 + r)
    kappa = 2.0 * s * np.sqrt(gr * (gr + 2.0 * (1.0 - g) / (one_minus_s * one_minus_s)))
    return eta, kappa


def gulbrandsen_inverse(ior, extinction):
    """(η, κ) -> (r, g): r = ((η-1)² + κ²)/((η+1)² + κ²); g from η = g n_m(r) + (1-g) n_d(r).

    g lies in [0, 1] only for (η, κ) on Gulbrandsen's manifold; returned unclamped."""
    eta = ior
    with np.errstate(over="ignore", invalid="ignore"):
        k2 = extinction * extinction
        r = ((eta - 1.0) ** 2 + k2) / ((eta + 1.0) ** 2 + k2)
    if not np.all(np.isfinite(r)):  # the squares overflow (huge η or κ): scale them first
        with np.errstate(invalid="ignore", divide="ignore"):
            sc = np.maximum(np.abs(eta) + 1.0, np.abs(extinction))
            a, k, c = (eta - 1.0) / sc, extinction / sc, (eta + 1.0) / sc
            r = np.where(np.isfinite(r), r, (a * a + k * k) / (c * c + k * k))
    s = np.sqrt(r)
    omr = 1.0 - r
    with np.errstate(divide="ignore", invalid="ignore"):
        n_d = (1.0 + s) ** 2 / omr
        n_m = omr / (1.0 + r)
        g = np.where(n_d > n_m, (n_d - eta) / (n_d - n_m), 0.0)
    return r, g


def dielectric_ior(reflectivity, one_minus_r=None):
    """η = (1+√r)/(1-√r) (paper, footnote of §2.3 and §2.4), as (1+√r)²/(1-r)."""
    s = np.sqrt(reflectivity)
    return (1.0 + s) ** 2 / (1.0 - reflectivity if one_minus_r is None else one_minus_r)


# --------------------------------------------------------------------------------------------
# HAZEMAPPING (paper §2.4, Algorithm)
# --------------------------------------------------------------------------------------------


def _normalise_distribution(distribution):
    d = str(distribution).upper().replace("-", "_").replace(" ", "_")
    if d in ("MULTISCATTER_GGX", "MULTI_SCATTER_GGX"):
        d = "MULTI_GGX"
    if d in ("ASHIKHMIN", "AS"):
        d = "ASHIKHMIN_SHIRLEY"
    if d not in DISTRIBUTIONS:
        raise ValueError(f"distribution must be one of {DISTRIBUTIONS}, got {distribution!r}")
    return d


def _broadcast_shape(named_shapes):
    try:
        return np.broadcast_shapes(*[s for _, s in named_shapes])
    except ValueError:
        desc = ", ".join(f"{n} {s}" for n, s in named_shapes)
        raise ValueError(f"input shapes do not broadcast to one texel grid: {desc}") from None


def haze_mapping(core_reflectivity, edge_tint, alpha, haziness, haze_extent, *,
                 distribution="GGX", smoothness=None, alpha_max=None, max_aspect=None,
                 strict=None) -> HazeMapping:
    """Perceptual -> physical parameters (the paper's HAZEMAPPING).

    core_reflectivity  [r_c]  colour in [0, 1], scalar (grey) or (..., 3)
    edge_tint          [g]    colour in [0, 1]; 0 = dielectric (κ = 0), scalar or (..., 3)
    alpha              [α_n]  narrow roughness >= 0 (α, not Blender's R = √α); scalar/array or
                              an (x, y) tuple of them
    haziness           [β_h]  in [0, 1)
    haze_extent        [λ_h]  >= 0, in units of sqrt(α_n^x α_n^y); scalar/array or (x, y) tuple
    distribution       "GGX" (default), "BECKMANN", "MULTI_GGX" (GGX's p: the single-scatter
                       mapping, which core.multiscatter.correct_mapping corrects), or
                       "ASHIKHMIN_SHIRLEY" (Cycles' exponent n = 2/α² - 2, α in [1e-4, 1])
    smoothness         None: Eq. 7.  A number w > 0 (or per-texel array): the rational Bézier of
                       Eqs. 12-15; w = inf is exactly Eq. 7.
    alpha_max          None: Eq. 8 unbounded (the paper).  A number (Blender: 1.0): α_w is
                       limited to it and p computed from the limited α — what the renderer uses.
                       α_n above it (or, for Ashikhmin-Shirley, outside [1e-4, 1]) is invalid:
                       ValueError in strict mode, else clamped and counted.
    max_aspect         None: no limit.  A number (Blender's Metallic/Principled: 10): the longer
                       axis of α_w is shortened to max_aspect × the shorter, p follows.
    strict             None: raise ValueError on bad input for a scalar call (every input one
                       texel), clamp and count for textures.  True/False forces either.
    """
    distribution = _normalise_distribution(distribution)
    ax_in, ay_in = xy_pair(alpha, "alpha")
    lx_in, ly_in = xy_pair(haze_extent, "haze_extent")
    dtype = working_dtype(core_reflectivity, edge_tint, ax_in, ay_in, haziness, lx_in, ly_in)
    one = dtype.type(1)

    rc = colour_array(core_reflectivity, dtype, "core_reflectivity")
    g = colour_array(edge_tint, dtype, "edge_tint")
    ax = np.asarray(ax_in, dtype=dtype)
    ay = np.asarray(ay_in, dtype=dtype)
    bh = np.asarray(haziness, dtype=dtype)
    lx = np.asarray(lx_in, dtype=dtype)
    ly = np.asarray(ly_in, dtype=dtype)
    w = None if smoothness is None else np.asarray(smoothness, dtype=dtype)

    named = [("core_reflectivity", rc.shape[:-1]), ("edge_tint", g.shape[:-1]),
             ("alpha.x", ax.shape), ("alpha.y", ay.shape), ("haziness", bh.shape),
             ("haze_extent.x", lx.shape), ("haze_extent.y", ly.shape)]
    if w is not None:
        named.append(("smoothness", w.shape))
    shape = _broadcast_shape(named)
    if strict is None:
        strict = shape == ()
    # a scalar call runs on one-texel arrays: numpy 1.x would promote float32 0-d arrays mixed
    # with Python floats to float64, so scalar and texture calls would round differently
    scalar = shape == ()
    if scalar:
        shape = (1,)

    v = Validator(strict)
    big = float(np.finfo(dtype).max)
    rc = v.check(np.broadcast_to(rc, shape + (3,)), "core_reflectivity", 0.0, 1.0, texel_axis=-1)
    g = v.check(np.broadcast_to(g, shape + (3,)), "edge_tint", 0.0, 1.0, texel_axis=-1)
    ax = v.check(np.broadcast_to(ax, shape), "alpha.x", 0.0, big)
    ay = v.check(np.broadcast_to(ay, shape), "alpha.y", 0.0, big)
    bh = v.check(np.broadcast_to(bh, shape), "haziness", 0.0, 1.0, hi_open=True)
    lx = v.check(np.broadcast_to(lx, shape), "haze_extent.x", 0.0, big)
    ly = v.check(np.broadcast_to(ly, shape), "haze_extent.y", 0.0, big)
    if w is not None:
        w = np.broadcast_to(w, shape)
        nan_or_low = np.isnan(w) | (w <= 0)
        if np.any(nan_or_low):
            if strict:
                raise ValueError("smoothness (Bézier weight w) must be > 0 (None selects Eq. 7)")
            v.clamped["smoothness <= 0 or NaN"] = int(np.count_nonzero(nan_or_low))
            w = np.where(nan_or_low, np.finfo(dtype).tiny, w).astype(dtype)
    if alpha_max is not None and not (alpha_max > 0 and math.isfinite(alpha_max)):
        raise ValueError(f"alpha_max must be a finite positive number, got {alpha_max!r}")

    # -- wide roughness (Eq. 8) and the roughness the renderer will really use ---------------
    wx, wy, gm = wide_roughness(ax, ay, lx, ly)
    if np.any(wx == big) or np.any(wy == big):
        v.clamped["alpha_wide overflow"] = int(np.count_nonzero((wx == big) | (wy == big)))
    # spread = α_w - α_n exactly as Eq. 8 defines it (no cancellation).
    with np.errstate(over="ignore"):
        sx = np.minimum(lx * gm, big)
        sy = np.minimum(ly * gm, big)
    nx, ny = ax, ay
    lo, hi = (None, alpha_max)
    if distribution == "ASHIKHMIN_SHIRLEY":
        lo, hi = _AS_ALPHA_RANGE[0], min(_AS_ALPHA_RANGE[1], alpha_max or _AS_ALPHA_RANGE[1])
    if lo is not None or hi is not None:
        lo_v = dtype.type(lo if lo is not None else 0.0)
        hi_v = dtype.type(hi if hi is not None else big)
        # α_n itself outside what the renderer uses: counted (raises in strict mode) and reported
        # as the clamped value, so that α_w >= α_n holds in the output
        alpha_out = np.zeros(shape, dtype=bool)
        for side, bad_x, bad_y, bound in (("<", nx < lo_v, ny < lo_v, lo),
                                          (">", nx > hi_v, ny > hi_v, hi)):
            if bound is None:
                continue
            for axis, bad in (("x", bad_x), ("y", bad_y)):
                if v.strict and np.any(bad):
                    raise ValueError(f"haze_mapping: alpha.{axis} {side} {bound:g} (renderer limit: "
                                     + ("alpha_max" if distribution != "ASHIKHMIN_SHIRLEY" else
                                        "Cycles clamps Ashikhmin-Shirley alpha to [0.0001, 1]")
                                     + ")")
            v._count(f"alpha {side} {bound:g} (renderer limit)", bad_x | bad_y)
            alpha_out |= bad_x | bad_y
        cnx, cny = np.clip(nx, lo_v, hi_v), np.clip(ny, lo_v, hi_v)
        cwx, cwy = np.clip(wx, lo_v, hi_v), np.clip(wy, lo_v, hi_v)
        # the exact α_w exceeds the limit iff spread > limit - α_n (α_w itself may round onto it)
        over_x, over_y = sx > hi_v - cnx, sy > hi_v - cny
        limited = (over_x | over_y) & ~alpha_out
        if np.any(limited):
            v.clamped[f"alpha_wide > {float(hi_v):g} (renderer limit)"] = int(np.count_nonzero(limited))
        sx = np.where(cnx != nx, cwx - cnx, np.minimum(sx, hi_v - cnx))
        sy = np.where(cny != ny, cwy - cny, np.minimum(sy, hi_v - cny))
        nx, ny, wx, wy = cnx, cny, cwx, cwy
    if max_aspect is not None:
        k = dtype.type(max_aspect)
        if not k >= 1:
            raise ValueError(f"max_aspect must be >= 1, got {max_aspect!r}")
        long_x, long_y = wx > k * wy, wy > k * wx
        if np.any(long_x | long_y):
            v.clamped[f"alpha_wide aspect > {float(k):g}:1 (renderer limit)"] = int(
                np.count_nonzero(long_x | long_y))
            # the shortened axis stays >= α_n as long as α_n itself respects the aspect limit
            nwx = np.where(long_x, np.maximum(k * wy, nx), wx)
            nwy = np.where(long_y, np.maximum(k * wx, ny), wy)
            sx = np.where(long_x, nwx - nx, sx)
            sy = np.where(long_y, nwy - ny, sy)
            wx, wy = nwx, nwy

    # -- peak ratio (Table 2) -------------------------------------------------------------------
    px, qx = _axis_ratio(nx, wx, sx, distribution)
    py, qy = _axis_ratio(ny, wy, sy, distribution)
    # α_n = 0 on an axis: the ratio is the limit along the isotropic scaling path.
    px, qx = _zero_alpha_limit(ax, ay, lx, px, qx, distribution)
    py, qy = _zero_alpha_limit(ay, ax, ly, py, qy, distribution)
    p = np.clip(px * py, 0, 1)
    q = np.clip(qx + px * qy, 0, 1)

    # -- haze intensity (Eq. 7 / Eqs. 12-15) on the max channel --------------------------------
    rc_max = rc.max(axis=-1)
    kh, beta, omr_max, one_minus_beta = haze_terms(rc_max, p, q, bh, w)

    # -- Eq. 5 with the core's chroma: r = r_c + (1-p) k̂_h c,  c = r_c / r̂_c ------------------
    with np.errstate(divide="ignore", invalid="ignore"):
        chroma = np.where(rc_max[..., None] > 0, rc / rc_max[..., None], one)
    halo = (q * kh)[..., None]
    r = np.minimum(rc + halo * chroma, one)
    r_max = np.minimum(rc_max + q * kh, one)
    # 1 - r per channel without cancellation: 1 - c r̂ = (1 - c) + c (1 - r̂)
    one_minus_r = (1.0 - chroma) + chroma * omr_max[..., None]

    # -- Fresnel parameters --------------------------------------------------------------------
    eps = np.finfo(dtype).eps
    at_one = one_minus_r < eps
    if np.any(at_one):
        v.clamped["reflectivity at 1 (η, κ use 1 - ε)"] = int(np.count_nonzero(at_one.any(-1)))
    one_minus_r = np.maximum(one_minus_r, eps)
    eta, kappa = gulbrandsen_ior(np.minimum(r, one - eps), g, one_minus_r)
    eta_d = dielectric_ior(np.minimum(r_max, one - eps), np.maximum(omr_max, eps))

    out = HazeMapping(
        beta=beta.astype(dtype, copy=False),
        reflectivity=r.astype(dtype, copy=False),
        ior=eta.astype(dtype, copy=False),
        extinction=kappa.astype(dtype, copy=False),
        alpha=(nx, ny),
        alpha_wide=(wx.astype(dtype, copy=False), wy.astype(dtype, copy=False)),
        peak_ratio=p.astype(dtype, copy=False),
        peak_complement=q.astype(dtype, copy=False),
        halo_intensity=kh,
        reflectivity_max=r_max.astype(dtype, copy=False),
        core_reflectivity=rc,
        edge_tint=g,
        haziness=bh,
        haze_extent=(lx, ly),
        weight_narrow=(one_minus_beta[..., None] * r).astype(dtype, copy=False),
        weight_wide=(beta[..., None] * r).astype(dtype, copy=False),
        dielectric_ior=eta_d.astype(dtype, copy=False),
        distribution=distribution,
        smoothness=smoothness,
        clamped=v.clamped,
    )
    if scalar:
        out = _squeeze_texel(out)
    return out


def _squeeze_texel(out):
    """Drop the one-texel axis a scalar call ran on."""
    def sq(a):
        if isinstance(a, tuple):
            return tuple(sq(x) for x in a)
        return a[0] if isinstance(a, np.ndarray) and a.ndim and a.shape[0] == 1 else a
    fields = {f: sq(getattr(out, f)) for f in out.__dataclass_fields__
              if f not in ("distribution", "smoothness", "clamped")}
    return HazeMapping(distribution=out.distribution, smoothness=out.smoothness,
                       clamped=out.clamped, **fields)


def _zero_alpha_limit(a_this, a_other, extent, p_axis, q_axis, distribution):
    """Where α_n is 0 the per-axis ratio α_n/α_w is 0/0; use its limit.

    Both axes 0: isotropic limit 1/(1+λ).  Only this axis 0: p_axis -> 0 (λ > 0) or 1 (λ = 0)."""
    if distribution == "ASHIKHMIN_SHIRLEY":  # α >= 1e-4 there
        return p_axis, q_axis
    zero = a_this == 0
    if not np.any(zero):
        return p_axis, q_axis
    both = zero & (a_other == 0)
    lim_p = np.where(both, 1.0 / (1.0 + extent), np.where(extent > 0, 0.0, 1.0))
    lim_q = np.where(both, extent / (1.0 + extent), np.where(extent > 0, 1.0, 0.0))
    return (np.where(zero, lim_p, p_axis).astype(p_axis.dtype),
            np.where(zero, lim_q, q_axis).astype(q_axis.dtype))


# --------------------------------------------------------------------------------------------
# Inverse: physical -> perceptual
# --------------------------------------------------------------------------------------------


def inverse_haze_mapping(beta, alpha, alpha_wide, *, reflectivity=None, ior=None, extinction=None,
                         distribution="GGX", smoothness=None, alpha_max=None) -> PerceptualParameters:
    """Physical (β, α_n, α_w and r, or η and κ) -> perceptual (r_c, g, β_h, λ_h).

    Give either ``reflectivity`` (legacy / Schlick form, then g = 0) or ``ior`` and
    ``extinction`` (conductor Fresnel, Gulbrandsen inverse).  Entries that no perceptual
    parameter reproduces are clamped to the nearest representable value, flagged in ``exact``
    and counted in ``clamped``: α_w < α_n, g outside [0, 1], β_h >= 1 (outside the bounds of
    Eq. 6, or outside the Bézier's reachable set), β or r outside [0, 1], α_w at ``alpha_max``
    (its extent beyond the limit is lost), α_n outside the renderer's range, r_c = 1 (β_h has no
    effect, so it is not recoverable).  Invalid inputs — NaN, ±inf, α or α_w < 0, η <= 0, κ < 0,
    w <= 0 — are counted once per texel under their own reason, replaced by a neutral value (α:
    0, or the largest float for +inf; (η, κ): (1, 0); w: the smallest normal float) and flagged;
    no output is ever NaN or inf.
    """
    distribution = _normalise_distribution(distribution)
    ax_in, ay_in = xy_pair(alpha, "alpha")
    wx_in, wy_in = xy_pair(alpha_wide, "alpha_wide")
    if (reflectivity is None) == (ior is None):
        raise ValueError("give either reflectivity or ior (+ extinction)")
    values = [beta, ax_in, ay_in, wx_in, wy_in, reflectivity, ior, extinction]
    dtype = working_dtype(*[x for x in values if x is not None])
    v = Validator(strict=False)
    big = np.finfo(dtype).max
    # invalid inputs (NaN, ±inf, negative where meaningless): counted once per texel and reason,
    # replaced by a neutral value, flagged not exact; the consequences are not counted again
    invalid_inputs = []

    def screen(reason, ok):
        bad = ~ok
        if np.any(bad):
            invalid_inputs.append((reason, bad))
        return bad

    if reflectivity is not None:
        r = colour_array(reflectivity, dtype, "reflectivity")
        g = np.zeros_like(r)
    else:
        eta = colour_array(ior, dtype, "ior")
        kap = colour_array(0.0 if extinction is None else extinction, dtype, "extinction")
        with np.errstate(invalid="ignore"):
            bad = screen("ior is NaN, <= 0 or infinite", np.isfinite(eta) & (eta > 0)) \
                | screen("extinction is NaN, negative or infinite", np.isfinite(kap) & (kap >= 0))
        if np.any(bad):  # treated as (η, κ) = (1, 0): no reflection
            eta = np.where(bad, dtype.type(1), eta)
            kap = np.where(bad, dtype.type(0), kap)
        r, g = gulbrandsen_inverse(eta, kap)
        r = r.astype(dtype)
        g = g.astype(dtype)
    b = np.asarray(beta, dtype=dtype)
    ax, ay = np.asarray(ax_in, dtype=dtype), np.asarray(ay_in, dtype=dtype)
    wx, wy = np.asarray(wx_in, dtype=dtype), np.asarray(wy_in, dtype=dtype)
    named = [("beta", b.shape), ("alpha.x", ax.shape), ("alpha.y", ay.shape),
             ("alpha_wide.x", wx.shape), ("alpha_wide.y", wy.shape),
             ("reflectivity", r.shape[:-1]), ("edge_tint", g.shape[:-1])]
    w = None if smoothness is None else np.asarray(smoothness, dtype=dtype)
    if w is not None:
        named.append(("smoothness", w.shape))
    shape = _broadcast_shape(named)
    r = np.broadcast_to(r, shape + (3,))
    g = np.broadcast_to(g, shape + (3,))
    b, ax, ay, wx, wy = (np.broadcast_to(x, shape) for x in (b, ax, ay, wx, wy))
    inexact = np.zeros(shape, dtype=bool)
    invalid = np.zeros(shape, dtype=bool)

    def per_texel(mask):
        mask = np.asarray(mask)
        if mask.ndim > len(shape):
            mask = mask.any(axis=-1)
        return np.broadcast_to(mask, shape)

    def flag(reason, mask, primary=False):
        nonlocal inexact, invalid
        mask = per_texel(mask)
        if not primary:
            mask = mask & ~invalid
        n = int(np.count_nonzero(mask))
        if n:
            v.clamped[reason] = v.clamped.get(reason, 0) + n
            inexact = inexact | mask
            if primary:
                invalid = invalid | mask

    for reason, mask in invalid_inputs:
        flag(reason, mask, primary=True)
    with np.errstate(invalid="ignore"):
        for name, (x, y) in (("alpha", (ax, ay)), ("alpha_wide", (wx, wy))):
            bad = ~(np.isfinite(x) & (x >= 0)) | ~(np.isfinite(y) & (y >= 0))
            flag(f"{name} is NaN, negative or infinite", bad, primary=True)
        # NaN and negative -> 0, +inf -> the largest finite value
        ax, ay, wx, wy = (np.where(np.isposinf(x), big, np.where(x >= 0, x, 0)).astype(dtype)
                          for x in (ax, ay, wx, wy))
    if w is not None:
        w = np.broadcast_to(w, shape)
        bad_w = np.isnan(w) | (w <= 0)
        flag("smoothness <= 0 or NaN", bad_w, primary=True)
        w = np.where(bad_w, np.finfo(dtype).tiny, w).astype(dtype)

    bad_b = ~((b >= 0) & (b <= 1))
    flag("beta outside [0, 1]", bad_b, primary=True)
    b = np.clip(np.nan_to_num(b), 0, 1)
    bad_r = ~((r >= 0) & (r <= 1))
    flag("reflectivity outside [0, 1]", bad_r, primary=reflectivity is not None)
    r = np.clip(np.nan_to_num(r), 0, 1)
    # rounding leaves g a few ulps outside [0, 1] for points on the manifold's edges (g = 0, 1);
    # recovering g from η divides by n_d - n_m ~ 1/(1-r), so the slack grows like ε/(1-r)
    eps = np.finfo(dtype).eps
    tol = 64 * eps / np.maximum(1.0 - r, eps)
    g = np.where((g < 0) & (g >= -tol), 0.0, np.where((g > 1) & (g <= 1 + tol), 1.0, g)).astype(dtype)
    bad_g = ~((g >= 0) & (g <= 1))
    flag("edge tint outside [0, 1] (not on Gulbrandsen's manifold)", bad_g)
    g = np.clip(np.nan_to_num(g), 0, 1)

    # -- haze extent: invert Eq. 8 ------------------------------------------------------------
    gm = np.sqrt(ax) * np.sqrt(ay)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        lx = np.where(gm > 0, (wx - ax) / gm, 0.0).astype(dtype)
        ly = np.where(gm > 0, (wy - ay) / gm, 0.0).astype(dtype)
    flag("alpha_wide < alpha (negative haze extent)", (lx < 0) | (ly < 0))
    flag("alpha_wide > alpha = 0 (Eq. 8 gives alpha_wide = 0 there)", (gm <= 0) & ((wx > ax) | (wy > ay)))
    lx, ly = np.maximum(lx, 0), np.maximum(ly, 0)
    flag("haze extent overflows (alpha_wide / alpha beyond the float range)",
         np.isinf(lx) | np.isinf(ly))
    lx, ly = np.minimum(lx, big), np.minimum(ly, big)
    limit = alpha_max
    if distribution == "ASHIKHMIN_SHIRLEY":  # Cycles clamps AS roughness to <= 1 anyway
        limit = min(alpha_max or _AS_ALPHA_RANGE[1], _AS_ALPHA_RANGE[1])
        flag(f"alpha < {_AS_ALPHA_RANGE[0]:g} (renderer limit)",
             (ax < _AS_ALPHA_RANGE[0]) | (ay < _AS_ALPHA_RANGE[0]))
    if limit is not None:
        flag(f"alpha > {limit:g} (renderer limit)", (ax > limit) | (ay > limit))
        flag(f"alpha_wide at the renderer limit {limit:g} (extent beyond it lost)",
             (wx >= limit) | (wy >= limit))
    wx, wy = np.maximum(wx, ax), np.maximum(wy, ay)

    probe = haze_mapping(np.zeros(shape + (3,), dtype), 0.0, (ax, ay), np.zeros(shape, dtype), (lx, ly),
                         distribution=distribution, alpha_max=alpha_max, strict=False)
    p, q = probe.peak_ratio, probe.peak_complement

    # -- reflectivity: r̂_c = r̂ (1 - (1-p) β)  (Eq. 3 at θ_d = 0 with Eq. 4) --------------------
    r_max = r.max(axis=-1)
    core_gain = 1.0 - q * b
    rc = r * core_gain[..., None]
    rc_max = r_max * core_gain

    # -- haziness: solve β = β_h / (σ + (1-p) β_h) for β_h, σ = r̂_c / t (see haze_intensity) ------
    with np.errstate(divide="ignore", invalid="ignore"):
        if smoothness is None:
            sigma = np.where(_on_positivity_side(rc_max, 1.0 - rc_max, p, q), p,
                             rc_max * q / (1.0 - rc_max))
        else:
            with np.errstate(over="ignore"):
                m = 1.0 / w  # inf where 1/w overflows: the w -> 0 limit, only β = 0 is reachable
            omr = 1.0 - rc_max
            d = np.where(p <= 0.5, rc_max - p, q - omr)
            s = np.sqrt(rc_max * omr)
            den = rc_max * q + p * omr + np.hypot(d, np.where(s > 0, m * s, 0.0))
            sigma = den / (2.0 * omr)
        bh = np.where(core_gain > 0, b * sigma / core_gain, np.inf)
    # r̂_c = 1 within rounding (the forward mapping evaluates Fresnel at r = 1 - ε there)
    at_one = rc_max >= 1.0 - 4 * eps
    no_effect = at_one & (b > 0)
    flag("core reflectivity 1 leaves no room for haze (haziness not recoverable)", no_effect)
    # Exactly reproduced but not unique: several perceptual points map to this physical one.
    unique = ~(at_one  # k̂_h = 0 for every β_h
               | (r_max <= 0.0)  # r = 0: η = 1, κ = 0 whatever g
               | (gm <= 0.0))  # α_n = 0: α_w = 0 for every λ_h
    bh = np.where(np.isnan(bh) | (rc_max >= 1.0), 0.0, bh)
    over = bh >= 1.0
    flag("haziness >= 1 (beyond the energy/positivity bounds or the Bézier's reach)", over)
    bh = np.where(over, np.nextafter(dtype.type(1), dtype.type(0)), bh).astype(dtype)

    return PerceptualParameters(core_reflectivity=rc.astype(dtype), edge_tint=g.astype(dtype),
                                alpha=(ax, ay), haziness=bh, haze_extent=(lx, ly),
                                exact=~inexact, unique=unique & ~inexact, clamped=v.clamped)
