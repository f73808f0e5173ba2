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
- (*) r [(1-β) S_n + β p S_w] = r_c S_0 solved for r at the mapping's own β by unrolled
  Newton steps from the single-scatter r (core.multiscatter.correct_mapping): the max channel
  first where its F_ss sets the IOR (dielectric, coat), then every channel.  Glossy lobes
  (their colours carry β) keep the β_max family of core.multiscatter._solve_glossy.

Each Newton step for r at fixed β is written as u' = y (1 + u δ) / (1 + y δ) with y = T/D(u),
δ = D'(u)/D(u) (Newton on u - T/D(u)): non-negative and <= 1 by construction.
"""
from __future__ import annotations

import numpy as np

from .. import constants as K
from .tables import cycles_ggx_tables as _tables
from .multiscatter import exact_conductor, generation
from .node_fresnel import TINY, gulbrandsen

__all__ = ("LOBES", "ITERATIONS", "table_stops", "correct", "dielectric_s")

#: Lobe types (core.multiscatter.LOBES).
LOBES = ("CONDUCTOR", "F82_TINT", "DIELECTRIC", "LEGACY", "COAT")

#: Unrolled Newton steps on (*) at the mapping's β, per lobe type: "m" the max channel's r̂
#: with its own F_ss (the coat, the dielectric), "c" every channel (the conductor on the chord
#: of its F_ss), "a" every channel of a dielectric whose tint raises F0 (its F_ss affine in r,
#: the start from r̂ close), "x" the conductor's steps with its exact F_ss.  The error each count leaves
#: is measured in docs/performance.md ("error against cost").
STEPS = {"COAT": {"m": 2}, "F82_TINT": {"c": 2}, "DIELECTRIC": {"m": 2, "c": 2, "a": 1},
         "CONDUCTOR": {"c": 1, "x": 1}}
#: Glossy lobes (their β_max family, core.multiscatter._solve_glossy): "k" for r̂_m(β_max)
#: (k̂_max), "m" the max channel r̂_m, "c" every channel, "b" β_max.
ITERATIONS = {"k": 2, "m": 1, "c": 2, "b": 4}

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
    a = np.asarray(_tables.EAVG_V53 if generation(version) == "V53" else _tables.EAVG_V4, np.float32)
    return tuple((i / 31.0, (float(e[i]), float(a[i]), 0.0)) for i in range(32))


class _Table:
    """E(1, x), E_avg(x) of one lobe: A = m E_avg = E_avg/E - E_avg (m = (1-E)/E) and
    B = E_avg - 1, so that S(F) = 1 + M, M = F A / (1 + F B) (microfacet_ggx_preserve_energy).
    (A ramp holding A and B themselves would save three nodes but interpolates A, not E: 1.2e-3
    off Cycles' lookup near x = 1, which moves the peak past the budget.)"""

    def __init__(self, g, x, stops, name):
        self.g = g
        e, a, _ = g.separate(g.ramp(x, stops, label=f"E(1,x), E_avg(x) {name}"))
        self.ma = g.sub(g.div(a, e), a, label=f"m E_avg {name}")
        self.am1 = g.sub(a, 1.0)


class _Lanes:
    """Both lobes' tables in the lanes of one vector (narrow, wide, 0), for a scalar unknown:
    A = E_avg (1-E)/E and B = E_avg - 1, so that each lobe's S(F) = 1 + F A / (1 + F B)
    comes from one Vector Math pass."""

    def __init__(self, tn, tw):
        g = tn.g
        self.g = g
        # (a table of _excess's: A as ``ma``, B as ``am1``, one lobe per lane)
        self.ma = g.combine(tn.ma, tw.ma, 0.0, label="E_avg (1-E)/E: narrow, wide")
        self.am1 = g.combine(tn.am1, tw.am1, 0.0, label="E_avg - 1: narrow, wide")

    def step(self, u, model, target, weights, c0):
        """One Newton step on u - T/D(u) with D = c0 + w · M(F(u)), M = S - 1 per lane
        (weights w = (1-β, β p, 0), c0 = 1-β + β p):
        u' = T (D + u D') / (D² + T D'), D' = F'(u) (w · A/(1 + F B)²)."""
        g = self.g
        f, df = model(u)
        excess, slope = _excess(_Ops(g, True), self, f)
        d = g.add(g.dot(weights, excess), c0)
        dp = g.mul(g.dot(weights, slope), df)
        return g.div(g.mul(target, g.madd(u, dp, d)), g.madd(d, d, g.mul(target, dp)))


class _Ops:
    """Math or Vector Math, by ``vec``."""

    def __init__(self, g, vec):
        self.g, self.vec = g, vec

    def __call__(self, op, *a):
        return self.g.vmath(op, *a) if self.vec else self.g.math(op, *a)


def _excess(o, t, f):
    """(M = S - 1, dS/dF) of table ``t`` at Fresnel average ``f``."""
    den = o("MULTIPLY_ADD", f, t.am1, 1.0)  # 1 - F (1 - E_avg) >= E_avg > 0
    q = o("DIVIDE", t.ma, den)
    return o("MULTIPLY", f, q), o("DIVIDE", q, den)


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


# --------------------------------------------------------------------------------------------
# F_ss of each node as a function of r
# --------------------------------------------------------------------------------------------


def _fit(g, u):
    """Kulla-Conty's F_ss,d(η(u)) = 2s/(A - B s) = s/d, d = (A - B s)/2, s = √u, and its
    derivative A/(s (A - Bs)²) = (A/4)/(s d²)."""
    s = g.maximum(g.sqrt(u), 1e-6)
    den = g.madd(s, -0.5 * _FIT_B, 0.5 * _FIT_A)
    return g.div(s, den), g.div(0.25 * _FIT_A, g.mul(s, g.mul(den, den)))


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
    """(β, r, ...) keeping the peak of the single-scatter node mapping ``ss`` (node_math's
    outputs: beta, reflectivity, reflectivity_max, core_max, chroma, peak_complement) under
    Cycles' energy factor; ``rc`` the clamped r_c, ``p`` the peak ratio, ``x_n``, ``x_w`` the
    lobes' roughness indices (α_x α_y)^¼, ``haziness`` β_h (or the Bézier's share β_h t/k̂_7,
    Glossy lobes only).  Lobes with a Fresnel keep the mapping's β (core.multiscatter.
    correct_mapping): r alone solves (*) by STEPS Newton steps from the single-scatter r.
    ``affine`` (DIELECTRIC only): (on, a, b), where ``on`` (1 / 0 per point) says the lobes
    raise F0 through the Specular Tint, whose F_ss is then a + b r per channel (the IOR's s
    fixed).  ``iterations`` overrides STEPS.  Returns beta, reflectivity, reflectivity_max,
    halo_intensity and, for Glossy lobes, halo_max, colour_narrow, colour_wide."""
    lobe = str(lobe).upper()
    if lobe not in LOBES:
        raise ValueError(f"multiscatter lobe must be one of {', '.join(LOBES)}; got {lobe!r}")
    stops = table_stops(version)
    tn, tw = _Table(g, x_n, stops, "narrow"), _Table(g, x_w, stops, "wide")
    s, v = _Ops(g, False), _Ops(g, True)
    if lobe == "LEGACY":
        it = {**ITERATIONS, **(iterations or {})}
        e = _max_lane(g, ss["chroma"])
        return _legacy(g, ss, rc, p, tn, tw, haziness, lambda x: g.dot(x, e), it)
    steps = {**STEPS[lobe], **(iterations or {})}
    beta = ss["beta"]

    def solve(o, u, target, model, n):
        for _ in range(n):
            u = _fixed_beta_step(o, u, beta, target, model, tn, tw, p)
        return u

    def solve_max(u, target, model):
        """The max channel (a scalar): both lobes in the lanes of one vector."""
        lanes = _Lanes(tn, tw)
        omb = g.sub(1.0, beta)
        bp = g.mul(beta, p)
        weights, c0 = g.combine(omb, bp, 0.0), g.add(omb, bp)
        for _ in range(steps["m"]):
            u = lanes.step(u, model, target, weights, c0)
        return g.minimum(u, 1.0) if steps["m"] else u  # (an iterate past 1 keeps the fit finite)

    if lobe == "COAT":  # grey: one scalar, the exact F_ss of the Coat IOR raised to r̂
        rc_m = ss["core_max"]
        mn0, _ = _excess(s, tn, _fit(g, rc_m)[0])
        u = solve_max(ss["reflectivity_max"], g.madd(rc_m, mn0, rc_m), lambda u: _fit(g, u))
        return dict(beta=beta, reflectivity=g.combine(u, u, u), reflectivity_max=u,
                    halo_intensity=g.mul(beta, u))
    if lobe == "F82_TINT":  # F_ss = a + b F0 per channel (fresnel_f82_Fss, fresnel_f82_B)
        om = g.vmath("SUBTRACT", 1.0, g.vclamp01(1.0 if tint is None else tint))
        model = _affine(g, g.vmath("MULTIPLY_ADD", om, -_K82 * _F5, 1.0 / 21.0),
                        g.vmath("MULTIPLY_ADD", om, -_K82 * (1.0 - _F5), 20.0 / 21.0))
        f0 = model(rc)[0]
    elif lobe == "CONDUCTOR":  # the chord from F_ss(r_c) to F_ss(1) = 1, then the exact F_ss
        exact = exact_conductor(version)
        f0 = _conductor_fss(g, rc, edge_tint, exact)
        h = g.vmath("DIVIDE", g.vmath("SUBTRACT", f0, rc),
                    g.vmath("MAXIMUM", g.vmath("SUBTRACT", 1.0, rc), TINY))
        model = _affine(g, h, g.vmath("SUBTRACT", 1.0, h))
    else:  # DIELECTRIC: F = r + s (1 - r), s from r̂ (the Specular Tint r / r̂)
        f0 = g.vmath("MULTIPLY_ADD", g.vmath("SUBTRACT", 1.0, rc), dielectric_s(g, ss["core_max"]), rc)
    mn0, _ = _excess(v, tn, f0)
    target = v("MULTIPLY_ADD", rc, mn0, rc)  # T = r_c S_0, per channel
    if lobe == "DIELECTRIC":
        # the max channel first, with its own F_ss (max(fit(η(r̂)), r̂); where the tint raises
        # F0, a + b r̂); then every channel at that r̂'s s, from r̂'s chroma
        rc_m = ss["core_max"]
        mn0m, _ = _excess(s, tn, g.maximum(_fit(g, rc_m)[0], rc_m))
        t_m = g.madd(rc_m, mn0m, rc_m)
        max_model = _dielectric_max
        if affine is not None:
            # the layer reads every channel's r only where the tint raises F0 (keep = 1):
            # there the model is affine, elsewhere the max channel's r̂ alone
            keep, a_t, b_t = affine
            lane = _max_lane(g, ss["chroma"])  # (the max channel's weights and target)
            a_m, b_m = g.dot(a_t, lane), g.dot(b_t, lane)
            f0 = g.vmath("MULTIPLY_ADD", rc, b_t, a_t)
            mn0, _ = _excess(v, tn, f0)
            target = v("MULTIPLY_ADD", rc, mn0, rc)
            t_m = g.select(keep, g.dot(target, lane), t_m)

            def max_model(g, u, raise_ior=_dielectric_max):
                f, df = raise_ior(g, u)
                return g.select(keep, g.madd(u, b_m, a_m), f), g.select(keep, b_m, df)
        u = solve_max(ss["reflectivity_max"], t_m, lambda u: max_model(g, u))
        if affine is None:
            sd = dielectric_s(g, u)
            model, n = _affine(g, sd, g.sub(1.0, sd)), steps["c"]
        else:
            model, n = _affine(g, a_t, b_t), steps["a"]
        r = solve(v, g.vmath("MINIMUM", g.vmath("SCALE", ss["chroma"], u), 1.0), target, model, n)
        return dict(beta=beta, reflectivity=r, reflectivity_max=u, halo_intensity=g.mul(beta, u))
    r = solve(v, ss["reflectivity"], target, model, steps["c"])
    if lobe == "CONDUCTOR":  # the exact F_ss at each iterate, F' by the secant
        r_prev, f_prev = rc, f0
        for _ in range(steps["x"]):
            f = _conductor_fss(g, r, edge_tint, exact)
            df = g.vmath("MAXIMUM", g.vmath("DIVIDE", g.vmath("SUBTRACT", f, f_prev),
                                            g.vmath("SUBTRACT", r, r_prev)), 0.0)
            r_prev, f_prev = r, f
            r = _fixed_beta_step(v, r, beta, target, lambda x, f=f, df=df: (f, f, df, df), tn, tw, p)
    r_max = g.channel_max(r)
    return dict(beta=beta, reflectivity=r, reflectivity_max=r_max, halo_intensity=g.mul(beta, r_max))


def _max_lane(g, chroma):
    """The indicator of the max channel (the first of equal maxima, as argmax): floor(chroma)
    is 1 exactly there (chroma = r_c / r̂_c); all 0 where r_c = 0."""
    e0, e1, e2 = g.separate(g.vmath("FLOOR", chroma))
    return g.combine(e0, g.mul(e1, g.sub(1.0, e0)), g.mul(e2, g.sub(1.0, g.maximum(e0, e1))),
                     label="max channel")


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
