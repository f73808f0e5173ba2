# SPDX-License-Identifier: GPL-3.0-or-later
"""The haze layer as node math on its BSDF's own inputs (no bpy): what the layer's node group
computes, written once against :class:`hazy_gloss.core.graph.Graph`.

A layer wraps the artist's Principled, Metallic or Glossy BSDF (the *core*).  Every input of the
core is a graph input ``"in:<socket name>"``, every haze parameter one ``"haze:<name>"``
(schema.HAZE_SOCKETS), so the group computes the wide lobe, the raised Fresnel (Eq. 3-5), β,
the metallic split, the coat's haze and the Multiscatter GGX correction per shading point, from
whatever feeds the group node: values, keyframes, drivers, textures.  Cycles folds the math of
constant inputs when it compiles the shader, and a Mix Shader whose factor folds to 0 or 1 drops
the closure it does not need.

The closure tree of a Principled core (5 BSDF slots at most: Cycles counts 12 closures per
Principled BSDF against its limit of 64, kernel MAX_CLOSURE):

    X_A = Mix(β_A, S1, S2)    X_B = Mix(β_B, S3, S4)    X = Mix(f_AB, X_A, X_B)
    result = Mix(f_5, X, S5)

Per shading point, with m = saturate(Metallic):

- m ∈ {0, 1} (no split): A = B = the part of m (dielectric or metal), S1/S2 its narrow and wide
  lobes under the narrow coat, S3/S4 the same under the wide coat; β_A = β_B = the part's β,
  f_AB = β_c, f_5 = 0.  Exact (the haze mapping of that part, the coat's own on top).
- 0 < m < 1 with haze (the Principled is linear in its metallic part, Cycles svm/closure.h): A = the
  dielectric part, B = the metal part (each its own β), f_AB = m, all four under the narrow
  coat; S5 is the user's own BSDF (no base haze) under the wide coat, f_5 = β_c.  Exact without
  coat haze; with it the base's halo lives in the (1 - β_c) share under the narrow coat, so its
  haziness is raised by 1/(1 - β_c) there (peaks exact, energy conserved: every slot is a
  Principled BSDF; the halo's weight approximate where β_h > 1 - β_c).

At haziness 0 (and coat haziness 0) nothing splits, every select picks the user's own input
(the Mix node, (1-t) a + t b at t = 0, is exactly a), β is 0 and the slot S1 is the user's BSDF
bit for bit.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .. import constants as K
from . import node_body_colour, node_fresnel, node_math, node_multiscatter, node_thin_film
from .graph import Graph
from .multiscatter import LATEST as _LATEST

__all__ = ("Config", "Slot", "Mix", "Layer", "build", "input_name", "haze_name", "baked_name",
           "slots_of", "BSDF_TYPES", "BAKED")

#: The core node types a layer wraps.
BSDF_TYPES = ("PRINCIPLED", "METALLIC", "GLOSSY")

#: Divisor floor where a quotient of a branch a select drops must stay finite.
_DIV_MIN = 1e-30
#: Cycles' CLOSURE_WEIGHT_CUTOFF: a coat below it is not built (kernel/svm/types.h).
_WEIGHT_CUTOFF = 1e-5
#: kernel/svm/types.h THINFILM_THICKNESS_CUTOFF (nm): thinner films are off.
_FILM_CUTOFF = 0.1
#: Fixed-point steps for the energy factor of a thin wall's raised tint (mapping.md §13).
_THIN_FIXED_POINT = 4


def input_name(socket):
    """The graph input of a core socket."""
    return "in:" + socket


def haze_name(param):
    """The graph input of a haze parameter (schema.HAZE_SOCKETS)."""
    return "haze:" + param


#: The parts a layer's group can hold, per BSDF: what a material uses.  A part left out is
#: computed nowhere; a point that needs it after all (a value changed where the add-on did
#: not see it) renders its lobe plain there, without haze (the panel says so).
PARTS = {"PRINCIPLED": ("dielectric", "metal", "coat", "film", "transmission", "thin_wall",
                        "aniso"),
         "METALLIC": ("aniso",), "GLOSSY": ("aniso",)}


@dataclass(frozen=True)
class Config:
    """What a layer group is built for (one group per configuration, shared by materials).

    ``bsdf``: PRINCIPLED, METALLIC or GLOSSY; ``distribution``: the core's; ``fresnel``: a
    Metallic BSDF's fresnel_type; ``smooth``: the Bézier haze curve (Eqs. 12-15) instead of
    Eq. 7; ``version``: the Cycles whose Multiscatter tables the math reproduces (None: the
    running one); ``baked``: the haze mapping's per-point values (BAKED) are inputs, read from
    maps texture conversion wrote (Principled only); ``body``: Keep Body Colour (the
    dielectric part's Base Color compensated for the raised specular's layering,
    core.node_body_colour; Principled only); ``parts``: the PARTS it holds (None: all)."""

    bsdf: str
    distribution: str = "GGX"
    fresnel: str = ""
    smooth: bool = False
    version: tuple = None
    baked: bool = False
    body: bool = False
    parts: frozenset = None

    def __post_init__(self):
        known = PARTS.get(self.bsdf, ())
        parts = frozenset(known if self.parts is None else self.parts)
        if parts - set(known):
            raise ValueError(f"a {self.bsdf} layer has no part {sorted(parts - set(known))}; "
                             f"its parts: {', '.join(known)}")
        if self.bsdf == "PRINCIPLED" and not parts & {"dielectric", "metal"}:
            raise ValueError("a Principled layer holds its dielectric part, its metal part or both")
        object.__setattr__(self, "parts", parts)

    def has(self, part):
        return part in self.parts

    @property
    def thin_wall(self):
        """Whether this Blender's Principled BSDF has a Thin Wall input (5.2 on)."""
        v = self.version or _LATEST
        return self.bsdf == "PRINCIPLED" and (int(v[0]), int(v[1])) >= (5, 2)

    def key(self):
        return (self.bsdf, self.distribution, self.fresnel, self.smooth,
                tuple(self.version) if self.version else None, self.baked, self.body,
                tuple(sorted(self.parts)))


