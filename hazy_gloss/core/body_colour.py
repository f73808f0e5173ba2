# SPDX-License-Identifier: GPL-3.0-or-later
"""The body colour under a hazy layer: Cycles' layering albedo and its compensation (no bpy).

Cycles puts the Principled BSDF's dielectric specular on top of its diffuse/subsurface base and
weights the base by 1 - A, A = the specular layer's albedo *estimate* for the view direction
(kernel/svm/closure.h, Principled; the same in Blender 4.5, 5.2 and 5.3 up to the differences
listed below).  For one Principled BSDF with closure weight w, view cosine μ = N·ω_o:

    f0       = F0(IOR) = ((IOR - 1)/(IOR + 1))²,  η = IOR         (IOR clamped to >= 1e-5)
    if Specular IOR Level L != 0.5:  f0 *= 2L,  η = (1 + √f0')/(1 - √f0'), f0' = min(f0, 0.99)
                                     (η -> 1/η when IOR < 1)
    no specular closure when η == 1 (float32): A = 0
    f0_c     = saturate(f0 · Specular Tint_c)                     (bsdf_microfacet_setup_...)
    x        = (α_x α_y)^¼, α saturated                            roughness index
    s        = ggx_gen_schlick_ior_s(x, y(μ), z),  z = √|(η - 1)/(η + 1)| = F0(η)^¼
    est_c    = f0_c + (1 - f0_c) s                                 bsdf_microfacet_estimate_albedo
    D_c      = Multiscatter GGX only: the energy-compensation factor the closure weight carries,
               (1 + F_ms,c (1 - E)/E) / (1/E), E = ggx_E(x, y_E(μ)), F_ms = F_ss E_avg /
               (1 - F_ss (1 - E_avg)), F_ss,c = f0_c + (1 - f0_c) saturate((Fss(η) - F0(η)) /
               (1 - F0(η))), Fss(η) Kulla-Conty's fit (microfacet_ggx_preserve_energy); else 1
    A        = 4.5, 5.2: max_c(D_c est_c)       (closure_layering_weight: one grey factor)
               5.3:      D_c · max_c'(est_c')   (closure_layer_albedo: reduce_max of the estimate)
    base weight = w · base · (1 - saturate(A))

Version differences: 4.5/5.2 read a 16³ table with y = μ, 5.3 a 32³ table with y = √μ (and a
different E table grid, y_E = μ vs √μ); 4.5/5.2 take the maximum over channels after the
multiscatter factor, 5.3 before it (so a tinted Multiscatter GGX specular darkens the base by a
coloured A in 5.3 only); 4.5 skips the table and returns 0 where the specular's Fresnel at the
view angle is 0 in every channel (Specular Tint black and F_dielectric(μ) < F0(η): past the
Brewster dip of a large IOR).
The tables come from the bpy wheels (scripts/extract_albedo_tables.py -> cycles_albedo_tables).

The estimate is not the GGX BRDF's albedo: s is the mean of the remapped Fresnel over visible
normals, which assumes an energy-conserving microfacet model (A -> 1 as f0 -> 1 for any
roughness); docs/body-colour.md compares the two.

Hazy layer (blender/model/layer.py, Make Hazy): the core keeps its roughness α_n, its IOR is raised to
IOR' (F0(IOR') = gain F0(IOR)); a copy with roughness α_w and the same IOR' is mixed in by β.
The base under the mix is base [(1-β)(1 - A(α_n, IOR')) + β(1 - A(α_w, IOR'))]: darker than the
original base (1 - A(α_n, IOR)).  :func:`compensation` gives the factor c(μ) that restores it,
as a polynomial in the Layer Weight node's Facing f = 1 - |N·I| for shader nodes, with the clamp
min(base c, 1) (a diffuse albedo above 1 would not conserve energy) and the darkening that the
clamp leaves.

Arithmetic is float64 (Cycles runs float32: ~1e-7 relative).  Non-finite inputs are read as the
kernel's clamps read NaN (saturate(NaN) = 0, fmaxf(NaN, a) = a, max(NaN, 0) = 0); +inf IOR and
Specular IOR Level are taken as their limits (clamped to 1e30), not the kernel's NaN path.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np

from .tables import cycles_albedo_tables as _albedo_tables
from .tables import cycles_ggx_tables as _ggx_tables
from .multiscatter import cycles_version

__all__ = ("DISTRIBUTIONS", "MAX_ANGLE", "specular_albedo", "albedo_estimate", "kernel_specular",
           "facing", "body_weights", "factor", "compensation", "BodyColour", "generation",
           "generation_tables")

#: The Principled BSDF's distributions (node enum names).
DISTRIBUTIONS = ("GGX", "MULTI_GGX")
#: +inf is read as this (the limit: F0 = 1 in float64).
_BIG = 1e30


# --------------------------------------------------------------------------------------------
# Tables and Cycles' lookups (kernel/util/lookup_table.h)
# --------------------------------------------------------------------------------------------


def generation(version):
    return "V53" if cycles_version(version) >= (5, 3) else "V4"


def _parse(text, shape):
    a = np.array(text.split(), dtype=np.int64)
    return (a / 1e6).astype(np.float32).astype(np.float64).reshape(shape)


@functools.cache
def generation_tables(gen):
    n = 32 if gen == "V53" else 16
    return {"ior_s": _parse(getattr(_albedo_tables, f"IOR_S_{gen}"), (n, n, n)),
            "e": _parse(getattr(_albedo_tables, f"E_{gen}"), (32, 32)),
            "eavg": np.asarray(getattr(_ggx_tables, f"EAVG_{gen}"), np.float32).astype(np.float64),
            "glass_e_mu1": _parse(getattr(_albedo_tables, f"GLASS_E_MU1_{gen}"), (n, n))}


def _saturate(x):
    """Cycles' saturatef: min(max(x, 0), 1) with max(NaN, 0) = 0."""
    x = np.asarray(x, np.float64)
    return np.where(np.isnan(x), 0.0, np.clip(x, 0.0, 1.0))


