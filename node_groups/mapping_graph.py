# SPDX-License-Identifier: GPL-3.0-or-later
"""The haze mapping as Math / Vector Math nodes, for texture-driven (per pixel) parameters.

It computes what hazy_gloss.core.haze_mapping computes with alpha_max = 1 and max_aspect = 10
(what Cycles really renders), in the same float32-stable forms (docs/mapping.md):
no 1 - p by subtraction, the Bézier through the conic's implicit equation, κ of Gulbrandsen's
mapping as a sum of non-negative terms.  Blender's Math divide is safe (x / 0 = 0).
"""

ONE_MINUS_ULP = 1.0 - 2.0 ** -23  # r <= 1 - ε (float32) keeps η, κ finite
MAX_HAZINESS = 0.9999
MIN_SMOOTHNESS = 1e-4
MAX_ASPECT = 10.0


def build_mapping(tb, src, *, kind, anisotropic, smooth, min_roughness, distribution="GGX"):
    """src: dict of sockets: core_reflectivity, edge_tint, roughness, anisotropy, rotation,
    haziness, haze_extent_x, haze_extent_y, smoothness.  Returns a dict of sockets."""
    out = {}
    # ---- clamp inputs to the valid domain (textures can hold anything) --------------------
    rough = tb.clamp(src["roughness"], min_roughness, 1.0, label="R (mirror cut-off .. 1)")
    bh = tb.clamp(src["haziness"], 0.0, MAX_HAZINESS, label="β_h")
    rc = tb.vmath("MINIMUM", tb.vmath("MAXIMUM", src["core_reflectivity"], 0.0), 1.0, label="r_c")
    alpha = tb.mul(rough, rough, label="α = R²")

    # ---- Eq. 8 + Cycles' α <= 1 and aspect <= 10, and p, q = 1 - p (Table 2: GGX/Beckmann) ------
    if anisotropic:
        a = tb.clamp(src["anisotropy"], 0.0, 1.0)
        s = tb.sqrt(tb.madd(a, -0.9, 1.0), label="s = √(1-0.9a)")
        ax = tb.minimum(tb.div(alpha, s), 1.0, label="α_n^x")
        ay = tb.mul(alpha, s, label="α_n^y")
        gm = tb.sqrt(tb.mul(ax, ay), label="√(α_x α_y)")
        lx = tb.maximum(src["haze_extent_x"], 0.0)
        ly = tb.maximum(src["haze_extent_y"], 0.0)
        # spread = α_w - α_n, limited by α <= 1; no subtraction of nearly equal numbers
        sx = tb.minimum(tb.mul(lx, gm), tb.sub(1.0, ax))
        sy = tb.minimum(tb.mul(ly, gm), tb.sub(1.0, ay))
        wx = tb.add(ax, sx)
        wy = tb.add(ay, sy)
        # aspect <= 10: shorten the long axis of the halo (never below α_n)
        wx2 = tb.maximum(tb.minimum(wx, tb.mul(wy, MAX_ASPECT)), ax, label="α_w^x")
        wy2 = tb.maximum(tb.minimum(wy, tb.mul(wx, MAX_ASPECT)), ay, label="α_w^y")
        sx = tb.minimum(sx, tb.sub(wx2, ax))
        sy = tb.minimum(sy, tb.sub(wy2, ay))
        px, qx = _axis_ratio(tb, ax, wx2, sx, distribution)
        py, qy = _axis_ratio(tb, ay, wy2, sy, distribution)
        p = tb.mul(px, py, label="p")
        q = tb.madd(px, qy, qx, label="q = 1-p")
        out["alpha_wide"] = (wx2, wy2)
    else:
        lam = tb.maximum(src["haze_extent_x"], 0.0)
        spread = tb.minimum(tb.mul(lam, alpha), tb.sub(1.0, alpha))
        aw = tb.add(alpha, spread, label="α_w")
        px, qx = _axis_ratio(tb, alpha, aw, spread, distribution)
        p = tb.mul(px, px, label="p")
        q = tb.madd(px, qx, qx, label="q = 1-p")
        out["alpha_wide"] = (aw, aw)
    out["peak_ratio"] = p

    # ---- haze intensity on r̂_c (Eq. 7 or the Bézier, Eqs. 12-15) -------------------------------
    rc_max = tb.channel_max(rc)
    omr = tb.sub(1.0, rc_max, label="1 - r̂_c")
    omb = tb.sub(1.0, bh, label="1 - β_h")
    low_p = tb.less(p, 0.5)
    # p - r̂_c without cancellation: near 1 subtract the complements instead
    p_minus_rc = tb.select(low_p, tb.sub(p, rc_max), tb.sub(omr, q), label="p - r̂_c")
    if smooth:
        w = tb.maximum(src["smoothness"], MIN_SMOOTHNESS)
        ms = tb.div(tb.sqrt(tb.mul(rc_max, omr)), w)
        hyp = tb.sqrt(tb.madd(p_minus_rc, p_minus_rc, tb.mul(ms, ms)))
        den = tb.add(tb.madd(rc_max, q, tb.mul(p, omr)), hyp, label="conic denominator")
        t = tb.div(tb.mul(tb.mul(rc_max, omr), 2.0), den)
        kh = tb.mul(bh, t, label="k̂_h (Eq. 15)")
        two_omr_bh = tb.mul(tb.mul(omr, bh), 2.0)
        beta = tb.div(two_omr_bh, tb.madd(q, two_omr_bh, den), label="β (Eq. 4)")
        # 1 - r̂ = c_0 + (1-p) t (1-β_h); c_0 from the conic t² = 4w²c_0c_2 when it is the smaller
        c0 = tb.madd(q, tb.mul(t, -1.0), omr)
        c2 = tb.madd(p, tb.mul(t, -1.0), rc_max)
        tw = tb.div(t, w)
        c0_conic = tb.div(tb.mul(tw, tw), tb.mul(c2, 4.0))
        c0 = tb.maximum(tb.select(tb.less(c0, c2), c0_conic, c0), 0.0)
        omr_hat = tb.madd(tb.mul(q, t), omb, c0, label="1 - r̂")
    else:
        # r̂_c > p: energy branch of Eq. 7, decided on the accurate complements when p > 1/2
        upper = tb.select(low_p, tb.less(p, rc_max), tb.less(omr, q))
        kh = tb.mul(bh, tb.select(upper, tb.div(omr, q), tb.div(rc_max, p)), label="k̂_h (Eq. 7)")
        # β = β_h / (σ + (1-p) β_h), σ = p or r̂_c (1-p)/(1-r̂_c); the energy branch multiplied
        # through by 1 - r̂_c so r̂_c = 1 gives β = 0 (a safe divide by 0 would give 1/(1-p))
        beta_up = tb.div(tb.mul(bh, omr), tb.mul(q, tb.madd(bh, omr, rc_max)))
        beta_lo = tb.div(bh, tb.madd(q, bh, p))
        beta = tb.select(upper, beta_up, beta_lo, label="β (Eq. 4)")
        # 1 - r̂ in non-negative terms: (1-r̂_c)(1-β_h), or ((p-r̂_c) + r̂_c (1-p)(1-β_h))/p
        omr_lo = tb.div(tb.madd(tb.mul(rc_max, q), omb, tb.maximum(p_minus_rc, 0.0)), p)
        omr_hat = tb.select(upper, tb.mul(omr, omb), omr_lo, label="1 - r̂")
    beta = tb.clamp(beta, 0.0, 1.0)
    out["beta"] = beta
    out["halo_intensity"] = kh
    omr_hat = tb.maximum(omr_hat, 1.0 - ONE_MINUS_ULP)

    # ---- Eq. 5 with the core's chroma: r = r_c (1 + (1-p) k̂_h / r̂_c) ---------------------------
    gain = tb.add(1.0, tb.div(tb.mul(q, kh), rc_max), label="r̂ / r̂_c")
    r = tb.vmath("MINIMUM", tb.vscale(rc, gain), ONE_MINUS_ULP, label="r")
    out["reflectivity"] = r
    # 1 - r per channel without cancellation: (1 - c) + c (1 - r̂), c = r_c / r̂_c
    # a true division (not a scale by 1/r̂_c), so the max channel's chroma is exactly 1
    chroma = tb.vmath("DIVIDE", rc, rc_max, label="chroma c")
    omr_v = tb.vmath("MULTIPLY_ADD", chroma, omr_hat, tb.vmath("SUBTRACT", 1.0, chroma), label="1 - r")
    omr_v = tb.vmath("MAXIMUM", omr_v, 1.0 - ONE_MINUS_ULP)

    if kind == "CONDUCTOR":
        g = tb.vmath("MINIMUM", tb.vmath("MAXIMUM", src["edge_tint"], 0.0), 1.0, label="g")
        s = tb.vmath("POWER", r, 0.5, label="√r")
        ops = tb.vmath("ADD", s, 1.0)
        n_d = tb.vmath("DIVIDE", tb.vmath("MULTIPLY", ops, ops), omr_v, label="(1+√r)/(1-√r)")
        n_m = tb.vmath("DIVIDE", omr_v, tb.vmath("ADD", r, 1.0), label="(1-r)/(1+r)")
        one_minus_g = tb.vmath("SUBTRACT", 1.0, g)
        eta = tb.vmath("MULTIPLY_ADD", g, n_m, tb.vmath("MULTIPLY", one_minus_g, n_d), label="η")
        gr = tb.vmath("DIVIDE", g, tb.vmath("ADD", r, 1.0))
        # 2(1-g)/(1-√r)² = 2(1-g) n_d / (1-r)
        edge = tb.vmath("DIVIDE", tb.vmath("MULTIPLY", tb.vscale(one_minus_g, 2.0), n_d), omr_v)
        inner = tb.vmath("MULTIPLY", gr, tb.vmath("ADD", gr, edge))
        kappa = tb.vmath("MULTIPLY", tb.vscale(s, 2.0), tb.vmath("POWER", inner, 0.5), label="κ")
        out["ior"] = eta
        out["extinction"] = kappa
    elif kind == "DIELECTRIC":
        r_max = tb.minimum(tb.madd(q, kh, rc_max), ONE_MINUS_ULP, label="r̂")
        sq = tb.add(tb.sqrt(r_max), 1.0)
        out["ior"] = tb.div(tb.mul(sq, sq), omr_hat, label="η = (1+√r̂)/(1-√r̂)")
        # chroma c = r_c / r̂_c (black where r_c = 0, where r̂ = 0 and it does not matter)
        out["specular_tint"] = chroma
    else:
        out["colour_narrow"] = tb.vscale(r, tb.sub(1.0, beta), label="k_n = (1-β) r")
        out["colour_wide"] = tb.vscale(r, beta, label="k_w = β r")

    # ---- wide lobe roughness in the node's convention -----------------------------------------
    wx, wy = out["alpha_wide"]
    if anisotropic:
        out["roughness_wide"] = tb.sqrt(tb.sqrt(tb.mul(wx, wy)), label="R_w = (α_x α_y)^¼")
        ratio = tb.div(tb.minimum(wx, wy), tb.maximum(wx, wy))
        if kind == "LEGACY":
            out["anisotropy_wide"] = tb.sub(tb.sqrt(ratio), 1.0, label="Glossy anisotropy")
        else:
            out["anisotropy_wide"] = tb.clamp(tb.div(tb.sub(1.0, ratio), 0.9), 0.0, 1.0,
                                              label="Metallic anisotropy")
        swap = tb.less(wx, wy)
        out["rotation_wide"] = tb.madd(swap, 0.25, src["rotation"], label="rotation (+¼ if α_x<α_y)")
    else:
        out["roughness_wide"] = tb.sqrt(wx, label="R_w = √α_w")
    out["roughness"] = rough
    return out


def _axis_ratio(tb, an, aw, spread, distribution):
    """Per-axis peak ratio and its complement (see hazy_gloss.core.mapping._axis_ratio)."""
    if distribution == "ASHIKHMIN_SHIRLEY":
        # Cycles' AS: peak ∝ sqrt((n_x+1)(n_y+1)), n+1 = (2-α²)/α²
        den = tb.mul(tb.mul(aw, aw), tb.madd(an, tb.mul(an, -1.0), 2.0))
        p2 = tb.div(tb.mul(tb.mul(an, an), tb.madd(aw, tb.mul(aw, -1.0), 2.0)), den)
        one_minus_p2 = tb.div(tb.mul(tb.mul(spread, tb.add(aw, an)), 2.0), den)
        px = tb.sqrt(p2)
        return px, tb.div(one_minus_p2, tb.add(px, 1.0))
    return tb.div(an, aw), tb.div(spread, aw)
