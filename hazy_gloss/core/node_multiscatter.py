# SPDX-License-Identifier: GPL-3.0-or-later
"""The Multiscatter GGX peak correction (core.multiscatter.correct_mapping) as node math.

Called by :func:`hazy_gloss.core.node_math.mapping` with ``multiscatter=LOBE`` on the graph of
the single-scatter mapping, so textured materials keep the peak under Cycles' energy factor
(docs/mapping.md §11, "In the shader").  Built-in nodes only:

- E(μ=1, x) and E_avg(x): one Color Ramp per lobe (32 linear stops at i/31 holding Cycles'
  table nodes; Blender resamples a ramp to 256 entries, so the lookup differs from Cycles' own
  by <= 1.2e-4 in E, 6.7e-5 in E_avg: the corners of the piecewise-linear table are cut);
- F_ss of the lobe's node as a function of r (the Newton variable): F82-tint and the
  Principled dielectric exactly (affine in r, or through Kulla-Conty's fit of η(r̂), which is
  2√r̂ / (5.08638 - 3.08496 √r̂)); the physical conductor's through two exact evaluations
  (F_c at 1/7 of Gulbrandsen's η, κ) and the chord between them;
- (*) r [(1-β) S_n + β p S_w] = r_c S_0 solved by unrolled safeguarded Newton steps in the
  order of correct_mapping: β_max (closed form for Fresnel lobes, Newton from β = 0 for
  Glossy), k̂_max = β_max r̂_m(β_max), k̂ = β_h k̂_max, r̂_m with β = k̂/r̂_m (the max channel),
  then every channel at that β.

Each Newton step for r at fixed β is written as u' = y (1 + u δ) / (1 + y δ) with y = T/D(u),
δ = D'(u)/D(u) (Newton on u - T/D(u)): non-negative and <= 1 by construction.
"""
from __future__ import annotations

import numpy as np

from .. import constants as K
from .tables import cycles_ggx_tables as _tables
from .multiscatter import _exact_conductor, _generation
from .node_fresnel import TINY, gulbrandsen

__all__ = ("LOBES", "ITERATIONS", "table_stops", "correct", "dielectric_s")

#: Lobe types (core.multiscatter.LOBES).
LOBES = ("CONDUCTOR", "F82_TINT", "DIELECTRIC", "LEGACY", "COAT")

#: Unrolled Newton steps: "k" for r̂_m(β_max) (k̂_max), "m" the max channel r̂_m, "c" every
#: channel at the final β (the physical conductor: "c0" on the chord model, then "c" with its
#: exact F_ss at each iterate), "b" Glossy lobes' β_max.  Measured bounds: docs/mapping.md §11.
ITERATIONS = {"k": 2, "m": 1, "c": 2, "b": 4}
#: Per lobe type: the coat has no per-channel solve, its max channel is the peak.
DEFAULTS = {"COAT": {"m": 2}, "CONDUCTOR": {"c0": 1, "c": 2}}

_F = 6.0 / 7.0  # F82: cos θ = 1/7
_F5 = _F ** 5
_K82 = 1.0 / (18.0 * _F ** 6)  # 7/f⁶ · 1/126 (fresnel_f82_Fss of fresnel_f82_B)
#: Kulla-Conty's fit at η = (1+s)/(1-s), s = √r̂: (η-1)/(4.08567 + 1.00071 η) = 2s/(A - B s)
_FIT_A = 4.08567 + 1.00071
_FIT_B = 4.08567 - 1.00071
_DIV_MIN = 1e-30


def table_stops(version=None):
    """The Color Ramp stops (x = i/31, (E(1, x), E_avg(x), 0)) of Cycles' tables."""
    e = np.asarray(_tables.E_MU1, np.float32)
    a = np.asarray(_tables.EAVG_V53 if _generation(version) == "V53" else _tables.EAVG_V4, np.float32)
    return tuple((i / 31.0, (float(e[i]), float(a[i]), 0.0)) for i in range(32))


