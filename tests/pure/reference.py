# SPDX-License-Identifier: GPL-3.0-or-later
"""Independent high-precision reference for the haze mapping (Barla, Pacanowski & Vangorp 2018).

Every formula below is transcribed from the PAPER as printed (section / equation numbers in the
comments), evaluated with mpmath at ``DPS`` (80) significant digits, so that cancellation in the
printed forms (the Bézier root of Eq. 12 near b = 1, Gulbrandsen's κ near r = 1, 1 - p near
p = 1) costs nothing measurable at float64 resolution.  It deliberately does NOT reuse the
rearranged, cancellation-free forms of ``hazy_gloss.core.mapping``: agreement between the two is
the point of the test.

Inputs are Python floats (or numpy scalars); ``mpf(float(x))`` is exact for float64 and float32
values, so the reference for a float32 call is the exact mapping of the float32 inputs.

Conventions the paper leaves open (all documented in the add-on's API):
* α_n = 0 on both axes (GGX-like distributions): p is the limit along the isotropic scaling path,
  1 / ((1+λx)(1+λy)); one axis 0: that axis' ratio -> 0 (λ > 0) or 1 (λ = 0).
* r = 1 (r̂_c = 1): the Gulbrandsen mapping is singular, η and κ are evaluated at r = 1 - ε
  (ε = machine epsilon of the working dtype), as the API documents.
* r̂_c = 0: β is the limit β_h / (p + (1-p) β_h) (same limit for Eq. 7 and the Bézier).
* ASHIKHMIN_SHIRLEY: as Cycles, α_n and α_w are clamped to [1e-4, 1] before n = 2/α² - 2.
* alpha_max: α_n and α_w are limited to it (what the renderer is given) before computing p.
"""
from __future__ import annotations

import math

import mpmath

DPS = 80
_mp = mpmath.mp


def mpf(x):
    """Exact promotion of a float64/float32 value (or an mpf) to an mpf."""
    if isinstance(x, mpmath.mpf):
        return x
    return _mp.mpf(float(x))


def _rgb(x):
    if isinstance(x, (list, tuple)):
        assert len(x) == 3
        return [mpf(v) for v in x]
    try:
        seq = list(x)  # numpy arrays
    except TypeError:
        return [mpf(x)] * 3
    if len(seq) == 1:
        return [mpf(seq[0])] * 3
    assert len(seq) == 3
    return [mpf(v) for v in seq]


def _pair(v):
    if isinstance(v, (list, tuple)):
        return mpf(v[0]), mpf(v[1])
    return mpf(v), mpf(v)


# ------------------------------------------------------------------------------------------------
# Eq. 8 and Table 2
# ------------------------------------------------------------------------------------------------


def wide_roughness(ax, ay, lx, ly):
    """Eq. 8: (α_w^x, α_w^y) = (α_n^x, α_n^y) + (λ^x, λ^y) sqrt(α_n^x α_n^y)."""
    root = _mp.sqrt(ax * ay)
    return ax + lx * root, ay + ly * root


def _as_exponent(a):
    """Cycles' Ashikhmin-Shirley exponent n = 2/α² - 2 (α already clamped to [1e-4, 1])."""
    return 2 / (a * a) - 2


def peak_ratio(nx, ny, wx, wy, distribution):
    """Table 2.  GGX / Beckmann (Walter / Ward / Cook-Torrance rows): p = αx_n αy_n / (αx_w αy_w).
    Ashikhmin-Shirley: p = sqrt((n^x_w+1)(n^y_w+1)) / sqrt((n^x_n+1)(n^y_n+1))."""
    if distribution == "ASHIKHMIN_SHIRLEY":
        nxn, nyn = _as_exponent(nx), _as_exponent(ny)
        nxw, nyw = _as_exponent(wx), _as_exponent(wy)
        return _mp.sqrt((nxw + 1) * (nyw + 1) / ((nxn + 1) * (nyn + 1)))
    return (nx * ny) / (wx * wy)


