# SPDX-License-Identifier: GPL-3.0-or-later
"""Haze layers (Make Hazy, blender/model/layer.py) as MaterialX 1.39 networks, bpy-free.

A layered material is the artist's own shading network with a haze layer in it: the user's
BSDF (the core) renders the narrow lobe, hidden copies of it the wide one, Mix Shaders mix
them by β (and by the metallic map, and the coat's β).  It is written as what the Blender
tree holds, node by node, from the Material Output the renderers use (:class:`Writer`):

- **Principled BSDF** -> ``open_pbr_surface`` (OpenPBR 1.1.1, the version MaterialX 1.39
  ships), the mapping Blender's own MaterialX exporter uses (base_metalness = Metallic,
  specular_weight = 2 · Specular IOR Level, specular_color = Specular Tint, fuzz = sheen, ...)
  with three corrections where OpenPBR's model differs from Cycles' Principled (measured in
  docs/interchange.md §5): α_x, α_y kept exactly (OpenPBR's anisotropy keeps α_x, Cycles
  the geometric mean; Blender's exporter scales the anisotropy by 0.7), and under a coat the
  roughening and the coat-relative IOR OpenPBR applies to the base specular undone
  (coat_darkening 0: Cycles does not darken the base beyond the coat's albedo);
- **Metallic BSDF** -> ``conductor_bsdf`` (Physical Conductor) or ``generalized_schlick_bsdf``
  (F82, color82 = Edge Tint, Cycles' F82-tint), **Glossy BSDF** -> ``generalized_schlick_bsdf``
  with F ≡ Color; roughness as the α Cycles renders; wrapped in ``surface``;
- **Mix Shader** -> ``mix`` (fg = the second shader, bg = the first, mix = the clamped factor:
  the layer's β, metallic map, coat β), of BSDFs when both sides are BSDFs, else of
  surfaceshaders; **Add Shader** -> ``add`` of BSDFs (the layer's Glossy lobes);
- values: the socket's value when unlinked; **Image Texture** -> ``image`` (file, colour space
  from the image's, filter, address mode; the layer's baked maps are image textures too);
  **Math / Vector Math / Mix / Separate / Combine XYZ / Color Ramp / Value / RGB / Layer Weight
  / Normal Map / Tangent** -> standard-library nodes with Cycles' semantics (safe division,
  safe power and square root, the Color Ramp as the piecewise-linear 256-entry table Cycles
  looks up, exact) — the layer's live node math is exported per pixel.  Anything else is
  exported at the socket's own value, with a note.

The module only reads a snapshot (:class:`Tree`, layered_tree.py), made from bpy by
blender/actions/interchange.py.  It holds the shaders and the documents' layer record; the value nodes
are written by layered_values.py's ValueWriter (Writer's base), the OpenPBR corrections as
constants are in openpbr_corrections.py.
"""
from __future__ import annotations

import json

import numpy as np

from .. import constants as K
from ..core import gulbrandsen_inverse
from .document import Input, NodeGraph, valid_name
from .layered_tree import (GLOSSY, METALLIC, MX_TYPE, PRINCIPLED, COLORSPACES, LUMA, BNode,
                           Socket, Tree)
from .layered_values import V, ValueWriter, mx_constant, format_value, tangent_kind
from .openpbr_corrections import (coat_eta, coat_ior_inverse, coat_roughening,
                                  coat_roughness_inverse, glossy_alpha, openpbr_alpha,
                                  openpbr_inverse, principled_alpha)

#: Re-exported from layered_tree, layered_values and openpbr_corrections (split off this module)
#: so that ``interchange.layered`` still names them.
__all__ = ("Socket", "BNode", "Tree", "Writer", "graph_of", "layer_record", "user_value",
           "preview_values", "LAYER_RECORD_VERSION", "V", "ValueWriter", "COLORSPACES", "LUMA",
           "principled_alpha", "glossy_alpha", "openpbr_alpha", "openpbr_inverse",
           "coat_roughening", "coat_roughness_inverse", "coat_eta", "coat_ior_inverse")


