# SPDX-License-Identifier: GPL-3.0-or-later
"""The surfaces material libraries ship, as Principled BSDF materials (bpy-free).

:func:`principled_of` turns one ``open_pbr_surface`` (1.1, and the 1.2 draft with
``specular_haze``), ``standard_surface``, ``gltf_pbr`` or ``UsdPreviewSurface`` node of a
:class:`~hazy_gloss.interchange.document.Document` into a :class:`SurfaceSpec`: the Principled
BSDF's socket values (or links into a small node network: Image Texture, Math, Vector Math, Mix,
Separate / Combine XYZ, Mapping, UV Map, Normal Map), its distribution, and, for OpenPBR haze,
the keywords of ``api.make_hazy``.  blender/model/surface_build.py makes the nodes; nothing here
imports bpy.  What is built (SurfaceSpec, Val, Builder) is in surface_nodes.py, the reading of a
document's inputs and upstream nodes (Upstream) in surface_inputs.py; this module holds the
conventions and the mapping of each surface.

Each mapping follows the way the format's own tools map it onto a Principled BSDF, corrected
where they are not exact (docs/interchange.md §2 has the tables and the measured differences):

- **OpenPBR**: the inverse of Blender's own MaterialX exporter (base_metalness = Metallic,
  specular_weight = 2 · Specular IOR Level, ...) and of the corrections interchange/layered.py
  writes (OpenPBR's anisotropy keeps α_x, Cycles' the geometric mean; OpenPBR roughens the base
  and sees η/η_c under a coat, Cycles does not — applied here so the Principled renders what
  OpenPBR means); Multiscatter GGX (OpenPBR: "the multiple scattering compensation is assumed to
  apply to both lobes").
- **standard_surface**: MaterialX's translation graph to OpenPBR (specular → specular_weight,
  sheen roughness^0.4 → fuzz roughness) and its own nodegraph (roughness_anisotropy, tangent
  turned by specular_rotation); the Gulbrandsen metal (base colour, edge colour specular_color)
  becomes Principled's F82 metal with the tint that matches its Fresnel at 82°; GGX (the spec's
  BRDFs are single-scattering GGX).
- **gltf_pbr**: Blender's glTF importer (Specular IOR Level = specular / 2, sheen weight 1 with
  sheen_color, anisotropy rotation / 2π), with glTF's anisotropy (α_t = mix(α, 1, s²)) mapped
  exactly; Multiscatter GGX (the glTF spec suggests multiple scattering).
- **UsdPreviewSurface**: Blender's USD importer, with the specular workflow's F(0) =
  specularColor kept (Specular IOR Level and Tint) and the clearcoat's IOR = ior (the spec); GGX.
"""
from __future__ import annotations

import math

from .. import constants as K
from ..core.mapping import gulbrandsen_ior
from .brdf import fresnel_conductor_at
from .surface_inputs import (DEFAULTS, COLORSPACES, Upstream, default_val, defaults_of,
                             surface_defaults, tangent_of)
from .surface_nodes import PRINCIPLED, Builder, C, Link, Notes, SurfaceSpec, TexNode, Val, triple

#: Link, TexNode, SurfaceSpec, Upstream and the others named here from surface_nodes and
#: surface_inputs (split off this module) are re-exported: ``interchange.surfaces`` still names them.
__all__ = ("Link", "TexNode", "SurfaceSpec", "SURFACES", "principled_of", "Upstream",
           "openpbr_principled_alpha", "coat_roughened", "coat_relative_ior", "f82_tint_of_conductor",
           "PRINCIPLED", "COLORSPACES", "Val", "C", "Builder", "Notes", "surface_defaults",
           "tangent_of", "ALIASES", "openpbr", "standard_surface", "gltf_pbr", "usd_preview_surface",
           "bsdf_core", "apply_owned")

#: The shader node categories read as Principled materials, with their distribution.
SURFACES = {"open_pbr_surface": "MULTI_GGX", "standard_surface": "GGX", "gltf_pbr": "MULTI_GGX",
            "UsdPreviewSurface": "GGX"}


# --------------------------------------------------------------------------------------------
# Conventions (constants; the node forms use the Builder)
# --------------------------------------------------------------------------------------------


def openpbr_principled_alpha(r, a):
    """(Roughness R, Anisotropic A) of Cycles' Principled that renders OpenPBR's (α_t, α_b) for
    roughness r, anisotropy a: α_t = r² √(2/(1+(1-a)²)), α_b = (1-a) α_t; Cycles α_x = R²/s,
    α_y = R² s, s = √(1-0.9A), so A = a/0.9 and R⁴ = α_t α_b = r⁴ 2(1-a)/(1+(1-a)²).
    Exact for a ≤ 0.9 (Cycles' aspect ≤ 10) and α ≤ 1; returns (R, A, exact)."""
    r = min(max(float(r), 0.0), 1.0)
    a = min(max(float(a), 0.0), 1.0)
    q = 2.0 * (1.0 - a) / (1.0 + (1.0 - a) ** 2)
    rough = r * q ** 0.25 if q > 0 else 0.0
    aniso = a / 0.9
    return min(rough, 1.0), min(aniso, 1.0), aniso <= 1.0 + 1e-12


