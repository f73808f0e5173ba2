# SPDX-License-Identifier: GPL-3.0-or-later
"""A plain blend of two lobes (OpenPBR 1.2's specular haze) as a haze layer's parameters
(bpy-free).

OpenPBR 1.2 draws its base specular as (1 - w) f_core + w f_haze: two GGX lobes with one
Fresnel F (F(0) = F0), the haze lobe at r_haze = lerp(r_core, 1, ξ) with the core's
anisotropy, each energy-compensated.  A haze layer on a Principled BSDF (blender/model/layer.py) draws
(1 - β) f_n + β f_w with F(0) = r, where (β, r, α_w) come from the paper's mapping of the
user's BSDF (F(0) = r_c) and the haze parameters (β_h, λ) — Eq. 3-8 of Barla et al. 2018, with
Cycles' Multiscatter GGX correction where the lobes are Multiscatter GGX (docs/mapping.md).
So the blend is reproduced exactly when

    β = w,   r = F0,   α_w = α_haze,

and :func:`solve` finds the user's r_c and (β_h, λ) that give it:

- λ from Eq. 8 per axis: λ_x = (α_w,x - α_n,x) / √(α_n,x α_n,y) (the halo keeps the core's
  aspect, so λ_x / λ_y = α_n,x / α_n,y);
- for GGX (single scattering) r_c and β_h in closed form: the peak kept by the layer is
  r_c = F0 [(1 - w) + w p], p = α_n,x α_n,y / (α_w,x α_w,y) (core.inverse_haze_mapping);
- under Multiscatter GGX, where each lobe has Cycles' energy factor S(α, F), from that start by
  fixed-point on r_c (r_c ← r_c F0 / r) and secant steps on β_h, each step the layer's own
  forward mapping (core.lobes.describe, as blender/model/layer.py calls it), to 1e-10.

The blend is reachable unless it is brighter at its peak than the energy bounds of Eq. 6 allow
(β_h would be ≥ 1) or its F0 would need r_c > 1; then β_h is capped at MAX_HAZINESS and the
residual is returned (measured in tests/pure/test_import_surfaces.py and docs/interchange.md §2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import constants as K
from ..core.conventions import alpha_from_roughness
from ..core.lobes import describe
from ..core.mapping import inverse_haze_mapping

__all__ = ("extent", "forward", "solve", "Solution")


def extent(rough, aniso, rough_wide):
    """(λ_x, λ_y) of Eq. 8 for a halo of roughness ``rough_wide`` with the core's anisotropy."""
    ax, ay = (float(a) for a in alpha_from_roughness(rough, aniso))
    wx, wy = (float(a) for a in alpha_from_roughness(rough_wide, aniso))
    g = math.sqrt(ax) * math.sqrt(ay)
    if g <= 0.0:
        return 0.0, 0.0
    return max(wx - ax, 0.0) / g, max(wy - ay, 0.0) / g


def forward(part, dist, rc, rough, aniso, rot, haziness, lam, tint=(1.0, 1.0, 1.0)):
    """(β, r, wide roughness) a haze layer renders on a Principled part with core F(0) ``rc``:
    the layer's constant path (blender/model/layer_values.py values(): describe, then the
    dielectric's F(0) raised by the max-channel gain, the metal's Base Color set to the mapping's
    r)."""
    anisotropic = aniso != 0.0 or lam[0] != lam[1]
    ms = dict(lobe="F82_TINT", tint=tuple(tint)) if part == "METAL" else None
    d = describe("DIELECTRIC", dist, core_reflectivity=tuple(rc), edge_tint=(0.0, 0.0, 0.0),
                 roughness=rough, anisotropy=aniso, rotation=rot, haziness=haziness,
                 haze_extent=tuple(lam), anisotropic=anisotropic, strict=False, multiscatter=ms)
    m = d.mapping
    if part == "METAL":
        r = np.asarray(m.reflectivity, float)
    else:
        core_max = float(np.max(m.core_reflectivity))
        gain = float(m.reflectivity_max) / max(core_max, 1e-30)
        r = gain * np.asarray(rc, float)
    wide = d.wide if d.wide is not None else d.narrow
    return float(d.beta), r, float(wide.roughness)


@dataclass
class Solution:
    """``haziness``, ``haze_extent``, ``core_reflectivity`` (the user's F(0) per channel) and the
    residual of the blend they render: ``beta_error`` (absolute), ``reflectivity_error``
    (relative), ``evaluations`` of the forward mapping, ``capped`` (β_h at its bound)."""

    haziness: float
    haze_extent: tuple
    core_reflectivity: tuple
    beta_error: float
    reflectivity_error: float
    evaluations: int
    capped: bool

    @property
    def error(self):
        return max(self.beta_error, self.reflectivity_error)


