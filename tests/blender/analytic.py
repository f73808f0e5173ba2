# SPDX-License-Identifier: GPL-3.0-or-later
"""Independent numpy evaluation of microfacet BRDFs, for checking renders (no bpy, no project code).

Written from the formulas, not from hazy_gloss code, so that a render can be compared against
something that does not share its mistakes:

- GGX / Trowbridge-Reitz and Beckmann normal distributions (anisotropic, Walter et al. 2007);
- height-correlated Smith masking-shadowing G2 = 1 / (1 + Λ(wi) + Λ(wo)) (Heitz 2014), which is
  what Cycles uses; GGX Λ exact, Beckmann Λ with Walter's rational approximation (as Cycles);
- exact unpolarised Fresnel for conductors (complex index η + iκ) and dielectrics, and the
  approximate conductor Fresnel that Blender 4.5's Metallic BSDF uses;
- the paper's two-lobe BRDF (Barla, Pacanowski & Vangorp 2018, Eq. 1):
      f_r(wi, wo) = ((1 - β) f_n(wi, wo) + β f_w(wi, wo)) F(θd),
  with f_n, f_w microfacet lobes without Fresnel, D G / (4 cosθi cosθo), and θd the angle
  between the half vector and wi.

Conventions: directions are unit vectors shaped (..., 3) in the local shading frame (x = tangent,
y = bitangent, z = normal), pointing away from the surface.  Roughness is α (Blender's
Roughness R maps to α = R²).  Everything broadcasts; colours come out shaped (..., 3).
"""
from __future__ import annotations

import numpy as np

__all__ = (
    "direction",
    "half_vector",
    "ggx_D",
    "ggx_lambda",
    "beckmann_D",
    "beckmann_lambda",
    "smith_G2",
    "conductor_fresnel",
    "conductor_fresnel_approx",
    "dielectric_fresnel",
    "microfacet_lobe",
    "microfacet_brdf",
    "two_lobe_brdf",
)


def direction(theta_deg, phi_deg=0.0):
    """Unit vector at polar angle θ from the normal (+z) and azimuth φ from the tangent (+x)."""
    t = np.radians(np.asarray(theta_deg, dtype=np.float64))
    p = np.radians(np.asarray(phi_deg, dtype=np.float64))
    return np.stack(np.broadcast_arrays(np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)),
                    axis=-1)


def _as_vec(w):
    return np.asarray(w, dtype=np.float64)


def half_vector(wi, wo):
    h = _as_vec(wi) + _as_vec(wo)
    return h / np.linalg.norm(h, axis=-1, keepdims=True)


def _slope_sq(alpha_x, alpha_y, w):
    """(wx/αx)² + (wy/αy)² over wz² — the squared 'stretched' tangent used by D."""
    w = _as_vec(w)
    return ((w[..., 0] / alpha_x) ** 2 + (w[..., 1] / alpha_y) ** 2) / w[..., 2] ** 2


def ggx_D(alpha_x, alpha_y, h):
    """GGX: D(h) = 1 / (π αx αy (hx²/αx² + hy²/αy² + hz²)²) for hz > 0, else 0."""
    h = _as_vec(h)
    hz = h[..., 2]
    s = (h[..., 0] / alpha_x) ** 2 + (h[..., 1] / alpha_y) ** 2 + hz ** 2
    return np.where(hz > 0, 1.0 / (np.pi * alpha_x * alpha_y * s * s), 0.0)