def coat_roughened(r, coat_r, coat_w):
    """OpenPBR's base roughness under a coat (MaterialX 1.39 open_pbr_surface):
    mix(r, min(1, 2 r_c⁴ + r⁴)^¼, coat_weight)."""
    w = min(max(coat_w, 0.0), 1.0)
    return (1.0 - w) * r + w * min(1.0, 2.0 * coat_r ** 4 + r ** 4) ** 0.25


def coat_relative_ior(eta, eta_c, coat_w):
    """OpenPBR's base IOR under a coat: mix(η, max(η/η_c, η_c/η), coat_weight)."""
    w = min(max(coat_w, 0.0), 1.0)
    if eta <= 0.0 or eta_c <= 0.0:
        return eta
    ratio = eta / eta_c
    return (1.0 - w) * eta + w * (ratio if ratio > 1.0 else 1.0 / ratio)


_ERR_MU = tuple(i / 8.0 for i in range(1, 9))


def f82_tint_of_conductor(f0, edge):
    """Principled's F82 tint (Specular Tint of a metal) for Gulbrandsen's conductor with
    reflectivity ``f0`` and edge colour ``edge`` (standard_surface's metal): the tint that makes
    F82-tint match the conductor's Fresnel at μ̄ = 1/7 (as engines.f82_tint_fit), per channel,
    and the largest |ΔF| over μ (8 samples) between the two models.  Python floats: it runs
    for every metal of a library."""
    tint, err = [], 0.0
    for r, g in zip(f0, edge):
        r = min(max(float(r), 0.0), 0.999)
        eta, kap = (float(x) for x in gulbrandsen_ior(r, min(max(float(g), 0.0), 1.0)))
        schlick = lambda mu: r + (1.0 - r) * (1.0 - mu) ** 5  # noqa: E731
        t = min(max(fresnel_conductor_at(K.F82_MU, eta, kap) / schlick(K.F82_MU), 0.0), 1.0)
        b = schlick(K.F82_MU) * (1.0 - t) / (K.F82_MU * (1.0 - K.F82_MU) ** 6)  # brdf.f82_tint's
        for mu in _ERR_MU:
            err = max(err, abs(fresnel_conductor_at(mu, eta, kap) - (schlick(mu) - b * mu * (1.0 - mu) ** 6)))
        tint.append(t)
    return tuple(tint), err


# --------------------------------------------------------------------------------------------
# The surfaces
# --------------------------------------------------------------------------------------------


_VECTOR_SOCKETS = frozenset(("Base Color", "Specular Tint", "Subsurface Radius", "Sheen Tint",
                             "Coat Tint", "Emission Color", "Color", "Edge Tint", "IOR3"))
#: Inputs of earlier drafts that files still carry (MaterialX's own OpenPBR examples), read as
#: the released names.
ALIASES = {"open_pbr_surface": {"specular_anisotropy": "specular_roughness_anisotropy",
                                "coat_anisotropy": "coat_roughness_anisotropy"}}