def _axis(u, size):
    """Index, next index and fraction of one table axis (saturated, scaled to the nodes,
    truncated, clamped to the last node)."""
    u = _saturate(u) * (size - 1)
    i = np.minimum(u.astype(np.int64), size - 1)
    return i, np.minimum(i + 1, size - 1), u - i


def _read1(table, x):
    i0, i1, t = _axis(x, table.shape[0])
    return (1.0 - t) * table[i0] + t * table[i1]


def _read2(table, x, y):
    """lookup_table_read_2D: table[y][x]."""
    ny, nx = table.shape
    j0, j1, ty = _axis(y, ny)
    i0, i1, tx = _axis(x, nx)

    def row(j):
        return (1.0 - tx) * table[j, i0] + tx * table[j, i1]
    return (1.0 - ty) * row(j0) + ty * row(j1)


def _read3(table, x, y, z):
    """lookup_table_read_3D: table[z][y][x]."""
    nz = table.shape[0]
    k0, k1, tz = _axis(z, nz)
    x, y = np.broadcast_arrays(x, y)
    return (1.0 - tz) * _read2_at(table, k0, x, y) + tz * _read2_at(table, k1, x, y)


def _read2_at(table, k, x, y):
    _, ny, nx = table.shape
    j0, j1, ty = _axis(y, ny)
    i0, i1, tx = _axis(x, nx)

    def row(j):
        return (1.0 - tx) * table[k, j, i0] + tx * table[k, j, i1]
    return (1.0 - ty) * row(j0) + ty * row(j1)


# --------------------------------------------------------------------------------------------
# The Principled specular as the kernel sets it up
# --------------------------------------------------------------------------------------------


def _f0_from_ior(ior):
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def _ior_from_f0(f0):
    q = np.sqrt(np.clip(f0, 0.0, 0.99))
    return (1.0 + q) / (1.0 - q)


def _finite(x, lo, hi=_BIG):
    """fmaxf(x, lo) (NaN -> lo), +inf -> hi."""
    x = np.asarray(x, np.float64)
    return np.where(np.isnan(x), lo, np.clip(x, lo, hi))


