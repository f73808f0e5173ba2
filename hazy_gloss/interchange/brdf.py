# SPDX-License-Identifier: GPL-3.0-or-later
"""Microfacet BRDFs in numpy, written independently of the shader code (bpy-free).

Everything is evaluated in the lobes' tangent frame: n = +z, the tangent (α_x) along +x.
Directions are unit vectors shaped (..., 3); colours come out shaped (..., 3).

- :func:`microfacet` — D G₂ / (4 |ωi·n| |ωo·n|) for GGX (Trowbridge-Reitz, anisotropic) or
  Beckmann, with the height-correlated Smith term G₂ = 1 / (1 + Λ(ωi) + Λ(ωo)) (what Cycles
  uses); single scattering only.
- Fresnel factors: the exact unpolarised conductor and dielectric reflectances, Schlick with
  F90, OpenPBR's / MaterialX's F82-tint (Hoffman 2023), and the generalized Schlick with the
  real-Fresnel remap that Blender's Principled BSDF uses for Specular Tint.
- :class:`Lobes` — Σ_k w_k f_k(ωi, ωo) · F(ωi·h): Eq. 1 of Barla et al. 2018 when the weights are
  (1-β, β) and F is shared; the other engines' models are built from the same pieces
  (hazy_gloss/interchange/engines.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import constants as K

__all__ = ("microfacet", "fresnel_conductor", "fresnel_dielectric", "schlick", "f82_tint",
           "principled_dielectric", "Lobe", "Lobes", "half_vector_quadrature", "compare",
           "fresnel_conductor_at")


# --------------------------------------------------------------------------------------------
# Microfacet lobes
# --------------------------------------------------------------------------------------------


def _erf(x):
    """erf to 1.5e-7 (Abramowitz & Stegun 7.1.26); numpy has none and math.erf is scalar."""
    s = np.sign(x)
    a = np.abs(x)
    t = 1.0 / (1.0 + 0.3275911 * a)
    y = 1.0 - (((((1.061405429 * t - 1.453152027) * t) + 1.421413741) * t - 0.284496736) * t
               + 0.254829592) * t * np.exp(-a * a)
    return s * y


def _lambda(w, ax, ay, distribution):
    """Smith Λ(ω) of the anisotropic distribution (ω in the tangent frame, ω_z > 0)."""
    wz = np.maximum(w[..., 2], 1e-12)
    s2 = (ax * ax * w[..., 0] ** 2 + ay * ay * w[..., 1] ** 2) / (wz * wz)  # α² tan² θ (projected)
    if distribution == "BECKMANN":
        a = 1.0 / np.sqrt(np.maximum(s2, 1e-300))
        return np.where(a > 30.0, 0.0, 0.5 * (_erf(a) - 1.0) + np.exp(-a * a) / (2.0 * a * math.sqrt(math.pi)))
    return 0.5 * (np.sqrt(1.0 + s2) - 1.0)


def _ndf(h, ax, ay, distribution):
    hx, hy, hz = h[..., 0], h[..., 1], np.maximum(h[..., 2], 1e-12)
    if distribution == "BECKMANN":
        e = (hx * hx / (ax * ax) + hy * hy / (ay * ay)) / (hz * hz)
        return np.exp(-e) / (math.pi * ax * ay * hz ** 4)
    d = hx * hx / (ax * ax) + hy * hy / (ay * ay) + hz * hz
    return 1.0 / (math.pi * ax * ay * d * d)


def microfacet(wi, wo, ax, ay, distribution="GGX"):
    """D(h) G₂(ωi, ωo) / (4 cos θi cos θo) without Fresnel; 0 below the horizon.

    ``distribution``: "GGX" (also used for MULTI_GGX: single scattering) or "BECKMANN"."""
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    h = wi + wo
    h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
    ci, co = wi[..., 2], wo[..., 2]
    ok = (ci > 0) & (co > 0)
    ax = float(ax)
    ay = float(ay)
    dist = "BECKMANN" if distribution == "BECKMANN" else "GGX"
    g2 = 1.0 / (1.0 + _lambda(wi, ax, ay, dist) + _lambda(wo, ax, ay, dist))
    f = _ndf(h, ax, ay, dist) * g2 / (4.0 * np.maximum(ci, 1e-12) * np.maximum(co, 1e-12))
    return np.where(ok, f, 0.0)


# --------------------------------------------------------------------------------------------
# Fresnel
# --------------------------------------------------------------------------------------------


def fresnel_conductor(cos_d, eta, kappa):
    """Unpolarised reflectance of a conductor η + iκ (per channel) at cos θ_d: (..., 3)."""
    c = np.clip(np.asarray(cos_d, dtype=np.float64), 1e-9, 1.0)[..., None]
    eta = np.asarray(eta, dtype=np.float64)
    k = np.asarray(kappa, dtype=np.float64)
    c2 = c * c
    s2 = 1.0 - c2
    e2, k2 = eta * eta, k * k
    t0 = e2 - k2 - s2
    a2b2 = np.sqrt(t0 * t0 + 4.0 * e2 * k2)
    a = np.sqrt(np.maximum(0.5 * (a2b2 + t0), 0.0))
    rs = (a2b2 + c2 - 2.0 * a * c) / (a2b2 + c2 + 2.0 * a * c)
    t1 = a2b2 * c2 + s2 * s2
    t2 = 2.0 * a * c * s2
    rp = rs * (t1 - t2) / (t1 + t2)
    return 0.5 * (rs + rp)


def fresnel_conductor_at(c, eta, kappa):
    """:func:`fresnel_conductor` for one channel and one cos θ_d, in Python floats: reading a
    library maps tens of thousands of materials, where numpy's per-call cost is ten times the
    arithmetic (tests/pure/test_import_surfaces.py checks the two agree)."""
    c = min(max(float(c), 1e-9), 1.0)
    c2 = c * c
    s2 = 1.0 - c2
    e2, k2 = eta * eta, kappa * kappa
    t0 = e2 - k2 - s2
    a2b2 = math.sqrt(t0 * t0 + 4.0 * e2 * k2)
    a = math.sqrt(max(0.5 * (a2b2 + t0), 0.0))
    rs = (a2b2 + c2 - 2.0 * a * c) / (a2b2 + c2 + 2.0 * a * c)
    t1 = a2b2 * c2 + s2 * s2
    t2 = 2.0 * a * c * s2
    return 0.5 * (rs + rs * (t1 - t2) / (t1 + t2))


def fresnel_dielectric(cos_d, eta):
    """Unpolarised reflectance of a dielectric interface of relative index η (scalar): (...)."""
    c = np.clip(np.asarray(cos_d, dtype=np.float64), 0.0, 1.0)
    eta = float(eta)
    g2 = eta * eta - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return np.where(g2 > 0, 0.5 * a * a * (1.0 + b * b), 1.0)


def schlick(cos_d, f0, f90=1.0):
    """F0 + (F90 - F0)(1 - cos θ_d)⁵ (per channel)."""
    c = np.clip(np.asarray(cos_d, dtype=np.float64), 0.0, 1.0)[..., None]
    f0 = np.asarray(f0, dtype=np.float64)
    return f0 + (np.asarray(f90, dtype=np.float64) - f0) * (1.0 - c) ** 5


def f82_tint(cos_d, f0, tint):
    """F82-tint (MaterialX generalized_schlick color82, OpenPBR metal): Schlick(μ) - a μ (1-μ)⁶
    with a = Schlick(μ̄)(1 - tint) / (μ̄ (1-μ̄)⁶), μ̄ = 1/7, so F(μ̄) = tint · Schlick(μ̄)."""
    mu = K.F82_MU
    f0 = np.asarray(f0, dtype=np.float64)
    s_bar = f0 + (1.0 - f0) * (1.0 - mu) ** 5
    a = s_bar * (1.0 - np.asarray(tint, dtype=np.float64)) / (mu * (1.0 - mu) ** 6)
    c = np.clip(np.asarray(cos_d, dtype=np.float64), 0.0, 1.0)[..., None]
    return schlick(cos_d, f0) - a * c * (1.0 - c) ** 6


def principled_dielectric(cos_d, eta, tint=(1.0, 1.0, 1.0)):
    """Blender's Principled BSDF dielectric reflection Fresnel with Specular Tint (Specular IOR
    Level 0.5): F = t F0 + (1 - t F0) (F_η(θ) - F0) / (1 - F0), F0 = ((η-1)/(η+1))²; t = 1
    gives the real Fresnel F_η."""
    f0 = ((float(eta) - 1.0) / (float(eta) + 1.0)) ** 2
    fr = fresnel_dielectric(cos_d, eta)[..., None]
    t0 = np.asarray(tint, dtype=np.float64) * f0
    return t0 + (1.0 - t0) * (fr - f0) / (1.0 - f0)


# --------------------------------------------------------------------------------------------
# Weighted sums of lobes with one Fresnel
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Lobe:
    weight: object  #: scalar or RGB
    alpha_x: float
    alpha_y: float
    distribution: str = "GGX"


@dataclass(frozen=True)
class Lobes:
    """f(ωi, ωo) = Σ_k w_k f_k(ωi, ωo) · F(ωi·h).  ``fresnel``: callable(cos θ_d) -> (..., 3)."""

    lobes: tuple
    fresnel: object
    notes: tuple = field(default_factory=tuple)

    def __call__(self, wi, wo):
        wi = np.asarray(wi, dtype=np.float64)
        wo = np.asarray(wo, dtype=np.float64)
        h = wi + wo
        h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
        cos_d = np.clip(np.sum(wi * h, axis=-1), 0.0, 1.0)
        total = 0.0
        for lobe in self.lobes:
            total = total + np.asarray(lobe.weight, dtype=np.float64) * \
                microfacet(wi, wo, lobe.alpha_x, lobe.alpha_y, lobe.distribution)[..., None]
        return total * self.fresnel(cos_d)


# --------------------------------------------------------------------------------------------
# Quadrature over the hemisphere of light directions
# --------------------------------------------------------------------------------------------


def _direction(theta, phi):
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def half_vector_quadrature(view, alpha_min, *, n_theta=320, n_phi=96):
    """Light directions ωi over the hemisphere for one view ωo, with solid-angle weights.

    Parametrised by the half vector h (θ_h on a geometric grid from alpha_min/20 to π/2 plus 0,
    φ_h uniform), ωi = 2 (ωo·h) h - ωo, dωi = 4 |ωo·h| sin θ_h dθ_h dφ_h (midpoint rule in
    log θ_h): samples cluster where sharp lobes live, so a core of α = 1e-3 is resolved as
    well as a halo of α = 1.  Directions below the horizon get weight 0.  Returns (ωi, weights)."""
    wo = np.asarray(view, dtype=np.float64)
    lo = max(float(alpha_min) / 20.0, 1e-6)
    edges = np.concatenate([[0.0], np.geomspace(lo, math.pi / 2, n_theta)])
    th = 0.5 * (edges[1:] + edges[:-1])
    dth = np.diff(edges)
    ph = (np.arange(n_phi) + 0.5) * (2 * math.pi / n_phi)
    T, P = np.meshgrid(th, ph, indexing="ij")
    h = _direction(T, P)
    hw = np.sum(h * wo, axis=-1)
    wi = 2.0 * hw[..., None] * h - wo
    w = 4.0 * np.abs(hw) * np.sin(T) * dth[:, None] * (2 * math.pi / n_phi)
    w = np.where((wi[..., 2] > 1e-6) & (hw > 0), w, 0.0)
    return wi.reshape(-1, 3), w.reshape(-1)


#: View directions of the error measurement: (θ_o, φ_o) in degrees.
VIEWS = tuple([(0.0, 0.0)] + [(t, p) for t in (20.0, 40.0, 60.0, 75.0) for p in (0.0, 45.0, 90.0)])


def compare(reference, candidate, alpha_min, *, views=VIEWS, n_theta=320, n_phi=96):
    """BRDF error of ``candidate`` against ``reference`` (callables (ωi, ωo) -> (..., 3)).

    For each view ωo in ``views`` the light directions cover the hemisphere
    (:func:`half_vector_quadrature`); the error is taken on f cos θi (reflected radiance for
    unit irradiance), all channels.  Returns dict(max=, mean=, peak=):
      max  = max over views of  max_ωi |Δ| / max_ωi (f_ref cos θi)   (peak-normalised worst case)
      mean = Σ_views ∫ |Δ| cos θi dωi / Σ_views ∫ f_ref cos θi dωi     (relative L1)
      peak = |Δ f(n, n)| / f_ref(n, n) at normal incidence (max channel)."""
    worst = 0.0
    num = 0.0
    den = 0.0
    for t, p in views:
        wo = _direction(math.radians(t), math.radians(p))
        wi, w = half_vector_quadrature(wo, alpha_min, n_theta=n_theta, n_phi=n_phi)
        wo_b = np.broadcast_to(wo, wi.shape)
        cos_i = np.maximum(wi[:, 2], 0.0)[:, None]
        fr = reference(wi, wo_b) * cos_i
        fc = candidate(wi, wo_b) * cos_i
        d = np.abs(fc - fr)
        ref_max = float(np.max(fr))
        if ref_max > 0:
            worst = max(worst, float(np.max(d[w > 0])) / ref_max)
        num += float(np.sum(d * w[:, None]))
        den += float(np.sum(fr * w[:, None]))
    n = np.array([[0.0, 0.0, 1.0]])
    pr = reference(n, n)[0]
    pc = candidate(n, n)[0]
    ch = int(np.argmax(pr))
    peak = abs(float(pc[ch] - pr[ch])) / float(pr[ch]) if pr[ch] > 0 else 0.0
    return dict(max=worst, mean=num / den if den > 0 else 0.0, peak=peak)