class _Surface:
    """One surface node being mapped: its inputs as Vals, the Principled's sockets."""

    __slots__ = ("node", "graph", "notes", "b", "up", "spec_in", "_memo", "out", "_inputs",
                 "_defaults")

    def __init__(self, doc, node, graph, name, notes):
        for old, new in ALIASES.get(node.category, {}).items():
            if old in node.inputs and new not in node.inputs:
                node.inputs[new] = node.inputs.pop(old)
                notes.say(f"{node.name}.{old} (an earlier draft's name) read as {new}")
        self.node = node
        self.graph = graph
        self.notes = notes
        self.b = Builder()
        self.up = Upstream(doc, self.b, notes, name)
        self.spec_in = surface_defaults(node)
        self._memo = {}
        self.out = {}
        self._inputs = node.inputs
        self._defaults = defaults_of(self.spec_in)
        spec_in = self.spec_in
        for k in node.inputs:
            if k not in spec_in and not (node.category == "open_pbr_surface" and k == "specular_rotation"):
                notes.say(f"{node.name}.{k} is not an input of {node.category}: ignored")

    def v(self, name):
        got = self._memo.get(name)
        if got is None:
            inp = self._inputs.get(name)
            if inp is None:  # the common case: the nodedef's default
                got = self._defaults[name] if name in self._defaults else default_val(self.spec_in, name)
            elif (inp.value is not None and inp.problem is None and inp.nodename is None
                  and inp.nodegraph is None and inp.interfacename is None and inp.channels is None
                  and inp.type == self.spec_in.get(name, ("",))[0]):  # a plain authored value
                x = inp.value
                got = Val(3, x) if type(x) is tuple and len(x) == 3 else C(x)
            else:
                got = self.up.input(self.node, self.graph, name, self.spec_in)
            self._memo[name] = got
        return got

    def set(self, socket, val, n=None):
        if val is None:
            return
        if val.link is None and (n is None or n == val.n):  # a constant as it is
            c = val.const
            self.out[socket] = c if val.n == 1 or isinstance(c, tuple) else (c, c, c)
            return
        self.out[socket] = self.b.socket(val, n)

    def copy(self, rows):
        """Inputs that are the Principled's sockets as they are: (socket, input) pairs; colour
        and vector sockets take three components."""
        for socket, name in rows:
            self.set(socket, self.v(name), 3 if socket in _VECTOR_SOCKETS else 1)

    def const(self, name):
        """A constant input's value (float or tuple), or None when it is linked."""
        x = self.v(name)
        return None if x is None or not x.is_const else x.const

    def is_default(self, name, dflt=None):
        if name not in self.node.inputs:
            return True
        v = self.v(name)
        if v is None:
            return True
        d = self.spec_in.get(name, ("", dflt))[1] if dflt is None else dflt
        return v.is_const and (triple(v.const) == triple(d) if isinstance(d, (tuple, float, int)) else True)

    def unsupported(self, names, what):
        for name in names:
            if name in self.spec_in and not self.is_default(name):
                self.notes.lose(f"{self.node.name}.{name} is not imported ({what})")

    def normals(self, pairs):
        for mx_name, socket in pairs:
            v = self.v(mx_name)
            if v is not None and not v.is_const:
                self.set(socket, v, 3)

    def tangent(self, name, rotation):
        """Tangent and rotation: a turn from rotate3d nodes is added to ``rotation`` (a Val)."""
        turns, kind, ok = self.up.tangent(self.node, self.graph, name)
        if not ok:
            self.notes.lose(f"{self.node.name}.{name}: tangent not recognised: the UV tangent is used")
        if kind.startswith("RADIAL"):
            self.notes.say(f"{self.node.name}.{name}: a radial tangent about {kind[-1]}: Cycles' default "
                           f"radial tangent is about Z through the bounding-box centre")
        key = self.b.node("ShaderNodeTangent", {"direction_type": "UV_MAP" if kind == "UV_MAP" else "RADIAL",
                                                "axis": kind[-1] if kind != "UV_MAP" else "Z"})
        self.out["Tangent"] = Link(key, "Tangent")
        return self.b.add(rotation, C(turns)) if turns else rotation

    def finish(self, source, distribution):
        spec = SurfaceSpec(self.up.name, source, dict(self.out), {"distribution": distribution},
                           self.b.nodes, notes=self.notes)
        return spec


def _opbr_anisotropy_nodes(s, r, a):
    """(R, A) Vals of openpbr_principled_alpha for linked inputs."""
    b = s.b
    ac = b.clamp(a)
    oma = b.sub(C(1.0), ac)
    q = b.div(b.mul(C(2.0), oma), b.add(C(1.0), b.mul(oma, oma)))
    rough = b.mul(r, b.pow(q, C(0.25)))
    return b.clamp(rough), b.clamp(b.mul(ac, C(1.0 / 0.9)))


def _base_colour(s, base, mixes):
    """Principled's Base Color: ``base``, mixed towards each (weight, colour) where the part
    they tint takes over (exact at weights 0 and 1; Blender's own versioning merged
    Subsurface Color the same way)."""
    b = s.b
    out = base
    for wname, cname, what in mixes:
        w, col = s.v(wname), s.v(cname)
        if w.is_const and w.const == 0.0:
            continue
        if not (col.is_const and out.is_const and triple(col.const) == triple(out.const)):
            if not (w.is_const and w.const in (1.0,)):
                s.notes.lose(f"{cname} differs from the base colour: the Principled has one colour for "
                             f"its diffuse and its {what} (mixed by {wname}; exact at 0 and 1)")
        out = b.mix(w, out, col)
    return out


def apply_owned(s, owned):
    """The inputs a haze layer owns, as the user set them (layered documents: the record's
    values, or the MaterialX node of the user's link)."""
    for socket, b in (owned or {}).items():
        if "value" in b:
            v = b["value"]
            s.out[socket] = tuple(float(x) for x in v[:3]) if isinstance(v, (list, tuple)) else float(v)
        elif "node" in b:
            scope = s.graph.nodes if s.graph is not None else s.up.doc.nodes
            n = scope.get(b["node"])
            v = s.up.node_value(n, s.graph, b.get("output"), socket) if n is not None else None
            if v is None:
                s.notes.lose(f"the user's link into {socket} is not in the document: the layer's value is kept")
            else:
                s.set(socket, v)