def kernel_specular(ior, level=0.5):
    """(η, F0 before tint, exists) of the Principled specular closure for the IOR and Specular
    IOR Level sockets, as svm/closure.h computes them (η is the closure's IOR, which indexes the
    table; ``exists`` is False where η == 1 in float32: no specular closure, A = 0)."""
    ior = _finite(ior, 1e-5)
    level = np.where(np.isnan(np.asarray(level, np.float64)), 0.0,
                     np.clip(np.asarray(level, np.float64), 0.0, _BIG))
    f0 = _f0_from_ior(ior)
    scaled = f0 * 2.0 * level
    eta_l = _ior_from_f0(scaled)
    eta_l = np.where(ior < 1.0, 1.0 / eta_l, eta_l)
    keep = level == 0.5
    eta = np.where(keep, ior, eta_l)
    f0 = np.where(keep, f0, scaled)
    return eta, f0, np.float32(eta) != np.float32(1.0)  # the kernel compares float32


def _fresnel_dielectric(c, eta):
    """fresnel_dielectric (unpolarised, from the polarised amplitudes), |c| <= 1."""
    t2 = eta * eta - (1.0 - c * c)
    with np.errstate(divide="ignore", invalid="ignore"):
        ct = -np.sqrt(np.maximum(t2, 0.0)) / eta
        rs = (c + eta * ct) / (c - eta * ct)
        rp = (ct + eta * c) / (eta * c - ct)
        f = 0.5 * (rs * rs + rp * rp)
    return np.where(t2 <= 0.0, 1.0, np.where(np.isfinite(f), f, 1.0))


def _fss_dielectric(eta):
    """fresnel_dielectric_Fss (Kulla-Conty's fit)."""
    lo = 0.997118 + eta * (0.1014 - eta * (0.965241 + eta * 0.130607))
    hi = (eta - 1.0) / (4.08567 + 1.00071 * eta)
    return np.where(eta < 1.0, lo, hi)


def _prepare(alpha_x, alpha_y, mu, ior, tint, level, version):
    t = np.asarray(tint, np.float64)
    colour = t.ndim >= 1 and t.shape[-1] == 3
    tint_c = t if colour else t[..., None]
    tint_c = np.where(np.isnan(tint_c), 0.0, np.clip(tint_c, 0.0, _BIG))  # max(tint, 0)
    lead = tint_c.shape[:-1]
    ax, ay, mu, ior, level = np.broadcast_arrays(
        *(np.asarray(v, np.float64) for v in (alpha_x, alpha_y, mu, ior, level)),
        np.empty(lead))[:-1]
    shape = ax.shape
    tint_c = np.broadcast_to(tint_c, shape + (tint_c.shape[-1],))
    eta, f0, exists = kernel_specular(ior, level)
    gen = generation(version)
    rough = np.sqrt(np.sqrt(_saturate(ax) * _saturate(ay)))
    mu = np.where(np.isnan(mu), 0.0, mu)
    y = np.sqrt(np.maximum(mu, 0.0)) if gen == "V53" else mu
    f0_c = _saturate(f0[..., None] * tint_c)
    return dict(colour=colour, gen=gen, eta=eta, f0=f0, f0_c=f0_c, exists=exists, rough=rough,
                mu=mu, y=y, shape=shape)


def _estimate(p, version):
    """bsdf_microfacet_estimate_albedo (reflection only), per channel (..., n)."""
    eta = p["eta"]
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.sqrt(np.abs((eta - 1.0) / (eta + 1.0)))
    s = _read3(generation_tables(p["gen"])["ior_s"], p["rough"], p["y"], z)
    est = p["f0_c"] + (1.0 - p["f0_c"]) * s[..., None]
    if cycles_version(version) < (5, 2):
        # 4.5: no table where microfacet_fresnel(cos_NI) is 0 in every channel: f0 = 0 and the
        # real Fresnel at the view angle below F0 (past the Brewster dip of a large IOR).  Face-on
        # F = F0 exactly and the kernel's float32 rounding decides (renders show both): the table
        # is taken there, a difference of at most s(α, 1, η) <= 1.8e-3.
        c = np.clip(p["mu"], 0.0, 1.0)
        f_real = _fresnel_dielectric(c, eta)
        zero = (np.max(p["f0_c"], axis=-1) == 0.0) & (f_real < _f0_from_ior(eta) * (1.0 - 1e-6))
        est = np.where(zero[..., None], 0.0, est)
    return est