@dataclass
class Slot:
    """One BSDF node of the group: ``writes`` input name -> Expr (the other inputs are the
    group's own, passed through)."""

    role: str
    writes: dict = field(default_factory=dict)


@dataclass
class Mix:
    """A Mix Shader (``add``: an Add Shader, ``factor`` unused)."""

    role: str
    factor: object
    a: object
    b: object
    add: bool = False


@dataclass
class Layer:
    """The group's math: ``cycles`` the full closure tree, ``eevee`` the folded one (one BSDF,
    each part's lobes folded into one with the same peak: mapping.md §12), ``shown`` values the
    panel can evaluate (β, r, IOR, α_w per part)."""

    config: Config
    graph: Graph
    cycles: object
    eevee: object
    shown: dict
    sections: list = field(default_factory=list)  # (frame title, first expression index)
    baked: dict = field(default_factory=dict)  # BAKED key -> Expr (what conversion bakes)

    def section_of(self, expr):
        """The frame title of an expression (by when it was made)."""
        title = self.sections[0][0] if self.sections else ""
        for t, start in self.sections:
            if expr.index >= start:
                title = t
        return title

    def outputs(self):
        """Every Expr the closure trees read (for emitting)."""
        out = {}
        for tree in (self.cycles, self.eevee):
            for node in walk(tree):
                if isinstance(node, Slot):
                    out.update({(node.role, k): v for k, v in node.writes.items()})
                elif not node.add:
                    out[(node.role, "factor")] = node.factor
        return out


def walk(tree):
    """The Mix and Slot nodes of a closure tree, parents first."""
    if isinstance(tree, Slot):
        yield tree
        return
    yield tree
    yield from walk(tree.a)
    yield from walk(tree.b)


def slots_of(tree):
    """The BSDF slots of a closure tree, in order."""
    return [n for n in walk(tree) if isinstance(n, Slot)]


# --------------------------------------------------------------------------------------------
# Building blocks
# --------------------------------------------------------------------------------------------


def _f0(g, ior):
    """((η - 1)/(η + 1))²."""
    return g.math("POWER", g.div(g.sub(ior, 1.0), g.add(ior, 1.0)), 2.0)


def _ior_from_f0(g, f0):
    """(1 + √f)² / (1 - f) = (1 + √f)/(1 - √f), no cancellation."""
    f0 = g.minimum(f0, K.ONE_MINUS_ULP32)
    sq = g.add(g.sqrt(f0), 1.0)
    return g.div(g.mul(sq, sq), g.maximum(g.sub(1.0, f0), 1e-12))


#: Haze inputs read through max(0, x): a NaN the socket holds renders as 0 does (it rendered as
#: no value does: a wide roughness of 0, β 1).  Measured: Cycles' Maximum gives 0 for NaN in
#: 4.5 and 5.x at run time, and 5.x's constant folding keeps a NaN *first* operand (a < b ? b : a),
#: so the 0 comes first; its Minimum and Clamp keep a constant NaN.
_AT_LEAST_ZERO = {"haziness", "coat_haziness", "haze_extent_x", "haze_extent_y", "coat_haze_extent",
                  "reflectivity_cap"}


class _Inputs:
    def __init__(self, g):
        self.g = g

    def __call__(self, name, vector=False):
        return self.g.input(input_name(name), vector=vector)

    def haze(self, name):
        raw = self.g.input(haze_name(name))
        if name in _AT_LEAST_ZERO:  # NaN (a script's, a driver's) renders as 0, in 4.5 and 5.x
            return self.g.maximum(0.0, raw, label=f"{name} (NaN: 0)")
        return raw


def _section(g, title):
    """Expressions made from here on belong to the frame ``title`` (the group's layout)."""
    g.section(title)


def _part(g, x, cfg, *, kind, rc, edge, rough, aniso, rot, haziness, lobe=None, tint=None,
          affine=None, title=None):
    """node_math.mapping of one part with the layer's inputs (the anisotropic form where the
    group holds its "aniso" part)."""
    src = dict(core_reflectivity=rc, edge_tint=edge, roughness=rough, anisotropy=aniso,
               rotation=rot, haziness=haziness, haze_extent_x=x.haze("haze_extent_x"),
               haze_extent_y=x.haze("haze_extent_y"),
               smoothness=x.haze("smoothness") if cfg.smooth else None)
    dist = cfg.distribution if cfg.distribution in K.NODE_DISTRIBUTIONS[kind] else "GGX"
    ms = None
    if dist == "MULTI_GGX":
        ms = lobe or node_math.MULTISCATTER_LOBE[kind]
    return node_math.mapping(g, src, kind=kind, anisotropic=cfg.has("aniso"), smooth=cfg.smooth,
                             distribution=dist, multiscatter=ms, tint=tint, version=cfg.version,
                             affine=affine if ms else None, title=title)


def _cap(g, x, rc):
    """The core reflectivity the mapping raises: at most the Reflectivity Cap (a colour at 1
    leaves no room for a halo; below it the peak drops by as much)."""
    return g.vmath("MINIMUM", rc, g.clamp(x.haze("reflectivity_cap"), 0.0, 1.0),
                   label="r_c (capped)")