def beckmann_D(alpha_x, alpha_y, h):
    """Beckmann: D(h) = exp(-(hx²/αx² + hy²/αy²)/hz²) / (π αx αy hz⁴) for hz > 0, else 0."""
    h = _as_vec(h)
    hz = h[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        val = np.exp(-_slope_sq(alpha_x, alpha_y, h)) / (np.pi * alpha_x * alpha_y * hz ** 4)
    return np.where(hz > 0, val, 0.0)


def _alpha_tan_sq(alpha_x, alpha_y, w):
    """α(w)² tan²θ with the projected roughness: (αx² wx² + αy² wy²) / wz²."""
    w = _as_vec(w)
    return ((alpha_x * w[..., 0]) ** 2 + (alpha_y * w[..., 1]) ** 2) / w[..., 2] ** 2


def ggx_lambda(alpha_x, alpha_y, w):
    """GGX Smith Λ(w) = (sqrt(1 + α(w)² tan²θ) - 1) / 2 (exact)."""
    return 0.5 * (np.sqrt(1.0 + _alpha_tan_sq(alpha_x, alpha_y, w)) - 1.0)


def beckmann_lambda(alpha_x, alpha_y, w):
    """Beckmann Smith Λ, Walter's rational approximation in a = 1/(α(w) tanθ):
    Λ = (1 - 1.259a + 0.396a²)/(3.535a + 2.181a²) for a < 1.6, else 0."""
    s = _alpha_tan_sq(alpha_x, alpha_y, w)
    with np.errstate(divide="ignore"):
        a = 1.0 / np.sqrt(s)
    b = np.minimum(a, 1.6)  # the formula is only used below 1.6 (avoids inf - inf at the normal)
    lam = (1.0 - 1.259 * b + 0.396 * b * b) / (3.535 * b + 2.181 * b * b)
    return np.where(a < 1.6, lam, 0.0)


_LAMBDA = {"GGX": ggx_lambda, "BECKMANN": beckmann_lambda}
_D = {"GGX": ggx_D, "BECKMANN": beckmann_D}


def smith_G2(alpha_x, alpha_y, wi, wo, distribution="GGX"):
    """Height-correlated Smith masking-shadowing: G2 = 1 / (1 + Λ(wi) + Λ(wo))."""
    lam = _LAMBDA[distribution.upper()]
    return 1.0 / (1.0 + lam(alpha_x, alpha_y, wi) + lam(alpha_x, alpha_y, wo))


def conductor_fresnel(cos_theta, eta, kappa):
    """Exact unpolarised Fresnel reflectance of a conductor with complex index n = η + iκ.

    rs = (c - s)/(c + s), rp = (n² c - s)/(n² c + s), s = sqrt(n² - sin²θ) (principal branch,
    which is the decaying wave since Im n² >= 0);  F = (|rs|² + |rp|²)/2.
    ``cos_theta`` shaped (...), ``eta``/``kappa`` broadcast against it (use [..., None] for RGB).
    κ = 0 gives the exact dielectric Fresnel (including total internal reflection for η < 1)."""
    c = np.asarray(cos_theta, dtype=np.float64)
    n = np.asarray(eta, dtype=np.float64) + 1j * np.asarray(kappa, dtype=np.float64)
    n2 = n * n
    sin2 = 1.0 - c * c
    s = np.sqrt(n2 - sin2 + 0j)
    rs = (c - s) / (c + s)
    rp = (n2 * c - s) / (n2 * c + s)
    return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


def conductor_fresnel_approx(cos_theta, eta, kappa):
    """The approximate conductor Fresnel of PBRT v2 (exact only at normal incidence), which is
    what Blender 4.5 LTS's Metallic BSDF (PHYSICAL_CONDUCTOR) renders; 5.0 uses the exact one:
        t = η² + κ², R∥ = (t c² - 2ηc + 1)/(t c² + 2ηc + 1), R⊥ = (t - 2ηc + c²)/(t + 2ηc + c²),
        F = (R∥ + R⊥)/2."""
    c = np.asarray(cos_theta, dtype=np.float64)
    eta = np.asarray(eta, dtype=np.float64)
    kappa = np.asarray(kappa, dtype=np.float64)
    t = eta * eta + kappa * kappa
    c2 = c * c
    r_par = (t * c2 - 2.0 * eta * c + 1.0) / (t * c2 + 2.0 * eta * c + 1.0)
    r_perp = (t - 2.0 * eta * c + c2) / (t + 2.0 * eta * c + c2)
    return 0.5 * (r_par + r_perp)


def dielectric_fresnel(cos_theta, eta):
    """Exact unpolarised dielectric Fresnel (Walter et al. 2007 form), 1 under total internal
    reflection:  g = sqrt(η² - 1 + c²),
    F = ½ ((g-c)/(g+c))² (1 + ((c(g+c) - 1)/(c(g-c) + 1))²)."""
    c = np.abs(np.asarray(cos_theta, dtype=np.float64))
    eta = np.asarray(eta, dtype=np.float64)
    g2 = eta * eta - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) / (g + c)
    b = (c * (g + c) - 1.0) / (c * (g - c) + 1.0)
    return np.where(g2 > 0, 0.5 * a * a * (1.0 + b * b), 1.0)


