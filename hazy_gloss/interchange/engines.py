# SPDX-License-Identifier: GPL-3.0-or-later
"""What a hazy material becomes in other engines, and how far each is from Eq. 1 (bpy-free).

For one hazy material (its :class:`hazy_gloss.core.lobes.HazyLobes`, from ``describe``) this
gives the closest parameters of

- **Unity HDRP StackLit** (Hazy Gloss parametrisation): Unity implements this paper's mapping
  itself with the smooth Bézier of w = 10 (Eqs. 12-15), a Schlick Fresnel with fresnel0 = r and
  a cap of ``hazyGlossMaxDielectricF0`` (0.25) for dielectrics.  Its perceptual inputs are found
  with :func:`hazy_gloss.core.inverse_haze_mapping` at w = 10, so its lobes and mix equal ours;
  what is lost is the conductor Fresnel (edge tint).
- **Unreal Engine Substrate** slab: Roughness, Anisotropy, SecondRoughness,
  SecondRoughnessWeight, one F0/F90 Schlick pair.  The second lobe shares the slab's anisotropy
  (one Anisotropy input), so a halo rounder than the core is not representable; F90 is a
  least-squares fit of the conductor Fresnel.
- **Filament** (released): one specular lobe — secondRoughness / secondRoughnessWeight are only
  announced in NEW_RELEASE_NOTES (apiLevel 2) with no documented combination, so they are not
  modelled.  Two fits: the core lobe alone (the halo is lost) and a clear coat (fixed F0 0.04,
  isotropic, V_Kelemen) carrying the weaker of the two lobes over a base carrying the other.
- **OpenPBR 1.2** (dev_1.2 branch, unreleased): specular_haze = β, specular_haze_spread ξ with
  r_haze = lerp(r_core, 1, ξ) in roughness, the haze's anisotropy tied to the core's; metals use
  F82-tint (F0 = base_color, specular_color fitted at μ̄ = 1/7), dielectrics the real Fresnel of
  specular_ior tinted by specular_color.

:func:`engine_parameters` returns them with the BRDF error of each against Eq. 1 measured on
the material (brdf.compare: max and mean over the hemisphere of light directions for 13 views).
Every model is single scattering with the exact height-correlated Smith term: the engines'
multiple-scattering compensation and their approximations of G are not modelled (they are the
same for Eq. 1 itself), so the figures isolate what each parametrisation can represent.
Specular reflection only: the diffuse base is the same Lambertian in every engine.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .. import constants as K
from ..core.mapping import haze_mapping, inverse_haze_mapping
from .brdf import (Lobe, Lobes, compare, f82_tint, fresnel_conductor, principled_dielectric,
                   schlick)

__all__ = ("EngineFit", "reference", "engine_parameters", "ENGINES", "unity_stacklit",
           "ue_substrate", "filament", "openpbr_12", "openpbr_anisotropy", "f82_tint_fit",
           "schlick_f90_fit")

ENGINES = ("unity_stacklit", "ue_substrate", "filament", "openpbr_1_2")


@dataclass
class EngineFit:
    """One engine's closest parameters for a hazy material and the model they render."""

    engine: str
    parameters: dict
    model: object  #: callable (ωi, ωo) -> f (..., 3), specular part
    notes: list = field(default_factory=list)
    exact: bool = False  #: the engine's model equals Eq. 1 for this material (up to rounding)
    error: dict = field(default_factory=dict)  #: brdf.compare(reference, model)
    alternatives: dict = field(default_factory=dict)  #: other fits (Filament: clear coat)


# --------------------------------------------------------------------------------------------
# The reference: Eq. 1 from the renderer-neutral description
# --------------------------------------------------------------------------------------------


def _f(x):
    return float(np.asarray(x))


def _rgb(x):
    return np.asarray(x, dtype=np.float64).reshape(-1)[:3] * np.ones(3)


def _alphas(lobes):
    m = lobes.mapping
    return (tuple(_f(a) for a in m.alpha), tuple(_f(a) for a in m.alpha_wide))


def _fit_inputs(lobes):
    """What every engine fit starts from: the core's and the wide lobe's (α_x, α_y), β and the
    reflectivity r (RGB)."""
    return _alphas(lobes), _f(lobes.beta), _rgb(lobes.mapping.reflectivity)