class Writer(ValueWriter):
    """Writes one Blender tree into a NodeGraph: the shaders (Mix / Add Shader, the BSDFs as
    open_pbr_surface / conductor / generalized_schlick) on top of :class:`ValueWriter`'s value
    nodes.  ``notes``: a list the writer appends to (what is approximate or not exported, in
    plain words, each once)."""

    # -- shaders -------------------------------------------------------------------------------
    def inverse_of_constants(self, inverse, values, note):
        """``inverse`` (a value and its residual) of constant ``values`` as a float constant,
        with the note ``note(residual)`` when it is not exact; None when a value is not a
        constant (the caller builds nodes)."""
        if not all(v.is_const for v in values):
            return None
        value, residual = inverse(*(v.const for v in values))
        if abs(residual) > 1e-6:
            self.note(note(residual))
        return mx_constant("float", value)

    def shader(self, sock):
        """("bsdf" | "edf" | "surface", Node) of a shader socket, or None (no closure)."""
        node, out = self._follow(sock)
        if node is None:
            return None
        if node.name in self._shaders:
            return self._shaders[node.name]
        self.stack.append(node.name)
        if len(self.stack) > 200:
            raise ValueError("node cycle or a network too deep to export")
        try:
            got = self._shader(node)
        finally:
            self.stack.pop()
        self._shaders[node.name] = got
        return got

    def shader_of_node(self, node):
        """:meth:`shader` of a node no socket leads to (the user's BSDF a layer node holds)."""
        if node.name not in self._shaders:
            self._shaders[node.name] = self._shader(node)
        return self._shaders[node.name]

    def _shader(self, node):
        t = node.type
        if node.mute:
            self.note(f"muted shader “{node.name}”: not exported")
            return None
        if t == PRINCIPLED:
            n = self.principled(node)
            self.surfaces[node.name] = n
            return ("surface", n)
        if t == METALLIC:
            n = self.metallic(node)
            self.surfaces[node.name] = n
            return ("bsdf", n)
        if t in GLOSSY:
            n = self.glossy(node)
            self.surfaces[node.name] = n
            return ("bsdf", n)
        if t == "ShaderNodeBsdfDiffuse":
            rough = self._in(node, "Roughness")
            if not rough.is_const or float(rough.const) != 0.0:
                self.note(f"Diffuse BSDF “{node.name}”: MaterialX's Oren-Nayar for Cycles' roughness")
            return ("bsdf", self.node("ND_oren_nayar_diffuse_bsdf", node.name, weight=1.0,
                                      color=self._in(node, "Color", "color3"), roughness=rough,
                                      **self.normal_kw(node, "Normal")))
        if t == "ShaderNodeEmission":
            col = self.mul(self._in(node, "Color", "color3"), self._in(node, "Strength"), node.name + "_color")
            return ("edf", self.node("ND_uniform_edf", node.name, color=col))
        if t == "ShaderNodeMixShader":
            return self.mix_shader(node)
        if t == "ShaderNodeAddShader":
            return self.add_shader(node)
        self.note(f"shader “{node.name}” ({t.replace('ShaderNode', '')}) is not exported: black")
        return None

    def normal_kw(self, node, key, name="normal"):
        s = node.input(key)
        if s is None or s.link is None:
            return {}
        v = self.value(s, "vector3")
        return {} if v.is_const else {name: v}

    def lift(self, sh, base):
        """A surfaceshader of a shader result."""
        if sh is None:
            if self._black is None:
                self._black = self.node("ND_surface", "black")
                self._black.set("opacity", "float", 1.0)
            return self._black
        kind, n = sh
        if kind == "surface":
            return n
        key = ("surface", n.name)
        if key not in self._values:
            s = self.node("ND_surface", base + "_surface")
            s.set("bsdf" if kind == "bsdf" else "edf", "BSDF" if kind == "bsdf" else "EDF", node=n)
            s.set("opacity", "float", 1.0)
            self._values[key] = s
        return self._values[key]

    def mix_shader(self, node):
        a = self.shader(node.inputs[1])
        b = self.shader(node.inputs[2])
        fac = self.clamp(self.value(node.inputs[0]), base=node.name + "_factor")
        if a is None and b is None:
            return None
        if fac.is_const and float(fac.const) in (0.0, 1.0):
            pass  # still written: the tree's structure (a mix by 0 or 1)
        if a is not None and b is not None and a[0] == b[0] and a[0] in ("bsdf", "edf"):
            kind = a[0]
            port = "BSDF" if kind == "bsdf" else "EDF"
            n = self.node("ND_mix_bsdf" if kind == "bsdf" else "ND_mix_edf", node.name, mix=fac)
            n.set("fg", port, node=b[1])
            n.set("bg", port, node=a[1])
            self.mixes[node.name] = n
            return (kind, n)
        n = self.node("ND_mix_surfaceshader", node.name, mix=fac)
        n.set("fg", "surfaceshader", node=self.lift(b, node.name + "_b"))
        n.set("bg", "surfaceshader", node=self.lift(a, node.name + "_a"))
        self.mixes[node.name] = n
        return ("surface", n)

    def add_shader(self, node):
        a = self.shader(node.inputs[0])
        b = self.shader(node.inputs[1])
        if a is None or b is None:
            return a or b
        if a[0] == b[0] and a[0] in ("bsdf", "edf"):
            nd = "ND_add_bsdf" if a[0] == "bsdf" else "ND_add_edf"
            n = self.node(nd, node.name)
            t = "BSDF" if a[0] == "bsdf" else "EDF"
            n.set("in1", t, node=a[1])
            n.set("in2", t, node=b[1])
            self.mixes[node.name] = n
            return (a[0], n)
        if {a[0], b[0]} == {"bsdf", "edf"}:
            bsdf, edf = (a, b) if a[0] == "bsdf" else (b, a)
            s = self.node("ND_surface", node.name)
            s.set("bsdf", "BSDF", node=bsdf[1])
            s.set("edf", "EDF", node=edf[1])
            s.set("opacity", "float", 1.0)
            self.mixes[node.name] = s
            return ("surface", s)
        self.note(f"Add Shader “{node.name}” adds an OpenPBR surface, which MaterialX 1.39 cannot "
                  f"add: its first shader is exported")
        return a

    # -- BSDFs ---------------------------------------------------------------------------------
    def _alpha(self, node, fn, r_name, a_name):
        """(α as a vector2 V, anisotropic?) with Cycles' convention ``fn`` (constants), or the
        node form of the Metallic/Principled convention."""
        r, a = self._in(node, r_name), self._in(node, a_name)
        if r.is_const and a.is_const:
            ax, ay = fn(r.const, a.const)
            return V("vector2", (ax, ay)), ax != ay
        if fn is glossy_alpha:
            self.note(f"Glossy BSDF “{node.name}”: textured roughness / anisotropy written with the "
                      f"Metallic convention α = roughness_anisotropy(R, 0.9 a)")
        r = self.clamp(r, base=node.name + "_rough")
        a = self.mul(self.clamp(a, base=node.name + "_aniso"), mx_constant("float", 0.9), node.name + "_aniso09")
        return V("vector2", node=self.node("ND_roughness_anisotropy", node.name + "_alpha",
                                           roughness=r, anisotropy=a)), True

    def _dist(self, node):
        d = node.props.get("distribution", "GGX")
        if d in ("BECKMANN", "ASHIKHMIN_SHIRLEY"):
            self.note(f"“{node.name}” uses {d.replace('_', '-').title()}: written as ggx (MaterialX "
                      f"1.39 has no other distribution)")
        return "ggx"

    def _tangent(self, node, rot_name, aniso):
        if not aniso:
            return None
        src, _ = self._follow(node.input("Tangent"))
        kind = tangent_kind(src) if src is not None and src.type == "ShaderNodeTangent" else "RADIAL_Z"
        if src is not None and src.type != "ShaderNodeTangent":
            self.note(f"the Tangent of “{node.name}” comes from “{src.name}”: written as a UV tangent")
            kind = "UV_MAP"
        rot = self._in(node, rot_name)
        return self.tangent_node(kind, float(rot.const) if rot.is_const else rot.node,
                                 "_" + valid_name(node.name))

    def metallic(self, node):
        alpha, aniso = self._alpha(node, principled_alpha, "Roughness", "Anisotropy")
        tangent = self._tangent(node, "Rotation", aniso)
        kw = dict(weight=1.0, roughness=alpha, distribution=self._dist(node), **self.normal_kw(node, "Normal"))
        if tangent is not None:
            kw["tangent"] = tangent
        if node.props.get("fresnel_type", "F82") == "PHYSICAL_CONDUCTOR":
            return self.node("ND_conductor_bsdf", node.name, ior=self._in(node, "IOR", "color3"),
                             extinction=self._in(node, "Extinction", "color3"), **kw)
        base = self.clamp(self._in(node, "Base Color", "color3"), base=node.name + "_f0")
        tint = self.clamp(self._in(node, "Edge Tint", "color3"), base=node.name + "_f82")
        return self.node("ND_generalized_schlick_bsdf", node.name, color0=base, color82=tint,
                         color90=(1.0, 1.0, 1.0), exponent=5.0, scatter_mode="R", **kw)

    def glossy(self, node):
        alpha, aniso = self._alpha(node, glossy_alpha, "Roughness", "Anisotropy")
        tangent = self._tangent(node, "Rotation", aniso)
        col = self.maximum(self._in(node, "Color", "color3"), mx_constant("color3", 0.0), node.name + "_colour")
        kw = dict(weight=1.0, roughness=alpha, distribution=self._dist(node), **self.normal_kw(node, "Normal"))
        if tangent is not None:
            kw["tangent"] = tangent
        return self.node("ND_generalized_schlick_bsdf", node.name, color0=col, color82=(1.0, 1.0, 1.0),
                         color90=col, exponent=5.0, scatter_mode="R", **kw)

    def principled(self, node):
        """open_pbr_surface with the Principled BSDF's values (module docstring)."""
        n = node.name
        val = lambda key, to="float": self._in(node, key, to)  # noqa: E731
        sat = lambda v, nm: self.clamp(v, base=f"{n}_{nm}")  # noqa: E731
        metallic = sat(val("Metallic"), "metallic")
        rough, aniso = sat(val("Roughness"), "rough"), sat(val("Anisotropic"), "aniso")
        coat_w = self.maximum(val("Coat Weight"), mx_constant("float", 0.0), n + "_coat_w")
        coat_r = sat(val("Coat Roughness"), "coat_rough")
        coat_ior = self.maximum(val("Coat IOR"), mx_constant("float", 1.0), n + "_coat_ior")
        ior = self.maximum(val("IOR"), mx_constant("float", 1e-5), n + "_ior")
        level = self.maximum(val("Specular IOR Level"), mx_constant("float", 0.0), n + "_level")
        coated = not (coat_w.is_const and float(coat_w.const) == 0.0)
        # α: OpenPBR keeps α_x = r² √(2/(1+(1-a)²)), α_y = (1-a) α_x; Cycles α_x = R²/s, α_y = R² s
        if rough.is_const and aniso.is_const:
            ax, ay = principled_alpha(rough.const, aniso.const)
            r_e, a_o = openpbr_inverse(ax, ay)
            r_e, a_o = mx_constant("float", r_e), mx_constant("float", a_o)
        elif aniso.is_const and float(aniso.const) == 0.0:
            r_e, a_o = rough, mx_constant("float", 0.0)
        else:
            r_e, a_o = self._openpbr_inverse_nodes(rough, aniso, n)
        # under a coat: undo OpenPBR's roughening and its coat-relative base IOR
        if coated:
            r_e = self.inverse_of_constants(
                coat_roughness_inverse, (r_e, coat_r, coat_w),
                lambda res: f"“{n}”: the coat roughens OpenPBR's base beyond its roughness "
                            f"{format_value(r_e.const)} (coat roughness {format_value(coat_r.const)}): written at 0") \
                or self._uncoated_roughness_nodes(r_e, coat_r, coat_w, n)
            ior = self.inverse_of_constants(
                coat_ior_inverse, (ior, coat_ior, coat_w),
                lambda res: f"“{n}”: no specular_ior gives OpenPBR's coat-relative IOR "
                            f"{format_value(ior.const)}: off by {res:.3g}") \
                or self._uncoated_ior_nodes(ior, coat_ior, coat_w, n)
        # specular_weight: Principled's Specular IOR Level acts on the dielectric only
        if metallic.is_const and float(metallic.const) >= 1.0:
            spec_w = mx_constant("float", 1.0)
        else:
            spec_w = self.mul(level, mx_constant("float", 2.0), n + "_spec_w")
            if not metallic.is_const or float(metallic.const) > 0.0:
                if not (level.is_const and float(level.const) == 0.5):
                    self.note(f"“{n}”: OpenPBR's specular_weight (2 × Specular IOR Level) also scales "
                              f"the metallic part; Principled's level does not")
        tint = val("Specular Tint", "color3")
        if metallic.is_const and float(metallic.const) >= 1.0:
            tint = self.clamp(tint, base=n + "_tint")  # Cycles' F82 tint is min(tint, 1)
        s = self.node("ND_open_pbr_surface_surfaceshader", n)
        put = lambda k, v: self.put(s, k, v)  # noqa: E731
        put("base_weight", mx_constant("float", 1.0))
        put("base_color", val("Base Color", "color3"))
        if node.input("Diffuse Roughness") is not None:
            put("base_diffuse_roughness", sat(val("Diffuse Roughness"), "diffuse_rough"))
        put("base_metalness", metallic)
        put("specular_weight", spec_w)
        put("specular_color", tint)
        put("specular_roughness", r_e)
        put("specular_ior", ior)
        put("specular_roughness_anisotropy", a_o)
        trans = sat(val("Transmission Weight"), "transmission")
        if not (trans.is_const and float(trans.const) == 0.0):
            self.note(f"“{n}”: transmission is approximate in MaterialX: OpenPBR tints the refracted "
                      f"light once by transmission_color (the Base Color), Cycles by √Base Color at "
                      f"each interface, and its dielectric Fresnel is the exact one where Cycles' "
                      f"Principled keeps F0 (docs/interchange.md §5)")
        put("transmission_weight", trans)
        put("transmission_color", val("Base Color", "color3"))
        put("subsurface_weight", sat(val("Subsurface Weight"), "subsurface"))
        put("subsurface_color", val("Base Color", "color3"))
        put("subsurface_radius", val("Subsurface Scale"))
        put("subsurface_radius_scale", val("Subsurface Radius", "color3"))
        if node.input("Subsurface Anisotropy") is not None:
            put("subsurface_scatter_anisotropy", val("Subsurface Anisotropy"))
        put("fuzz_weight", self.maximum(val("Sheen Weight"), mx_constant("float", 0.0), n + "_sheen"))
        put("fuzz_color", val("Sheen Tint", "color3"))
        put("fuzz_roughness", sat(val("Sheen Roughness"), "sheen_rough"))
        put("coat_weight", coat_w)
        put("coat_color", val("Coat Tint", "color3"))
        put("coat_roughness", coat_r)
        put("coat_ior", coat_ior)
        put("coat_darkening", mx_constant("float", 0.0))
        put("emission_luminance", val("Emission Strength"))
        put("emission_color", val("Emission Color", "color3"))
        if node.input("Thin Film Thickness") is not None:
            thick = val("Thin Film Thickness")
            if not (thick.is_const and float(thick.const) <= 0.1):
                self.note(f"“{n}”: the thin film is OpenPBR's model in MaterialX (its film on the "
                          f"specular_ior the layer raised); Cycles' film reflectance differs "
                          f"(docs/thin-film.md)")
            if thick.is_const:
                put("thin_film_weight", mx_constant("float", 1.0 if float(thick.const) > 0.1 else 0.0))
            else:
                put("thin_film_weight", self.select("ifgreater", thick, mx_constant("float", 0.1), mx_constant("float", 1.0),
                                                    mx_constant("float", 0.0), n + "_film_on"))
            put("thin_film_thickness", self.mul(thick, mx_constant("float", 0.001), n + "_film_um"))
            put("thin_film_ior", val("Thin Film IOR"))
        put("geometry_opacity", sat(val("Alpha"), "alpha"))
        for key, inp in (("Normal", "geometry_normal"), ("Coat Normal", "geometry_coat_normal")):
            kw = self.normal_kw(node, key, inp)
            if kw:
                put(inp, kw[inp])
        aniso_on = not (a_o.is_const and float(a_o.const) == 0.0)
        tangent = self._tangent(node, "Anisotropic Rotation", aniso_on)
        if tangent is not None:
            s.set("geometry_tangent", "vector3", node=tangent)
        if coated:
            tint_c = val("Coat Tint", "color3")
            if not (tint_c.is_const and np.all(tint_c.array() == 1.0)):
                self.note(f"“{n}”: OpenPBR's coat_color tints by a constant factor, Cycles' Coat Tint "
                          f"by tint^(1/cos θ_t) (the same at normal incidence)")
        return s

    def _uncoated_roughness_nodes(self, r_e, coat_r, coat_w, n):
        """OpenPBR's coat roughening undone in nodes, exact at coat weight 0 and 1:
        mix(r, (max(r⁴ - 2 c⁴, 0))^¼, w)."""
        r4 = self.mul(self.mul(r_e, r_e, n + "_r2"), self.mul(r_e, r_e, n + "_r2b"), n + "_r4")
        c2 = self.mul(coat_r, coat_r, n + "_c2")
        c4 = self.mul(self.mul(c2, c2, n + "_c4"), mx_constant("float", 2.0), n + "_2c4")
        inner = self.maximum(self.sub(r4, c4, n + "_r4c4"), mx_constant("float", 0.0), n + "_pos")
        un = self.sqrt(self.sqrt(inner, n + "_q2"), n + "_q4")
        if not coat_w.is_const:
            self.note(f"“{n}”: textured Coat Weight: OpenPBR's coat roughening and base IOR "
                      f"are undone exactly at weights 0 and 1 only")
        return self.mix(self.clamp(coat_w, base=n + "_coat_w01"), r_e, un, n + "_uncoated")

    def _uncoated_ior_nodes(self, ior, coat_ior, coat_w, n):
        """OpenPBR's coat-relative base IOR undone in nodes, the branch η_o ≥ η_c:
        η / ((1-w) + w/η_c)."""
        w = self.clamp(coat_w, base=n + "_coat_wi")
        den = self.add(self.sub(mx_constant("float", 1.0), w, n + "_1mw"), self.div(w, coat_ior, n + "_w_c"),
                       n + "_den")
        return self.div(ior, den, n + "_ior_coated")

    def _openpbr_inverse_nodes(self, rough, aniso, n):
        """Node form of openpbr_inverse(principled_alpha(R, A)) (α clamps at 1 not modelled)."""
        s2 = self.sub(mx_constant("float", 1.0), self.mul(aniso, mx_constant("float", 0.9), n + "_a09"), n + "_s2")
        a_o = self.sub(mx_constant("float", 1.0), s2, n + "_aniso_o")
        # r_e = R ((1 + s⁴) / (2 s²))^¼
        s4 = self.mul(s2, s2, n + "_s4")
        q = self.div(self.add(s4, mx_constant("float", 1.0), n + "_1ps4"), self.mul(s2, mx_constant("float", 2.0), n + "_2s2"),
                     n + "_q")
        r_e = self.mul(rough, self.sqrt(self.sqrt(q, n + "_q2"), n + "_q4"), n + "_rough_o")
        return r_e, a_o