class _Table:
    """E(1, x), E_avg(x) of one lobe: m = (1-E)/E, m E_avg and E_avg - 1, so that
    S(F) = 1 + M, M = F m E_avg / (1 - F (1 - E_avg)) (microfacet_ggx_preserve_energy)."""

    def __init__(self, g, x, stops, name):
        e, a, _ = g.separate(g.ramp(x, stops, label=f"E(1,x), E_avg(x) {name}"))
        self.ma = g.mul(g.div(g.sub(1.0, e), e), a, label=f"m E_avg {name}")
        self.am1 = g.sub(a, 1.0)


class _Ops:
    """Math or Vector Math, by ``vec``."""

    def __init__(self, g, vec):
        self.g, self.vec = g, vec

    def __call__(self, op, *a):
        return self.g.vmath(op, *a) if self.vec else self.g.math(op, *a)


def _excess(o, t, f):
    """(M = S - 1, dS/dF) of table ``t`` at Fresnel average ``f``."""
    den = o("MULTIPLY_ADD", f, t.am1, 1.0)  # 1 - F (1 - E_avg) >= E_avg > 0
    return (o("DIVIDE", o("MULTIPLY", f, t.ma), den),
            o("DIVIDE", t.ma, o("MULTIPLY", den, den)))


def _fixed_beta_step(o, u, beta, T, model, tn, tw, p):
    """One Newton step on u - T/D(u), D = (1-β)(1 + M_n) + β p (1 + M_w) at fixed β."""
    g = o.g
    fn, fw, dfn, dfw = model(u)
    mn, dsn = _excess(o, tn, fn)
    mw, dsw = _excess(o, tw, fw)
    omb, bp = g.sub(1.0, beta), g.mul(beta, p)
    d = o("ADD", o("MULTIPLY_ADD", mn, omb, omb), o("MULTIPLY_ADD", mw, bp, bp))
    if fw is fn and dfw is dfn:  # one Fresnel: D' = F' ((1-β) S_n' + β p S_w')
        dp = o("MULTIPLY", o("MULTIPLY_ADD", dsn, omb, o("MULTIPLY", dsw, bp)), dfn)
    else:
        dp = o("MULTIPLY_ADD", o("MULTIPLY", dsn, dfn), omb, o("MULTIPLY", o("MULTIPLY", dsw, dfw), bp))
    y = o("DIVIDE", T, d)
    delta = o("DIVIDE", dp, d)
    un = o("DIVIDE", o("MULTIPLY", y, o("MULTIPLY_ADD", u, delta, 1.0)), o("MULTIPLY_ADD", y, delta, 1.0))
    return o("MINIMUM", un, 1.0)


def _max_channel_step(g, u, k, t_m, model, tn, tw, p):
    """One Newton step on G(u) = u - k - (T_m - k p S_w)/S_n (the max channel with β = k/u):
    G' = 1 + F' (k p S_w' + z S_n')/S_n, z = (T_m - k p S_w)/S_n; u kept in [k, 1]."""
    o = _Ops(g, False)
    f, _, df, _ = model(u)
    mn, dsn = _excess(o, tn, f)
    mw, dsw = _excess(o, tw, f)
    kp = g.mul(k, p)
    sn = g.add(mn, 1.0)
    z = g.div(g.sub(t_m, g.madd(mw, kp, kp)), sn)
    gp = g.madd(g.madd(z, dsn, g.mul(dsw, kp)), g.div(df, sn), 1.0)
    un = g.sub(u, g.div(g.sub(g.sub(u, z), k), gp))
    return g.minimum(g.maximum(un, k), 1.0)


# --------------------------------------------------------------------------------------------
# F_ss of each node as a function of r
# --------------------------------------------------------------------------------------------


def _fit(g, u):
    """Kulla-Conty's F_ss,d(η(u)) = 2s/(A - B s), s = √u, and its derivative A/(s (A - Bs)²)."""
    s = g.maximum(g.sqrt(u), 1e-6)
    den = g.madd(s, -_FIT_B, _FIT_A)
    f = g.div(g.mul(s, 2.0), den)
    return f, g.div(_FIT_A, g.mul(s, g.mul(den, den)))