def _on(g, haziness):
    """1 where haze is on (β_h > 0), else 0: what the selects of the user's own values read."""
    return g.math("GREATER_THAN", haziness, 0.0, label="haze on")


def _off_where(g, value, cutoff):
    """1 where ``value`` <= ``cutoff`` (a feature the group holds no part for is off there)."""
    return g.sub(1.0, g.math("GREATER_THAN", value, cutoff))


def _isotropic_gate(g, x, cfg, aniso):
    """Without the "aniso" part: 1 where the core and the halo are isotropic (Anisotropic
    <= 0 renders isotropic; both extents equal), else 0 (plain).  With it: 1."""
    if cfg.has("aniso"):
        return g.value(1.0)
    same = g.math("COMPARE", x.haze("haze_extent_x"), x.haze("haze_extent_y"), 0.0)
    return g.mul(_off_where(g, aniso, 0.0), same, label="isotropic (else plain)")


def _raised(g, f0, m):
    """``f0`` raised by r̂ / r̂_c (Eq. 5's raise of the brightest channel), as r̂ (f0 / r̂_c):
    the ratio folds into a constant where the core's F0 is not textured."""
    return g.mul(m["reflectivity_max"], g.div(f0, g.maximum(m["core_max"], _DIV_MIN)))


# --------------------------------------------------------------------------------------------
# Principled BSDF
# --------------------------------------------------------------------------------------------


#: A Principled layer's per-point values that texture conversion bakes into maps (the
#: Converted Maps panel of a baked group): key -> (socket name, colour?).
BAKED = {"ior_d": ("Raised IOR", False), "beta_d": ("β Dielectric", False),
         "base_m": ("Raised Base Color", True), "beta_m": ("β Metal", False),
         "roughness_wide": ("Wide Roughness", False), "anisotropy_wide": ("Wide Anisotropy", False),
         "rotation_wide": ("Wide Rotation", False), "coat_ior": ("Raised Coat IOR", False),
         "coat_roughness_wide": ("Coat Wide Roughness", False), "beta_c": ("β Coat", False)}


def baked_name(key):
    """The graph input of a baked value (a baked group reads it from its Converted Maps)."""
    return "baked:" + key


