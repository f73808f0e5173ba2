# SPDX-License-Identifier: GPL-3.0-or-later
"""Keep Body Colour as node math (no bpy): core.body_colour's compensation computed per shading
point from the layer's inputs, so that it follows keyframes, drivers and textures.

Cycles weights the Principled BSDF's diffuse/subsurface base by 1 - A, A the dielectric
specular layer's albedo estimate for the view cosine μ (core.body_colour has the derivation and
the version differences).  A haze layer mixes two specular lobes with the raised IOR', so its
base is weighted (1-β)(1 - A(α_n, IOR')) + β(1 - A(α_w, IOR')) instead of 1 - A(α_n, IOR):

    c(μ) = (1 - A(α_n, μ, IOR)) / [(1-β)(1 - A(α_n, μ, IOR')) + β(1 - A(α_w, μ, IOR'))]

and Base Color · c restores the body (clamped to 1: a brighter diffuse would not conserve
energy).  A is read from Cycles' own tables, as images (Graph.table, an Image Texture each
with Cycles' linear interpolation): the 3-D ggx_gen_schlick_ior_s as an atlas of its z slices
(two reads and a blend, as lookup_table_read_3D), ggx_E and E_avg for Multiscatter GGX.  μ is
the Layer Weight node's Facing: a graph input the group feeds.
"""
from __future__ import annotations

from . import body_colour as _bc

__all__ = ("specular_albedo", "compensation", "peak_albedos", "peak_energy", "FACING")

#: The graph input holding the Layer Weight node's Facing (1 - |N·I|, Blend 0.5).
FACING = "geom:facing"
_TINY = 1e-12


def _tables(version):
    gen = _bc.generation(version)
    t = _bc.generation_tables(gen)
    s = t["ior_s"]  # [z][y][x]
    n = s.shape[0]
    return gen, {"ior_s": (s.reshape(n * n, n), n), "e": (t["e"], 32),
                 "eavg": (t["eavg"].reshape(1, -1), 32), "glass_e": (t["glass_e_mu1"], n)}


def _coord(g, x, n):
    """The texture coordinate of table index x·(n-1) (x in [0, 1]) on an axis of n texels."""
    return g.div(g.madd(g.clamp(x, 0.0, 1.0), float(n - 1), 0.5), float(n))


def _read2(g, name, data, x, y, nx, ny, v_offset=0.0, rows=None):
    rows = rows or ny
    v = g.div(g.add(g.madd(g.clamp(y, 0.0, 1.0), float(ny - 1), 0.5), v_offset), float(rows))
    return g.separate(g.table(name, data, _coord(g, x, nx), v))[0]


def _read3(g, name, data, n, x, y, z):
    """lookup_table_read_3D on the atlas (slices of n rows stacked): two reads, blended."""
    k = g.mul(g.clamp(z, 0.0, 1.0), float(n - 1))
    k0 = g.math("FLOOR", k)
    k1 = g.minimum(g.add(k0, 1.0), float(n - 1))
    t = g.sub(k, k0)
    s0 = _read2(g, name, data, x, y, n, n, g.mul(k0, float(n)), n * n)
    s1 = _read2(g, name, data, x, y, n, n, g.mul(k1, float(n)), n * n)
    return g.mix(t, s0, s1)


def peak_albedos(g, rough_n, rough_w, ior, version=None):
    """(E_glass(1, x_n, η), E(1, x_w)) at a view along the normal: the single-scatter albedos
    behind Multiscatter GGX's energy factor 1/E (microfacet_ggx_preserve_energy) of a glass
    closure of roughness index ``rough_n`` and IOR ``ior`` and of a reflection closure of
    ``rough_w`` (the table rows y = 1: μ and √μ give the same row)."""
    gen, tabs = _tables(version)
    g_data, n = tabs["glass_e"]
    z = g.sqrt(g.math("ABSOLUTE", g.div(g.sub(ior, 1.0), g.add(ior, 1.0))))
    e_glass = _read2(g, f"glass E(1) {gen}", g_data, rough_n, z, n, n)
    e_data, _ = tabs["e"]
    e_wide = _read2(g, f"E {gen}", e_data, rough_w, 1.0, 32, 32)
    return g.at_least(e_glass, 1e-6), g.at_least(e_wide, 1e-6)


def peak_energy(g, fss, rough, version=None):
    """Multiscatter GGX's factor on a reflection closure at a view along the normal
    (microfacet_ggx_preserve_energy): 1 + F_ms m, m = (1 - E)/E, F_ms = F_ss E_avg /
    (1 - F_ss (1 - E_avg)), per channel of ``fss`` (E = E(1, x), E_avg(x), x = ``rough``)."""
    gen, tabs = _tables(version)
    e_data, _ = tabs["e"]
    e = g.at_least(_read2(g, f"E {gen}", e_data, rough, 1.0, 32, 32), 1e-6)
    a_data, _ = tabs["eavg"]
    eavg = _read2(g, f"Eavg {gen}", a_data, rough, 0.0, 32, 1)
    m = g.div(g.sub(1.0, e), e)
    den = g.vmath("SUBTRACT", 1.0, g.vmath("SCALE", fss, g.sub(1.0, eavg)))
    fms = g.vmath("DIVIDE", g.vmath("SCALE", fss, eavg), g.vmath("MAXIMUM", den, _TINY))
    return g.vmath("MULTIPLY_ADD", fms, m, 1.0)