def _dielectric_max(g, u):
    """Principled dielectric, max channel (tint 1, F0 = u): F = u + s (1-u) with
    s = saturate((fit - u)/(1 - u)), i.e. max(fit, u)."""
    f, df = _fit(g, u)
    above = g.less(u, f)
    return g.maximum(f, u), g.select(above, df, 1.0)


def _conductor_fss(g, r, edge, exact):
    """The Metallic node's F_ss (physical conductor) at F(0) = r, Gulbrandsen's η, κ (vectors):
    F82 fit through F(1) = r and F_c(1/7), saturated (fresnel_conductor_Fss)."""
    omr = g.vmath("MAXIMUM", g.vmath("SUBTRACT", 1.0, r), TINY)
    r = g.vmath("MINIMUM", r, K.ONE_MINUS_ULP32)
    eta, kappa = gulbrandsen(g, r, omr, edge)
    c = 1.0 / 7.0
    n2, k2 = g.vmath("MULTIPLY", eta, eta), g.vmath("MULTIPLY", kappa, kappa)
    # r_s, r_p = (a - b)/(a + b) each, so F82 = (r_s + r_p)/2 = 1 - X, X = Σ b/(a + b)
    if exact:  # fresnel_conductor_polarized, F82 < 0 branch: u, v from t1, t2
        d = g.vmath("SUBTRACT", n2, k2)
        t1 = g.vmath("SUBTRACT", d, 1.0 - c * c)
        nk = g.vmath("MULTIPLY", eta, kappa)
        t2 = g.vmath("POWER", g.vmath("MULTIPLY_ADD", t1, t1, g.vmath("SCALE", g.vmath("MULTIPLY", nk, nk), 4.0)), 0.5)
        su = g.vmath("POWER", g.vmath("ADD", t2, t1), 0.5)  # √2 u
        sv = g.vmath("POWER", g.vmath("SUBTRACT", t2, t1), 0.5)  # √2 v (POWER of < 0 is 0)
        # r_s = (c² + t2 - 2cu)/(c² + t2 + 2cu)
        a_s = g.vmath("ADD", t2, c * c)
        b_s = g.vmath("SCALE", su, 2.0 * c / np.sqrt(2.0))
        # r_p = (c²(η²+κ²)² + t2 - 2c(d u + 2ηκ v)) / (... + ...)
        s2 = g.vmath("ADD", n2, k2)
        a_p = g.vmath("MULTIPLY_ADD", g.vmath("MULTIPLY", s2, s2), c * c, t2)
        w = g.vmath("MULTIPLY_ADD", d, su, g.vmath("MULTIPLY", g.vmath("SCALE", nk, 2.0), sv))
        b_p = g.vmath("SCALE", w, 2.0 * c / np.sqrt(2.0))
    else:  # 4.5's fresnel_conductor (exact at normal incidence only): b = 2ηc in both
        s2 = g.vmath("ADD", n2, k2)
        b_s = b_p = g.vmath("SCALE", eta, 2.0 * c)
        a_p = g.vmath("MULTIPLY_ADD", s2, c * c, 1.0)
        a_s = g.vmath("ADD", s2, c * c)
    x = g.vmath("ADD", g.vmath("DIVIDE", b_s, g.vmath("ADD", a_s, b_s)),
                g.vmath("DIVIDE", b_p, g.vmath("ADD", a_p, b_p)))
    # F_ss = mix(r, 1, 1/21) - (mix(r, 1, f⁵) - F82)·7/(126 f⁶): affine in r and F82; <= 1
    # for r <= 1, saturated below (fresnel_conductor_Fss)
    lin = g.vmath("MULTIPLY_ADD", r, 20.0 / 21.0 - _K82 * (1.0 - _F5), 1.0 / 21.0 - _K82 * _F5 + _K82)
    return g.vmath("MAXIMUM", g.vmath("MULTIPLY_ADD", x, -_K82, lin), 0.0)