# --------------------------------------------------------------------------------------------
# One material
# --------------------------------------------------------------------------------------------


def graph_of(tree, name, notes, *, directory=None):
    """(NodeGraph NG_<name> with a surfaceshader output "out", Writer) for a layered tree."""
    g = NodeGraph(f"NG_{name}")
    w = Writer(tree, g, notes, directory=directory)
    out = tree.nodes.get(tree.output) if tree.output else None
    if out is None:
        raise ValueError(f"{tree.name}: no Material Output the renderers use")
    surf = out.input("Surface")
    sh = w.shader(surf)
    top = w.lift(sh, "surface")
    for key in ("Volume", "Displacement"):
        s = out.input(key)
        if s is not None and s.link is not None:
            w.note(f"the Material Output's {key} is not exported")
    g.outputs["out"] = Input("out", "surfaceshader", nodename=top.name)
    lay = tree.layer or {}
    g.attrs[f"{K.MATERIALX_ATTR}_kind"] = "LAYER"
    g.attrs[f"{K.MATERIALX_ATTR}_model"] = (
        "haze layer on the user's BSDF: the core (narrow lobe, F(0) raised to r) and its wide "
        "copies as open_pbr_surface / pbr BSDFs, mixed by beta as the Blender tree mixes them")
    if lay.get("live_math"):
        w.note("the layer's node math (textured inputs) is exported per pixel as standard-library "
               "math with Cycles' semantics")
    return g, w


