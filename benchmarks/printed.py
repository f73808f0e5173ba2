# SPDX-License-Identifier: GPL-3.0-or-later
"""A direct numpy transcription of the paper's printed formulas, in a chosen dtype, to show what
the stable forms of hazy_gloss.core.mapping buy (docs/numerics.md).

- p from Table 2 (GGX/Beckmann: α_n^x α_n^y / (α_w^x α_w^y)) and 1 - p by subtraction;
- Eq. 7 as printed;
- Eqs. 12-14: u = (b - √Δ) / (2(b - 1)), with the paper's Taylor expansion of u in a window of
  a few ulp around b = 1 (the window implementations ship: |b - 1| <= WINDOW_ULPS · ε);
- Eq. 15 for k_h, Eq. 5 and Eq. 4;
- Gulbrandsen 2014 as printed: η = g(1-r)/(1+r) + (1-g)(1+√r)/(1-√r),
  κ = sqrt((r(η+1)² - (η-1)²) / (1-r)).
Same Blender limits as the product (α <= alpha_max, aspect <= max_aspect) so only the
arithmetic differs.
"""
from __future__ import annotations

import numpy as np

WINDOW_ULPS = 4


def bezier_u(rc, p, w, dtype):
    """Eqs. 12-14 with the Taylor window around b = 1 (r_c = r*_c)."""
    t = np.dtype(dtype).type
    rc, p, w = t(rc), t(p), t(w)
    one, two, four = t(1), t(2), t(4)
    b = two * (rc * (one - w) + w * p)
    eps = np.finfo(dtype).eps
    with np.errstate(all="ignore"):
        if abs(b - one) <= WINDOW_ULPS * eps:
            r_star = (t(0.5) - w * p) / (one - w)
            return (two * w * p - one - (four * w * w * p * p - four * w * w * p + one) * (rc - r_star)) \
                / (two * (w - one))
        delta = b * b - four * (b - one) * rc
        return (b - np.sqrt(delta)) / (two * (b - one))


def bezier_kh(u, w, bh, dtype):
    t = np.dtype(dtype).type
    u, w, bh = t(u), t(w), t(bh)
    one, two = t(1), t(2)
    with np.errstate(all="ignore"):
        return two * (one - u) * u * w * bh / ((one - u) ** 2 + two * (one - u) * u * w + u * u)


def gulbrandsen(r, g, dtype):
    t = np.dtype(dtype).type
    r = np.asarray(r, dtype)
    g = np.asarray(g, dtype)
    one = t(1)
    with np.errstate(all="ignore"):
        s = np.sqrt(r)
        eta = g * (one - r) / (one + r) + (one - g) * (one + s) / (one - s)
        kappa = np.sqrt((r * (eta + one) ** 2 - (eta - one) ** 2) / (one - r))
    return eta, kappa


def mapping(rc, g, ax, ay, bh, lx, ly, w, dtype, alpha_max=1.0, max_aspect=10.0):
    """One case (scalars; rc, g RGB) -> dict of the fields the catalogue compares."""
    t = np.dtype(dtype).type
    one = t(1)
    rc = np.asarray(rc, dtype)
    g = np.asarray(g, dtype)
    ax, ay, bh, lx, ly = (t(x) for x in (ax, ay, bh, lx, ly))
    with np.errstate(all="ignore"):
        root = np.sqrt(ax * ay)
        wx = min(ax + lx * root, t(alpha_max))
        wy = min(ay + ly * root, t(alpha_max))
        k = t(max_aspect)
        if wx > k * wy:
            wx = max(k * wy, ax)
        elif wy > k * wx:
            wy = max(k * wx, ay)
        p = (ax * ay) / (wx * wy)
        q = one - p
        rch = rc.max()
        if w is None:
            kh = bh * rch / p if rch <= p else bh * (one - rch) / (one - p)
        else:
            u = bezier_u(rch, p, w, dtype)
            kh = bezier_kh(u, w, bh, dtype)
        rhat = rch + q * kh
        r = rhat / rch * rc if rch > 0 else np.full(3, rhat, dtype)
        beta = kh / rhat
        eps = np.finfo(dtype).eps
        eta, kappa = gulbrandsen(np.minimum(r, one - t(eps)), g, dtype)
    return {"beta": beta, "halo_intensity": kh, "peak_ratio": p, "alpha_wide_x": wx,
            "alpha_wide_y": wy, "reflectivity": r, "ior": eta, "extinction": kappa}