def _affine(g, a, b):
    """F = a + b r (per channel), F' = b; the scalar model of the max channel from a, b and
    the channel weights e."""
    def vec(r):
        f = g.vmath("MULTIPLY_ADD", r, b, a)
        return f, f, b, b
    return vec


# --------------------------------------------------------------------------------------------
# The correction
# --------------------------------------------------------------------------------------------


def correct(g, ss, *, lobe, rc, p, x_n, x_w, haziness, edge_tint=None, tint=None, version=None,
            iterations=None, affine=None):
    """Corrected (β, r, ...) for the single-scatter node mapping ``ss`` (node_math's outputs:
    reflectivity_max, core_max, chroma, peak_complement); ``rc`` the clamped r_c, ``p`` the
    peak ratio, ``x_n``, ``x_w`` the lobes' roughness indices (α_x α_y)^¼, ``haziness`` β_h
    (or the Bézier's share β_h t/k̂_7).  ``affine`` (DIELECTRIC only): (on, a, b), where ``on``
    (1 / 0 per point) says the lobes raise F0 through the Specular Tint, whose F_ss is then
    a + b r per channel (the IOR's s fixed).  Returns beta, reflectivity, reflectivity_max,
    halo_intensity, halo_max (k̂_max) and, for Glossy lobes, colour_narrow, colour_wide.
    peak_ratio / peak_complement stay the single-scatter p, 1 - p of the node math."""
    lobe = str(lobe).upper()
    if lobe not in LOBES:
        raise ValueError(f"multiscatter lobe must be one of {', '.join(LOBES)}; got {lobe!r}")
    it = {**ITERATIONS, **DEFAULTS.get(lobe, {}), **(iterations or {})}
    stops = table_stops(version)
    tn, tw = _Table(g, x_n, stops, "narrow"), _Table(g, x_w, stops, "wide")
    s = _Ops(g, False)
    if lobe == "COAT":  # grey: one channel (r_c = r̂_c), scalar nodes
        v, rc = s, ss["core_max"]
        lane_m = lambda x: x  # noqa: E731
    else:
        v = _Ops(g, True)
        # the max channel m (the first of equal maxima, as argmax): e = its indicator, from
        # floor(chroma) (chroma = r_c / r̂_c is exactly 1 there); all 0 where r_c = 0
        e0, e1, e2 = g.separate(g.vmath("FLOOR", ss["chroma"]))
        e = g.combine(e0, g.mul(e1, g.sub(1.0, e0)), g.mul(e2, g.sub(1.0, g.maximum(e0, e1))),
                      label="max channel")
        lane_m = lambda x: g.dot(x, e)  # noqa: E731
    if lobe == "LEGACY":
        return _legacy(g, ss, rc, p, tn, tw, haziness, lane_m, it)

    # -- F_ss of the node as a function of r: per channel (vec_model), max channel (max_model)
    if lobe == "F82_TINT":  # F_ss = a + b F0, F0 = Base Color (fresnel_f82_Fss, fresnel_f82_B)
        om = g.vmath("SUBTRACT", 1.0, g.vclamp01(1.0 if tint is None else tint))
        a = g.vmath("MULTIPLY_ADD", om, -_K82 * _F5, 1.0 / 21.0)
        b = g.vmath("MULTIPLY_ADD", om, -_K82 * (1.0 - _F5), 20.0 / 21.0)
        vec_model = _affine(g, a, b)
        f0, f1 = vec_model(rc)[0], g.vmath("ADD", a, b)
        a_m, b_m = lane_m(a), lane_m(b)
        max_model = lambda u: (g.madd(u, b_m, a_m),) * 2 + (b_m,) * 2  # noqa: E731
    elif lobe == "CONDUCTOR":
        # exact F_ss at r_c; the max channel's solves use the chord to F_ss(1) = 1 (h = (F-r)/(1-r)
        # frozen at r_c), every channel's Newton steps the exact F_ss at the iterate (below)
        exact = _exact_conductor(version)
        f0, f1 = _conductor_fss(g, rc, edge_tint, exact), 1.0
        h = g.vmath("DIVIDE", g.vmath("SUBTRACT", f0, rc),
                    g.vmath("MAXIMUM", g.vmath("SUBTRACT", 1.0, rc), TINY))
        a_m = lane_m(h)
        b_m = g.sub(1.0, a_m)
        max_model = lambda u: (g.madd(u, b_m, a_m),) * 2 + (b_m,) * 2  # noqa: E731
    elif lobe == "DIELECTRIC":  # F = r + s (1 - r), s from r̂ (Specular Tint r / r̂)
        f0 = g.vmath("MULTIPLY_ADD", g.vmath("SUBTRACT", 1.0, rc), dielectric_s(g, ss["core_max"]), rc)
        f1 = 1.0
        max_model = lambda u: (lambda f, df: (f, f, df, df))(*_dielectric_max(g, u))  # noqa: E731
        if affine is not None:  # where the tint raises F0: F_ss = a + b r
            keep, a_t, b_t = affine
            f0 = g.select(keep, g.vmath("MULTIPLY_ADD", rc, b_t, a_t), f0)
            f1 = g.select(keep, g.vmath("ADD", a_t, b_t), (1.0, 1.0, 1.0))
            a_tm, b_tm, raise_ior = lane_m(a_t), lane_m(b_t), max_model

            def max_model(u):
                f, _, df, _ = raise_ior(u)
                f = g.select(keep, g.madd(u, b_tm, a_tm), f)
                df = g.select(keep, b_tm, df)
                return f, f, df, df
    else:  # COAT: F_ss = fresnel_dielectric_Fss(η(r̂))
        f0, f1 = _fit(g, rc)[0], 2.0 / (_FIT_A - _FIT_B)
        max_model = lambda u: (lambda f, df: (f, f, df, df))(*_fit(g, u))  # noqa: E731

    # -- the haze-free peak and the largest halo ----------------------------------------------
    mn0, _ = _excess(v, tn, f0)
    T = v("MULTIPLY_ADD", rc, mn0, rc)  # T = r_c S_0: (*)'s right side, per channel
    t_m = lane_m(T)
    o1 = v if getattr(f1, "vector", False) else s
    mn1, _ = _excess(o1, tn, f1)
    mw1, _ = _excess(o1, tw, f1)
    # β at which each channel needs r = 1: (S_n(1) - T)/(S_n(1) - p S_w(1)), the divisor as
    # (1-p) + (M_n - p M_w) (no cancellation as p -> 1)
    den = o1("MAXIMUM", o1("ADD", o1("MULTIPLY_ADD", mw1, g.mul(p, -1.0), mn1), ss["peak_complement"]),
             _DIV_MIN)
    beta_e = v("DIVIDE", v("SUBTRACT", o1("ADD", mn1, 1.0), T), den)
    if v.vec:
        b0, b1, b2 = g.separate(beta_e)
        beta_e = g.minimum(g.minimum(b0, b1), b2)
    beta_max = g.minimum(beta_e, 1.0, label="β_max")
    # r̂_m(β_max): Newton at fixed β from T_m / D(F(r̂_c)) (>= the root: F grows with r)
    mw0, _ = _excess(v, tw, f0)
    omb, bp = g.sub(1.0, beta_max), g.mul(beta_max, p)
    d0 = g.add(g.madd(lane_m(mn0), omb, omb), g.madd(lane_m(mw0), bp, bp))
    u = g.minimum(g.div(t_m, d0), 1.0)
    for _ in range(it["k"]):
        u = _fixed_beta_step(s, u, beta_max, t_m, max_model, tn, tw, p)
    k_max = g.mul(beta_max, u, label="k̂_max")
    k = g.mul(haziness, k_max, label="k̂_h")

    # -- the max channel: r̂ with β = k̂ / r̂, from r̂_c + β_h (r̂(β_max) - r̂_c) (Eq. 5's form) -
    u = g.minimum(g.maximum(g.madd(haziness, g.sub(u, ss["core_max"]), ss["core_max"]), k), 1.0)
    for _ in range(it["m"]):
        u = _max_channel_step(g, u, k, t_m, max_model, tn, tw, p)
    beta = g.div(k, u, label="β = k̂_h / r̂")
    out = dict(beta=beta, reflectivity_max=u, halo_intensity=k, halo_max=k_max)
    if lobe == "COAT":  # one Coat IOR: every channel is r̂
        out["reflectivity"] = g.combine(u, u, u)
        return out

    # -- every channel at that β, from the max channel's r̂ scaled by the targets -------------
    r = g.vmath("MINIMUM", g.vmath("SCALE", T, g.div(u, t_m)), 1.0)
    if lobe == "CONDUCTOR":  # exact F_ss at each iterate, F' by the secant through the last two
        r_prev, f_prev = rc, f0
        for _ in range(it.get("c0", 0)):  # steps on the chord model (per channel h frozen at r_c)
            hv = g.vmath("DIVIDE", g.vmath("SUBTRACT", f0, rc), g.vmath("MAXIMUM", g.vmath("SUBTRACT", 1.0, rc), TINY))
            r = _fixed_beta_step(v, r, beta, T, _affine(g, hv, g.vmath("SUBTRACT", 1.0, hv)), tn, tw, p)
        for _ in range(it["c"]):
            f = _conductor_fss(g, r, edge_tint, exact)
            df = g.vmath("MAXIMUM", g.vmath("DIVIDE", g.vmath("SUBTRACT", f, f_prev),
                                            g.vmath("SUBTRACT", r, r_prev)), 0.0)
            r_prev, f_prev = r, f
            r = _fixed_beta_step(v, r, beta, T, lambda x, f=f, df=df: (f, f, df, df), tn, tw, p)
    else:
        if lobe == "DIELECTRIC":  # s fixed by r̂: F affine in r
            sd = dielectric_s(g, u)
            if affine is None:
                vec_model = _affine(g, sd, g.sub(1.0, sd))
            else:
                one = (1.0, 1.0, 1.0)
                vec_model = _affine(g, g.select(keep, a_t, g.vmath("SCALE", one, sd)),
                                    g.select(keep, b_t, g.vmath("SCALE", one, g.sub(1.0, sd))))
        for _ in range(it["c"]):
            r = _fixed_beta_step(v, r, beta, T, vec_model, tn, tw, p)
    out["reflectivity"] = r
    return out


