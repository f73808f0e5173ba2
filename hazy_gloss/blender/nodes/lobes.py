# SPDX-License-Identifier: GPL-3.0-or-later
"""The two lobes of Eq. 1 and their mix, for each lobe kind.

Operands are sockets or constants (see builder.TreeBuilder.feed), so the lean tree (constants
from Python) and the in-shader group (sockets from the mapping graph) share this code.

- CONDUCTOR:  two Metallic BSDFs, PHYSICAL_CONDUCTOR, same η and κ, mixed by β: Eq. 1 exactly.
- DIELECTRIC: two Principled BSDFs sharing IOR, tint, base colour and transmission, differing only
              in roughness, mixed by β.
- LEGACY:     two Glossy BSDFs (no Fresnel) with colours k_n = (1-β) r and k_w = β r, added.
"""

from ...core.lobes import check_kind

__all__ = ("LOBE_NODES", "ANISO_INPUTS", "tangent", "build_lobes")

_NODE = {"CONDUCTOR": "ShaderNodeBsdfMetallic", "DIELECTRIC": "ShaderNodeBsdfPrincipled",
         "LEGACY": "ShaderNodeBsdfGlossy"}
#: bl_idnames a lobe of each kind reports (the Glossy BSDF reports the old Anisotropic id).
LOBE_NODES = {"CONDUCTOR": ("ShaderNodeBsdfMetallic",), "DIELECTRIC": ("ShaderNodeBsdfPrincipled",),
              "LEGACY": ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic")}
#: (anisotropy, rotation) input names per kind.
ANISO_INPUTS = {"CONDUCTOR": ("Anisotropy", "Rotation"),
                "DIELECTRIC": ("Anisotropic", "Anisotropic Rotation"),
                "LEGACY": ("Anisotropy", "Rotation")}


def tangent(tb, kind, depth=0):
    """A Tangent node: ``kind`` "UV_MAP", or "RADIAL_X/Y/Z" (around that object axis)."""
    t = tb.node("ShaderNodeTangent", name="Tangent", depth=depth)
    if kind == "UV_MAP":
        t.direction_type = "UV_MAP"
    else:
        t.direction_type = "RADIAL"
        t.axis = kind[-1]
    return t.outputs[0]


def _lobe(tb, kind, distribution, which, *, roughness, anisotropy, rotation, fresnel, shared,
          colour=None, depth=0):
    n = tb.node(_NODE[kind], name=f"{which} lobe", label=f"Hazy Gloss {which.lower()} lobe",
                depth=depth)
    n.distribution = distribution  # node default is MULTI_GGX: always set explicitly
    if kind == "CONDUCTOR" and "schlick_f0" in fresnel:
        n.fresnel_type = "F82"  # F = F0 + (1 - F0)(1 - cos θd)^5 - b ..., b = 0 at Edge Tint 1
        tb.feed(n.inputs["Base Color"], fresnel["schlick_f0"])
        tb.feed(n.inputs["Edge Tint"], (1.0, 1.0, 1.0))
    elif kind == "CONDUCTOR":
        n.fresnel_type = "PHYSICAL_CONDUCTOR"  # node default is F82
        tb.feed(n.inputs["IOR"], fresnel["ior"])
        tb.feed(n.inputs["Extinction"], fresnel["extinction"])
    elif kind == "DIELECTRIC":
        tb.feed(n.inputs["Base Color"], fresnel.get("base_color", 0.0))
        tb.feed(n.inputs["Metallic"], 0.0)
        tb.feed(n.inputs["IOR"], fresnel["ior"])
        tb.feed(n.inputs["Specular IOR Level"], 0.5)  # 0.5 = Fresnel exactly from IOR
        tb.feed(n.inputs["Specular Tint"], fresnel.get("specular_tint", 1.0))
        tb.feed(n.inputs["Transmission Weight"], fresnel.get("transmission", 0.0))
    else:
        tb.feed(n.inputs["Color"], colour)
    tb.feed(n.inputs["Roughness"], roughness)
    if anisotropy is not None:
        a_name, rot_name = ANISO_INPUTS[kind]
        tb.feed(n.inputs[a_name], anisotropy)
        tb.feed(n.inputs[rot_name], rotation)
        if shared.get("tangent") is not None:
            tb.feed(n.inputs["Tangent"], shared["tangent"])
    if shared.get("normal") is not None:
        tb.feed(n.inputs["Normal"], shared["normal"])
    return n


def build_lobes(tb, kind, distribution, *, beta, narrow, wide, fresnel, shared, depth,
                always_wide=False):
    """Wire Eq. 1 and return the BSDF output socket.

    narrow / wide: dict(roughness=, anisotropy=None|value, rotation=) in the node's convention.
    wide=None (or a constant beta of 0, unless ``always_wide``) builds the core lobe alone: no
    halo where haze is 0.
    fresnel: CONDUCTOR {ior, extinction} or {schlick_f0} (F82 at Edge Tint 1: Schlick, the
    recomposite's lobes); DIELECTRIC {ior, specular_tint, base_color, transmission}; LEGACY
    {colour_narrow, colour_wide}.
    """
    check_kind(kind, distribution)
    no_halo = wide is None or (not always_wide and not hasattr(beta, "node") and float(beta) <= 0.0)
    n_lobe = _lobe(tb, kind, distribution, "Narrow", fresnel=fresnel, shared=shared,
                   colour=fresnel.get("colour_narrow"), depth=depth, **narrow)
    if no_halo:
        if kind == "LEGACY" and fresnel.get("colour_narrow") is None:
            raise ValueError("legacy lobes need colour_narrow")
        return n_lobe.outputs[0]
    w_lobe = _lobe(tb, kind, distribution, "Wide", fresnel=fresnel, shared=shared,
                   colour=fresnel.get("colour_wide"), depth=depth, **wide)
    if kind == "LEGACY":  # f_r = k_n f_n + k_w f_w, weights already in the colours
        mix = tb.node("ShaderNodeAddShader", name="Lobe sum", label="k_n f_n + k_w f_w",
                      depth=depth + 1)
        tb.link(n_lobe.outputs[0], mix.inputs[0])
        tb.link(w_lobe.outputs[0], mix.inputs[1])
    else:  # (1-β) f_n F + β f_w F with one shared Fresnel (Eq. 1)
        mix = tb.node("ShaderNodeMixShader", name="Lobe mix", label="Eq. 1: mix by β",
                      depth=depth + 1)
        tb.feed(mix.inputs[0], beta)
        tb.link(n_lobe.outputs[0], mix.inputs[1])
        tb.link(w_lobe.outputs[0], mix.inputs[2])
    return mix.outputs[0]