def _principled_mapping(g, x, cfg, m, a_metal, b_metal):
    """The haze mapping of a Principled core, per point: the values the slots need (BAKED's
    keys), the split, and what the panel shows.  Only the parts the group holds are computed;
    the others keep the user's values (no haze there)."""
    bh = x.haze("haziness")
    rough, aniso, rot = x("Roughness"), x("Anisotropic"), x("Anisotropic Rotation")
    has_d, has_m = cfg.has("dielectric"), cfg.has("metal")

    # -- the coat's haze (its own mapping on the Coat IOR's F0; always energy-preserving GGX) --
    v = {"beta_c": g.value(0.0), "coat_ior": x("Coat IOR"), "coat_roughness_wide": x("Coat Roughness")}
    coat_on = g.value(0.0)
    if cfg.has("coat"):
        _section(g, "Coat: its haze on F0 of the Coat IOR")
        cw = x("Coat Weight")
        ch = x.haze("coat_haziness")
        coat_on = g.mul(_on(g, ch), g.math("GREATER_THAN", cw, _WEIGHT_CUTOFF), label="coat haze on")
        f0c = _f0(g, g.maximum(x("Coat IOR"), 1.0))
        coat_src = dict(core_reflectivity=f0c, edge_tint=0.0, roughness=x("Coat Roughness"),
                        anisotropy=0.0, rotation=0.0, haziness=ch,
                        haze_extent_x=x.haze("coat_haze_extent"),
                        haze_extent_y=x.haze("coat_haze_extent"), smoothness=None)
        mc = node_math.mapping(g, coat_src, kind="DIELECTRIC", anisotropic=False, smooth=False,
                               distribution="MULTI_GGX", multiscatter="COAT", version=cfg.version,
                               title="Coat")
        _section(g, "Coat: Eq. 5, the Coat IOR raised to r")
        v["beta_c"] = g.mul(mc["beta"], coat_on, label="β coat")
        v["coat_ior"] = g.select(coat_on, _ior_from_f0(g, _raised(g, f0c, mc)), x("Coat IOR"),
                                 label="Coat IOR (raised)")
        v["coat_roughness_wide"] = g.select(coat_on, mc["roughness_wide"], x("Coat Roughness"),
                                            label="coat R_w")

    # -- a fractional m splits into its two parts only where there is haze: without it the
    #    user's BSDF renders as it is (bit for bit, not as the mix of its parts)
    split = g.mul(g.sub(b_metal, a_metal), g.maximum(_on(g, bh), coat_on),
                  label="split (0 < m < 1, haze on)")
    bh_eff = bh
    if has_d and has_m and cfg.has("coat"):
        # the base's haziness: raised where the split puts its halo under the narrow coat only
        share = g.sub(1.0, g.mul(v["beta_c"], split))
        bh_eff = g.select(split, g.clamp(g.div(bh, g.maximum(share, _DIV_MIN)), 0.0, K.MAX_HAZINESS),
                          bh, label="β_h of the base")
    # -- where a point needs a part the group does not hold, its lobe renders plain ------------
    iso = _isotropic_gate(g, x, cfg, aniso)
    gate_d, gate_m = iso, iso
    if not has_m:  # a dielectric group: only m = 0 is hazed
        gate_d = g.mul(gate_d, _off_where(g, m, 0.0))
    if not has_d:  # a metal group: only m = 1 is hazed
        gate_m = g.mul(gate_m, g.math("GREATER_THAN", m, K.ONE_MINUS_ULP32))
    if not cfg.has("film"):
        gate_d = g.mul(gate_d, _off_where(g, x("Thin Film Thickness"), _FILM_CUTOFF))
    if not cfg.has("transmission"):
        gate_d = g.mul(gate_d, _off_where(g, x("Transmission Weight"), _WEIGHT_CUTOFF))
    elif cfg.thin_wall and not cfg.has("thin_wall"):
        thin = g.mul(g.math("GREATER_THAN", x("Transmission Weight"), _WEIGHT_CUTOFF),
                     g.math("GREATER_THAN", x("Thin Wall"), 0.5))
        gate_d = g.mul(gate_d, g.sub(1.0, thin))
    bh_d, bh_m = g.mul(bh_eff, gate_d, label="β_h dielectric"), g.mul(bh_eff, gate_m, label="β_h metal")
    on_d, on_m = _on(g, bh_d), _on(g, bh_m)

    ior = x("IOR")
    tint = x("Specular Tint", True)
    base = x("Base Color", True)
    one = (1.0, 1.0, 1.0)
    v.update(ior_d=ior, ior_baked=ior, beta_d=g.value(0.0), mix_d=g.value(0.0), tint_n=tint,
             tint_w=tint, mirror=g.value(0.0), mirror_colour=g.value(one), base_m=base,
             beta_m=g.value(0.0))
    shown = {"reflectivity dielectric": g.value(0.0), "haze room dielectric": g.value(0.0),
             "transmissive": g.value(0.0), "tint narrow": tint, "mix dielectric": g.value(0.0)}
    md = mm = None
    if has_d:
        md, tinted = _dielectric_part(g, x, cfg, v, bh_d, on_d, ior, tint, rough, aniso, rot)
        shown = {"reflectivity dielectric": md["reflectivity"],
                 "haze room dielectric": md["halo_intensity"], "transmissive": v["transmissive"],
                 "tint narrow": v["tint_n"], "mix dielectric": v["mix_d"]}
    if has_m:
        # -- metal part: F82-tint with F0 = Base Color, raised per channel (Eq. 5) -----------
        _section(g, "Metal part: F0 = Base Color")
        mm = _part(g, x, cfg, kind="DIELECTRIC", rc=_cap(g, x, base), edge=0.0, rough=rough,
                   aniso=aniso, rot=rot, haziness=bh_m, lobe="F82_TINT",
                   tint=x("Specular Tint", True), title="Metal part")
        _section(g, "Metal part: Eq. 5, Base Color raised to r")
        v["base_m"] = g.select(on_m, mm["reflectivity"], base, label="Base Color (raised)")
        v["beta_m"] = g.mul(mm["beta"], on_m, label="β metal")
    # α_w depends on α_n and λ_h only: the same for both parts
    wide = md or mm
    v.update(roughness_wide=wide["roughness_wide"])
    if cfg.has("aniso"):
        v.update(anisotropy_wide=wide["anisotropy_wide"], rotation_wide=wide["rotation_wide"])
    if cfg.body and has_d:  # (where the tint raises F0, the body is not compensated: mapping.md §13)
        _section(g, "Keep Body Colour: the base as it was")
        kw = dict(tint=x("Specular Tint", True), level=x("Specular IOR Level"),
                  multiscatter=cfg.distribution == "MULTI_GGX", version=cfg.version)
        c = node_body_colour.compensation(
            g, mu=node_body_colour.mu_from_facing(g), beta=v["beta_d"], ior=ior,
            ior_hazy=v["ior_d"], rough_n=_roughness_index(g, rough, aniso),
            rough_w=_roughness_index(g, v["roughness_wide"], v.get("anisotropy_wide", aniso)), **kw)
        v["base_d"] = g.select(g.sub(on_d, tinted), g.vmath("MINIMUM", g.vmath("MULTIPLY", base, c), 1.0),
                               base, label="Base Color (body kept)")
    return v, split, shown


