# SPDX-License-Identifier: GPL-3.0-or-later
"""The haze mapping as node math (one description for the shader group and the compositor).

Written against :class:`hazy_gloss.core.graph.Graph`: it computes what
:func:`hazy_gloss.core.lobes.describe` computes (the mapping with Cycles' limits α <= 1 and
aspect <= 10, the add-on's clamps, the wide lobe in the node convention) in the same
float32-stable forms (docs/mapping.md): no 1 - p by subtraction, the Bézier through the conic's
implicit equation, κ of Gulbrandsen's mapping as a product of non-negative terms.  Blender's
safe divide (x / 0 = 0) is relied upon where a quotient is unused (its select weight is 0).
"""
from __future__ import annotations

from .. import constants as K
from .node_fresnel import TINY, gulbrandsen
from .node_multiscatter import correct

__all__ = ("mapping", "haze_terms", "reflectivity", "glossy_to_metallic", "folded_roughness",
           "INPUTS")

#: Inputs of :func:`mapping` (vector ones are colours).
INPUTS = {"core_reflectivity": True, "edge_tint": True, "roughness": False, "anisotropy": False,
          "rotation": False, "haziness": False, "haze_extent_x": False, "haze_extent_y": False,
          "smoothness": False}

#: Divisors that can underflow (p, 1 - p, r̂_c, c_2 of garbage or extreme texels) are kept >= this
#: where they divide: a quotient in the branch a Mix node does not select must stay finite
#: (0 · inf = NaN); nothing visible depends on values below it.
_DIV_MIN = 1e-30


#: The Multiscatter GGX lobe type each kind draws (multiscatter=True).
MULTISCATTER_LOBE = {"CONDUCTOR": "CONDUCTOR", "DIELECTRIC": "DIELECTRIC", "LEGACY": "LEGACY"}