def dielectric_s(g, r_hat):
    """The Principled dielectric's s = saturate((F_ss,d(η) - F0(η))/(1 - F0(η))), F0(η) = r̂."""
    f, _ = _fit(g, r_hat)
    return g.clamp(g.div(g.sub(f, r_hat), g.maximum(g.sub(1.0, r_hat), TINY)), 0.0, 1.0)


def _legacy(g, ss, rc, p, tn, tw, haziness, lane_m, it):
    """Glossy lobes: F_ss is the colour, (1-β) r narrow and β r wide."""
    v, s = _Ops(g, True), _Ops(g, False)
    mn0, _ = _excess(v, tn, rc)
    T = g.vmath("MULTIPLY_ADD", rc, mn0, rc, label="T = r_c S_0")
    t_m = lane_m(T)
    # β_max: the first root of g(β) = (1-β) S_n(1-β) + β p S_w(β) - T_c (r = 1) over the
    # channels; g - T_c is the same for all, so it is the root for T* = max T_c.  g is convex
    # with g(0) >= 0: Newton steps from the left of the root increase to it monotonically (no
    # root: pushed to 1 where g' >= 0 while g > 0).  Three starts in the lanes of one Vector
    # Math pass: 0, and (for the slow double-root-like cases) β_l and β_l/2, where β_l <= 1 is
    # the root of the chord bound (1-β) S_n(1) + β p S_w(1) - T* >= g (its first Newton step
    # lands left of the root when g(β_l) <= 0).  Used: the largest iterate known to be left of
    # the root (its last step taken from g >= 0, g' < 0), lane 0 always.
    t0, t1, t2 = g.separate(T)
    t_max = g.maximum(g.maximum(t0, t1), t2)
    mn1, _ = _excess(s, tn, 1.0)
    mw1, _ = _excess(s, tw, 1.0)
    den1 = g.maximum(g.add(g.madd(mw1, g.mul(p, -1.0), mn1), ss["peak_complement"]), _DIV_MIN)
    b_l = g.minimum(g.div(g.sub(g.add(mn1, 1.0), t_max), den1), 1.0)
    b = g.combine(0.0, g.mul(b_l, 0.5), b_l)
    ok = None
    for i in range(it["b"]):
        om = v("SUBTRACT", 1.0, b)
        mn, dsn = _excess(v, tn, om)
        mw, dsw = _excess(v, tw, b)
        gb = v("SUBTRACT", v("ADD", v("MULTIPLY_ADD", mn, om, om), v("MULTIPLY", v("MULTIPLY_ADD", mw, b, b), p)), t_max)
        # g' = -(S_n + (1-β) S_n') + p (S_w + β S_w')
        gp = v("SUBTRACT", v("MULTIPLY", v("ADD", v("MULTIPLY_ADD", dsw, b, mw), 1.0), p),
               v("ADD", v("MULTIPLY_ADD", dsn, om, mn), 1.0))
        if i == it["b"] - 1:  # left of the root: g >= 0 and g' < 0 where the last step started
            (_, g1, g2), (_, d1, d2) = g.separate(gb), g.separate(gp)
            ok = [g.mul(g.math("GREATER_THAN", gi, -1e-30), g.less(di, 0.0)) for gi, di in ((g1, d1), (g2, d2))]
        b = v("MINIMUM", v("MAXIMUM", v("SUBTRACT", b, v("DIVIDE", gb, v("MINIMUM", gp, -_DIV_MIN))), 0.0), 1.0)
    b0, b1, b2 = g.separate(b)
    beta_max = g.maximum(g.maximum(b0, g.mul(b1, ok[0])), g.mul(b2, ok[1]), label="β_max")

    def model(beta):
        omb = g.sub(1.0, beta)
        return lambda u: (s("MULTIPLY", u, omb) if not getattr(u, "vector", False) else v("SCALE", u, omb),
                          s("MULTIPLY", u, beta) if not getattr(u, "vector", False) else v("SCALE", u, beta),
                          omb, beta)

    u = g.const(1.0)
    for _ in range(it["k"]):
        u = _fixed_beta_step(s, u, beta_max, t_m, model(beta_max), tn, tw, p)
    k_max = g.mul(beta_max, u, label="k̂_max")
    k = g.mul(haziness, k_max, label="k̂_h")
    # the max channel: F_n = r̂ - k̂, F_w = k̂, so w S_n(w) = T_m - k̂ p S_w(k̂), w = r̂ - k̂: a
    # quadratic, (m E_avg + E_avg - 1) w² + (1 - R (E_avg - 1)) w - R = 0
    mwk, _ = _excess(s, tw, k)
    rr = g.maximum(g.sub(t_m, g.mul(g.madd(mwk, k, k), p)), 0.0)
    bq = g.madd(rr, g.mul(tn.am1, -1.0), 1.0)
    aq = g.add(tn.ma, tn.am1)
    w = g.div(g.mul(rr, 2.0), g.add(bq, g.sqrt(g.madd(g.mul(aq, rr), 4.0, g.mul(bq, bq)))))
    u = g.minimum(g.add(w, k), 1.0)
    beta = g.div(k, u, label="β = k̂_h / r̂")
    r = g.vmath("MINIMUM", g.vmath("SCALE", T, g.div(u, t_m)), 1.0)
    for _ in range(it["c"]):
        r = _fixed_beta_step(v, r, beta, T, model(beta), tn, tw, p)
    out = dict(beta=beta, reflectivity=r, reflectivity_max=u, halo_intensity=k, halo_max=k_max)
    out["colour_narrow"] = g.vmath("SCALE", r, g.sub(1.0, beta), label="k_n = (1-β) r")
    out["colour_wide"] = g.vmath("SCALE", r, beta, label="k_w = β r")
    return out