def _multiscatter(p):
    """The factor microfacet_ggx_preserve_energy puts on the closure weight, per channel."""
    t = generation_tables(p["gen"])
    eta = p["eta"]
    f0_eta = _f0_from_ior(eta)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = _saturate((_fss_dielectric(eta) - f0_eta) / (1.0 - f0_eta))
    fss = p["f0_c"] + (1.0 - p["f0_c"]) * s[..., None]
    e = _read2(t["e"], p["rough"], p["y"])[..., None]
    eavg = _read1(t["eavg"], p["rough"])[..., None]
    missing = (1.0 - e) / e
    with np.errstate(divide="ignore", invalid="ignore"):
        fms = fss * eavg / (1.0 - fss * (1.0 - eavg))
    fms = np.where(np.isfinite(fms), fms, 1.0)
    dark = (1.0 + fms * missing) / (1.0 + missing)
    return np.where(np.all(fss == 1.0, axis=-1, keepdims=True), 1.0, dark)


def _check_distribution(distribution):
    d = str(distribution).upper()
    if d not in DISTRIBUTIONS:
        raise ValueError(f"distribution must be one of {', '.join(DISTRIBUTIONS)}; got {distribution!r}")
    return d


def albedo_estimate(alpha_x, alpha_y, mu, ior, tint=1.0, level=0.5, version=None):
    """Cycles' albedo estimate of the Principled specular closure alone (its Glossy Color
    before the closure weight): f0_c + (1 - f0_c) s, per channel when ``tint`` is a colour
    (shape (..., 3)), else one value; 0 where the node makes no specular closure."""
    p = _prepare(alpha_x, alpha_y, mu, ior, tint, level, version)
    est = np.where(p["exists"][..., None], _estimate(p, version), 0.0)
    return est if p["colour"] else est[..., 0]


def specular_albedo(alpha_x, alpha_y, mu, ior, tint=1.0, level=0.5, distribution="GGX",
                    version=None):
    """A: the fraction of the diffuse/subsurface base that the Principled dielectric specular
    takes (base weight = base (1 - A)), exactly as Cycles computes it (module docstring).

    alpha_x, alpha_y: the closure's α (Roughness², split by Anisotropic; only α_x α_y counts);
    mu: view cosine N·ω_o; ior, tint (Specular Tint), level (Specular IOR Level): the node's
    sockets; distribution "GGX" or "MULTI_GGX"; version: Blender (major, minor) or "4.5"
    (None: the running Blender, else the newest).  Broadcasting float64 arrays; ``tint`` a
    scalar or a colour (..., 3) — then A is (..., 3) (per channel in 5.3 with Multiscatter GGX,
    the same value in every channel otherwise).  Result in [0, 1]."""
    multi = _check_distribution(distribution) == "MULTI_GGX"
    p = _prepare(alpha_x, alpha_y, mu, ior, tint, level, version)
    est = _estimate(p, version)
    dark = _multiscatter(p) if multi else np.ones_like(est)
    if p["gen"] == "V53":
        a = dark * np.max(est, axis=-1, keepdims=True)
    else:
        a = np.broadcast_to(np.max(dark * est, axis=-1, keepdims=True), est.shape)
    a = np.where(p["exists"][..., None], _saturate(a), 0.0)
    return a if p["colour"] else a[..., 0]


def facing(mu):
    """The Layer Weight node's Facing output at Blend 0.5: 1 - |N·I| (svm/fresnel.h)."""
    return 1.0 - np.abs(np.asarray(mu, np.float64))



# --------------------------------------------------------------------------------------------
# The compensation for a hazy layer
# --------------------------------------------------------------------------------------------

#: View angles the fit covers by default (beyond, the polynomial is extrapolated to 90°).
MAX_ANGLE = 80.0
#: Fit nodes (Chebyshev points of [0, f_max]); the tables are piecewise linear in μ or √μ, so c
#: has kinks at their nodes and is sampled densely.
_FIT_POINTS = 240
#: Report grid: μ from 0 to 1 (trapezoid rule for the 2μ-weighted averages).
_REPORT_POINTS = 1025
_FLOOR = 1e-12
#: c never exceeds this (a vanishing hazy body, e.g. IOR' -> ∞, would make it unbounded).
C_LIMIT = 1e3