def mapping(g, src, *, kind, anisotropic, smooth, distribution="GGX", multiscatter=None,
            tint=None, version=None, iterations=None, affine=None, title=None):
    """The physical parameters of Eq. 1 from perceptual inputs ``src`` (name -> Expr or number;
    see INPUTS).

    ``multiscatter``: None (the single-scatter mapping), True (the lobe type of ``kind``) or a
    lobe type of core.multiscatter.correct_mapping — "CONDUCTOR", "F82_TINT" (Base Color r,
    ``tint`` the Specular / Edge Tint colour), "DIELECTRIC", "LEGACY", "COAT" (kind DIELECTRIC,
    grey r_c = F0 of the Coat IOR): β and r keep the peak under Cycles' Multiscatter GGX energy
    factor (core.node_multiscatter; ``version`` picks the Cycles reproduced, None = the running
    Blender; ``iterations`` overrides its Newton step counts; ``affine``: node_multiscatter's,
    for a dielectric whose F0 the Specular Tint raises).  ``title``: the part's name, for the
    graph's sections (Graph.section: a layer group's frames).  Independent of
    ``distribution``, whose p is GGX's for MULTI_GGX: the coat is always energy preserving.  Returns a dict of Exprs: roughness, roughness_wide, [anisotropy_wide,
    rotation_wide], alpha_wide, beta, peak_ratio, peak_complement, halo_intensity,
    reflectivity_max (r̂), reflectivity, [anisotropy_narrow (legacy: Glossy convention)], and per kind ior + extinction (conductor), ior + specular_tint
    (dielectric) or colour_narrow + colour_wide (legacy)."""
    out = {}

    def section(what):
        if title:
            g.section(f"{title}: {what}")

    section("Eq. 8 halo roughness, Table 2 peak ratio")
    # -- the valid domain (textures can hold anything) -----------------------------------------
    rough = g.clamp(src["roughness"], K.min_roughness(distribution), 1.0, label="R")
    bh = g.clamp(src["haziness"], 0.0, K.MAX_HAZINESS, label="β_h")
    rc = g.vclamp01(src["core_reflectivity"], label="r_c")
    alpha = g.mul(rough, rough, label="α = R²")

    # -- Eq. 8 with Cycles' α <= 1 and aspect <= 10; p and q = 1 - p (Table 2) -----------------
    if anisotropic:
        a = g.clamp(src["anisotropy"], 0.0, 1.0)
        s = g.sqrt(g.madd(a, -0.9, 1.0), label="s = √(1-0.9a)")
        ax_raw = g.div(alpha, s)
        ax = g.minimum(ax_raw, 1.0, label="α_n^x")
        ay = g.mul(alpha, s, label="α_n^y")
        gm = g.sqrt(g.mul(ax, ay), label="√(α_x α_y)")
        # spread = α_w - α_n = λ_h √(α_x α_y) in [0, 1 - α_n] (λ_h < 0 or NaN: no halo):
        # no subtraction of nearly equal numbers
        sx = g.clamp(g.mul(src["haze_extent_x"], gm), 0.0, g.sub(1.0, ax))
        sy = g.clamp(g.mul(src["haze_extent_y"], gm), 0.0, g.sub(1.0, ay))
        # aspect <= 10: shorten the halo's long axis (never below α_n), to 10 α_w^y - α_n^x =
        # 10 s_y + (10 α_n^y - α_n^x) with 10 α_n^y - α_n^x = 9 α (1-a)/s (+ what α <= 1 cut off
        # α_n^x): formed without cancellation (at a = 1 the raw difference is pure rounding)
        d_x = g.add(g.div(g.mul(g.mul(alpha, 9.0), g.sub(1.0, a)), s),
                    g.maximum(g.sub(ax_raw, 1.0), 0.0), label="10 α_n^y - α_n^x")
        if distribution == "ASHIKHMIN_SHIRLEY":
            floored = g.maximum(g.less(ax, _AS_ALPHA_MIN), g.less(ay, _AS_ALPHA_MIN))
            ax, sx = _as_floor(g, ax, sx)
            ay, sy = _as_floor(g, ay, sy)
            # a floored α_n^y is the constant 1e-4: the difference is then formed directly
            d_x = g.select(floored, g.madd(ay, K.MAX_ASPECT, g.mul(ax, -1.0)), d_x)
        sx_lim = g.minimum(sx, g.madd(sy, K.MAX_ASPECT, d_x))
        sy = g.minimum(sy, g.maximum(g.madd(g.add(ax, sx), K.MAX_ASPECT, g.mul(ay, -1.0)), 0.0))
        sx = sx_lim
        wx2 = g.add(ax, sx, label="α_w^x")
        wy2 = g.add(ay, sy, label="α_w^y")
        px, qx = _axis_ratio(g, ax, wx2, sx, distribution)
        py, qy = _axis_ratio(g, ay, wy2, sy, distribution)
        p = g.mul(px, py, label="p")
        q = g.madd(px, qy, qx, label="q = 1 - p")
        out["alpha_wide"] = (wx2, wy2)
        if kind == "LEGACY":  # Glossy's convention: a = s - 1 gives α_x = R²/s, α_y = R² s
            out["anisotropy_narrow"] = g.sub(s, 1.0, label="Glossy anisotropy")
    else:
        spread = g.clamp(g.mul(src["haze_extent_x"], alpha), 0.0, g.sub(1.0, alpha))
        if distribution == "ASHIKHMIN_SHIRLEY":
            alpha, spread = _as_floor(g, alpha, spread)
        aw = g.add(alpha, spread, label="α_w")
        px, qx = _axis_ratio(g, alpha, aw, spread, distribution)
        p = g.mul(px, px, label="p")
        q = g.madd(px, qx, qx, label="q = 1 - p")
        out["alpha_wide"] = (aw, aw)
    out["peak_ratio"] = p
    out["peak_complement"] = q

    # -- haze intensity, β and 1 - r̂ on r̂_c (Eq. 7 or the Bézier) -----------------------------
    section("Eqs. 12-15 haze, Eqs. 4-5 β and r" if smooth else
            "Eq. 7 haze intensity, Eqs. 4-5 β and r")
    rc_max = g.channel_max(rc)
    kh, beta, omr_hat, r_hat = haze_terms(g, rc_max, p, q, bh,
                                          src.get("smoothness") if smooth else None)
    out["beta"] = beta
    out["halo_intensity"] = kh
    out["reflectivity_max"] = r_hat
    out["core_max"] = rc_max

    # -- Eq. 5 with the core's chroma, and 1 - r per channel without cancellation ---------------
    r, omr_v, chroma = reflectivity(g, rc, rc_max, r_hat, omr_hat)
    out["reflectivity"] = r
    out["chroma"] = chroma
    if multiscatter:  # Multiscatter GGX: β, r from (*) (docs/mapping.md §11), 1 - r by subtraction
        section("Multiscatter GGX, r keeps the peak")
        lobe = MULTISCATTER_LOBE[kind] if multiscatter is True else str(multiscatter).upper()
        if smooth:  # β_h keeps its meaning: the Bézier's share k̂_h / k̂_7 of Eq. 7's bound
            k7 = g.minimum(g.div(rc_max, g.maximum(p, _DIV_MIN)), g.div(g.sub(1.0, rc_max), g.maximum(q, _DIV_MIN)))
            bh_ms = g.div(kh, k7)
        else:
            bh_ms = bh
        # roughness index x = (α_x α_y)^¼ of each lobe (Cycles' table coordinate)
        x_n = g.sqrt(gm) if anisotropic else rough
        wx_, wy_ = out["alpha_wide"]
        x_w = g.sqrt(g.sqrt(g.mul(wx_, wy_))) if anisotropic else g.sqrt(wx_)
        ms = correct(g, out, lobe=lobe, rc=rc, p=p, x_n=x_n, x_w=x_w, haziness=bh_ms,
                     edge_tint=src.get("edge_tint"), tint=tint, version=version,
                     iterations=iterations, affine=affine)
        out.update(ms)
        beta, r, r_hat = ms["beta"], ms["reflectivity"], ms["reflectivity_max"]
        omr_hat = g.maximum(g.sub(1.0, r_hat), TINY)
        omr_v = g.vmath("MAXIMUM", g.vmath("SUBTRACT", 1.0, r), TINY)
        r = g.vmath("MINIMUM", r, K.ONE_MINUS_ULP32)
        chroma = g.vmath("DIVIDE", ms["reflectivity"], r_hat)

    section("the Fresnel of r, the wide lobe")
    if kind == "CONDUCTOR":
        out["ior"], out["extinction"] = gulbrandsen(g, r, omr_v, src["edge_tint"])
    elif kind == "DIELECTRIC":
        sq = g.add(g.sqrt(r_hat), 1.0)
        out["ior"] = g.div(g.mul(sq, sq), g.maximum(omr_hat, TINY), label="η = (1+√r̂)/(1-√r̂)")
        out["specular_tint"] = chroma  # black where r_c = 0 (r̂ = 0 there: it does not matter)
    elif "colour_narrow" not in out:
        out["colour_narrow"] = g.vmath("SCALE", r, g.sub(1.0, beta), label="k_n = (1-β) r")
        out["colour_wide"] = g.vmath("SCALE", r, beta, label="k_w = β r")

    # -- the wide lobe in the node's convention --------------------------------------------------
    wx, wy = out["alpha_wide"]
    if anisotropic:
        out["roughness_wide"] = g.sqrt(g.sqrt(g.mul(wx, wy)), label="R_w = (α_x α_y)^¼")
        ratio = g.div(g.minimum(wx, wy), g.maximum(wx, wy))
        if kind == "LEGACY":
            out["anisotropy_wide"] = g.sub(g.sqrt(ratio), 1.0, label="Glossy anisotropy")
        else:
            out["anisotropy_wide"] = g.clamp(g.div(g.sub(1.0, ratio), 0.9), 0.0, 1.0,
                                             label="Metallic anisotropy")
        rot = g.maximum(g.minimum(src["rotation"], 1e6), -1e6)  # finite turns (NaN, ±inf)
        out["rotation_wide"] = g.madd(g.less(wx, wy), 0.25, rot, label="rotation (+¼ if α_x < α_y)")
    else:
        out["roughness_wide"] = g.sqrt(wx, label="R_w = √α_w")
    out["roughness"] = rough
    return out