def _ggx_zero_alpha_axis(a_this, a_other, lam, a_wide):
    if a_this != 0:
        return a_this / a_wide
    if a_other == 0:
        return 1 / (1 + lam)
    return _mp.mpf(0) if lam > 0 else _mp.mpf(1)


# ------------------------------------------------------------------------------------------------
# Eq. 7 and Appendix (Eqs. 12-15)
# ------------------------------------------------------------------------------------------------


def haze_intensity_eq7(rc, p, bh):
    """Eq. 7: k_h = β_h r_c / p if r_c <= p else β_h (1 - r_c) / (1 - p)."""
    if rc <= p:
        return bh * rc / p if p != 0 else _mp.mpf(0)
    return bh * (1 - rc) / (1 - p)


def bezier_u(rc, p, w, form="printed"):
    """Eqs. 12-14 as printed: b = 2(r_c(1-w) + wp), Δ = b² - 4(b-1) r_c,
    u = (b - sqrt Δ) / (2(b-1)); exactly u = r_c at b = 1 (the quadratic (b-1)u² - bu + r_c = 0
    degenerates to the linear -u + r_c = 0).  ``form="conjugate"`` returns the algebraically
    identical 2 r_c / (b + sqrt Δ) (used only to cross-check the reference itself)."""
    b = 2 * (rc * (1 - w) + w * p)
    delta = b * b - 4 * (b - 1) * rc
    if delta < 0:  # cannot happen for r_c, p in [0, 1]; guard against a silent complex sqrt
        raise ArithmeticError(f"negative discriminant {delta} for rc={rc}, p={p}, w={w}")
    sq = _mp.sqrt(delta)
    if form == "conjugate":
        den = b + sq
        return 2 * rc / den if den != 0 else _mp.mpf(0)
    if b == 1:
        return rc
    return (b - sq) / (2 * (b - 1))


def haze_intensity_bezier(rc, p, bh, w, form="printed"):
    """Eq. 15: k_h = 2(1-u)u w β_h / ((1-u)² + 2(1-u)u w + u²)."""
    u = bezier_u(rc, p, w, form)
    return 2 * (1 - u) * u * w * bh / ((1 - u) ** 2 + 2 * (1 - u) * u * w + u * u)


# ------------------------------------------------------------------------------------------------
# Gulbrandsen 2014
# ------------------------------------------------------------------------------------------------


def gulbrandsen(r, g):
    """η = g(1-r)/(1+r) + (1-g)(1+√r)/(1-√r);  κ = sqrt((r(η+1)² - (η-1)²)/(1-r)).
    κ = 0 exactly at g = 0 (the numerator vanishes identically there)."""
    s = _mp.sqrt(r)
    eta = g * (1 - r) / (1 + r) + (1 - g) * (1 + s) / (1 - s)
    if g == 0:
        return eta, _mp.mpf(0)
    num = r * (eta + 1) ** 2 - (eta - 1) ** 2
    if num < 0:  # only possible through rounding for g within ~10^-DPS of 0
        num = _mp.mpf(0)
    return eta, _mp.sqrt(num / (1 - r))


def gulbrandsen_reflectivity(eta, kappa):
    """Normal-incidence Fresnel reflectance of a conductor: ((η-1)² + κ²)/((η+1)² + κ²)."""
    return ((eta - 1) ** 2 + kappa ** 2) / ((eta + 1) ** 2 + kappa ** 2)


# ------------------------------------------------------------------------------------------------
# Algorithm HAZEMAPPING (§2.4)
# ------------------------------------------------------------------------------------------------


def _flatten(result):
    out = []
    for key in sorted(result):
        v = result[key]
        out.extend(v if isinstance(v, (list, tuple)) else [v])
    return out