def _dielectric_part(g, x, cfg, v, bh, on, ior, tint, rough, aniso, rot):
    """The dielectric part (β, the raised F(0)): F0 = F0(IOR) 2 Level Specular Tint, raised
    through the IOR; where light passes through (Transmission Weight > 0) or a thin film
    interferes, the IOR stays (it sets the refraction and the film) and the Specular Tint,
    which scales F0 alone (svm/closure.h), raises it (mapping.md §13).  Writes its values into
    ``v``; returns (its mapping, 1 where the tint raises F0)."""
    _section(g, "Dielectric part: F0 of IOR, Level, Tint")
    f0_user = _f0(g, ior)
    has_tr, has_film = cfg.has("transmission"), cfg.has("film")
    tr = g.math("GREATER_THAN", x("Transmission Weight"), _WEIGHT_CUTOFF, label="transmissive") \
        if has_tr else g.value(0.0)
    film = g.math("GREATER_THAN", x("Thin Film Thickness"), _FILM_CUTOFF, label="thin film") \
        if has_film else g.value(0.0)
    keep = g.maximum(tr, film, label="IOR kept")
    # the transmission lobe's F0 has no Specular IOR Level (generalized_schlick_setup): the
    # peak of a partly transmissive point is F0 tint ((1 - w) 2 Level + w), linear in the tint
    level = g.mul(g.maximum(x("Specular IOR Level"), 0.0), 2.0)
    if has_tr:
        level = g.select(tr, g.mix(g.clamp(x("Transmission Weight"), 0.0, 1.0), level, 1.0), level)
    rc_d = g.vmath("SCALE", tint, g.mul(f0_user, level))
    f_base, s_tint = g.value((1.0, 1.0, 1.0)), g.value((1.0, 1.0, 1.0))
    a_t = b_t = None
    if has_tr or has_film:
        # a film: F(0) is the film's F scaled per channel by F (1 + s (τ F0/F0_real - 1)),
        # s = saturate((1 - F)/(1 - F0_real)) (generalized_schlick_fresnel); the closure's η:
        # the transmission lobe's IOR, or the specular's with Specular IOR Level applied
        _section(g, "Dielectric part: film or glass F(0), via the Tint")
        eta_s, f0_s, _ = node_body_colour.kernel_specular(g, ior, g.mul(level, 0.5))
        f_base = g.vmath("SCALE", (1.0, 1.0, 1.0), f0_s)
        if has_film:
            f_film = node_thin_film.dielectric_film(g, x("Thin Film Thickness"), x("Thin Film IOR"),
                                                    eta_s, version=cfg.version)
            scale = g.vmath("SCALE", g.vmath("MINIMUM", g.vmath("SCALE", tint, f0_s), 1.0),
                            g.div(1.0, g.maximum(f0_s, _DIV_MIN)))
            s_film = g.vclamp01(g.vmath("SCALE", g.vmath("SUBTRACT", 1.0, f_film),
                                        g.div(1.0, g.maximum(g.sub(1.0, f0_s), _DIV_MIN))))
            f_base = g.select(film, f_film, f_base, label="F (before the tint)")
            s_tint = g.select(film, s_film, (1.0, 1.0, 1.0), label="s (the tint's share)")
            rc_d = g.select(film, g.vmath("MULTIPLY", f_film, g.vmath("MULTIPLY_ADD", s_film, g.vmath(
                "SUBTRACT", scale, 1.0), 1.0)), rc_d)
        # Multiscatter GGX: a tinted lobe's F_ss = f0' + s_η (1 - f0'), f0' = F0 τ' and τ'
        # affine in the peak r (tint_for): a + b r per channel (microfacet_ggx_preserve_energy)
        s_eta = node_multiscatter.dielectric_s(g, f0_s)
        inv_s = g.vmath("DIVIDE", 1.0, g.vmath("MAXIMUM", s_tint, _DIV_MIN))
        a_t = g.vmath("MULTIPLY_ADD", g.vmath("SCALE", g.vmath("SUBTRACT", 1.0, inv_s),
                                              g.mul(f0_s, g.sub(1.0, s_eta))), 1.0, s_eta)
        b_t = g.vmath("SCALE", g.vmath("DIVIDE", inv_s, g.vmath("MAXIMUM", f_base, _DIV_MIN)),
                      g.mul(f0_s, g.sub(1.0, s_eta)))

    def tint_for(target):
        """The Specular Tint giving the peak ``target`` (per channel): 1 + (target/F - 1)/s."""
        q = g.vmath("DIVIDE", target, g.vmath("MAXIMUM", f_base, _DIV_MIN))
        return g.vmath("ADD", g.vmath("DIVIDE", g.vmath("SUBTRACT", q, 1.0),
                                      g.vmath("MAXIMUM", s_tint, _DIV_MIN)), 1.0)
    thin = None
    if cfg.thin_wall and has_tr and cfg.has("thin_wall"):
        # a thin wall's reflection lobe is always energy-compensated with F_ss = Specular Tint
        # (bsdf_thin_glass_reflection_setup): its peak is R'(F0 tint) S(tint)
        thin = g.mul(tr, g.math("GREATER_THAN", x("Thin Wall"), 0.5), label="thin wall")
        x_n = _roughness_index(g, rough, g.value(0.0))
        rc_d = g.select(thin, g.vmath("MULTIPLY", _thin_reflectance(g, rc_d, x("Base Color", True)),
                                      node_body_colour.peak_energy(g, tint, x_n, cfg.version)), rc_d)
    rc_d = _cap(g, x, rc_d)
    md = _part(g, x, cfg, kind="DIELECTRIC", rc=rc_d, edge=0.0, rough=rough, aniso=aniso, rot=rot,
               haziness=bh, affine=(keep, a_t, b_t) if a_t is not None else None,
               title="Dielectric part")
    _section(g, "Dielectric part: Eq. 5, IOR raised to r")
    raised_ior = _ior_from_f0(g, _raised(g, f0_user, md))
    v["ior_d"] = g.select(g.mul(on, g.sub(1.0, keep)), raised_ior, ior, label="IOR (raised)")
    # converted maps hold the raised IOR everywhere (they have no tint map: mapping.md §13)
    v["ior_baked"] = g.select(on, raised_ior, ior)
    v["beta_d"] = g.mul(md["beta"], on, label="β dielectric")
    v["mix_d"] = v["beta_d"]
    v["transmissive"] = tr
    tinted = g.mul(on, keep, label="F0 raised by the tint")
    if not (has_tr or has_film):
        return md, tinted
    # transmissive: the halo is a mirror lobe of weight f = β r̂ and colour r / r̂ that
    # transmits nothing, so the narrow lobe keeps the refraction and (1 - f) of it; its F0 is
    # raised by t = (1 - f p S_w / (r̂_c S_n)) / (1 - f), which keeps the peak (S: Multiscatter
    # GGX's energy factors at the peak, 1 for GGX) and makes R + T the original's
    # (per channel: under Multiscatter GGX each channel's r keeps its own peak; the tint is RGB)
    narrow = raised = tint_for(md["reflectivity"])
    if has_tr:
        _section(g, "Glass: the halo as a mirror, narrow F(0) up")
        f_t = g.mul(v["beta_d"], md["reflectivity_max"], label="f = β r̂ (mirror)")
        v["mix_d"] = g.select(tr, f_t, v["beta_d"], label="mix of the dielectric lobes")
        halo = g.mul(f_t, md["peak_ratio"])
        v["mirror_colour"] = g.vmath("SCALE", rc_d, g.div(1.0, g.maximum(md["core_max"], _DIV_MIN)),
                                     label="r / r̂")
        if cfg.distribution == "MULTI_GGX":  # the mirror's factor per channel: F_ss = c + (1-c)/21
            x_w = _roughness_index(g, md["roughness_wide"], md.get("anisotropy_wide", aniso))
            e_n, _ = node_body_colour.peak_albedos(g, _roughness_index(g, rough, aniso), x_w, ior,
                                                   cfg.version)
            fss = g.vmath("MULTIPLY_ADD", g.vmath("SUBTRACT", 1.0, v["mirror_colour"]), 1.0 / 21.0,
                          v["mirror_colour"])
            halo = g.vmath("SCALE", node_body_colour.peak_energy(g, fss, x_w, cfg.version), halo,
                           label="f p S_w")
            s_n = g.div(1.0, e_n)
        else:
            s_n = 1.0
        if thin is not None:  # the thin wall's S is in r̂_c already
            s_n = g.select(thin, 1.0, s_n)
        # t per channel, (1 - f p S_w / (r̂_c S_n)) / (1 - f) >= 0
        share = g.vmath("SCALE", halo, g.div(1.0, g.maximum(g.mul(md["core_max"], s_n), _DIV_MIN)))
        t_n = g.vmath("SCALE", g.vmath("MAXIMUM", g.vmath("SUBTRACT", 1.0, share), 0.0),
                      g.div(1.0, g.maximum(g.sub(1.0, f_t), _DIV_MIN)), label="t (narrow F0 gain)")
        narrow = g.select(tr, tint_for(g.vmath("MULTIPLY", rc_d, t_n)), raised)
        if thin is not None:
            base_c = x("Base Color", True)
            target = g.vmath("MULTIPLY", rc_d, t_n)  # R'(s F0) S(s) = target: S from the last root
            s0 = _thin_tint(g, g.vmath("DIVIDE", target, node_body_colour.peak_energy(
                g, tint, x_n, cfg.version)), f0_user, base_c)
            for _ in range(_THIN_FIXED_POINT):
                s0 = _thin_tint(g, g.vmath("DIVIDE", target, node_body_colour.peak_energy(
                    g, s0, x_n, cfg.version)), f0_user, base_c)
            narrow = g.select(thin, s0, narrow)
        v["mirror"] = g.mul(on, tr, label="wide lobe is the mirror")
    v["tint_n"] = g.select(tinted, narrow, tint, label="Specular Tint (narrow)")
    v["tint_w"] = g.select(tinted, raised, tint, label="Specular Tint (wide)")
    return md, tinted