def _set_base(s, weight, subsurface, transmission, metalness, diffuse_roughness):
    """The base layer OpenPBR and standard_surface share, by their input names: Base Color
    (base_color times ``weight``, with the ``subsurface`` and ``transmission`` (weight, colour,
    name) tints), Metallic and Diffuse Roughness.  Returns the base colour and the metalness."""
    base = s.b.mul(s.v("base_color"), s.v(weight))
    s.set("Base Color", _base_colour(s, base, (subsurface, transmission)), 3)
    metal = s.v(metalness)
    s.set("Metallic", metal, 1)
    s.set("Diffuse Roughness", s.v(diffuse_roughness), 1)
    return base, metal


def openpbr(doc, node, graph, name, notes, owned=None):
    """open_pbr_surface (1.1.1; 1.2 draft: specular_haze, emission_weight).  ``owned``: the
    record of a layered document (the user's values of the inputs the layer owns)."""
    s = _Surface(doc, node, graph, name, notes)
    b = s.b
    v = s.v
    version = str(node.attrs.get("version", "1.1"))
    _, metal = _set_base(s, "base_weight", ("subsurface_weight", "subsurface_color", "subsurface"),
                        ("transmission_weight", "transmission_color", "transmission"),
                        "base_metalness", "base_diffuse_roughness")
    spec_w = v("specular_weight")
    s.set("Specular IOR Level", b.mul(spec_w, C(0.5)), 1)
    if not (spec_w.is_const and spec_w.const == 1.0) and not (metal.is_const and metal.const == 0.0):
        notes.lose("specular_weight also scales OpenPBR's metal; Principled's Specular IOR Level does not")
    s.set("Specular Tint", v("specular_color"), 3)
    cw, cr, cior = v("coat_weight"), v("coat_roughness"), v("coat_ior")
    coated = not (cw.is_const and cw.const == 0.0)
    r, a = v("specular_roughness"), v("specular_roughness_anisotropy")
    if coated:  # OpenPBR roughens the base under the coat; Cycles does not: give Cycles that
        if r.is_const and cr.is_const and cw.is_const:
            r = C(coat_roughened(r.const, cr.const, cw.const))
        else:
            c4 = b.mul(C(2.0), b.pow(b.mul(cr, cr), C(2.0)))
            rough4 = b.pow(b.mul(r, r), C(2.0))
            r = b.mix(b.clamp(cw), r, b.pow(b.minimum(b.add(c4, rough4), C(1.0)), C(0.25)))
    if r.is_const and a.is_const:
        rough, aniso, ok = openpbr_principled_alpha(r.const, a.const)
        if not ok:
            notes.lose(f"specular_roughness_anisotropy {a.const:g} is beyond Cycles' aspect 10: "
                       f"Anisotropic 1")
        s.set("Roughness", C(rough))
        s.set("Anisotropic", C(aniso))
    else:
        rough, aniso = _opbr_anisotropy_nodes(s, r, a)
        s.set("Roughness", rough)
        s.set("Anisotropic", aniso)
    eta = v("specular_ior")
    if coated:  # OpenPBR's base sees η/η_c under the coat (Cycles: the Principled IOR)
        if eta.is_const and cior.is_const and cw.is_const:
            eta = C(coat_relative_ior(eta.const, cior.const, cw.const))
            if abs(eta.const - 1.0) < 0.01:
                notes.say(f"under the coat OpenPBR's base has the IOR relative to the coat's: "
                          f"{eta.const:.4g} (the base barely reflects)")
        else:
            eta = b.mix(b.clamp(cw), eta, b.div(eta, cior))
            notes.lose("linked coat or IOR: OpenPBR's coat-relative IOR is taken as η/η_c")
        if not (v("coat_darkening").is_const and v("coat_darkening").const == 0.0):
            notes.lose("coat_darkening: OpenPBR darkens the base under the coat, Cycles does not")
    s.set("IOR", eta, 1)
    s.copy((("Transmission Weight", "transmission_weight"),
            ("Transmission Dispersion Scale", "transmission_dispersion_scale"),
            ("Transmission Dispersion Abbe Number", "transmission_dispersion_abbe_number"),
            ("Subsurface Weight", "subsurface_weight"), ("Subsurface Radius", "subsurface_radius_scale"),
            ("Subsurface Scale", "subsurface_radius"), ("Subsurface Anisotropy", "subsurface_scatter_anisotropy"),
            ("Sheen Weight", "fuzz_weight"), ("Sheen Tint", "fuzz_color"), ("Sheen Roughness", "fuzz_roughness"),
            ("Coat Weight", "coat_weight"), ("Coat Tint", "coat_color"), ("Coat Roughness", "coat_roughness"),
            ("Coat IOR", "coat_ior")))
    s.unsupported(("transmission_depth", "transmission_scatter", "transmission_scatter_anisotropy"),
                  "the Principled BSDF has no interior medium")
    s.unsupported(("coat_roughness_anisotropy",), "the Principled coat is isotropic")
    tfw, tft = v("thin_film_weight"), v("thin_film_thickness")
    thick = b.mul(tft, C(1000.0))  # μm -> nm
    if tfw.is_const:
        if tfw.const == 0.0:
            thick = C(0.0)
        elif tfw.const != 1.0:
            notes.lose(f"thin_film_weight {tfw.const:g}: the film is imported at full weight")
    else:
        notes.lose("a linked thin_film_weight: the film is imported where the weight is above 0")
        thick = b.mul(thick, b.greater(tfw, C(0.0)))
    s.set("Thin Film Thickness", thick, 1)
    s.set("Thin Film IOR", v("thin_film_ior"), 1)
    lum = v("emission_luminance")
    if version.startswith("1.2"):
        lum = b.mul(lum, v("emission_weight"))
    s.set("Emission Color", v("emission_color"), 3)
    s.set("Emission Strength", lum, 1)
    s.set("Alpha", v("geometry_opacity"), 1)
    if not s.is_default("geometry_thin_walled", False):
        s.set("Thin Wall", v("geometry_thin_walled"), 1)
    s.normals((("geometry_normal", "Normal"), ("geometry_coat_normal", "Coat Normal")))
    rot = C(0.0)
    old_rot = node.inputs.get("specular_rotation")  # an earlier draft's: turns, as standard_surface
    if old_rot is not None and isinstance(old_rot.value, float):
        rot = C(-old_rot.value)
        notes.say(f"{node.name}.specular_rotation (an earlier draft's input) read as a turn of the tangent")
    aniso_on = not (a.is_const and a.const == 0.0)
    if aniso_on:
        rot = s.tangent("geometry_tangent", rot)
        s.set("Anisotropic Rotation", b.affine(rot, 1.0, 0.0), 1)
    apply_owned(s, owned)
    spec = s.finish(f"open_pbr_surface {version}", SURFACES["open_pbr_surface"])
    if version.startswith("1.2") or "specular_haze" in node.inputs:
        _openpbr_haze(s, spec, r, a, coated)
    return spec