def _dynamic_range_digits(*values):
    """Digits the printed formulas can lose to cancellation: at most the decimal dynamic range
    of the (finite, non-zero) inputs, e.g. 300 for r_c = 1e-300 (Eq. 12's b - sqrt Δ then
    cancels to 300 digits).  Starting there makes the doubling check below meaningful (two
    totally cancelled evaluations would otherwise 'agree' at 0)."""
    mags = []

    def walk(v):
        if v is None or isinstance(v, str):
            return
        if isinstance(v, (list, tuple)):
            for x in v:
                walk(x)
            return
        try:
            seq = list(v)
        except TypeError:
            x = abs(float(v))
            if x != 0 and math.isfinite(x):
                mags.append(abs(math.log10(x)))
            return
        for x in seq:
            walk(x)

    for v in values:
        walk(v)
    return int(math.ceil(max(mags, default=0.0)))


def _agree(a, b, digits):
    if a == b:
        return True
    return abs(a - b) <= abs(b) * _mp.mpf(10) ** (-digits)


def haze_mapping(core_reflectivity, edge_tint, alpha, haziness, haze_extent, *,
                 distribution="GGX", smoothness=None, alpha_max=None, eps=2.0 ** -52, dps=DPS,
                 bezier_form="printed", max_dps=2560, agree_digits=40):
    """Reference HAZEMAPPING.  Returns a dict of mpf (RGB fields are lists of 3 mpf).

    The printed formulas cancel catastrophically in a few corners (Eq. 12 as r_c -> 0 or 1,
    Gulbrandsen's η - 1 as r -> 0, κ as g -> 0), losing up to ~log10(1/r_c) digits.  So the
    mapping is evaluated at ``dps`` and 2·``dps`` digits, doubling (Ziv's strategy) until every
    output agrees to ``agree_digits`` digits between consecutive precisions.  A quantity that
    keeps shrinking with the precision (|x| < 10^(-dps/2) at ``max_dps``) is an exact zero of
    the formula (e.g. k_h at r_c = 1 in the Bézier) and is returned as 0."""
    args = (core_reflectivity, edge_tint, alpha, haziness, haze_extent)
    dps = dps + _dynamic_range_digits(*args, smoothness, alpha_max)
    kw = dict(distribution=distribution, smoothness=smoothness, alpha_max=alpha_max, eps=eps,
              bezier_form=bezier_form)
    lo = haze_mapping_at(*args, dps=dps, **kw)
    while True:
        hi = haze_mapping_at(*args, dps=2 * dps, **kw)
        with _mp.workdps(2 * dps):
            ok = all(_agree(a, b, agree_digits) for a, b in zip(_flatten(lo), _flatten(hi)))
        if ok:
            return hi
        if 2 * dps >= max_dps:
            break
        dps *= 2
        lo = hi
    # not converged: zero out the quantities at the noise level of the precision
    with _mp.workdps(2 * dps):
        noise = _mp.mpf(10) ** (-dps // 2)
        fixed = {}
        for key, v in hi.items():
            vals = v if isinstance(v, (list, tuple)) else [v]
            lov = lo[key] if isinstance(lo[key], (list, tuple)) else [lo[key]]
            new = []
            for a, b in zip(lov, vals):
                if _agree(a, b, agree_digits):
                    new.append(b)
                elif abs(b) < noise:
                    new.append(_mp.mpf(0))
                else:
                    raise ArithmeticError(f"reference did not converge for {key}: {a} vs {b}")
            fixed[key] = type(v)(new) if isinstance(v, (list, tuple)) else new[0]
        return fixed


def haze_mapping_at(core_reflectivity, edge_tint, alpha, haziness, haze_extent, *,
                    distribution="GGX", smoothness=None, alpha_max=None, eps=2.0 ** -52,
                    dps=DPS, bezier_form="printed"):
    """One evaluation of the printed formulas at ``dps`` digits (see :func:`haze_mapping`)."""
    with _mp.workdps(dps):
        rc = _rgb(core_reflectivity)
        g = _rgb(edge_tint)
        ax, ay = _pair(alpha)
        lx, ly = _pair(haze_extent)
        bh = mpf(haziness)

        wx, wy = wide_roughness(ax, ay, lx, ly)  # Eq. 8
        nx, ny = ax, ay
        if distribution == "ASHIKHMIN_SHIRLEY":
            lo, hi = _mp.mpf(1e-4), _mp.mpf(1)
            if alpha_max is not None:
                hi = min(hi, mpf(alpha_max))
        else:
            lo, hi = _mp.mpf(0), (mpf(alpha_max) if alpha_max is not None else None)
        clip = (lambda a: min(max(a, lo), hi)) if hi is not None else (lambda a: max(a, lo))
        nx, ny, wx, wy = clip(nx), clip(ny), clip(wx), clip(wy)

        if distribution != "ASHIKHMIN_SHIRLEY" and (nx == 0 or ny == 0):
            p = (_ggx_zero_alpha_axis(nx, ny, lx, wx) * _ggx_zero_alpha_axis(ny, nx, ly, wy))
        else:
            p = peak_ratio(nx, ny, wx, wy, distribution)  # Table 2
        q = 1 - p

        rc_hat = max(rc)  # ‖r_c‖∞
        if smoothness is None or math.isinf(float(smoothness)):
            kh = haze_intensity_eq7(rc_hat, p, bh)  # Eq. 7
        else:
            kh = haze_intensity_bezier(rc_hat, p, bh, mpf(smoothness), bezier_form)  # Eqs. 12-15

        r_hat = rc_hat + (1 - p) * kh  # Eq. 5 on the max channel
        if rc_hat > 0:
            r = [r_hat / rc_hat * c for c in rc]  # r = (r̂ / r̂_c) r_c
            beta = kh / r_hat  # Eq. 4
        else:
            r = [r_hat] * 3
            den = p + (1 - p) * bh
            beta = bh / den if den != 0 else _mp.mpf(0)

        one_m = 1 - mpf(eps)
        eta, kappa = [], []
        for ri, gi in zip(r, g):
            e, k = gulbrandsen(min(ri, one_m), gi)
            eta.append(e)
            kappa.append(k)
        rh = min(r_hat, one_m)
        eta_d = (1 + _mp.sqrt(rh)) / (1 - _mp.sqrt(rh))  # §2.4, dielectric case

        return {
            "beta": beta,
            "reflectivity": r,
            "ior": eta,
            "extinction": kappa,
            "alpha_wide": (wx, wy),
            "peak_ratio": p,
            "peak_complement": q,
            "halo_intensity": kh,
            "reflectivity_max": r_hat,
            "weight_narrow": [(1 - beta) * ri for ri in r],
            "weight_wide": [beta * ri for ri in r],
            "dielectric_ior": eta_d,
        }


def gulbrandsen_at(r, g, dps=DPS, max_dps=2560, agree_digits=40):
    """Stage reference: Gulbrandsen (η, κ) at given float r, g (scalars), with the same
    precision doubling as :func:`haze_mapping` (η - 1 cancels as r -> 0, κ's numerator as
    g -> 0)."""
    with _mp.workdps(dps):
        lo = gulbrandsen(mpf(r), mpf(g))
    while True:
        with _mp.workdps(2 * dps):
            hi = gulbrandsen(mpf(r), mpf(g))
            if all(_agree(a, b, agree_digits) for a, b in zip(lo, hi)):
                return hi
        if 2 * dps >= max_dps:
            raise ArithmeticError(f"Gulbrandsen reference did not converge at r={r}, g={g}")
        dps *= 2
        lo = hi


#: Scalar fields and RGB fields of the result compared by the tests.
SCALAR_FIELDS = ("beta", "peak_ratio", "peak_complement", "halo_intensity", "reflectivity_max",
                 "dielectric_ior")
RGB_FIELDS = ("reflectivity", "ior", "extinction", "weight_narrow", "weight_wide")