def _fresnel_of(lobes):
    """F(cos θ_d) of the material: conductor η, κ; Principled dielectric; legacy r."""
    m = lobes.mapping
    if lobes.kind == "CONDUCTOR":
        eta, kap = _rgb(m.ior), _rgb(m.extinction)
        return lambda c: fresnel_conductor(c, eta, kap)
    if lobes.kind == "DIELECTRIC":
        eta = _f(m.dielectric_ior)
        tint = _rgb(lobes.fresnel["specular_tint"])
        return lambda c: principled_dielectric(c, eta, tint)
    r = _rgb(m.reflectivity)
    return lambda c: np.broadcast_to(r, np.shape(c) + (3,))


def reference(lobes):
    """Eq. 1, f = ((1-β) f_n + β f_w) F(θ_d), of one material's ``HazyLobes`` (tangent frame of
    the core: α_x along +x)."""
    (ax, ay), (wx, wy) = _alphas(lobes)
    beta = _f(lobes.beta)
    dist = "BECKMANN" if lobes.distribution == "BECKMANN" else "GGX"
    return Lobes((Lobe(1.0 - beta, ax, ay, dist), Lobe(beta, wx, wy, dist)), _fresnel_of(lobes))


def _alpha_min(lobes):
    (ax, ay), (wx, wy) = _alphas(lobes)
    return min(ax, ay, wx, wy)


# --------------------------------------------------------------------------------------------
# Fresnel fits
# --------------------------------------------------------------------------------------------

_MU = np.linspace(0.0, 1.0, 257)


def schlick_f90_fit(fresnel, f0):
    """F90 (per channel, clamped to [0, 1]) minimising ∫ |F0 + (F90-F0)(1-μ)⁵ - F(μ)|² dμ."""
    f = fresnel(_MU)
    w = (1.0 - _MU)[:, None] ** 5
    f0 = np.asarray(f0, dtype=np.float64)
    d = np.sum(w * (f - f0), axis=0) / np.sum(w * w, axis=0)
    return np.clip(f0 + d, 0.0, 1.0)


def f82_tint_fit(fresnel, f0):
    """OpenPBR specular_color for a metal: F(μ̄) / Schlick(μ̄) at μ̄ = 1/7, clamped to [0, 1]
    (the F82-tint model then matches F at μ = 1 and μ̄).  Returns (tint, unclamped tint)."""
    mu = np.array([K.F82_MU])
    f = fresnel(mu)[0]
    s = schlick(mu, f0)[0]
    raw = f / s
    return np.clip(raw, 0.0, 1.0), raw


def _max_fresnel_error(fa, fb):
    return float(np.max(np.abs(fa(_MU) - fb(_MU))))


# --------------------------------------------------------------------------------------------
# Roughness conventions of the engines
# --------------------------------------------------------------------------------------------


def _tb_from_alpha(ax, ay):
    """(ρ, a) with α_x = ρ(1+a), α_y = ρ(1-a): Unity HDRP, Unreal and Filament anisotropy."""
    rho = 0.5 * (ax + ay)
    return rho, (ax - ay) / (ax + ay) if ax + ay > 0 else 0.0


def openpbr_anisotropy(r, a):
    """OpenPBR (α_t, α_b) from roughness r and anisotropy a: α_t = r² √(2/(1+(1-a)²)),
    α_b = (1-a) α_t (OpenPBR 1.1/1.2 spec; mtlx open_pbr_anisotropy)."""
    c = math.sqrt(2.0 / (1.0 + (1.0 - a) ** 2))
    at = r * r * c
    return at, (1.0 - a) * at


# --------------------------------------------------------------------------------------------
# The engines
# --------------------------------------------------------------------------------------------