#: Cycles clamps Ashikhmin-Shirley α to >= 1e-4 (bsdf_ashikhmin_shirley_setup).
_AS_ALPHA_MIN = 1e-4


def _as_floor(g, an, spread):
    """Cycles' Ashikhmin-Shirley floor α >= 1e-4 on both lobes of one axis: (α_n, α_w - α_n)
    as rendered (core.mapping clips α_n and α_w alike); the spread is recomputed only where the
    floor acts, so it keeps its digits elsewhere."""
    low = g.less(an, _AS_ALPHA_MIN)
    an_c = g.maximum(an, _AS_ALPHA_MIN)
    lifted = g.maximum(g.sub(g.add(an, spread), _AS_ALPHA_MIN), 0.0)
    return an_c, g.select(low, lifted, spread)


def _axis_ratio(g, an, aw, spread, distribution):
    """Per-axis peak ratio and its complement (hazy_gloss.core.mapping._axis_ratio)."""
    if distribution == "ASHIKHMIN_SHIRLEY":
        # Cycles' AS: peak ∝ sqrt((n_x+1)(n_y+1)), n+1 = (2-α²)/α²
        den = g.mul(g.mul(aw, aw), g.madd(an, g.mul(an, -1.0), 2.0))
        p2 = g.div(g.mul(g.mul(an, an), g.madd(aw, g.mul(aw, -1.0), 2.0)), den)
        one_minus_p2 = g.div(g.mul(g.mul(spread, g.add(aw, an)), 2.0), den)
        px = g.sqrt(p2)
        return px, g.div(one_minus_p2, g.add(px, 1.0))
    return g.div(an, aw), g.div(spread, aw)


