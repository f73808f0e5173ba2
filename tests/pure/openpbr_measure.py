# SPDX-License-Identifier: GPL-3.0-or-later
"""Measured: Cycles' Principled against MaterialX's OpenPBR 1.1.1 (docs/interchange.md §5).

The numbers docs/interchange.md cites for a layered export (scripts/layer_interchange_report.py)
and the checks of tests/pure/test_layered_network.py: the layer's constants as
blender/model/layer.py maps them, the Fresnel of each renderer, the peak drift MaterialX's energy
compensation causes, OpenPBR's coat darkening and tint.  Measurement code, not shipped.
"""
import math

import numpy as np

from hazy_gloss.core.lobes import describe
from hazy_gloss.interchange.brdf import Lobe, Lobes, compare, fresnel_dielectric


def _f0(eta):
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def _ior_from_f0(f):
    s = math.sqrt(min(max(f, 0.0), 1.0 - 1e-12))
    return (1.0 + s) / (1.0 - s)


def principled_fresnel(cos_d, eta, tint=(1.0, 1.0, 1.0)):
    """Cycles' Principled dielectric reflection (generalized Schlick with exponent -η):
    t F0 + (1 - t F0) saturate((F_η - F0) / (1 - F0)): max(F_η, F0) for t = 1."""
    f0 = _f0(float(eta))
    s = np.clip((fresnel_dielectric(cos_d, eta) - f0) / (1.0 - f0), 0.0, 1.0)[..., None]
    t0 = np.asarray(tint, dtype=np.float64) * f0
    return t0 + (1.0 - t0) * s


def openpbr_fresnel(cos_d, eta, tint=(1.0, 1.0, 1.0)):
    """MaterialX 1.39's dielectric_bsdf reflection: tint · F_η (the tint scales every angle)."""
    return np.asarray(tint, dtype=np.float64) * fresnel_dielectric(cos_d, eta)[..., None]


def layer_part(rc, roughness=0.3, haziness=0.5, haze_extent=5.0, distribution="GGX", lobe=None,
               tint=None, anisotropy=0.0):
    """One part of a layer as the layer maps its constants (blender/model/layer.py _mapping: kind
    DIELECTRIC for Principled parts, ``lobe`` "F82_TINT" for a metal part, "COAT" for the coat):
    dict(beta, alpha, alpha_wide, r, r_c)."""
    ms = None
    if lobe is not None and distribution == "MULTI_GGX":
        ms = dict(lobe=lobe)
        if tint is not None:
            ms["tint"] = tuple(np.broadcast_to(np.asarray(tint, float), 3))
    rc = tuple(float(x) for x in np.broadcast_to(np.asarray(rc, float), 3))
    d = describe("DIELECTRIC", distribution, core_reflectivity=rc, roughness=roughness,
                 anisotropy=anisotropy, haziness=haziness, haze_extent=haze_extent,
                 anisotropic=anisotropy != 0.0, strict=False, multiscatter=ms)
    m = d.mapping
    return dict(beta=float(d.beta), alpha=tuple(map(float, m.alpha)),
                alpha_wide=tuple(map(float, m.alpha_wide)), r=tuple(map(float, m.reflectivity)),
                r_c=rc)


def hazy_dielectric(ior=1.5, tint=(1.0, 1.0, 1.0), level=0.5, roughness=0.3, haziness=0.5,
                    haze_extent=5.0, distribution="GGX"):
    """A layered Principled dielectric as the layer writes its constants: layer_part's lobes with
    eta (the specular's effective η' after the raise and Specular IOR Level), eta_core (the
    user's, haziness 0), ior_hazy (what the layer writes on IOR) and tint."""
    tint = np.asarray(tint, dtype=np.float64)
    rc = _f0(ior) * 2.0 * level * tint
    part = layer_part(rc, roughness, haziness, haze_extent, distribution)
    gain = max(part["r"]) / max(float(np.max(rc)), 1e-30)
    ior_hazy = _ior_from_f0(_f0(ior) * gain)
    part.update(eta=_ior_from_f0(_f0(ior_hazy) * 2.0 * level), eta_core=_ior_from_f0(_f0(ior) * 2.0 * level),
                ior_hazy=ior_hazy, tint=tuple(map(float, tint)))
    return part