def _openpbr_haze(s, spec, r_eff, a, coated):
    """specular_haze > 0: the target blend (β, α_n, α_w) for the haze layer (haze_blend)."""
    v = s.v
    haze = v("specular_haze")
    if haze.is_const and haze.const == 0.0:
        return
    spread = v("specular_haze_spread")
    if not (haze.is_const and spread.is_const and r_eff.is_const and a.is_const):
        s.notes.lose("a linked specular_haze / spread or roughness: the haze is not imported")
        return
    r0 = v("specular_roughness").const
    r_haze = r0 + (1.0 - r0) * min(max(spread.const, 0.0), 1.0)  # lerp(r_core, 1, spread)
    if coated:  # 1.2's reference graph roughens the haze under the coat as the core
        cw, cr = v("coat_weight").const, v("coat_roughness").const
        if cw is None or cr is None:
            s.notes.lose("a linked coat: the haze is not imported")
            return
        r_haze = coat_roughened(r_haze, cr, cw)
    rn, an_, _ = openpbr_principled_alpha(r_eff.const, a.const)
    rw, aw_, _ = openpbr_principled_alpha(r_haze, a.const)
    spec.haze_target = dict(beta=min(max(float(haze.const), 0.0), 1.0), roughness=rn, anisotropy=an_,
                            roughness_wide=rw, anisotropy_wide=aw_)