def _alphas(alpha):
    a = np.asarray(alpha, np.float64)
    if a.ndim == 0:
        return float(a), float(a)
    if a.shape != (2,):
        raise ValueError(f"alpha must be a number or (alpha_x, alpha_y); got shape {a.shape}")
    return float(a[0]), float(a[1])


def body_weights(alpha, ior, ior_hazy, beta, alpha_wide, mu, *, tint=1.0, level=0.5,
                 distribution="GGX", version=None):
    """The base's weight under the original specular, 1 - A(α_n, μ, IOR), and under the hazy
    layer, (1-β)(1 - A(α_n, μ, IOR')) + β(1 - A(α_w, μ, IOR')); each (..., 3) for μ (...)."""
    mu = np.asarray(mu, np.float64)
    tint3 = np.broadcast_to(np.asarray(tint, np.float64), (3,))

    def body(a, ior_):
        ax, ay = _alphas(a)
        return 1.0 - specular_albedo(ax, ay, mu, ior_, tint3, level, distribution, version)

    b = float(np.where(np.isfinite(beta), np.clip(beta, 0.0, 1.0), 0.0))
    return body(alpha, ior), (1.0 - b) * body(alpha, ior_hazy) + b * body(alpha_wide, ior_hazy)


def factor(alpha, ior, ior_hazy, beta, alpha_wide, mu, **kw):
    """c(μ) = original body weight / hazy body weight, per channel (..., 3), <= C_LIMIT
    (1 where the original body is 0)."""
    orig, hazy = body_weights(alpha, ior, ior_hazy, beta, alpha_wide, mu, **kw)
    return _ratio(orig, hazy)


def _ratio(orig, hazy):
    c = np.where(orig > _FLOOR, orig / np.maximum(hazy, _FLOOR), 1.0)
    return np.minimum(c, C_LIMIT)