def haze_terms(g, rc_max, p, q, bh, smoothness=None):
    """(k̂_h, β, 1 - r̂, r̂) from r̂_c, p, q = 1 - p and β_h: Eq. 7 (``smoothness`` None) or
    the rational Bézier through its implicit equation (docs/mapping.md §5-6).

    β = k̂_h / r̂ (Eq. 4): 0 at r̂_c = 0, where the numpy mapping returns the limit
    β_h / (p + (1-p) β_h) — nothing renders differently there, both lobes reflect 0."""
    omr = g.sub(1.0, rc_max, label="1 - r̂_c")
    omb = g.sub(1.0, bh, label="1 - β_h")
    if smoothness is not None:
        # p - r̂_c = p (1-r̂_c) - r̂_c (1-p): both products are accurate whether p, r̂_c are near
        # 0 (where 1 - r̂_c has rounded off r̂_c's low digits, but p (1-r̂_c) keeps them
        # relative) or near 1 (where the complements carry the digits)
        rq = g.mul(rc_max, q)
        p_minus_rc = g.sub(g.mul(p, omr), rq, label="p - r̂_c")
        w = g.maximum(K.MIN_SMOOTHNESS, smoothness)  # (a NaN w: the bound, layer_graph._AT_LEAST_ZERO)
        ms = g.div(g.sqrt(g.mul(rc_max, omr)), w)
        hyp = g.sqrt(g.madd(p_minus_rc, p_minus_rc, g.mul(ms, ms)))
        den = g.add(g.madd(p, omr, rq), hyp, label="conic denominator")
        t = g.div(g.mul(g.mul(rc_max, omr), 2.0), den)
        kh = g.mul(bh, t, label="k̂_h (Eq. 15)")
        r_hat = g.madd(q, kh, rc_max, label="r̂ (Eq. 5)")
        # 1 - r̂ = c_0 + (1-p) t (1-β_h); c_0 from the conic t² = 4w²c_0c_2 when it is the smaller
        c0 = g.madd(q, g.mul(t, -1.0), omr)
        c2 = g.madd(p, g.mul(t, -1.0), rc_max)
        tw = g.div(t, w)
        c0_conic = g.div(g.mul(tw, tw), g.mul(g.maximum(c2, _DIV_MIN), 4.0))
        c0 = g.maximum(g.select(g.less(c0, c2), c0_conic, c0), 0.0)
        omr_hat = g.madd(g.mul(q, t), omb, c0, label="1 - r̂")
    else:
        # Eq. 7: k̂_h = β_h u, u = min(r̂_c / p, (1 - r̂_c) / (1 - p)) (positivity, energy).  With
        # v = (1-p) u = min((1-p) r̂_c / p, 1 - r̂_c) (exactly 1 - r̂_c on the energy side):
        # r̂ = r̂_c + β_h v and 1 - r̂ = v (1-β_h) + (1 - r̂_c - v), sums of non-negative terms
        # (the last one is 0 on the energy side, (p - r̂_c) / p on the other, as accurate as
        # p (1-r̂_c) - r̂_c (1-p)).  p > 0 (α_n >= 1.6e-5, α_w <= 1); 1 - p = 0: no halo
        u_pos = g.div(rc_max, p)
        v = g.at_most(g.mul(q, u_pos), omr, label="(1-p) u")
        u = g.at_most(u_pos, g.div(omr, g.at_least(q, _DIV_MIN)), label="u (Eq. 7)")
        kh = g.mul(bh, u, label="k̂_h (Eq. 7)")
        r_hat = g.madd(bh, v, rc_max, label="r̂ (Eq. 5)")
        omr_hat = g.madd(v, omb, g.sub(omr, v), label="1 - r̂")
    # no clamp: β is in [0, 1] up to rounding and the Mix Shader clamps its factor
    beta = g.div(kh, r_hat, label="β = k̂_h / r̂ (Eq. 4)")
    return kh, beta, omr_hat, r_hat