def unity_stacklit(lobes, max_dielectric_f0=K.UNITY_MAX_DIELECTRIC_F0):
    """Unity HDRP StackLit, Dual Specular Lobe = Hazy Gloss."""
    ((ax, ay), (wx, wy)), beta, r = _fit_inputs(lobes)
    notes = []
    inv = inverse_haze_mapping(beta, (ax, ay), (wx, wy), reflectivity=r, distribution="GGX",
                               smoothness=K.UNITY_HAZE_BEZIER_W, alpha_max=K.ALPHA_MAX)
    exact_inv = bool(np.all(inv.exact))
    if not exact_inv:
        notes.append("Unity's w = 10 mapping cannot reach this β: " + "; ".join(inv.warnings))
    rc_u = _rgb(inv.core_reflectivity)
    bh_u = _f(inv.haziness)
    lx, ly = (_f(v) for v in inv.haze_extent)
    metallic = 0.0 if lobes.kind == "DIELECTRIC" else 1.0  # legacy: no dielectric F0 cap
    cap = max_dielectric_f0 + (1.0 - max_dielectric_f0) * metallic
    # Unity: alpha_n = ClampRoughnessForAnalyticalLights(α) = max(α, 1/1024)
    a_lo = 1.0 / 1024.0
    ax_u, ay_u = max(ax, a_lo), max(ay, a_lo)
    if (ax_u, ay_u) != (ax, ay):
        notes.append("Unity clamps α to ≥ 1/1024 for analytic lights")
    fwd = haze_mapping(rc_u, 0.0, (ax_u, ay_u), min(bh_u, K.MAX_HAZINESS), (lx, ly),
                       smoothness=K.UNITY_HAZE_BEZIER_W, alpha_max=1.0, strict=False)
    f0 = np.minimum(_rgb(fwd.reflectivity), cap)
    if np.any(_rgb(fwd.reflectivity) > cap):
        notes.append(f"fresnel0 capped at hazyGlossMaxDielectricF0 = {cap:g}")
    beta_u = _f(fwd.beta)
    uwx, uwy = (_f(v) for v in fwd.alpha_wide)
    model = Lobes((Lobe(1.0 - beta_u, ax_u, ay_u), Lobe(beta_u, uwx, uwy)),
                  lambda c: schlick(c, f0))
    rho, a = _tb_from_alpha(ax, ay)
    h_ext = 0.5 * (lx + ly)
    params = dict(fresnel0=tuple(rc_u), metallic=metallic,
                  perceptual_smoothness_a=1.0 - math.sqrt(rho), anisotropy_a=a,
                  haziness=bh_u, haze_extent=h_ext,
                  anisotropy_b=(lx - ly) / (lx + ly) if lx + ly > 0 else 0.0,
                  hazy_gloss_max_dielectric_f0=max_dielectric_f0)
    if lobes.kind == "CONDUCTOR":
        notes.append("Schlick Fresnel with fresnel0 = r: the edge tint (η, κ) is lost "
                     f"(max |ΔF| = {_max_fresnel_error(_fresnel_of(lobes), lambda c: schlick(c, r)):.3g})")
    elif lobes.kind == "LEGACY":
        notes.append("Schlick Fresnel where the legacy lobes have none (F ≡ r)")
    return EngineFit("unity_stacklit", params, model, notes)


def ue_substrate(lobes):
    """Unreal Engine 5 Substrate slab with a second roughness."""
    ((ax, ay), (wx, wy)), beta, r = _fit_inputs(lobes)
    notes = []
    fres = _fresnel_of(lobes)
    if lobes.kind == "LEGACY":
        f90 = r.copy()  # F0 = F90 = r: Schlick is the constant r exactly
    elif lobes.kind == "DIELECTRIC":
        f90 = np.ones(3)
    else:
        f90 = schlick_f90_fit(fres, r)
    rho, a = _tb_from_alpha(ax, ay)
    # the second lobe shares Anisotropy a: α2 (1 ± a); match its peak density α2² (1 - a²) = α_w^x α_w^y
    rho2 = math.sqrt(wx * wy / max(1.0 - a * a, 1e-12))
    rho2 = min(rho2, 1.0)
    s_x, s_y = rho2 * (1 + a), rho2 * (1 - a)
    if abs(s_x / s_y - wx / wy) > 1e-6 * (wx / wy):
        notes.append(f"the second lobe keeps the core's anisotropy: halo aspect {s_x / s_y:.3g} "
                     f"instead of {wx / wy:.3g}")
    model = Lobes((Lobe(1.0 - beta, rho * (1 + a), rho * (1 - a)), Lobe(beta, s_x, s_y)),
                  lambda c: schlick(c, r, f90))
    if lobes.kind != "LEGACY":
        notes.append(f"Schlick F0/F90 (F90 = {', '.join(f'{v:.3g}' for v in f90)}): "
                     f"max |ΔF| = {_max_fresnel_error(fres, lambda c: schlick(c, r, f90)):.3g}")
    params = dict(f0=tuple(r), f90=tuple(f90), roughness=math.sqrt(rho), anisotropy=a,
                  second_roughness=math.sqrt(rho2), second_roughness_weight=beta)
    return EngineFit("ue_substrate", params, model, notes)