def _thin_reflectance(g, front, base):
    """A thin wall's reflection at normal incidence (bsdf_thin_glass_fresnel): the front
    interface's R, then the internal bounces R' = R + c² R (1 - R)² / (1 - c² R²), c the
    clamped Base Color (the wall's absorption)."""
    c2 = g.vmath("MULTIPLY", g.vclamp01(base), g.vclamp01(base))
    r = front
    omr = g.vmath("SUBTRACT", 1.0, r)
    back = g.vmath("MULTIPLY", g.vmath("MULTIPLY", c2, r), g.vmath("MULTIPLY", omr, omr))
    den = g.vmath("MAXIMUM", g.vmath("SUBTRACT", 1.0, g.vmath("MULTIPLY", c2, g.vmath(
        "MULTIPLY", r, r))), _DIV_MIN)
    return g.vmath("ADD", r, g.vmath("DIVIDE", back, den))


def _thin_tint(g, target, f0, base):
    """The narrow lobe's Specular Tint of a transmissive thin wall, per channel, whose peak
    R'(s F0) (_thin_reflectance) is ``target``: R' (1 - c² R²) = R (1 + c²) - 2 c² R² is a
    quadratic in R, whose root in [0, 1] is R = 2R' / (1 + c² + √((1 + c²)² - 4 c² R' (2 - R')))
    (no cancellation; c = 0 gives R = R')."""
    c2 = g.vmath("MULTIPLY", g.vclamp01(base), g.vclamp01(base))
    p = g.vclamp01(target)
    b = g.vmath("ADD", c2, 1.0)
    disc = g.vmath("SUBTRACT", g.vmath("MULTIPLY", b, b), g.vmath("MULTIPLY", g.vmath(
        "SCALE", c2, 4.0), g.vmath("MULTIPLY", p, g.vmath("SUBTRACT", 2.0, p))))
    r = g.vmath("DIVIDE", g.vmath("SCALE", p, 2.0), g.vmath("MAXIMUM", g.vmath(
        "ADD", b, g.vsqrt(disc)), _DIV_MIN))
    return g.vmath("SCALE", r, g.div(1.0, g.maximum(f0, _DIV_MIN)), label="Specular Tint (thin wall)")


def _roughness_index(g, roughness, anisotropy):
    """(α_x α_y)^¼ of a Principled lobe as the kernel sets it up (α = R², split by the
    anisotropy, each clamped to 1): the roughness index of Cycles' tables."""
    r = g.clamp(roughness, 0.0, 1.0)
    a = g.clamp(anisotropy, 0.0, 1.0)
    s = g.sqrt(g.madd(a, -0.9, 1.0))
    r2 = g.mul(r, r)
    ax = g.minimum(g.div(r2, s), 1.0)
    return g.sqrt(g.sqrt(g.mul(ax, g.mul(r2, s))))


