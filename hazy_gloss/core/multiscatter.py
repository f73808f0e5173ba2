# SPDX-License-Identifier: GPL-3.0-or-later
"""Cycles' Multiscatter GGX at normal incidence, and the haze mapping corrected for it (no bpy).

What Cycles does (``kernel/closure/bsdf_microfacet.h``, ``microfacet_ggx_preserve_energy``; the
same logic in Blender 4.5, 5.2 and 5.3), once per closure, for the view direction wo:

    x       = (α_x α_y)^¼  (each α clamped to <= 1)          roughness index
    E, E_avg = table_ggx_E(μ_o, x), table_ggx_Eavg(x)          single-scatter albedo, its average
    F_ms    = F_ss E_avg / (1 - F_ss (1 - E_avg))              per channel
    f_ms    = f_ss · S,   S = 1 + F_ms (1 - E) / E              (S = 1/E when F_ss = 1)

F_ss is the cosine-weighted average of the lobe's Fresnel, computed by each node's setup
(:func:`single_scatter_albedo`).  S depends on the view only, and at the peak (view and light
along the normal) on E(1, x), E_avg(x) and F_ss.  Two lobes of one hazy material have
different x and, because F(0) = r changes with haziness, different F_ss than the haze-free
material: the peak ratio is p S_w / S_n, not p, and the core's F(0) no longer sets the peak
alone.  :func:`correct_mapping` solves for (β, r) that keep the peak of every channel
(docs/mapping.md, "Multiscatter GGX").

Tables: ``cycles_ggx_tables`` (the μ = 1 row of table_ggx_E and table_ggx_Eavg, extracted from
the bpy wheels by scripts/extract_ggx_tables.py; Cycles data, Apache-2.0).  Everything here is
the view along the normal: the only direction the peak needs.  Arithmetic is float64 (Cycles
runs float32; the difference is ~1e-7 relative, far below the renders' agreement needed here).

Versions: :func:`cycles_version` (None = the running Blender if bpy is already imported, else
the newest supported).  4.5 - 5.2 and 5.3 differ in E_avg (<= 1e-6) and 4.5's Metallic
PHYSICAL_CONDUCTOR uses an approximate conductor Fresnel off normal incidence, which enters
F_ss; the μ = 1 row of E is the same in all.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, replace

import numpy as np

from .tables import cycles_ggx_tables as _tables
from .mapping import HazeMapping, haze_terms, dielectric_ior, gulbrandsen_ior

__all__ = ("FRESNELS", "LOBES", "MultiscatterPeak", "cycles_version", "roughness_index",
           "albedo_normal", "albedo_average", "single_scatter_albedo", "fss_dielectric_exact",
           "energy_scale", "peak_ratio", "correct_mapping", "peak_factor", "exact_conductor",
           "generation", "LATEST")

#: Newest Blender whose Cycles this module reproduces; later versions are assumed to match it.
LATEST = (5, 3)
#: Fresnel modes of :func:`single_scatter_albedo` (how each node computes F_ss).
FRESNELS = ("CONDUCTOR", "F82_TINT", "F82", "DIELECTRIC", "DIELECTRIC_EXACT", "CONSTANT")
#: Lobe types of :func:`correct_mapping`: which node draws the two lobes and how its Fresnel
#: follows from the mapping's reflectivity r.
LOBES = ("CONDUCTOR", "F82_TINT", "DIELECTRIC", "LEGACY", "COAT")

_E_MU1 = np.asarray(_tables.E_MU1, np.float32).astype(np.float64)
_EAVG = {"V4": np.asarray(_tables.EAVG_V4, np.float32).astype(np.float64),
         "V53": np.asarray(_tables.EAVG_V53, np.float32).astype(np.float64)}


# --------------------------------------------------------------------------------------------
# Versions and tables
# --------------------------------------------------------------------------------------------


def cycles_version(version=None):
    """(major, minor) whose Cycles to reproduce.  ``version``: None (the running Blender when
    ``bpy`` is already imported — it is never imported from here — else :data:`LATEST`), a
    string "4.5" or a tuple such as ``bpy.app.version``."""
    if version is None:
        bpy = sys.modules.get("bpy")
        app = getattr(bpy, "app", None)
        version = getattr(app, "version", None) or LATEST
    if isinstance(version, str):
        version = tuple(int(v) for v in version.split(".")[:2])
    major, minor = (tuple(int(v) for v in version) + (0,))[:2]
    if (major, minor) < (4, 5):
        raise ValueError(f"Blender {major}.{minor} is not supported (4.5 LTS and later)")
    return major, minor


def generation(version):
    return "V53" if cycles_version(version) >= (5, 3) else "V4"


def exact_conductor(version):
    """Metallic PHYSICAL_CONDUCTOR evaluates the exact conductor Fresnel from 5.0 on."""
    return cycles_version(version) >= (5, 0)


def _lookup(table, x):
    """util/lookup_table.h lookup_table_read: x saturated, scaled to the 32 nodes, truncated
    index, linear blend (exactly the node value where the fraction is 0)."""
    u = np.clip(np.asarray(x, np.float64), 0.0, 1.0) * (len(table) - 1)
    i = np.minimum(u.astype(np.int64), len(table) - 1)
    t = u - i
    return (1.0 - t) * table[i] + t * table[np.minimum(i + 1, len(table) - 1)]


def roughness_index(alpha_x, alpha_y=None):
    """x = (α_x α_y)^¼ after Cycles' clamp of each α to <= 1 (= R for an isotropic lobe)."""
    ax = np.minimum(np.asarray(alpha_x, np.float64), 1.0)
    ay = ax if alpha_y is None else np.minimum(np.asarray(alpha_y, np.float64), 1.0)
    return np.sqrt(np.sqrt(ax * ay))