#: Version of the hazygloss_layer record: 2 adds what the importer needs to rebuild the layer
#: (the core's node, its settings and the user's own values of the inputs the layer owns).
LAYER_RECORD_VERSION = 2


def layer_record(tree, writer=None):
    """The layer's state as JSON for the document (hazygloss_layer): the haze parameters, the
    core (its Blender name, type and settings, the MaterialX node written for it) and, per
    input the layer owns, the user's own value or the MaterialX node of the user's link — what
    materialx_import needs to rebuild the same layer (the core's other inputs are in its
    node)."""
    lay = dict(tree.layer or {})
    lay["record"] = LAYER_RECORD_VERSION
    core = tree.core()
    if core is not None:
        lay["core_props"] = {k: core.props[k] for k in ("distribution", "fresnel_type",
                                                        "subsurface_method") if k in core.props}
        if writer is not None and core.name not in writer.surfaces and not core.mute:
            writer.shader_of_node(core)  # a layer node's core renders inside it: its own surface
        if writer is not None and core.name in writer.surfaces:
            lay["core_node"] = writer.surfaces[core.name].name
        base = {}
        for name, b in (core.base or {}).items():
            if "value" in b:
                c = np.asarray(b["value"], float).reshape(-1)
                base[name] = {"value": float(c[0]) if c.size == 1 else [float(x) for x in c[:3]]}
            elif "link" in b and writer is not None:
                sock = core.input(name)
                probe = Socket(sock.identifier if sock else name, name, sock.type if sock else "VALUE",
                               None, tuple(b["link"]), True, False, core.name)
                v = writer.value(probe, MX_TYPE.get(probe.type, "float"))
                if v is not None and not v.is_const:
                    base[name] = {"node": v.node.name, "output": v.output}
                elif v is not None:
                    c = np.asarray(v.const, float).reshape(-1)
                    base[name] = {"value": float(c[0]) if c.size == 1 else [float(x) for x in c[:3]]}
        lay["base"] = base
    return json.dumps(lay, sort_keys=True, default=lambda o: list(o) if isinstance(o, tuple) else str(o))