def reflectivity(g, rc, rc_max, r_hat, omr_hat):
    """Eq. 5 with the core's chroma c = r_c / r̂_c: (r, 1 - r, c), with 1 - r = (1 - c) + c (1 - r̂)
    per channel (no cancellation as r -> 1).  r may exceed 1 by rounding (1 - r is what the
    Fresnel terms divide by)."""
    # a true division (not a scale by 1/r̂_c), so the max channel's chroma is exactly 1
    chroma = g.vmath("DIVIDE", rc, rc_max, label="chroma c")
    r = g.vmul(r_hat, chroma, label="r")
    omr_v = g.vmix(chroma, 1.0, omr_hat, label="1 - r")  # (1-c) 1 + c (1-r̂): one node
    omr_v = g.vmath("MAXIMUM", omr_v, TINY)
    return r, omr_v, chroma


def glossy_to_metallic(g, anisotropy, rotation):
    """A Glossy lobe's (anisotropy, rotation) in the Metallic convention (Metallic: α_x = R²/s,
    α_y = R² s, s² = 1 - 0.9 A): α_y/α_x = (1 - |a|)², a > 0 turns the long axis by ¼."""
    a = g.minimum(g.maximum(anisotropy, -0.99), 0.99)
    k = g.sub(1.0, g.math("ABSOLUTE", a))
    metallic = g.clamp(g.div(g.madd(k, g.mul(k, -1.0), 1.0), 0.9), 0.0, 1.0)
    return metallic, g.madd(g.math("GREATER_THAN", a, 0.0), 0.25, rotation)


def folded_roughness(g, beta, r_n, r_w):
    """R_f = R_n ((1 - β) + β (R_n / R_w)⁴)^(-1/4): the single GGX lobe with the peak of
    (1 - β) D(α_n) + β D(α_w) at the same F(0) (1/α_f² = (1-β)/α_n² + β/α_w², α = R²; the
    EEVEE-only output, blender.actions.eevee_output).  POWER bases are kept > 0 (4.5: 0^-¼ is inf)."""
    ratio = g.div(r_n, g.maximum(r_w, 1e-6))
    s = g.madd(beta, g.math("POWER", ratio, 4.0), g.sub(1.0, beta))
    return g.mul(r_n, g.math("POWER", g.maximum(s, 1e-12), -0.25), label="R_f")