@dataclass(frozen=True)
class BodyColour:
    """The compensation of one hazy material's body colour (:func:`compensation`).

    coefficients: degree + 1 rows of 3 (R, G, B): c(f) ≈ Σ_k a_k f^k, f = Layer Weight Facing
    = 1 - μ; grey: the three channels share them (a scalar polynomial suffices).
    fit_error: max |c_fit/c - 1| over view angles 0..max_angle (what the fit minimises);
    fit_error_hemisphere: the same to 90° (beyond max_angle the polynomial is extrapolated);
    fit_rms: the 2μ-weighted rms of c_fit/c - 1 over the hemisphere.
    base: the base colour; darkening_face_on / darkening_average: per channel, how much darker
    the hazy body is than the original without compensation (μ = 1, and the 2μ-weighted mean
    over the hemisphere); residual_face_on / residual_average: the same with the compensation
    min(base c, 1) (exact c: what the clamp leaves); clamped: whether base c > 1 anywhere."""

    coefficients: tuple
    grey: bool
    degree: int
    max_angle: float
    fit_error: float
    fit_error_hemisphere: float
    fit_rms: float
    base: tuple
    c_face_on: tuple
    c_max: float
    darkening_face_on: tuple
    darkening_average: tuple
    residual_face_on: tuple
    residual_average: tuple
    clamped: bool

    def polynomial(self, f):
        """c_fit(f) per channel, shape (..., 3) (Horner, as the nodes evaluate it)."""
        f = np.asarray(f, np.float64)[..., None]
        a = np.asarray(self.coefficients, np.float64)
        out = np.broadcast_to(a[-1], f.shape[:-1] + (3,)).copy()
        for k in range(a.shape[0] - 2, -1, -1):
            out = out * f + a[k]
        return out

    def compensated_base(self, mu):
        """min(base c_fit(1 - μ), 1) per channel, shape (..., 3): the Base Color to wire."""
        return np.minimum(np.asarray(self.base) * self.polynomial(facing(mu)), 1.0)

    def warning(self, threshold=0.005):
        """One line when the clamp leaves more than ``threshold`` of darkening (face-on or on
        average, any channel), else None."""
        avg, face = np.asarray(self.residual_average), np.asarray(self.residual_face_on)
        if not self.clamped or max(avg.max(), face.max()) <= threshold:
            return None
        ch = "RGB"[int(np.argmax(face))] if face.max() >= avg.max() else "RGB"[int(np.argmax(avg))]
        return (f"Base Color too bright to keep under the haze: body colour stays "
                f"{100 * face.max():.1f}% darker face-on, {100 * avg.max():.1f}% on average "
                f"(worst channel {ch}; base x {max(self.c_face_on):.2f} would exceed 1)")

    def nodes(self):
        """A builder-independent description of the shader nodes: Layer Weight (Blend 0.5)
        -> Facing f; c = a[n] f^n + ... + a[0] by Horner, p <- p f + a[k] (one MULTIPLY_ADD
        per degree); Base Color = min(base c, 1): n + 3 nodes for degree n >= 1.
        "constant_base": the same with the base folded into the coefficients (b[k] = base a[k],
        Vector Math MULTIPLY_ADD, then MINIMUM): n + 2 nodes, for an unlinked Base Color."""
        a = np.asarray(self.coefficients, np.float64)
        n = a.shape[0] - 1
        coeffs = [float(x) for x in a[:, 0]] if self.grey else [tuple(map(float, r)) for r in a]
        math = "ShaderNodeMath" if self.grey else "ShaderNodeVectorMath"
        folded = [tuple(float(x) for x in np.asarray(self.base) * r) for r in a]
        return {
            "facing": {"node": "ShaderNodeLayerWeight", "output": "Facing", "Blend": 0.5,
                       "Normal": "the core's Normal input (the same link, if any)"},
            "coefficients": coeffs,
            "formula": "c = sum(a[k] * f**k for k in range(n + 1)); "
                       "Base Color = min(base * c, 1) per channel",
            "horner": [{"node": math, "operation": "MULTIPLY_ADD",
                        "inputs": ("a[n]" if k == n - 1 else "previous", "f", f"a[{k}]")}
                       for k in range(n - 1, -1, -1)],
            "base": [{"node": "ShaderNodeVectorMath", "operation": "MULTIPLY",
                      "inputs": ("base", "c")},
                     {"node": "ShaderNodeVectorMath", "operation": "MINIMUM",
                      "inputs": ("previous", (1.0, 1.0, 1.0))}],
            "node_count": n + 3 if n > 0 else 2,
            "constant_base": {
                "coefficients": folded,
                "horner": [{"node": "ShaderNodeVectorMath", "operation": "MULTIPLY_ADD",
                            "inputs": ("b[n]" if k == n - 1 else "previous", "f", f"b[{k}]")}
                           for k in range(n - 1, -1, -1)],
                "base": [{"node": "ShaderNodeVectorMath", "operation": "MINIMUM",
                          "inputs": ("previous", (1.0, 1.0, 1.0))}],
                "node_count": n + 2 if n > 0 else 0,
            },
        }


def _fit(f, c, degree, iterations=40):
    """Polynomial in f minimising max |p/c - 1| (Lawson's iteratively reweighted least
    squares, started from plain relative least squares)."""
    vander = f[:, None] ** np.arange(degree + 1)[None, :]
    w = np.ones_like(f)
    best, best_err = None, np.inf
    for _ in range(iterations if degree > 0 else 1):
        sw = np.sqrt(w) / c
        a = np.linalg.lstsq(vander * sw[:, None], c * sw, rcond=None)[0]
        r = np.abs(vander @ a / c - 1.0)
        if r.max() < best_err:
            best, best_err = a, r.max()
        w = w * (r + 1e-3 * r.max() + 1e-300)
        w /= w.sum()
    return best