def _principled_baked(g, x, m, a_metal, b_metal):
    """The same values read from the Converted Maps (texture conversion evaluated the live
    mapping per texel): haze is on where a map holds a β above 0."""
    _section(g, "Converted maps: the mapping baked per texel")
    v = {k: g.input(baked_name(k), vector=vec) for k, (_, vec) in BAKED.items()}
    on = g.math("GREATER_THAN", g.maximum(g.maximum(v["beta_d"], v["beta_m"]), v["beta_c"]), 0.0)
    split = g.mul(g.sub(b_metal, a_metal), on, label="split (0 < m < 1, haze on)")
    tint = x("Specular Tint", True)
    v.update(mix_d=v["beta_d"], tint_n=tint, tint_w=tint, mirror=0.0, mirror_colour=(1.0, 1.0, 1.0))
    return v, split, {}


def _principled(g, x, cfg):
    _section(g, "Metallic: which parts this point has")
    metallic = x("Metallic")
    m = g.clamp(metallic, 0.0, 1.0, label="m")
    if cfg.has("dielectric") and cfg.has("metal"):
        a_metal = g.math("GREATER_THAN", m, K.ONE_MINUS_ULP32, label="A is metal (m = 1)")
        b_metal = g.math("GREATER_THAN", m, 0.0, label="B is metal (m > 0)")
    else:  # one part: A and B are it (the other's points render plain: _principled_mapping)
        a_metal = b_metal = g.value(1.0 if cfg.has("metal") else 0.0)
    if cfg.baked:
        v, split, shown = _principled_baked(g, x, m, a_metal, b_metal)
    else:
        v, split, shown = _principled_mapping(g, x, cfg, m, a_metal, b_metal)
    ior, base, tint = x("IOR"), x("Base Color", True), x("Specular Tint", True)

    def slot(role, part_metal, lobe_wide, coat):
        """``part_metal``: an Expr 1 (metal) / 0 (dielectric); ``coat``: "narrow", "wide" or
        an Expr 1 (wide) / 0 (narrow)."""
        w = {"Metallic": g.select(split, g.select(part_metal, 1.0, 0.0), metallic),
             "IOR": g.select(part_metal, ior, v["ior_d"]),
             "Base Color": g.select(part_metal, v["base_m"], v.get("base_d", base)),
             "Specular Tint": g.select(part_metal, tint, v["tint_w" if lobe_wide else "tint_n"])}
        if lobe_wide:
            w["Roughness"] = v["roughness_wide"]
            if "anisotropy_wide" in v:
                w.update({"Anisotropic": v["anisotropy_wide"],
                          "Anisotropic Rotation": v["rotation_wide"]})
            # a transmissive dielectric's halo: a mirror (Metallic 1, F0 = r / r̂, white F82,
            # no film)
            mirror = g.select(part_metal, 0.0, v["mirror"])
            w["Metallic"] = g.select(mirror, 1.0, w["Metallic"])
            w["Base Color"] = g.select(mirror, v["mirror_colour"], w["Base Color"])
            w["Specular Tint"] = g.select(mirror, (1.0, 1.0, 1.0), w["Specular Tint"])
            w["Thin Film Thickness"] = g.select(mirror, 0.0, x("Thin Film Thickness"))
        w["Coat IOR"] = v["coat_ior"]
        if coat == "wide":
            w["Coat Roughness"] = v["coat_roughness_wide"]
        elif coat != "narrow":
            w["Coat Roughness"] = g.select(coat, v["coat_roughness_wide"], x("Coat Roughness"))
        return Slot(role, w)

    _section(g, "What each BSDF gets (Eq. 1)")
    both, coat = cfg.has("dielectric") and cfg.has("metal"), cfg.has("coat")
    s1 = slot("A narrow", a_metal, False, "narrow")
    s2 = slot("A wide", a_metal, True, "narrow")
    beta_a = g.select(a_metal, v["beta_m"], v["mix_d"], label="β_A")
    mix_a = Mix("Mix A", beta_a, s1, s2)
    if not (both or coat):  # one part, no coat haze: its two lobes
        cycles = mix_a
    else:
        b_coat = g.sub(1.0, split) if coat else g.value(0.0)  # no split: B is A under the wide coat
        s3 = slot("B narrow", b_metal, False, b_coat)
        s4 = slot("B wide", b_metal, True, b_coat)
        beta_b = g.select(b_metal, v["beta_m"], v["mix_d"], label="β_B")
        f_ab = g.select(split, m, v["beta_c"], label="f_AB (m, or β coat)")
        cycles = Mix("Mix parts or coat", f_ab, mix_a, Mix("Mix B", beta_b, s3, s4))
        if both and coat:
            s5 = Slot("user under the wide coat", {"Coat IOR": v["coat_ior"],
                                                   "Coat Roughness": v["coat_roughness_wide"]})
            f5 = g.mul(split, v["beta_c"], label="f_5 (β coat of a split)")
            cycles = Mix("Mix coat of a split", f5, cycles, s5)

    # -- EEVEE: one BSDF, each layer's lobes folded (1/α_f² = (1-β)/α_n² + β/α_w²) ------------
    _section(g, "EEVEE: each layer's lobes folded into one")
    rough = g.clamp(x("Roughness"), K.min_roughness("GGX"), 1.0)
    coat_rough = g.clamp(x("Coat Roughness"), K.min_roughness("GGX"), 1.0)
    r_fd = node_math.folded_roughness(g, v["beta_d"], rough, v["roughness_wide"])
    r_fm = node_math.folded_roughness(g, v["beta_m"], rough, v["roughness_wide"])
    r_fc = node_math.folded_roughness(g, v["beta_c"], coat_rough, v["coat_roughness_wide"])
    eevee = Slot("EEVEE folded", {"Roughness": g.mix(m, r_fd, r_fm),
                                  "Base Color": g.vmix(m, base, v["base_m"]), "IOR": v["ior_d"],
                                  "Specular Tint": g.vmix(m, v["tint_w"], tint),
                                  "Coat IOR": v["coat_ior"], "Coat Roughness": r_fc})
    shown.update({"beta dielectric": v["beta_d"], "beta metal": v["beta_m"],
                  "beta coat": v["beta_c"], "IOR dielectric": v["ior_d"],
                  "reflectivity metal": v["base_m"], "roughness wide": v["roughness_wide"],
                  "coat IOR": v["coat_ior"], "coat roughness wide": v["coat_roughness_wide"],
                  "split": split})
    baked = {k: v.get(k + "_baked", v.get(k, g.value(0.0))) for k in BAKED}
    return cycles, eevee, shown, baked