def standard_surface(doc, node, graph, name, notes):
    """standard_surface 1.0.1 (1.0.0 with version="1.0.0")."""
    s = _Surface(doc, node, graph, name, notes)
    b = s.b
    v = s.v
    base, metal = _set_base(s, "base", ("subsurface", "subsurface_color", "subsurface"),
                            ("transmission", "transmission_color", "transmission"),
                            "metalness", "diffuse_roughness")
    s.set("Specular IOR Level", b.mul(v("specular"), C(0.5)), 1)
    spec_c = v("specular_color")
    if metal.is_const and metal.const >= 1.0 and base.is_const and spec_c.is_const:
        tint, err = f82_tint_of_conductor(triple(base.const), triple(spec_c.const))
        s.set("Specular Tint", C(tint))
        notes.lose(f"the Gulbrandsen metal (edge colour specular_color) is Principled's F82 metal with "
                   f"Specular Tint {', '.join(f'{t:.3f}' for t in tint)} (max |ΔF| {err:.3f})")
    else:
        s.set("Specular Tint", spec_c, 3)
        if not (metal.is_const and metal.const == 0.0) and not (spec_c.is_const and triple(spec_c.const) == (1.0, 1.0, 1.0)):
            notes.lose("specular_color is the metal's edge colour in standard_surface and its F82 tint "
                       "in the Principled: read as the tint")
    # roughness: MaterialX's graph, coat_affect_roughness first, then roughness_anisotropy
    r = v("specular_roughness")
    car = b.mul(b.mul(v("coat_affect_roughness"), v("coat")), v("coat_roughness"))
    r = b.mix(car, r, C(1.0))
    a = v("specular_anisotropy")
    if a.is_const:
        if a.const > 0.9:
            notes.lose(f"specular_anisotropy {a.const:g} is beyond Cycles' aspect 10: Anisotropic 1")
        s.set("Anisotropic", C(min(max(a.const, 0.0) / 0.9, 1.0)))
    else:
        s.set("Anisotropic", b.clamp(b.mul(a, C(1.0 / 0.9))))
    s.set("Roughness", r, 1)
    s.copy((("IOR", "specular_IOR"), ("Transmission Weight", "transmission"),
            ("Subsurface Weight", "subsurface"), ("Subsurface Radius", "subsurface_radius"),
            ("Subsurface Scale", "subsurface_scale"), ("Subsurface Anisotropy", "subsurface_anisotropy"),
            ("Sheen Weight", "sheen"), ("Sheen Tint", "sheen_color"), ("Coat Weight", "coat"),
            ("Coat Tint", "coat_color"), ("Coat Roughness", "coat_roughness"), ("Coat IOR", "coat_IOR"),
            ("Thin Film Thickness", "thin_film_thickness"), ("Thin Film IOR", "thin_film_IOR"),
            ("Emission Color", "emission_color"), ("Emission Strength", "emission")))
    s.unsupported(("transmission_depth", "transmission_scatter", "transmission_scatter_anisotropy",
                   "transmission_dispersion", "transmission_extra_roughness"),
                  "the Principled BSDF's transmission has no medium of its own")
    # MaterialX's standard_surface_to_open_pbr: fuzz_roughness = sheen_roughness^0.4 (by eye)
    s.set("Sheen Roughness", b.pow(v("sheen_roughness"), C(0.4)), 1)
    if not s.is_default("sheen"):
        notes.lose("sheen: standard_surface's sheen (Estevez-Kulla) is Cycles' microfiber sheen with "
                   "roughness^0.4 (MaterialX's translation to OpenPBR)")
    s.unsupported(("coat_anisotropy", "coat_rotation", "coat_affect_color"),
                  "the Principled coat is isotropic and does not saturate the base")
    op = v("opacity")
    if op.is_const and len(set(triple(op.const))) > 1:
        notes.lose("a coloured opacity is imported as its average (Alpha)")
    s.set("Alpha", b.mean(op), 1)
    if not s.is_default("thin_walled", False):
        s.set("Thin Wall", v("thin_walled"), 1)
    s.normals((("normal", "Normal"), ("coat_normal", "Coat Normal")))
    if not (a.is_const and a.const == 0.0):
        rot = s.tangent("tangent", b.affine(v("specular_rotation"), -1.0, 0.0))
        s.set("Anisotropic Rotation", rot, 1)
    return s.finish("standard_surface", SURFACES["standard_surface"])