def _filament_alpha(alpha):
    """Filament clamps perceptual roughness to >= 0.045 (α >= 0.045²)."""
    return max(alpha, 0.045 ** 2)


def _filament_f90(f0):
    return min(1.0, float(np.sum(np.asarray(f0)) * 50.0 * 0.33))


class _ClearCoat:
    """Filament's clear coat over a one-lobe base: f = f_base (1 - s Fc) + s Fc D_c V_c,
    Fc = Schlick(0.04, θ_d), V_c = 1 / (4 (ωi·h)²) (Kelemen), D_c isotropic GGX."""

    def __init__(self, base, strength, alpha_coat):
        self.base = base
        self.s = strength
        self.a = alpha_coat

    def __call__(self, wi, wo):
        wi = np.asarray(wi, dtype=np.float64)
        wo = np.asarray(wo, dtype=np.float64)
        h = wi + wo
        h = h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)
        c = np.clip(np.sum(wi * h, axis=-1), 1e-6, 1.0)
        fc = self.s * (K.FILAMENT_CLEARCOAT_F0 + (1 - K.FILAMENT_CLEARCOAT_F0) * (1 - c) ** 5)
        hz = np.maximum(h[..., 2], 1e-12)
        a2 = self.a * self.a
        d = a2 / (math.pi * (hz * hz * (a2 - 1.0) + 1.0) ** 2)
        ok = (wi[..., 2] > 0) & (wo[..., 2] > 0)
        coat = np.where(ok, d * fc * 0.25 / (c * c), 0.0)
        return self.base(wi, wo) * (1.0 - fc)[..., None] + coat[..., None]


def filament(lobes):
    """Filament (released): the core lobe alone; the clear-coat fit as an alternative."""
    m = lobes.mapping
    ((ax, ay), (wx, wy)), beta, r = _fit_inputs(lobes)
    rc = _rgb(m.core_reflectivity)
    notes = ["no second specular lobe in released Filament (secondRoughness / "
             "secondRoughnessWeight are announced for apiLevel 2 without a documented model)"]
    rho, a = _tb_from_alpha(ax, ay)
    rho_f = _filament_alpha(rho)
    if rho_f != rho:
        notes.append("perceptual roughness clamped to 0.045")
    if lobes.kind == "DIELECTRIC":
        f0_core = np.full(3, float(np.max(rc)))
        notes.append("dielectric F0 is achromatic (reflectance); the core's tint is lost")
    else:
        f0_core = rc
    f90 = _filament_f90(f0_core)
    core = Lobes((Lobe(1.0, rho_f * (1 + a), rho_f * (1 - a)),), lambda c: schlick(c, f0_core, f90))
    params = dict(base_color=tuple(f0_core), metallic=1.0 if lobes.kind != "DIELECTRIC" else 0.0,
                  reflectance=math.sqrt(float(np.max(rc)) / 0.16) if lobes.kind == "DIELECTRIC" else None,
                  roughness=math.sqrt(rho_f), anisotropy=a)
    if lobes.kind == "DIELECTRIC" and params["reflectance"] > 1.0:
        notes.append("dielectric F0 above Filament's 0.16 (reflectance 1)")
    notes.append("the halo is dropped: the core lobe (the material at haziness 0) keeps the peak")
    fit = EngineFit("filament", params, core, notes)
    # clear coat: (i) coat = core, base = halo; (ii) coat = halo, base = core
    alts = {}
    rmax = float(np.max(r))
    _, a_w = _tb_from_alpha(wx, wy)
    for name, (coat_alpha, coat_w, base_ax, base_ay, base_w) in {
        "clear_coat_core": (math.sqrt(ax * ay), 1.0 - beta, wx, wy, beta),
        "clear_coat_halo": (math.sqrt(wx * wy), beta, ax, ay, 1.0 - beta),
    }.items():
        s = min(1.0, coat_w * rmax / K.FILAMENT_CLEARCOAT_F0)
        base_f0 = np.clip(base_w * r / (1.0 - K.FILAMENT_CLEARCOAT_F0 * s), 0.0, 1.0)
        bx, by = _filament_alpha(base_ax), _filament_alpha(base_ay)
        base = Lobes((Lobe(1.0, bx, by),), lambda c, f0=base_f0: schlick(c, f0, _filament_f90(f0)))
        model = _ClearCoat(base, s, max(coat_alpha, 0.089 ** 2))
        brho, ba = _tb_from_alpha(bx, by)
        alts[name] = EngineFit(
            "filament:" + name,
            dict(clear_coat=s, clear_coat_roughness=math.sqrt(max(coat_alpha, 0.089 ** 2)),
                 base_color=tuple(base_f0), roughness=math.sqrt(brho), anisotropy=ba),
            model, [f"clear coat F0 fixed at 0.04, strength {s:.3g}; isotropic coat"])
    fit.alternatives = alts
    return fit