def _f0(g, eta):
    return g.math("POWER", g.div(g.sub(eta, 1.0), g.add(eta, 1.0)), 2.0)


def kernel_specular(g, ior, level):
    """(η, F0 before tint, exists) of the Principled specular closure (body_colour's)."""
    ior = g.at_least(ior, 1e-5)
    level = g.clamp(level, 0.0, 1e30)
    f0 = _f0(g, ior)
    scaled = g.mul(f0, g.mul(level, 2.0))
    q = g.sqrt(g.clamp(scaled, 0.0, 0.99))
    eta_l = g.div(g.add(q, 1.0), g.sub(1.0, q))
    eta_l = g.select(g.less(ior, 1.0), g.div(1.0, eta_l), eta_l)
    keep = g.math("COMPARE", level, 0.5, 0.0)
    eta = g.select(keep, ior, eta_l)
    return eta, g.select(keep, f0, scaled), g.sub(1.0, g.math("COMPARE", eta, 1.0, 0.0))


def specular_albedo(g, rough, mu, ior, tint, level, *, multiscatter, version=None):
    """A per channel (a vector) for the closure roughness index ``rough`` = (α_x α_y)^¼, view
    cosine ``mu``, the node's IOR, Specular Tint and Specular IOR Level."""
    gen, tabs = _tables(version)
    eta, f0, exists = kernel_specular(g, ior, level)
    f0_c = g.vclamp01(g.vmath("SCALE", g.vmath("MAXIMUM", tint, 0.0), f0))
    y = g.sqrt(g.at_least(mu, 0.0)) if gen == "V53" else mu
    z = g.sqrt(g.math("ABSOLUTE", g.div(g.sub(eta, 1.0), g.add(eta, 1.0))))
    data, n = tabs["ior_s"]
    s = _read3(g, f"ior_s {gen}", data, n, rough, y, z)
    est = g.vmath("MULTIPLY_ADD", g.vmath("SUBTRACT", 1.0, f0_c), s, f0_c)
    if multiscatter:
        f0_eta = _f0(g, eta)
        lo = g.madd(eta, g.madd(eta, g.madd(eta, -0.130607, -0.965241), 0.1014), 0.997118)
        hi = g.div(g.sub(eta, 1.0), g.madd(eta, 1.00071, 4.08567))
        fss_eta = g.select(g.less(eta, 1.0), lo, hi)
        sf = g.clamp(g.div(g.sub(fss_eta, f0_eta), g.sub(1.0, f0_eta)), 0.0, 1.0)
        fss = g.vmath("MULTIPLY_ADD", g.vmath("SUBTRACT", 1.0, f0_c), sf, f0_c)
        e_data, _ = tabs["e"]
        e = g.at_least(_read2(g, f"E {gen}", e_data, rough, y, 32, 32), 1e-6)
        a_data, _ = tabs["eavg"]
        eavg = _read2(g, f"Eavg {gen}", a_data, rough, 0.0, 32, 1)
        missing = g.div(g.sub(1.0, e), e)
        den = g.vmath("SUBTRACT", 1.0, g.vmath("SCALE", fss, g.sub(1.0, eavg)))
        fms = g.vmath("DIVIDE", g.vmath("SCALE", fss, eavg), g.vmath("MAXIMUM", den, _TINY))
        dark = g.vmath("DIVIDE", g.vmath("MULTIPLY_ADD", fms, missing, 1.0), g.add(missing, 1.0))
        lossy = g.math("GREATER_THAN", g.channel_max(g.vmath("ABSOLUTE", g.vmath("SUBTRACT", fss, 1.0))), 0.0)
        dark = g.vmix(lossy, 1.0, dark)  # the kernel's shortcut: no factor where F_ss = 1
    else:
        dark = None
    if gen == "V53":
        a = g.channel_max(est)
        a = g.vmath("SCALE", dark, a) if dark is not None else g.combine(a, a, a)
    else:
        m = g.channel_max(g.vmath("MULTIPLY", dark, est) if dark is not None else est)
        a = g.combine(m, m, m)
    return g.vmath("SCALE", g.vclamp01(a), exists)


def compensation(g, *, mu, rough_n, rough_w, beta, ior, ior_hazy, tint, level, multiscatter,
                 version=None):
    """c(μ) per channel (a vector, <= body_colour.C_LIMIT; 1 where the original body is 0)."""
    kw = dict(tint=tint, level=level, multiscatter=multiscatter, version=version)
    orig = g.vmath("SUBTRACT", 1.0, specular_albedo(g, rough_n, mu, ior, **kw))
    a_n = specular_albedo(g, rough_n, mu, ior_hazy, **kw)
    a_w = specular_albedo(g, rough_w, mu, ior_hazy, **kw)
    hazy = g.vmath("SUBTRACT", 1.0, g.vmix(beta, a_n, a_w))  # (1-β)(1-A_n) + β(1-A_w)
    c = g.vmath("DIVIDE", orig, g.vmath("MAXIMUM", hazy, _TINY))
    c = g.vmath("MINIMUM", c, _bc.C_LIMIT)
    # 1 where the original body is 0 (orig <= 1e-12, per channel)
    gone = g.vmath("SUBTRACT", 1.0, g.vmath("MINIMUM", g.vmath("DIVIDE", orig, _TINY), 1.0))
    return g.vmix(gone, c, 1.0)


def mu_from_facing(g):
    """μ = 1 - Facing (Layer Weight, Blend 0.5)."""
    return g.sub(1.0, g.input(FACING))