def albedo_normal(x):
    """E(μ = 1, x): single-scatter GGX albedo (height-correlated Smith, F = 1) for a view along
    the normal, as Cycles reads its table (bilinear in x; at μ = 1 only the last row is read)."""
    return _lookup(_E_MU1, x)


def albedo_average(x, version=None):
    """E_avg(x) = ∫ 2μ E(μ, x) dμ as Cycles reads its table."""
    return _lookup(_EAVG[generation(version)], x)


# --------------------------------------------------------------------------------------------
# F_ss: the average single-scatter Fresnel each node computes (kernel/closure/bsdf_util.h)
# --------------------------------------------------------------------------------------------

_F = 6.0 / 7.0  # F82 models: the reference angle has cos = 1/7, 1 - cos = 6/7
_F5 = _F ** 5


def _mix(a, b, t):
    return a + t * (b - a)


def _fresnel_conductor(cos_i, ior, extinction, exact=True):
    """The Metallic node's conductor Fresnel F(cos θ), unpolarised, ambient IOR 1: exact (5.x
    ``fresnel_conductor``) or 4.5's approximation (exact at normal incidence only)."""
    n, k, c = ior, extinction, cos_i
    if not exact:
        c2 = c * c
        nk2 = n * n + k * k
        rpar2 = (nk2 * c2 - 2 * n * c + 1) / (nk2 * c2 + 2 * n * c + 1)
        rper2 = (nk2 - 2 * n * c + c2) / (nk2 + 2 * n * c + c2)
        return 0.5 * (rpar2 + rper2)
    n2k2 = n * n - k * k
    t1 = n2k2 - (1.0 - c * c)
    two_nk = 2.0 * n * k
    t2 = np.sqrt(t1 * t1 + two_nk * two_nk)
    u2 = np.maximum(0.5 * (t2 + t1), 0.0)
    v2 = np.maximum(0.5 * (t2 - t1), 0.0)
    u, v = np.sqrt(u2), np.sqrt(v2)
    rs = ((c - u) ** 2 + v2) / ((c + u) ** 2 + v2)
    t3, t4 = n2k2 * c, two_nk * c
    rp = ((t3 - u) ** 2 + (t4 - v) ** 2) / ((t3 + u) ** 2 + (t4 + v) ** 2)
    return 0.5 * (rs + rp)


def _f82_fss(f0, b):
    """fresnel_f82_Fss: ∫ 2μ F82(μ) dμ = mix(F0, 1, 1/21) - B/126."""
    return _mix(f0, 1.0, 1.0 / 21.0) - b / 126.0


def fss_conductor(ior, extinction, version=None, *, exact=None):
    """Metallic BSDF, PHYSICAL_CONDUCTOR (bsdf_microfacet_setup_fresnel_conductor): the F82
    model through F(1) and F(1/7) of the node's conductor Fresnel, F_ss saturated; η, κ >= 0.
    ``exact``: the exact Fresnel (5.x) or 4.5's approximation; None decides from ``version``."""
    n = np.maximum(np.asarray(ior, np.float64), 0.0)
    k = np.maximum(np.asarray(extinction, np.float64), 0.0)
    if exact is None:
        exact = exact_conductor(version)
    f0 = _fresnel_conductor(1.0, n, k, exact)
    f82 = _fresnel_conductor(1.0 / 7.0, n, k, exact)
    b = 7.0 / (_F5 * _F) * (_mix(f0, 1.0, _F5) - f82)  # fresnel_f82_B
    return np.clip(_f82_fss(f0, b), 0.0, 1.0)


def fss_f82_tint(f0, tint):
    """Metallic BSDF F82 (Base Color, Edge Tint) and the Principled metallic lobe (Base Color,
    Specular Tint) (bsdf_microfacet_setup_fresnel_f82_tint): F0 and the tint saturated;
    B = mix(F0, 1, f⁵)·7/(f⁶)·(1 - tint), 0 when the tint is exactly white; not saturated."""
    f0 = np.clip(np.asarray(f0, np.float64), 0.0, 1.0)
    tint = np.broadcast_to(np.clip(np.asarray(tint, np.float64), 0.0, 1.0), f0.shape)
    white = np.all(tint == 1.0, axis=-1, keepdims=True) if tint.ndim else tint == 1.0
    b = np.where(white, 0.0, _mix(f0, 1.0, _F5) * (7.0 / (_F5 * _F)) * (1.0 - tint))
    return _f82_fss(f0, b)


def _dielectric_fss_fit(eta):
    """fresnel_dielectric_Fss: Kulla-Conty's fit of the average dielectric Fresnel."""
    eta = np.asarray(eta, np.float64)
    lo = 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    hi = (eta - 1.0) / (4.08567 + 1.00071 * eta)
    return np.where(eta < 1.0, lo, hi)