def solve(part, dist, f0, beta, rough, aniso, rough_wide, *, rot=0.0, tint=(1.0, 1.0, 1.0),
          tol=1e-10, max_iter=40):
    """The haze parameters and core F(0) whose layer renders the blend (``beta``, F(0) ``f0``,
    core roughness / anisotropy, halo roughness ``rough_wide``).  ``part``: "DIELECTRIC" (the
    core's F(0) keeps the chroma of f0) or "METAL" (per channel)."""
    f0 = np.clip(np.asarray(f0, float), 0.0, 1.0)
    beta = min(max(float(beta), 0.0), 1.0)
    lam = extent(rough, aniso, rough_wide)
    if beta <= 0.0 or max(lam) <= 0.0 or float(np.max(f0)) <= 0.0:
        return Solution(0.0, lam, tuple(map(float, f0)), 0.0, 0.0, 0, False)
    ax, ay = (float(a) for a in alpha_from_roughness(rough, aniso))
    wx, wy = (float(a) for a in alpha_from_roughness(rough_wide, aniso))
    # the paper's mapping inverted in closed form: exact for single scattering
    inv = inverse_haze_mapping(beta, (ax, ay), (wx, wy), reflectivity=f0, distribution="GGX",
                               alpha_max=K.ALPHA_MAX)
    rc = np.clip(np.asarray(inv.core_reflectivity, float), 1e-12, 1.0)
    bh = min(max(float(inv.haziness), 0.0), K.MAX_HAZINESS)
    if part != "METAL":  # one IOR: the chroma of F0 is kept
        rc = float(np.max(rc)) * f0 / max(float(np.max(f0)), 1e-30)
    rc = np.asarray(rc, float)
    # r_c = c w: the chroma w of the user's F(0) (a dielectric: F0's, one IOR raises every
    # channel alike; a metal: per channel, updated by fixed point below) and its scale c.
    # Newton on x = (β_h, log c) with residuals (β - w_haze, log(r/F0) of the brightest channel),
    # Jacobian by finite differences of the forward mapping, steps halved until the residual
    # shrinks.  β is the brightest channel's (Eq. 4), so the other channels follow from their
    # own r_c alone.
    k = int(np.argmax(f0))
    pos = f0 > 0
    w = np.where(pos, np.maximum(rc, 1e-12), 0.0) / max(float(rc[k] if np.ndim(rc) else rc), 1e-30) \
        if part == "METAL" else f0 / max(float(f0[k]), 1e-30)
    evals = 0

    def run(x):
        nonlocal evals
        bh_ = min(max(float(x[0]), 0.0), K.MAX_HAZINESS)
        rc_ = np.clip(math.exp(min(float(x[1]), 0.0)) * w, 0.0, 1.0)
        b_, r_, _ = forward(part, dist, rc_, rough, aniso, rot, bh_, lam, tint)
        evals += 1
        lr = math.log(max(float(r_[k]), 1e-300) / float(f0[k]))
        return np.array([b_ - beta, lr]), b_, r_, bh_, rc_

    x = np.array([bh, math.log(max(float(np.max(rc)), 1e-12))])
    res, b_got, r_got, bh, rc = run(x)
    for _outer in range(12):
        for _ in range(max_iter):
            if float(np.max(np.abs(res))) <= tol:
                break
            jac = np.empty((2, 2))
            for j in range(2):
                h = 1e-7 * max(abs(x[j]), 1.0)
                xh = x.copy()
                xh[j] += h if not (j == 0 and x[0] + h > K.MAX_HAZINESS) else -h
                jac[:, j] = (run(xh)[0] - res) / (xh[j] - x[j])
            try:
                dx = np.linalg.solve(jac, -res)
            except np.linalg.LinAlgError:
                dx = np.linalg.lstsq(jac, -res, rcond=None)[0]
            t = 1.0
            for _ in range(30):
                xn = x + t * dx
                xn[0] = min(max(xn[0], 0.0), K.MAX_HAZINESS)
                got = run(xn)
                if float(np.max(np.abs(got[0]))) < float(np.max(np.abs(res))):
                    break
                t *= 0.5
            else:
                break  # no step reduces the residual: the closest the layer can render
            moved = not np.allclose(xn, x, rtol=0.0, atol=1e-16)
            x, (res, b_got, r_got, bh, rc) = xn, got
            if not moved:
                break
        if part != "METAL":
            break
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(pos & (r_got > 0), f0 / r_got, 1.0)
        if float(np.max(np.abs(ratio - 1.0))) <= tol:
            break
        w = np.clip(w * ratio, 0.0, None)
        w[k] = 1.0
        res, b_got, r_got, bh, rc = run(x)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = float(np.max(np.abs(np.where(f0 > 0, r_got / f0 - 1.0, 0.0))))
    capped = bh >= K.MAX_HAZINESS and b_got < beta - 1e-6
    return Solution(float(bh), lam, tuple(float(c) for c in np.broadcast_to(rc, (3,))),
                    abs(beta - b_got), rel, evals, capped)