def microfacet_lobe(wi, wo, alpha_x, alpha_y=None, distribution="GGX"):
    """A microfacet lobe without Fresnel: D(h) G2(wi, wo) / (4 cosθi cosθo), 0 below the horizon."""
    if alpha_y is None:
        alpha_y = alpha_x
    wi, wo = _as_vec(wi), _as_vec(wo)
    h = half_vector(wi, wo)
    d = _D[distribution.upper()](alpha_x, alpha_y, h)
    g = smith_G2(alpha_x, alpha_y, wi, wo, distribution)
    ci, co = wi[..., 2], wo[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        val = d * g / (4.0 * ci * co)
    return np.where((ci > 0) & (co > 0), val, 0.0)


_FRESNEL = {"exact": conductor_fresnel, "approx": conductor_fresnel_approx}


def _fresnel_rgb(wi, wo, eta, kappa, fresnel="exact"):
    """Conductor Fresnel at cosθd = h·wi, per channel, shaped (..., 3)."""
    h = half_vector(wi, wo)
    cos_d = np.clip(np.sum(h * _as_vec(wi), axis=-1), 0.0, 1.0)
    f = _FRESNEL[fresnel](cos_d[..., None], np.asarray(eta, np.float64),
                          np.asarray(kappa, np.float64))
    return np.broadcast_to(f, f.shape[:-1] + (3,)) if f.shape[-1] == 1 else f


def microfacet_brdf(wi, wo, alpha_x, alpha_y=None, *, eta, kappa, distribution="GGX",
                    fresnel="exact"):
    """Single-lobe conductor BRDF D G F / (4 cosθi cosθo), F at cosθd = h·wi; RGB (..., 3).

    This is what Cycles' Metallic BSDF (PHYSICAL_CONDUCTOR, GGX or BECKMANN; Base Color and
    Edge Tint unused) evaluates: with ``fresnel="exact"`` in Blender 5.0, with
    ``fresnel="approx"`` (:func:`conductor_fresnel_approx`) in Blender 4.5."""
    lobe = microfacet_lobe(wi, wo, alpha_x, alpha_y, distribution)
    return lobe[..., None] * _fresnel_rgb(wi, wo, eta, kappa, fresnel)


def two_lobe_brdf(wi, wo, *, beta, alpha_n, alpha_w, eta, kappa, distribution="GGX",
                  fresnel="exact"):
    """The paper's Eq. 1: f_r = ((1 - β) f_n + β f_w) F(θd), RGB (..., 3).

    alpha_n, alpha_w: α of the narrow (core) and wide (halo) lobes, each a scalar or an (x, y)
    pair.  eta, kappa: per-channel conductor index (κ = 0 for a dielectric).  ``fresnel`` as in
    :func:`microfacet_brdf`."""
    anx, any_ = (alpha_n if isinstance(alpha_n, (tuple, list)) else (alpha_n, alpha_n))
    awx, awy = (alpha_w if isinstance(alpha_w, (tuple, list)) else (alpha_w, alpha_w))
    fn = microfacet_lobe(wi, wo, anx, any_, distribution)
    fw = microfacet_lobe(wi, wo, awx, awy, distribution)
    mix = (1.0 - beta) * fn + beta * fw
    return mix[..., None] * _fresnel_rgb(wi, wo, eta, kappa, fresnel)