def fss_dielectric(ior, f0=None, specular_tint=1.0):
    """Principled BSDF dielectric specular, IOR Level 0.5 (bsdf_microfacet_setup_fresnel_
    generalized_schlick, exponent -η): F_ss = mix(f0, 1, s) with f0 = saturate(F0(η)·tint) and
    s = saturate((F_ss,dielectric(η) - F0(η)) / (1 - F0(η))).  Pass ``f0`` when F0(η) is known
    more accurately than from η (the mapping's r̂)."""
    eta = np.maximum(np.asarray(ior, np.float64), 1e-5)
    f0_eta = ((eta - 1.0) / (eta + 1.0)) ** 2 if f0 is None else np.asarray(f0, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.clip(np.where(f0_eta < 1.0, (_dielectric_fss_fit(eta) - f0_eta) / (1.0 - f0_eta), 1.0),
                    0.0, 1.0)
    tinted = np.clip(f0_eta[..., None] * np.asarray(specular_tint, np.float64), 0.0, 1.0)
    return _mix(tinted, 1.0, s[..., None])


def fss_dielectric_exact(ior):
    """Lobes with the exact dielectric Fresnel: the Principled BSDF's coat (bsdf_coat_setup ->
    bsdf_microfacet_setup_fresnel_dielectric, the same in 4.5, 5.2 and 5.3: always energy
    preserving, whatever the node's distribution): F_ss = fresnel_dielectric_Fss(η), the fit
    itself (not saturated, below F0(η) for η ≳ 3000), with η = max(Coat IOR, 1) as the
    closure code clamps it.  Grey (one value per texel)."""
    return _dielectric_fss_fit(np.maximum(np.asarray(ior, np.float64), 1.0))


def fss_constant(colour):
    """Glossy BSDF (bsdf_microfacet_setup_fresnel_constant): F_ss = max(Color, 0)."""
    return np.maximum(np.asarray(colour, np.float64), 0.0)


def single_scatter_albedo(fresnel, *, version=None, **params):
    """F_ss of a lobe, per channel (colours shaped (..., 3)), as the node computes it.

    fresnel="CONDUCTOR"   ior, extinction (..., 3): Metallic BSDF, Physical Conductor
            "F82_TINT"    f0, tint (..., 3): Metallic BSDF F82 (Base Color, Edge Tint) or the
                          Principled metallic lobe (Base Color, Specular Tint)
            "F82"         f0, f82 (..., 3): the F82 model through F(0°) = f0 and F(cos⁻¹ 1/7)
                          = f82 (what Cycles fits to any Fresnel it averages this way)
            "DIELECTRIC"  ior (...), specular_tint (..., 3) [, f0 = F0(ior)]: Principled
                          dielectric specular at IOR Level 0.5
            "DIELECTRIC_EXACT"  ior (...): the Principled coat (exact dielectric Fresnel),
                          F_ss = fresnel_dielectric_Fss(η), grey
            "CONSTANT"    colour (..., 3): Glossy BSDF"""
    f = str(fresnel).upper()
    if f == "CONDUCTOR":
        return fss_conductor(params["ior"], params["extinction"], version)
    if f == "F82_TINT":
        return fss_f82_tint(params["f0"], params["tint"])
    if f == "F82":
        f0 = np.asarray(params["f0"], np.float64)
        return _f82_fss(f0, 7.0 / (_F5 * _F) * (_mix(f0, 1.0, _F5) - np.asarray(params["f82"], np.float64)))
    if f == "DIELECTRIC":
        return fss_dielectric(params["ior"], params.get("f0"), params.get("specular_tint", 1.0))
    if f == "DIELECTRIC_EXACT":
        return fss_dielectric_exact(params["ior"])
    if f == "CONSTANT":
        return fss_constant(params["colour"])
    raise ValueError(f"fresnel must be one of {', '.join(FRESNELS)}; got {fresnel!r}")


# --------------------------------------------------------------------------------------------
# The energy factor at normal incidence and the peak ratio
# --------------------------------------------------------------------------------------------


class _Lobe:
    """(1 - E(1, x))/E(1, x) and E_avg(x) of one lobe: S(F_ss) = 1 + excess(F_ss)."""

    def __init__(self, x, version):
        e = albedo_normal(x)
        self.missing = ((1.0 - e) / e)[..., None]  # on the colour axis
        self.eavg = albedo_average(x, version)[..., None]

    def excess(self, fss):
        """S - 1 = F_ms (1 - E)/E, without forming S - 1 by subtraction."""
        return _excess(self.missing, self.eavg, fss)


def _alphas(alpha):
    return alpha if isinstance(alpha, tuple) else (alpha, alpha)


def energy_scale(alpha, fss, *, version=None):
    """S at normal view: the factor Multiscatter GGX multiplies a GGX lobe of roughness
    ``alpha`` (α, or an (α_x, α_y) pair) and average Fresnel ``fss`` (..., 3) by, per channel."""
    lobe = _Lobe(roughness_index(*_alphas(alpha)), version)
    return 1.0 + lobe.excess(np.asarray(fss, np.float64))


def peak_ratio(alpha, alpha_wide, fss, fss_wide=None, *, version=None):
    """(p_ms, 1 - p_ms) per channel: f_w(n,n)/f_n(n,n) of two Multiscatter GGX lobes,
    p S_w / S_n with p = (α_n^x α_n^y)/(α_w^x α_w^y) (α clamped to <= 1 as Cycles does).
    ``fss_wide``: the wide lobe's F_ss when it differs (Glossy lobes: their colours).
    1 - p_ms = (1 - p) + p (M_n - M_w) / S_n, M = S - 1: no cancellation as p -> 1."""
    (nx, ny), (wx, wy) = (tuple(np.minimum(np.asarray(a, np.float64), 1.0) for a in _alphas(a))
                          for a in (alpha, alpha_wide))
    p = ((nx / wx) * (ny / wy))[..., None]
    q = ((wx - nx) / wx + (nx / wx) * (wy - ny) / wy)[..., None]
    n, w = _Lobe(roughness_index(nx, ny), version), _Lobe(roughness_index(wx, wy), version)
    fss = np.asarray(fss, np.float64)
    m_n, m_w = n.excess(fss), w.excess(fss if fss_wide is None else np.asarray(fss_wide, np.float64))
    s_n = 1.0 + m_n
    return p * (1.0 + m_w) / s_n, q + p * (m_n - m_w) / s_n


# --------------------------------------------------------------------------------------------
# The corrected mapping
# --------------------------------------------------------------------------------------------

#: 1 - r is kept >= this where F_ss is evaluated (r = 1: Gulbrandsen's η, κ are infinite).
_OMR_MIN = 1e-12
_EPS = np.finfo(np.float64).eps


@dataclass(frozen=True)
class MultiscatterPeak:
    """How :func:`correct_mapping` kept the peak (arrays of the mapping's texel shape S; colours
    S + (3,)).  Every channel's peak is r [(1-β) S_n + β p S_w] · D_n(0)/4, and that of the
    haze-free material r_c S_0 · D_n(0)/4."""

    lobe: str  #: lobe type (see LOBES)
    version: tuple  #: (major, minor) of the Cycles reproduced
    energy_narrow: np.ndarray  #: S_n, the narrow lobe's factor, per channel
    energy_wide: np.ndarray  #: S_w
    energy_reference: np.ndarray  #: S_0, the haze-free material's factor (F(0) = r_c)
    peak_ratio: np.ndarray  #: p_ms = p S_w / S_n per channel
    peak_complement: np.ndarray  #: 1 - p_ms per channel (< 0 possible for Glossy lobes)
    steps: int  #: Newton steps of the slowest texel (all solves)
    residual: float  #: max over texels and channels of |hazy peak / haze-free peak - 1| (model)
    #: Glossy lobes: k̂_max, the largest halo weight β r̂ that keeps the peak (β_h = 1); None
    #: for lobes with a Fresnel (they keep the mapping's β)
    halo_max: np.ndarray = None


class _Texels:
    """Per-texel constants of the peak of one lobe type (rows = texels, colours on the last
    axis; ``take`` selects rows and, optionally, one colour channel)."""

    _ROWS = ("mn", "en", "mw", "ew", "p", "rc", "g", "tint", "white")

    def __init__(self, lobe, exact, **a):
        self.lobe, self.exact = lobe, exact
        for k in self._ROWS:
            setattr(self, k, a[k])

    def take(self, rows, channel=None):
        def sel(a):
            a = a[rows]
            return a if channel is None or a.shape[-1] == 1 else np.take_along_axis(
                a, channel[rows, None] if np.ndim(channel) else np.full((len(a), 1), channel), -1)
        return _Texels(self.lobe, self.exact, **{k: sel(getattr(self, k)) for k in self._ROWS})

    def fss(self, r, omr, r_hat, omr_hat, beta):
        """(F_ss narrow, F_ss wide) when the lobes' F(0) is r (1 - r = omr), the max channel's
        r̂ (for the dielectric IOR) and the mix weight β (for the Glossy colours)."""
        omr = np.maximum(omr, _OMR_MIN)
        if self.lobe == "CONDUCTOR":  # η, κ of Gulbrandsen's mapping
            eta, kappa = gulbrandsen_ior(r, self.g, omr)
            f = fss_conductor(eta, kappa, exact=self.exact)
            return f, f
        if self.lobe == "F82_TINT":  # Base Color r, the given tint
            b = np.where(self.white, 0.0, _mix(r, 1.0, _F5) * (7.0 / (_F5 * _F)) * (1.0 - self.tint))
            f = _f82_fss(r, b)
            return f, f
        if self.lobe == "DIELECTRIC":  # IOR from r̂, tint r / r̂: F0(η) tint = r
            omr_hat = np.maximum(omr_hat, _OMR_MIN)
            eta = dielectric_ior(np.minimum(r_hat, 1.0 - _OMR_MIN), omr_hat)
            s = np.clip((_dielectric_fss_fit(eta) - r_hat) / omr_hat, 0.0, 1.0)
            f = r + s * omr
            return f, f
        if self.lobe == "COAT":  # Coat IOR from r̂ (F0(η) = r̂, white tint): F_ss = fit(η)
            omr_hat = np.maximum(omr_hat, _OMR_MIN)
            eta = dielectric_ior(np.minimum(r_hat, 1.0 - _OMR_MIN), omr_hat)
            f = np.broadcast_to(_dielectric_fss_fit(eta), np.shape(r))
            return f, f
        return (1.0 - beta) * r, beta * r  # LEGACY: the Glossy colours

    def peak(self, r, omr, r_hat, omr_hat, beta):
        """r [(1-β) S_n + β p S_w] per channel."""
        fn, fw = self.fss(r, omr, r_hat, omr_hat, beta)
        return r * ((1.0 - beta) * (1.0 + _excess(self.mn, self.en, fn))
                    + beta * self.p * (1.0 + _excess(self.mw, self.ew, fw)))


def _excess(missing, eavg, fss):
    """S - 1 = F_ms (1 - E)/E."""
    return fss * eavg / (1.0 - fss * (1.0 - eavg)) * missing


def _root(f, lo, hi, x0, rows, scale, max_iter=80):
    """x in [lo, hi] with f(x, rows) = 0, f increasing in x, elementwise (arrays shaped like
    ``lo``; ``rows`` is passed to f so it evaluates only the unfinished rows).  Newton with a
    relative forward difference, bisection whenever a step leaves the bracket; stops at a
    relative step of 1e-15 or |f| <= 8 ε ``scale`` (f's rounding level).  f(lo) <= 0 <= f(hi)
    is assumed (the callers make sure).  Returns (x, iterations)."""
    lo, hi = lo.copy(), hi.copy()
    x = np.clip(x0, lo, hi)
    todo = np.arange(len(x))
    it = 0
    for it in range(1, max_iter + 1):
        xa = x[todo]
        fx = f(xa, rows[todo])
        small = np.abs(fx) <= 8 * _EPS * scale[todo]  # at f's rounding level: done
        small = small.reshape(len(todo), -1).all(axis=-1) if small.ndim > 1 else small
        todo, xa, fx = todo[~small], xa[~small], fx[~small]
        if not len(todo):
            break
        h = np.maximum(1e-7 * np.abs(xa), 1e-300)
        h = np.where(xa + h <= hi[todo], h, -h)
        slope = (f(xa + h, rows[todo]) - fx) / h
        lo_a = np.where(fx <= 0, xa, lo[todo])
        hi_a = np.where(fx >= 0, xa, hi[todo])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            nx = xa - fx / slope
        newton = np.isfinite(nx) & (slope > 0) & (nx >= lo_a) & (nx <= hi_a)
        nx = np.where(fx == 0, xa, np.where(newton, nx, 0.5 * (lo_a + hi_a)))
        lo[todo], hi[todo], x[todo] = lo_a, hi_a, nx
        done = ((fx == 0) | (newton & (np.abs(nx - xa) <= 1e-15 * np.abs(xa)))
                | (hi_a - lo_a <= 1e-15 * np.abs(nx)))
        done = done.reshape(len(todo), -1).all(axis=-1) if done.ndim > 1 else done
        todo = todo[~done]
        if not len(todo):
            break
    return x, it


def peak_factor(lobe, alpha, alpha_wide, reflectivity, beta, *, edge_tint=0.0, tint=1.0,
                halo=True, version=None):
    """The normal-incidence peak of Eq. 1 under Multiscatter GGX, per channel, in units of the
    narrow lobe's D_n(0)/4: r [(1-β) S_n + β p S_w] (``halo`` False: the narrow lobe alone,
    r S_n).  The haze-free material is ``reflectivity`` = r_c with ``halo`` False."""
    lobe = _check_lobe(lobe)
    r = np.clip(np.asarray(reflectivity, np.float64), 0.0, 1.0)
    beta = np.asarray(beta, np.float64)[..., None] * (1.0 if halo else 0.0)
    (nx, ny), (wx, wy) = (tuple(np.minimum(np.asarray(a, np.float64), 1.0) for a in _alphas(a))
                          for a in (alpha, alpha_wide))
    n, w = _Lobe(roughness_index(nx, ny), version), _Lobe(roughness_index(wx, wy), version)
    tint = np.broadcast_to(np.clip(np.asarray(tint, np.float64), 0.0, 1.0), r.shape)
    t = _Texels(lobe, exact_conductor(version), mn=n.missing, en=n.eavg, mw=w.missing,
                ew=w.eavg, p=((nx / wx) * (ny / wy))[..., None],
                rc=r, g=np.asarray(edge_tint, np.float64), tint=tint,
                white=np.all(tint == 1.0, axis=-1, keepdims=True))
    r_hat = r.max(axis=-1, keepdims=True)
    return t.peak(r, 1.0 - r, r_hat, 1.0 - r_hat, beta)


def _check_lobe(lobe):
    lobe = str(lobe).upper()
    if lobe not in LOBES:
        raise ValueError(f"lobe must be one of {', '.join(LOBES)}; got {lobe!r}")
    return lobe


#: Texels solved together (bounds the working memory of texture conversions).
_CHUNK = 1 << 15


def correct_mapping(mapping: HazeMapping, lobe, *, tint=None, version=None) -> HazeMapping:
    """The haze mapping with the peak kept under Cycles' Multiscatter GGX.

    ``mapping``: :func:`hazy_gloss.core.haze_mapping` of the material (the roughness Cycles
    uses: α <= 1, aspect <= 10), drawn as two lobes of type ``lobe`` mixed by β:
      CONDUCTOR   Metallic BSDFs, Physical Conductor, η, κ = Gulbrandsen(r, g)
      F82_TINT    Metallic BSDFs F82 / Principled metallic lobes: Base Color r, ``tint`` (the
                  Edge Tint / Specular Tint colour, kept as given)
      DIELECTRIC  Principled dielectric lobes, IOR (1+√r̂)/(1-√r̂), Specular Tint r / r̂
      LEGACY      Glossy BSDFs with colours (1-β) r and β r, added
      COAT        Principled coats (Coat Weight 1, white Coat Tint) of two BSDFs mixed by β:
                  Coat IOR (1+√r̂)/(1-√r̂), exact dielectric Fresnel, F_ss = fresnel_dielectric_Fss
                  (Cycles draws the coat with Multiscatter GGX's factor whatever the node's
                  distribution); r_c must be grey (F0 of the Coat IOR), r is grey
    Returns a HazeMapping whose r (and η, κ, dielectric IOR, Glossy weights, r̂, k̂_h = β r̂)
    give every channel, at normal incidence, the peak of the haze-free material (the same lobe
    type, one lobe, F(0) = r_c), at the mapping's own β (Eq. 4, with the single-scatter p):

        r [(1-β) S_n + β p S_w] = r_c S_0                                              (*)

    β_h keeps exactly the paper's meaning: only the Fresnel's F(0) moves to hold the peak.
    With S = 1 this is the paper's mapping.  docs/mapping.md ("Multiscatter GGX") derives it.
    ``peak_ratio`` and ``peak_complement`` hold the max channel's p_ms = p S_w/S_n and 1 - p_ms,
    ``multiscatter`` the factors per channel (:class:`MultiscatterPeak`).  Computed in float64
    by safeguarded Newton on monotone 1-D equations, vectorised over texels; fields keep the
    mapping's dtype."""
    lobe = _check_lobe(lobe)
    ver = cycles_version(version)
    if lobe == "COAT":
        rc_c = np.asarray(mapping.core_reflectivity, np.float64)
        if np.any(np.ptp(np.reshape(rc_c, (-1, 3)), axis=-1) > 0):
            raise ValueError("correct_mapping: a COAT lobe has a grey core reflectivity (F0 of "
                             "the Coat IOR); got a coloured one")
    dtype = np.asarray(mapping.beta).dtype
    shape = np.shape(mapping.beta)
    n = int(np.prod(shape, dtype=np.int64))

    def flat(a, colour=False):
        a = np.asarray(a, np.float64)
        return np.broadcast_to(a, shape + ((3,) if colour else ())).reshape((n, 3) if colour else (n,))

    ax, ay = (np.minimum(flat(a), 1.0) for a in mapping.alpha)  # Cycles clamps α <= 1
    wx, wy = (np.minimum(flat(a), 1.0) for a in mapping.alpha_wide)
    p, q = flat(mapping.peak_ratio), flat(mapping.peak_complement)
    if dtype.itemsize < 8:  # p + q = 1 to float64 precision: recompute from the float32 α
        # (α_w - α_n of two float32 numbers is exact in float64: no cancellation)
        with np.errstate(divide="ignore", invalid="ignore"):
            px, py = ax / wx, ay / wy
            ok = (wx > 0) & (wy > 0)
            p = np.where(ok, px * py, p)
            q = np.where(ok, (wx - ax) / wx + px * (wy - ay) / wy, q)
    rc, g = flat(mapping.core_reflectivity, True), flat(mapping.edge_tint, True)
    tint_f = np.clip(flat(1.0 if tint is None else tint, True), 0.0, 1.0)
    r0, b0 = flat(mapping.reflectivity, True), flat(mapping.beta)
    if lobe == "LEGACY":
        bh = flat(mapping.haziness) * _bezier_share(mapping, flat, rc, p, q, dtype)
        beta, k_max = np.empty(n), np.empty(n)

    out = {k: np.empty((n, 3)) for k in ("r", "omr", "s_n", "s_w", "s_0")}
    steps, residual, over = 0, 0.0, 0
    for lo in range(0, n, _CHUNK):
        sl = slice(lo, min(n, lo + _CHUNK))
        x_n, x_w = roughness_index(ax[sl], ay[sl]), roughness_index(wx[sl], wy[sl])
        if lobe == "LEGACY":
            res = _solve_glossy(lobe, ver, x_n, x_w, p[sl], rc[sl], g[sl], tint_f[sl], bh[sl],
                                r0[sl], b0[sl])
            beta[sl], k_max[sl] = res["beta"], res["k_max"]
        else:
            res = _solve(lobe, ver, x_n, x_w, p[sl], rc[sl], g[sl], tint_f[sl], r0[sl], b0[sl])
        for k in out:
            out[k][sl] = res[k]
        steps = max(steps, res["steps"])
        residual = max(residual, res["residual"])
        over += res["over"]

    eps = np.finfo(dtype).eps
    r, omr = out["r"], np.maximum(out["omr"], eps)
    eta, kappa = gulbrandsen_ior(np.minimum(r, 1.0 - eps), g, omr)
    m = np.argmax(rc, axis=-1)[:, None]
    r_max, omr_max = r.max(axis=-1), omr.min(axis=-1)
    eta_d = dielectric_ior(np.minimum(r_max, 1.0 - eps), omr_max)
    if lobe != "LEGACY":
        beta = b0
    s_n, s_w = out["s_n"], out["s_w"]
    p_ms = p[:, None] * s_w / s_n
    q_ms = q[:, None] + p[:, None] * ((s_n - 1.0) - (s_w - 1.0)) / s_n
    clamped = dict(mapping.clamped)
    if over:
        clamped["reflectivity > 1 (Multiscatter GGX peak not kept)"] = over

    def back(a, colour=False):
        a = np.asarray(a).reshape(shape + ((3,) if colour else ())).astype(dtype)
        return a[()] if a.ndim == 0 else a

    info = MultiscatterPeak(
        lobe=lobe, version=ver, energy_narrow=back(s_n, True), energy_wide=back(s_w, True),
        energy_reference=back(out["s_0"], True), peak_ratio=back(p_ms, True),
        peak_complement=back(q_ms, True), steps=steps, residual=residual,
        halo_max=back(k_max) if lobe == "LEGACY" else None)
    return replace(
        mapping, beta=back(beta), reflectivity=back(r, True), ior=back(eta, True),
        extinction=back(kappa, True),
        peak_ratio=back(np.take_along_axis(p_ms, m, -1)[:, 0]),
        peak_complement=back(np.clip(np.take_along_axis(q_ms, m, -1)[:, 0], 0.0, 1.0)),
        halo_intensity=back(beta * r_max), reflectivity_max=back(r_max),
        weight_narrow=back((1.0 - beta)[:, None] * r, True),
        weight_wide=back(beta[:, None] * r, True), dielectric_ior=back(eta_d), clamped=clamped,
        multiscatter=info)


def _bezier_share(mapping, flat, rc, p, q, dtype):
    """The Bézier's share of the largest halo (Eq. 15 over Eq. 7 at β_h = 1; 1 for Eq. 7)."""
    n = len(p)
    if mapping.smoothness is None:
        return np.ones(n)
    w = flat(mapping.smoothness)
    w = np.where(np.isnan(w) | (w <= 0), np.finfo(dtype).tiny, w)
    rc_max, one = rc.max(axis=-1), np.ones(n)
    k_w, _, _, _ = haze_terms(rc_max, p, q, one, w)
    k_7, _, _, _ = haze_terms(rc_max, p, q, one, None)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(k_7 > 0, np.clip(k_w / k_7, 0.0, 1.0), 1.0)


def _texels_and_targets(lobe, version, x_n, x_w, p, rc, g, tint):
    """The chunk's texels and what (*) holds them to: (texels, the max channel's texels, its
    index m, S_0, the haze-free peak r_c S_0 per channel, that peak of channel m)."""
    narrow, wide = _Lobe(x_n, version), _Lobe(x_w, version)
    white = np.all(tint == 1.0, axis=-1, keepdims=True)
    t = _Texels(lobe, exact_conductor(version), mn=narrow.missing, en=narrow.eavg,
                mw=wide.missing, ew=wide.eavg, p=p[:, None], rc=rc, g=g, tint=tint, white=white)
    n = len(p)
    m = np.argmax(rc, axis=-1)
    tm = t.take(np.arange(n), m)  # the max channel (colour axis of length 1)
    rc_m = np.take_along_axis(rc, m[:, None], -1)
    # the haze-free material: one lobe, F(0) = r_c, β = 0
    f0, _ = t.fss(rc, 1.0 - rc, rc_m, 1.0 - rc_m, np.zeros((n, 1)))
    s_0 = 1.0 + _excess(t.mn, t.en, f0)
    target = rc * s_0
    return t, tm, m, s_0, target, np.take_along_axis(target, m[:, None], -1)[:, 0]


def _channels(lobe, t, m, target, r_hat, omr_hat, beta, r0):
    """Every channel's r from (*) at β and the max channel's r̂ (which channel m gets again):
    r, 1 - r, S_n, S_w, the Newton steps, the channels even r = 1 leaves short, and the
    largest |hazy / haze-free peak - 1| of the others."""
    n = len(beta)
    rows = np.arange(n)

    def f_ch(x, sel):
        sub = t.take(sel)
        return target[sel] - sub.peak(1.0 - x, x, r_hat[sel, None], omr_hat[sel, None], beta[sel, None])

    short = f_ch(np.zeros((n, 3)), rows) > 0
    omr, steps = _root(f_ch, np.zeros((n, 3)), np.ones((n, 3)), np.clip(1.0 - r0, 0.0, 1.0), rows,
                       target)
    omr = np.where(short, 0.0, omr)
    np.put_along_axis(omr, m[:, None], omr_hat[:, None], -1)
    if lobe == "COAT":  # one Coat IOR: every channel is the max channel (equal up to rounding)
        omr = np.repeat(omr_hat[:, None], 3, -1)
    r = 1.0 - omr
    b = beta[:, None]
    fn, fw = t.fss(r, omr, r_hat[:, None], omr_hat[:, None], b)
    s_n = 1.0 + _excess(t.mn, t.en, fn)
    s_w = 1.0 + _excess(t.mw, t.ew, fw)
    hazy = r * ((1.0 - b) * s_n + b * t.p * s_w)
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.where((target > 0) & ~short, hazy / target - 1.0, 0.0)
    return dict(r=r, omr=omr, s_n=s_n, s_w=s_w, steps=steps, short=short,
                residual=float(np.abs(err).max(initial=0.0)))


def _solve(lobe, version, x_n, x_w, p, rc, g, tint, r0, beta):
    """(*) for one chunk of texels (1-D arrays, colours (n, 3)) at the mapping's own β: the
    max channel m (of r_c) first (the dielectric's IOR and the coat's follow from r̂), then
    every channel.  (*) is increasing in r: each channel has one root in [0, 1], or none when
    even r = 1 falls short (counted)."""
    t, tm, m, s_0, target, t_m = _texels_and_targets(lobe, version, x_n, x_w, p, rc, g, tint)
    n = len(p)
    rows = np.arange(n)

    # the max channel, in x = 1 - r̂ (the peak falls as x grows)
    def f_hat(x, sel):
        sub = tm.take(sel)
        r = 1.0 - x[:, None]
        return t_m[sel] - sub.peak(r, x[:, None], r, x[:, None], beta[sel, None])[:, 0]

    short_m = f_hat(np.zeros(n), rows) > 0  # even r̂ = 1 falls short
    x0 = np.clip(1.0 - r0.max(axis=-1), 0.0, 1.0)
    omr_hat, steps = _root(f_hat, np.zeros(n), np.ones(n), x0, rows, t_m)
    omr_hat = np.where(short_m, 0.0, omr_hat)
    r_hat = 1.0 - omr_hat

    solved = _channels(lobe, t, m, target, r_hat, omr_hat, beta, r0)
    return dict(r=solved["r"], omr=solved["omr"], s_n=solved["s_n"], s_w=solved["s_w"], s_0=s_0,
                steps=max(steps, solved["steps"]),
                over=int(np.count_nonzero(solved["short"].any(axis=-1) | short_m)),
                residual=solved["residual"])


def _solve_glossy(lobe, version, x_n, x_w, p, rc, g, tint, bh, r0, b0):
    """Glossy lobes: (*) for one chunk of texels (1-D arrays, colours (n, 3)); ``bh`` is β_h
    times the Bézier share.  The peak-keeping family: for each β every channel's r follows from (*).
    β_max = min(1, first β at which a channel needs r = 1); k_max = β_max r̂_m(β_max) is the
    largest halo weight of the max channel m (of r_c); k̂ = bh k_max; r̂_m from (*) with
    β = k̂ / r̂_m; then each channel's r from (*) with that β."""
    t, tm, m, s_0, target, t_m = _texels_and_targets(lobe, version, x_n, x_w, p, rc, g, tint)
    n = len(p)
    rows = np.arange(n)
    steps = 0

    def peak_m(r, omr, beta, sel):
        sub = tm.take(sel)
        return sub.peak(r[:, None], omr[:, None], r[:, None], omr[:, None], beta[:, None])[:, 0]

    # the largest β: 1 (positivity, Eq. 6), or the first β at which some channel needs r = 1 to
    # keep its peak (energy): r = 1 gives r [(1-β) S_n + β p S_w] - T, convex in β (linear for
    # Fresnel lobes); for the dielectric that channel is the max, so r̂ = 1 too
    def peak_at_one(beta, sel):
        one = np.ones((len(sel), 3))
        sub = t.take(sel)
        return sub.peak(one, np.zeros_like(one), one[:, :1], np.zeros((len(sel), 1)),
                        beta[:, None] * np.ones((1, 3))) - target[sel]

    beta_max = np.ones(n)
    for ch in range(3):  # each channel's energy bound (a colour axis per channel would do too)
        b_ch, it = _first_descent_root(lambda b, sel: peak_at_one(b, sel)[:, ch], beta_max.copy(), rows,
                                       target[:, ch])
        beta_max = np.minimum(beta_max, b_ch)
        steps = max(steps, it)
    # the max channel's halo weight there: k_max = β_max r̂(β_max)
    def f_max(x, sel):
        r = 1.0 - x
        return t_m[sel] - peak_m(r, x, beta_max[sel], sel)  # increasing in x

    omr_bound, it = _root(f_max, np.zeros(n), np.ones(n), np.zeros(n), rows, t_m)  # r̂ = 1 usually
    steps = max(steps, it)
    k_max = beta_max * (1.0 - omr_bound)
    k = bh * k_max

    # r̂ from (*) with β = k / r̂, in x = 1 - r̂ ∈ [0, 1 - k] (decreasing in x)
    def f_hat(x, sel):
        r = 1.0 - x
        with np.errstate(divide="ignore", invalid="ignore"):
            beta = np.where(r > 0, k[sel] / r, 0.0)
        return t_m[sel] - peak_m(r, x, beta, sel)  # increasing in x

    x0 = np.clip(1.0 - r0.max(axis=-1), 0.0, 1.0 - k)
    omr_hat, it = _root(f_hat, np.zeros(n), 1.0 - k, x0, rows, t_m)
    steps = max(steps, it)
    r_hat = 1.0 - omr_hat
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = np.where(r_hat > 0, k / r_hat, b0)  # r̂_c = 0: the mapping's limit value

    solved = _channels(lobe, t, m, target, r_hat, omr_hat, beta, r0)
    return dict(r=solved["r"], omr=solved["omr"], beta=beta, k=k, k_max=k_max, s_n=solved["s_n"],
                s_w=solved["s_w"], s_0=s_0, steps=max(steps, solved["steps"]),
                over=int(np.count_nonzero(solved["short"].any(axis=-1))), residual=solved["residual"])


def _first_descent_root(g, k_hi, rows, scale, max_iter=60):
    """The smallest k in [0, k_hi] with g(k) = 0 for a convex g with g(0) >= 0, or k_hi where g
    stays >= 0 on [0, k_hi] (linear g: one Newton step).  Newton from k = 0 does not pass the
    first root of a convex function (but for the difference quotient, which the next steps
    correct); it stops at |g| <= 8 ε ``scale`` or a relative step of 1e-15.
    Returns (k, iterations)."""
    k = np.zeros_like(k_hi)
    todo = np.arange(len(k))
    it = 0
    for it in range(1, max_iter + 1):
        ka, hi = k[todo], k_hi[todo]
        gk = g(ka, rows[todo])
        h = np.maximum(1e-6 * hi, 1e-300)
        slope = (g(ka + h, rows[todo]) - gk) / h
        with np.errstate(divide="ignore", invalid="ignore"):
            # no descent left while g > 0: the minimum is above 0, no root up to k_hi
            nk = np.where(slope < 0, ka - gk / slope, np.where(gk > 0, np.inf, ka))
        nk = np.clip(nk, 0.0, hi)
        k[todo] = nk
        done = ((np.abs(gk) <= 8 * _EPS * scale[todo]) | (nk >= hi)
                | (np.abs(nk - ka) <= 1e-15 * np.abs(nk)))
        k[todo] = np.where(np.abs(gk) <= 8 * _EPS * scale[todo], ka, nk)
        todo = todo[~done]
        if not len(todo):
            break
    return k, it