def gltf_pbr(doc, node, graph, name, notes):
    """gltf_pbr 2.0.1 (MaterialX's glTF PBR: the glTF 2.0 metallic-roughness model and its
    KHR_materials extensions)."""
    s = _Surface(doc, node, graph, name, notes)
    b = s.b
    v = s.v
    s.set("Base Color", v("base_color"), 3)
    metal = v("metallic")
    s.set("Metallic", metal, 1)
    r = v("roughness")
    st = v("anisotropy_strength")
    if st.is_const and st.const == 0.0:
        s.set("Roughness", r, 1)
    elif r.is_const and st.is_const:  # glTF: α_t = mix(α, 1, s²), α_b = α
        alpha = r.const ** 2
        at = alpha + (1.0 - alpha) * min(max(st.const, 0.0), 1.0) ** 2
        ab = alpha
        ratio = ab / at if at > 0 else 1.0
        aniso = (1.0 - ratio) / 0.9
        if aniso > 1.0:
            notes.lose(f"anisotropy_strength {st.const:g}: the aspect {1 / ratio:.3g} is beyond Cycles' 10")
        s.set("Roughness", C(min((at * ab) ** 0.25, 1.0)))
        s.set("Anisotropic", C(min(aniso, 1.0)))
    else:
        s.set("Roughness", r, 1)
        s.set("Anisotropic", st, 1)
        notes.lose("linked glTF anisotropy: strength read as Anisotropic (Blender's glTF importer)")
    if not (st.is_const and st.const == 0.0):
        rot = s.tangent("tangent", b.affine(v("anisotropy_rotation"), 1.0 / (2.0 * math.pi), 0.0))
        s.set("Anisotropic Rotation", rot, 1)
    s.set("IOR", v("ior"), 1)
    spec = v("specular")
    s.set("Specular IOR Level", b.mul(spec, C(0.5)), 1)
    if not (spec.is_const and spec.const == 1.0):
        notes.lose("specular ≠ 1: glTF scales F(90°) too, the Principled only F(0)")
    spec_c = v("specular_color")
    s.set("Specular Tint", spec_c, 3)
    if not (metal.is_const and metal.const == 0.0) and not (spec_c.is_const and triple(spec_c.const) == (1.0, 1.0, 1.0)):
        notes.lose("specular_color tints glTF's dielectric only; the Principled's Specular Tint also "
                   "tints its metal (F82)")
    s.set("Transmission Weight", v("transmission"), 1)
    mode = s.const("alpha_mode")
    mode = int(mode) if isinstance(mode, (int, float)) else 0
    alpha = v("alpha")
    if mode == 0:
        s.set("Alpha", C(1.0))
    elif mode == 1:
        cut = s.const("alpha_cutoff")
        cut = 0.5 if cut is None else float(cut)
        s.set("Alpha", b.greater(alpha, C(cut - 1e-7)) if not alpha.is_const else
              C(1.0 if alpha.const >= cut else 0.0), 1)
    else:
        s.set("Alpha", alpha, 1)
    s.set("Coat Weight", v("clearcoat"), 1)
    s.set("Coat Roughness", v("clearcoat_roughness"), 1)
    s.set("Coat IOR", C(1.5), 1)  # KHR_materials_clearcoat: a fixed IOR of 1.5
    sheen = v("sheen_color")
    if not (sheen.is_const and triple(sheen.const) == (0.0, 0.0, 0.0)):
        s.set("Sheen Weight", C(1.0))
        s.set("Sheen Tint", sheen, 3)
        s.set("Sheen Roughness", v("sheen_roughness"), 1)
        notes.lose("sheen: glTF's Charlie sheen is Cycles' microfiber sheen (Blender's glTF importer)")
    s.set("Emission Color", v("emissive"), 3)
    s.set("Emission Strength", v("emissive_strength"), 1)
    irid = v("iridescence")
    if not (irid.is_const and irid.const == 0.0):
        s.set("Thin Film Thickness", b.mul(v("iridescence_thickness"), b.greater(irid, C(0.0))), 1)
        s.set("Thin Film IOR", v("iridescence_ior"), 1)
        if not (irid.is_const and irid.const == 1.0):
            notes.lose("iridescence below 1: the film is imported at full weight")
    s.unsupported(("thickness", "attenuation_color", "dispersion"),
                  "KHR_materials_volume / dispersion: Blender's glTF importer adds a Volume Absorption "
                  "node, not made here")
    occ = v("occlusion")
    if not (occ.is_const and occ.const == 1.0):
        notes.say("occlusion is not imported (path tracers compute it)")
    s.normals((("normal", "Normal"), ("clearcoat_normal", "Coat Normal")))
    spec_out = s.finish("gltf_pbr", SURFACES["gltf_pbr"])
    if mode == 1:
        spec_out.alpha_clip = 0.5 if s.const("alpha_cutoff") is None else float(s.const("alpha_cutoff"))
    return spec_out