def openpbr_12(lobes):
    """OpenPBR 1.2 with specular_haze (dev_1.2 branch)."""
    m = lobes.mapping
    ((ax, ay), (wx, wy)), beta, r = _fit_inputs(lobes)
    notes = []
    swap = ay > ax
    t, b = (ay, ax) if swap else (ax, ay)  # OpenPBR's tangent is the long axis
    aniso = 1.0 - b / t if t > 0 else 0.0
    c = math.sqrt(2.0 / (1.0 + (1.0 - aniso) ** 2))
    r_core = math.sqrt(t / c)
    # haze: same anisotropy; match its peak density α_t α_b = r_h⁴ c² (1-a) to α_w^x α_w^y
    r_h = (wx * wy / (c * c * max(1.0 - aniso, 1e-12))) ** 0.25
    spread_raw = (r_h - r_core) / (1.0 - r_core) if r_core < 1 else 0.0
    spread = min(max(spread_raw, 0.0), 1.0)
    if spread != spread_raw:
        notes.append(f"specular_haze_spread clamped to [0, 1] (needs {spread_raw:.3g})")
    r_haze = r_core + (1.0 - r_core) * spread
    ht, hb = openpbr_anisotropy(r_haze, aniso)
    hx, hy = (hb, ht) if swap else (ht, hb)
    if abs(hx / hy - wx / wy) > 1e-6 * (wx / wy):
        notes.append(f"the haze lobe keeps the core's anisotropy: aspect {hx / hy:.3g} instead "
                     f"of {wx / wy:.3g} (λ_h^x ≠ λ_h^y or an anisotropic core is not representable)")
    fres = _fresnel_of(lobes)
    params = dict(base_weight=1.0, specular_weight=1.0, specular_roughness=r_core,
                  specular_roughness_anisotropy=aniso, specular_haze=beta,
                  specular_haze_spread=spread, geometry_tangent_rotation=0.25 if swap else 0.0)
    if lobes.kind == "DIELECTRIC":
        eta = _f(m.dielectric_ior)
        tint = _rgb(lobes.fresnel["specular_tint"])
        params.update(base_metalness=0.0, specular_ior=eta, specular_color=tuple(tint))
        fo = lambda cd: tint * principled_dielectric(cd, eta)  # noqa: E731
        if np.any(tint < 1):
            notes.append("specular_color tints the whole dielectric Fresnel (Blender's Specular "
                         "Tint leaves the grazing edge white)")
    else:
        tint, raw = f82_tint_fit(fres, r)
        params.update(base_metalness=1.0, base_color=tuple(r), specular_color=tuple(tint))
        fo = lambda cd: np.clip(f82_tint(cd, r, tint), 0.0, 1.0)  # noqa: E731
        if np.any(raw > 1):
            notes.append(f"specular_color clamped to 1 (the fit asks {', '.join(f'{v:.3g}' for v in raw)})")
        notes.append(f"metal Fresnel F82-tint: max |ΔF| = {_max_fresnel_error(fres, fo):.3g}"
                     + (" (the legacy lobes have no Fresnel)" if lobes.kind == "LEGACY" else ""))
    model = Lobes((Lobe(1.0 - beta, ax, ay), Lobe(beta, hx, hy)), fo)
    return EngineFit("openpbr_1_2", params, model, notes)