# --------------------------------------------------------------------------------------------
# Metallic and Glossy BSDFs
# --------------------------------------------------------------------------------------------


def _metallic(g, x, cfg):
    _section(g, "The core: r_c from the node's Fresnel")
    rough, aniso, rot = x("Roughness"), x("Anisotropy"), x("Rotation")
    bh = g.mul(x.haze("haziness"), _isotropic_gate(g, x, cfg, aniso), label="β_h")
    on = _on(g, bh)
    if cfg.fresnel == "PHYSICAL_CONDUCTOR":
        rc, edge = node_fresnel.gulbrandsen_inverse(g, x("IOR", True), x("Extinction", True))
        m = _part(g, x, cfg, kind="CONDUCTOR", rc=_cap(g, x, rc), edge=edge, rough=rough,
                  aniso=aniso, rot=rot, haziness=bh, title="Haze")
        own = {"IOR": g.select(on, m["ior"], x("IOR", True), label="IOR (η, raised)"),
               "Extinction": g.select(on, m["extinction"], x("Extinction", True),
                                      label="Extinction (κ, raised)")}
        shown = {"ior": own["IOR"], "extinction": own["Extinction"]}
    else:
        base = x("Base Color", True)
        m = _part(g, x, cfg, kind="DIELECTRIC", rc=_cap(g, x, base), edge=0.0, rough=rough,
                  aniso=aniso, rot=rot, haziness=bh, lobe="F82_TINT", tint=x("Edge Tint", True),
                  title="Haze")
        own = {"Base Color": g.select(on, m["reflectivity"], base, label="Base Color (raised)")}
        shown = {}
    _section(g, "What each BSDF gets")
    beta = g.mul(m["beta"], on, label="β")
    wide = dict(own, Roughness=m["roughness_wide"])
    if cfg.has("aniso"):
        wide.update(Anisotropy=m["anisotropy_wide"], Rotation=m["rotation_wide"])
    cycles = Mix("Mix lobes", beta, Slot("narrow", dict(own)), Slot("wide", wide))
    eevee = Slot("EEVEE folded", dict(own, Roughness=node_math.folded_roughness(
        g, beta, m["roughness"], m["roughness_wide"])))
    shown.update({"beta": beta, "reflectivity": m["reflectivity"],
                  "roughness wide": m["roughness_wide"]})
    return cycles, eevee, shown


def _glossy(g, x, cfg):
    _section(g, "The core: r_c, the node's colour")
    aniso, rot = node_math.glossy_to_metallic(g, x("Anisotropy"), x("Rotation"))
    bh = g.mul(x.haze("haziness"), _isotropic_gate(g, x, cfg, g.math("ABSOLUTE", x("Anisotropy"))),
               label="β_h")
    on = _on(g, bh)
    colour = x("Color", True)
    m = _part(g, x, cfg, kind="LEGACY", rc=_cap(g, x, colour), edge=0.0, rough=x("Roughness"),
              aniso=aniso, rot=rot, haziness=bh, title="Haze")
    _section(g, "What each BSDF gets")
    narrow = g.select(on, m["colour_narrow"], colour, label="Color k_n")
    wide = {"Color": g.select(on, m["colour_wide"], (0.0, 0.0, 0.0), label="Color k_w"),
            "Roughness": m["roughness_wide"]}
    if cfg.has("aniso"):
        wide.update(Anisotropy=m["anisotropy_wide"], Rotation=m["rotation_wide"])
    # no Fresnel: the lobes' colours carry β (Add Shader, as Eq. 1's legacy form)
    cycles = Mix("Add lobes", None, Slot("narrow", {"Color": narrow}), Slot("wide", wide), add=True)
    beta = g.mul(m["beta"], on, label="β")
    folded = node_math.folded_roughness(g, beta, m["roughness"], m["roughness_wide"])
    eevee = Slot("EEVEE folded", {"Color": g.select(on, m["reflectivity"], colour),
                                  "Roughness": folded})
    return cycles, eevee, {"beta": beta, "reflectivity": m["reflectivity"],
                           "roughness wide": m["roughness_wide"]}


_BUILDERS = {"PRINCIPLED": _principled, "METALLIC": _metallic, "GLOSSY": _glossy}


def build(config):
    """The :class:`Layer` of ``config``."""
    if config.bsdf not in _BUILDERS:
        raise ValueError(f"a haze layer wraps a {', '.join(BSDF_TYPES)} BSDF, not {config.bsdf!r}")
    if (config.baked or config.body) and config.bsdf != "PRINCIPLED":
        raise ValueError("converted maps and Keep Body Colour are for a Principled core only")
    if config.baked and config.body:
        raise ValueError("Keep Body Colour is not available with converted maps")
    if config.baked and config.parts != frozenset(PARTS["PRINCIPLED"]):
        raise ValueError("a converted layer's group holds every part")
    g = Graph()
    g.sections = []
    cycles, eevee, shown, *baked = _BUILDERS[config.bsdf](g, _Inputs(g), config)
    return Layer(config, g, cycles, eevee, shown, list(g.sections), baked[0] if baked else {})