def usd_preview_surface(doc, node, graph, name, notes):
    """UsdPreviewSurface 2.6 (metallic and specular workflows)."""
    s = _Surface(doc, node, graph, name, notes)
    b = s.b
    v = s.v
    s.set("Base Color", v("diffuseColor"), 3)
    s.set("Emission Color", v("emissiveColor"), 3)
    s.set("Emission Strength", C(1.0))
    wf = s.const("useSpecularWorkflow")
    ior = v("ior")
    if wf is not None and float(wf) != 0.0:  # specular workflow: F(0) = specularColor, F(90) = 1
        s.set("Metallic", C(0.0))
        sc = v("specularColor")
        if sc.is_const and ior.is_const:
            m = max(triple(sc.const))
            f0 = ((ior.const - 1.0) / (ior.const + 1.0)) ** 2 if ior.const > 0 else 0.04
            level = m / (2.0 * f0) if f0 > 0 else 0.5
            if level > 1.0:
                notes.lose(f"specularColor {m:.3g} is beyond the Principled's F(0) range at IOR "
                           f"{ior.const:g} (Specular IOR Level at most 1 = 2 F0): capped")
            s.set("Specular IOR Level", C(min(level, 1.0)))
            s.set("Specular Tint", C(tuple(c / m for c in triple(sc.const)) if m > 0 else (1.0, 1.0, 1.0)))
        else:
            s.set("Specular Tint", sc, 3)
            notes.lose("a linked specularColor is read as the Specular Tint (Blender's USD importer)")
        notes.say("the specular workflow's Schlick Fresnel is the Principled's dielectric Fresnel from "
                  "the same F(0)")
    else:
        s.set("Metallic", v("metallic"), 1)
    s.set("Roughness", v("roughness"), 1)
    s.set("IOR", ior, 1)
    s.set("Coat Weight", v("clearcoat"), 1)
    s.set("Coat Roughness", v("clearcoatRoughness"), 1)
    s.set("Coat IOR", ior, 1)  # the spec: ior applies to the clearcoat
    op = v("opacity")
    thr = s.const("opacityThreshold")
    thr = 0.0 if thr is None else float(thr)
    alpha_clip = None
    if thr > 0.0:
        alpha_clip = thr
        op = b.greater(op, C(thr - 1e-7)) if not op.is_const else C(1.0 if op.const >= thr else 0.0)
    s.set("Alpha", op, 1)
    nrm = v("normal")
    if nrm is not None and not nrm.is_const:  # tangent-space, [-1, 1]: the Normal Map's 0-1 colour
        enc = b.affine(nrm, 0.5, 0.5)
        key = b.node("ShaderNodeNormalMap", {"space": "TANGENT"}, {"Color": b.socket(enc, 3), "Strength": 1.0})
        s.out["Normal"] = Link(key, "Normal")
    disp = v("displacement")
    if not (disp.is_const and disp.const == 0.0):
        notes.lose("displacement is not imported")
    occ = v("occlusion")
    if not (occ.is_const and occ.const == 1.0):
        notes.say("occlusion is not imported (path tracers compute it)")
    out = s.finish("UsdPreviewSurface", SURFACES["UsdPreviewSurface"])
    out.alpha_clip = alpha_clip
    return out


def bsdf_core(doc, node, graph, name, notes, core_type, owned=None):
    """The core of a layered document that is not a Principled: a conductor_bsdf (Metallic,
    Physical Conductor), generalized_schlick_bsdf with color82 = Edge Tint (Metallic F82) or
    with color0 = color90 (Glossy), as interchange/layered.py writes them; roughness is the α
    Cycles renders."""
    s = _Surface(doc, node, graph, name, notes)
    s.spec_in = DEFAULTS.get((node.category, "BSDF"), {})
    s._defaults = defaults_of(s.spec_in)
    v = s.v
    alpha = v("roughness")
    ax, ay = (triple(alpha.const)[:2] if alpha is not None and alpha.is_const else (0.01, 0.01))
    if alpha is not None and not alpha.is_const:
        notes.lose("a linked roughness of the core is imported at its default")
    rough = math.sqrt(math.sqrt(max(ax, 0.0)) * math.sqrt(max(ay, 0.0)))
    s.set("Roughness", C(min(rough, 1.0)))
    glossy = core_type == "GLOSSY"
    if glossy:  # Glossy: a >= 0 makes y the long axis (α_x = R²(1-a), α_y = R²/(1-a))
        ratio = math.sqrt(min(ax, ay) / max(ax, ay)) if max(ax, ay) > 0 else 1.0
        aniso = (1.0 - ratio) if ay >= ax else -(1.0 - ratio)
        s.set("Anisotropy", C(aniso))
        s.set("Color", v("color0"), 3)
        bsdf = "ShaderNodeBsdfGlossy"
    else:
        ratio = min(ax, ay) / max(ax, ay) if max(ax, ay) > 0 else 1.0
        s.set("Anisotropy", C(min((1.0 - ratio) / 0.9, 1.0)))
        bsdf = "ShaderNodeBsdfMetallic"
        if node.category == "conductor_bsdf":
            s.set("IOR", v("ior"), 3)
            s.set("Extinction", v("extinction"), 3)
        else:
            s.set("Base Color", v("color0"), 3)
            s.set("Edge Tint", v("color82"), 3)
    turns, kind, ok = s.up.tangent(node, graph, "tangent")
    rot = turns + (0.25 if not glossy and ay > ax else 0.0)
    if ax != ay:
        s.tangent("tangent", C(0.0))
        s.set("Rotation", C(rot - math.floor(rot)))
    s.normals((("normal", "Normal"),))
    apply_owned(s, owned)
    spec = s.finish(node.category, "GGX")
    spec.bsdf = bsdf
    return spec


_MAPPERS = {"open_pbr_surface": openpbr, "standard_surface": standard_surface, "gltf_pbr": gltf_pbr,
            "UsdPreviewSurface": usd_preview_surface}


def principled_of(doc, node, graph, name, notes=None):
    """SurfaceSpec of one library surface node (``node.category`` in SURFACES)."""
    notes = notes if notes is not None else Notes()
    spec = _MAPPERS[node.category](doc, node, graph, name, notes)
    spec.lossy = notes.lost
    return spec