def fresnel_gap(eta):
    """max over angles of (F0 - F_η)/F0: where Cycles' max(F_η, F0) lifts the exact Fresnel."""
    mu = np.linspace(0.0, 1.0, 2001)
    f0 = _f0(float(eta))
    return float(np.max(np.maximum(f0 - fresnel_dielectric(mu, eta), 0.0)) / f0)


def specular_error(lobes, *, tint=None, n_theta=160, n_phi=48):
    """brdf.compare of the hazy specular (both lobes, β, single scattering) with MaterialX's
    Fresnel against Cycles' Principled's; ``lobes``: hazy_dielectric(...)."""
    tint = lobes["tint"] if tint is None else tint
    b = lobes["beta"]
    ls = (Lobe(1.0 - b, *lobes["alpha"]), Lobe(b, *lobes["alpha_wide"]))
    eta = lobes["eta"]
    ref = Lobes(ls, lambda c: principled_fresnel(c, eta, tint))
    got = Lobes(ls, lambda c: openpbr_fresnel(c, eta, tint))
    return compare(ref, got, min(min(lobes["alpha"]), min(lobes["alpha_wide"])), n_theta=n_theta,
                   n_phi=n_phi)


def materialx_albedo(cos_v, alpha):
    """MaterialX's GGX directional albedo E(μ, α) for F0 = F90 = 1 (mx_ggx_dir_albedo_analytic)."""
    x, y = float(cos_v), float(alpha)
    x2, y2 = x * x, y * y
    c = np.array([[0.1003, 0.9345, 1.0, 1.0], [-0.6303, -2.323, -1.765, 0.2281],
                  [9.748, 2.229, 8.263, 15.94], [-2.038, -3.748, 11.53, -55.83],
                  [29.34, 1.424, 28.96, 13.08], [-8.245, -0.7684, -7.507, 41.26],
                  [-26.44, 1.436, -36.11, 54.9], [19.99, 0.2913, 15.86, 300.2],
                  [-5.448, 0.6286, 33.37, -285.1]])
    terms = np.array([1.0, x, y, x * y, x2, y2, x2 * y, x * y2, x2 * y2])
    r = terms @ c
    a, b = np.clip(r[:2] / r[2:], 0.0, 1.0)
    return float(a + b)


def materialx_peak_drift(part):
    """How far a MaterialX renderer moves the hazy part's peak f(n, n) from the haze-free one's:
    its reference shaders compensate every GGX lobe by 1 + F (1-E)/E (E: mx_ggx_dir_albedo at
    μ = 1, α = √(α_x α_y)), Cycles' GGX not at all and its Multiscatter GGX its own way (which
    the layer's mapping follows).  ``part``: layer_part / hazy_dielectric.  hazy / haze-free - 1
    (the max channel)."""
    def comp(alpha, f):
        a = math.sqrt(alpha[0] * alpha[1])
        e = materialx_albedo(1.0, a)
        return 1.0 + f * (1.0 - e) / e
    ch = int(np.argmax(part["r_c"]))
    r, rc = part["r"][ch], part["r_c"][ch]
    an, aw, b = part["alpha"], part["alpha_wide"], part["beta"]
    hazy = r * ((1.0 - b) * comp(an, r) / (an[0] * an[1]) + b * comp(aw, r) / (aw[0] * aw[1]))
    plain = rc * comp(an, rc) / (an[0] * an[1])
    return hazy / plain - 1.0


def coat_darkening_factor(base_albedo, coat_ior):
    """The base darkening OpenPBR applies under a full coat ((1 - K)/(1 - E K), K = 1 -
    (1 - F0)/η², MaterialX's open_pbr_surface; coat_darkening = 0 turns it off — Cycles has
    none beyond the coat's albedo)."""
    f0 = _f0(float(coat_ior))
    k = 1.0 - (1.0 - f0) / (float(coat_ior) ** 2)
    e = np.asarray(base_albedo, dtype=np.float64)
    return (1.0 - k) / (1.0 - e * k)


def coat_tint_factor(tint, coat_ior, cos_i):
    """(Cycles' tint^(1/cos θ_t), OpenPBR's constant tint) of the base under a coat at cos θ_i."""
    ct = math.sqrt(max(1.0 - (1.0 - cos_i * cos_i) / (float(coat_ior) ** 2), 1e-12))
    t = np.asarray(tint, dtype=np.float64)
    return t ** (1.0 / ct), t