# --------------------------------------------------------------------------------------------
# The user's BSDF at haziness 0 (USD preview, export fallback)
# --------------------------------------------------------------------------------------------


def user_value(core, name):
    """The core's input ``name`` as the user set it: the stamped user value of an owned input
    (the layer wrote another), else the socket's own value (also when it is linked)."""
    b = (core.base or {}).get(name)
    if b is not None and "value" in b:
        return b["value"]
    s = core.input(name)
    return s.value if s is not None else None


def preview_values(tree):
    """UsdPreviewSurface inputs of the user's BSDF at haziness 0 (constants: a linked input
    gives its socket's value), or None without a core."""
    core = tree.core()
    if core is None:
        return None
    u = lambda name, d=0.0: user_value(core, name) if core.input(name) is not None else d  # noqa: E731
    rgb = lambda v: tuple(float(x) for x in np.broadcast_to(np.asarray(v, float).reshape(-1)[:3], 3))  # noqa: E731
    out = dict(metallic=1.0, roughness=float(u("Roughness")), ior=1.5, clearcoat=0.0,
               clearcoatRoughness=0.01, opacity=1.0, emissiveColor=(0.0, 0.0, 0.0))
    if core.type == PRINCIPLED:
        out.update(metallic=min(max(float(u("Metallic")), 0.0), 1.0), diffuseColor=rgb(u("Base Color")),
                   ior=float(u("IOR", 1.5)), clearcoat=min(max(float(u("Coat Weight")), 0.0), 1.0),
                   clearcoatRoughness=float(u("Coat Roughness", 0.03)),
                   opacity=min(max(float(u("Alpha", 1.0)), 0.0), 1.0),
                   emissiveColor=tuple(c * float(u("Emission Strength")) for c in rgb(u("Emission Color", (1, 1, 1)))))
    elif core.type == METALLIC:
        if core.props.get("fresnel_type") == "PHYSICAL_CONDUCTOR":
            r, _ = gulbrandsen_inverse(np.maximum(np.asarray(rgb(u("IOR")), float), 0.0),
                                       np.maximum(np.asarray(rgb(u("Extinction")), float), 0.0))
            out["diffuseColor"] = rgb(np.clip(np.nan_to_num(r), 0.0, 1.0))
        else:
            out["diffuseColor"] = rgb(u("Base Color"))
    else:
        out["diffuseColor"] = rgb(u("Color"))
    return out