def compensation(alpha, ior, ior_hazy, beta, alpha_wide, base_color=(1.0, 1.0, 1.0), *,
                 tint=1.0, level=0.5, distribution="GGX", degree=3, max_angle=MAX_ANGLE,
                 version=None):
    """The body-colour compensation of a hazy Principled material: c(μ) = (1 - A(α_n, μ, IOR))
    / [(1-β)(1 - A(α_n, μ, IOR')) + β(1 - A(α_w, μ, IOR'))], fitted as c ≈ Σ_k a_k f^k in the
    Layer Weight node's Facing f = 1 - μ, and what the clamp min(base c, 1) leaves.  Returns
    a :class:`BodyColour`.

    alpha, alpha_wide: the closure α of the core and of the wide lobe (a number, or (α_x, α_y):
    only the product counts); ior: the core's IOR as the user set it; ior_hazy: IOR' as the layer
    writes it on both lobes; tint (Specular Tint, a number or RGB) and level (Specular IOR
    Level) are shared by the three and applied by the kernel to each; beta: the Mix Shader
    factor (the wide lobe's weight); base_color: RGB, for the clamp and its report (c does not
    depend on it; for a textured base pass its brightest value).

    The fit minimises the largest relative error over view angles 0..``max_angle`` (f in
    [0, 1 - cos max_angle]); ``degree`` 0..8 (3: four coefficients, six nodes)."""
    if not (isinstance(degree, (int, np.integer)) and not isinstance(degree, bool)
            and 0 <= degree <= 8):
        raise ValueError(f"degree must be an integer 0..8; got {degree!r}")
    if not (np.isfinite(max_angle) and 0.0 < max_angle <= 90.0):
        raise ValueError(f"max_angle must be in (0, 90] degrees; got {max_angle!r}")
    base = np.broadcast_to(np.asarray(base_color, np.float64), (3,))
    base = np.where(np.isfinite(base), np.clip(base, 0.0, None), np.where(base > 0, 1.0, 0.0))
    kw = dict(tint=tint, level=level, distribution=distribution, version=version)

    f_max = 1.0 - np.cos(np.radians(max_angle))
    n = _FIT_POINTS
    f = 0.5 * f_max * (1.0 - np.cos(np.pi * (np.arange(n) + 0.5) / n))
    c = factor(alpha, ior, ior_hazy, beta, alpha_wide, 1.0 - f, **kw)
    grey = bool(np.all(c == c[:, :1]))
    if grey:
        coeffs = np.repeat(_fit(f, c[:, 0], int(degree))[:, None], 3, axis=1)
    else:
        coeffs = np.stack([_fit(f, c[:, ch], int(degree)) for ch in range(3)], axis=1)

    mu = np.linspace(0.0, 1.0, _REPORT_POINTS)
    orig, hazy = body_weights(alpha, ior, ior_hazy, beta, alpha_wide, mu, **kw)
    c_all = _ratio(orig, hazy)
    result = BodyColour(
        coefficients=tuple(tuple(float(x) for x in row) for row in coeffs), grey=grey,
        degree=int(degree), max_angle=float(max_angle), fit_error=0.0,
        fit_error_hemisphere=0.0, fit_rms=0.0, base=tuple(float(b) for b in base),
        c_face_on=tuple(float(x) for x in c_all[-1]), c_max=float(c_all.max()),
        darkening_face_on=(), darkening_average=(), residual_face_on=(), residual_average=(),
        clamped=False)
    rel_in = result.polynomial(f) / c - 1.0
    rel = result.polynomial(1.0 - mu) / c_all - 1.0
    w = 2.0 * mu * _trapezoid_weights(mu)
    target = base * orig
    with np.errstate(divide="ignore"):  # min(base c, 1) hazy = target min(1, 1/(base c))
        kept = target * np.minimum(1.0, 1.0 / (base * c_all))

    def lost(achieved):
        with np.errstate(divide="ignore", invalid="ignore"):
            face = np.where(target[-1] > 0, 1.0 - achieved[-1] / target[-1], 0.0)
        num, den = w @ (target - achieved), w @ target
        avg = np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)
        return tuple(float(x) for x in face), tuple(float(x) for x in avg)

    dark = lost(base * hazy)
    resid = lost(kept)
    inside = mu >= np.cos(np.radians(max_angle)) - 1e-12
    fit_error = max(float(np.abs(rel_in).max()), float(np.abs(rel[inside]).max(initial=0.0)))
    return replace(result, fit_error=fit_error,
                   fit_error_hemisphere=float(np.abs(rel).max()),
                   fit_rms=float(np.sqrt(w @ np.mean(rel ** 2, axis=1) / w.sum())),
                   darkening_face_on=dark[0], darkening_average=dark[1],
                   residual_face_on=resid[0], residual_average=resid[1],
                   clamped=bool(np.any(base * c_all > 1.0)))


def _trapezoid_weights(x):
    d = np.diff(x)
    w = np.zeros_like(x)
    w[:-1] += 0.5 * d
    w[1:] += 0.5 * d
    return w