_BUILDERS = {"unity_stacklit": unity_stacklit, "ue_substrate": ue_substrate,
             "filament": filament, "openpbr_1_2": openpbr_12}


def engine_parameters(lobes, engines=ENGINES, *, measure=True, **quadrature):
    """{engine: EngineFit} for one material's ``HazyLobes`` (core.lobes.describe of one
    material).  ``measure``: compute each fit's BRDF error against Eq. 1 (brdf.compare; about
    0.1 s per engine); quadrature keywords go to brdf.compare (n_theta, n_phi, views)."""
    if np.ndim(lobes.beta) != 0:
        raise ValueError("engine_parameters takes one material (scalar parameters), not textures")
    out = {}
    ref = reference(lobes) if measure else None
    amin = _alpha_min(lobes)
    for name in engines:
        if name not in _BUILDERS:
            raise ValueError(f"unknown engine {name!r}; known: {', '.join(ENGINES)}")
        fit = _BUILDERS[name](lobes)
        if lobes.distribution == "ASHIKHMIN_SHIRLEY":
            fit.notes.append("Ashikhmin-Shirley lobes are compared as GGX lobes of the same α")
        if measure:
            fit.error = compare(ref, fit.model, amin, **quadrature)
            fit.exact = fit.error["max"] < 1e-6
            for alt in fit.alternatives.values():
                alt.error = compare(ref, alt.model, amin, **quadrature)
        out[name] = fit
    return out


# --------------------------------------------------------------------------------------------
# The single-surface fallback: the core lobe
# --------------------------------------------------------------------------------------------


def core_surface(p, describe_fn):
    """The closest single metallic-roughness surface: the material at haziness 0 (its core
    lobe).  The mapping keeps the peak at r_c f_n(n, n) whatever the haziness, so this is the
    core highlight exactly, without the halo.  ``p``: normalised perceptual parameters;
    ``describe_fn``: materialx.lobes_of (core.lobes.describe of one material).

    Returns dict(metallic, base_color, roughness (Blender R = (α_x α_y)^¼), anisotropy and
    rotation (Metallic/Principled convention, None when isotropic), alpha (α_x, α_y),
    ior (dielectric: from r̂_c), specular_tint (conductor: the F82 tint of the core's Fresnel,
    clamped to [0, 1]; dielectric: chroma of r_c), base (dielectric base colour),
    transmission)."""
    q = dict(p)
    q["haziness"] = 0.0
    d = describe_fn(q)
    m = d.mapping
    rc = _rgb(m.core_reflectivity)
    aniso = d.anisotropic and p["anisotropy"] > 0  # Metallic/Principled convention, all kinds
    out = dict(roughness=float(d.narrow.roughness),
               anisotropy=float(p["anisotropy"]) if aniso else None,
               rotation=float(p["rotation"]) if aniso else None,
               alpha=tuple(_f(a) for a in m.alpha),
               transmission=float(p.get("transmission", 0.0)))
    if d.kind == "DIELECTRIC":
        out.update(metallic=0.0, base_color=tuple(float(c) for c in p["base_color"]),
                   ior=_f(m.dielectric_ior), specular_tint=tuple(_rgb(d.fresnel["specular_tint"])),
                   f0=tuple(rc))
    else:
        if d.kind == "CONDUCTOR":
            eta, kap = _rgb(m.ior), _rgb(m.extinction)
            tint, _ = f82_tint_fit(lambda c: fresnel_conductor(c, eta, kap), rc)
        else:
            tint = np.ones(3)
        out.update(metallic=1.0, base_color=tuple(rc), ior=1.5, specular_tint=tuple(tint),
                   f0=tuple(rc))
    return out


def table(fits):
    """Plain-text table of engine_parameters' result (engine, max, mean, peak, notes)."""
    rows = []
    for name, fit in fits.items():
        for label, f in [(name, fit)] + [(f"{name}:{k}", a) for k, a in fit.alternatives.items()]:
            e = f.error or {}
            rows.append(f"{label:<28} max {e.get('max', float('nan')):8.4f}  mean "
                        f"{e.get('mean', float('nan')):8.4f}  peak {e.get('peak', float('nan')):8.2e}"
                        + (f"  — {'; '.join(f.notes)}" if f.notes else ""))
    return "\n".join(rows)
