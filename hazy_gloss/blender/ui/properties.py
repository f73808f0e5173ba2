# SPDX-License-Identifier: GPL-3.0-or-later
"""``Material.hazy_gloss_settings``: the perceptual parameters as UI properties.

The stamp ``mat["hazy_gloss"]`` written by :mod:`hazy_gloss.api` is the only storage of the
parameters (it travels with the .blend and is all a render farm needs).  Every parameter
property here is a *view* on that stamp: its getter reads the stamp, its setter calls
``api.update_material`` (through ``edit.edit_material``).  So nothing has to be synced: after
the add-on is disabled and enabled again, after undo, after loading a file written by a script
or another machine, the panel shows what the stamp says.

Why not ``Material.hazy_gloss``: in Blender 4.5 a registered property shares its storage with
the custom property of the same name, so ``Material.hazy_gloss`` would overwrite the stamp
(measured: writing one field of the group deleted other keys of ``mat["hazy_gloss"]``).  5.0
keeps them apart, but one name has to work in both.

A few properties are plain stored UI state: the haze-extent link toggle and what a switch
remembers (the edge tint while the kind is not a conductor, the smoothness weight while the
smooth mapping is off).

Edits go through ``edit.edit_material``, which
- refuses linked-library and override materials with a clear message (no crash),
- ignores re-entrant calls for the same material (a setter triggered while that material is
  being rebuilt, e.g. by a handler or driver of the user's),
- keeps what the user connected to the hazy nodes: textures linked into the group's inputs
  and the links from the hazy BSDF output into other nodes (a Mix Shader, say) survive the
  rebuild, and nodes the user moved stay where they were,
- records a plain-language message per material when a change is refused
  (``messages.last_error``, shown by the panel).
"""
import math

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty, PointerProperty

from ... import constants as K
from ...core.parameters import HAZE_DEFAULTS, normalise
from ..actions import edit, eevee_output, messages
from ..model import material, material_read
from ..actions.messages import plain_message

PROPERTY_NAME = "hazy_gloss_settings"
GROUP_NODE = material.GROUP_NODE
NODE_DISTRIBUTIONS = K.NODE_DISTRIBUTIONS

KIND_ITEMS = (
    ("CONDUCTOR", "Conductor", "Metal: Metallic BSDF lobes with the physical conductor Fresnel "
     "from core reflectivity and edge tint (Gulbrandsen 2014)", 0),
    ("DIELECTRIC", "Dielectric", "Plastic, varnish, glass: Principled BSDF specular lobes over a "
     "base colour; keep haziness small (about 0-0.1)", 1),
    ("LEGACY", "Legacy", "Glossy BSDF lobes without Fresnel (colours only)", 2),
)
DISTRIBUTION_ITEMS = (
    ("GGX", "GGX", "GGX microfacets (all kinds)", 0),
    ("BECKMANN", "Beckmann", "Beckmann microfacets (conductor and legacy)", 1),
    ("MULTI_GGX", "Multiscatter GGX", "GGX with multiple-scattering energy compensation "
     "(β and r corrected so the peak stays invariant)", 2),
    ("ASHIKHMIN_SHIRLEY", "Ashikhmin-Shirley", "Ashikhmin-Shirley lobes (legacy only)", 3),
)
TANGENT_ITEMS = (
    ("UV_MAP", "UV Map", "Tangent from the object's UV map (the usual choice)", 0),
    ("RADIAL_X", "Radial X", "Radial tangent around the object's X axis", 1),
    ("RADIAL_Y", "Radial Y", "Radial tangent around the object's Y axis", 2),
    ("RADIAL_Z", "Radial Z", "Radial tangent around the object's Z axis (Blender's default "
     "for an unconnected Tangent)", 3),
)
_KIND_IDS = [i[0] for i in KIND_ITEMS]
_DIST_IDS = [i[0] for i in DISTRIBUTION_ITEMS]
_TANGENT_IDS = [i[0] for i in TANGENT_ITEMS]



# --------------------------------------------------------------------------------------------
# Reading and editing
# --------------------------------------------------------------------------------------------


def settings(mat):
    return getattr(mat, PROPERTY_NAME)


def has_hazy_nodes(mat):
    tree = getattr(mat, "node_tree", None)
    return tree is not None and bool(material.ours(tree))


def parameters(mat):
    """The stamped parameters; the defaults for a non-hazy material and for whatever part of a
    damaged stamp does not read (stamp_problem says what)."""
    if mat is None or not material_read.is_hazy(mat):
        return normalise({})
    p, _ = material_read.read_parameters_lenient(mat)
    return p if p is not None else normalise({})


def stamp_problem(mat):
    """Why the stamp cannot be read (one line naming the key and the way out), or None."""
    if mat is None or not material_read.is_hazy(mat):
        return None
    _, problem = material_read.read_parameters_lenient(mat)
    return problem


# --------------------------------------------------------------------------------------------
# Property getters and setters (views on the stamp)
# --------------------------------------------------------------------------------------------


#: Open strict_settings() blocks: lists collecting (material name, message) of refused changes.
_strict = []


def _set(pg, **changes):
    """A setter: Blender prints and swallows exceptions raised in a property setter, so a
    refused change is recorded (``messages.last_error``, api.last_error) and collected by an open
    :func:`strict_settings` block, which raises when it closes."""
    mat = pg.id_data
    _, msg = edit.edit_material(mat, **changes)
    if msg:
        print(f"Hazy Gloss: {mat.name}: {msg}")
        for errors in _strict:
            errors.append((mat.name, msg))


class strict_settings:
    """``with strict_settings(): mat.hazy_gloss_settings.roughness = 2`` raises ValueError (one
    line) when the block ends if a setting made in it was refused (api.strict_settings)."""

    def __enter__(self):
        self.errors = []
        _strict.append(self.errors)
        return self.errors

    def __exit__(self, typ, value, tb):
        _strict.remove(self.errors)
        if typ is None and self.errors:
            name, msg = self.errors[0]
            more = f" (and {len(self.errors) - 1} more refused)" if len(self.errors) > 1 else ""
            raise ValueError(f"{name}: {msg}{more}")
        return False


def _finite(value, default=0.0):
    """A getter's float: ``default`` for what is not a finite number (a baked layer's
    "texture" haziness, say)."""
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        return float(default)
    if not math.isfinite(x):
        return float(default)
    return max(-_FLOAT32_MAX, min(x, _FLOAT32_MAX))  # a float property is a C float


_FLOAT32_MAX = 3.0e38


def _get_float(key):
    def get(self):
        default = HAZE_DEFAULTS.get(key, 0.0)
        return _finite(parameters(self.id_data).get(key, default), default)
    return get


def _set_float(key):
    def set_(self, value):
        _set(self, **{key: float(value)})
    return set_


def _get_rgb(key):
    def get(self):
        return tuple(_finite(c) for c in parameters(self.id_data)[key])
    return get


def _set_rgb(key):
    def set_(self, value):
        _set(self, **{key: tuple(float(x) for x in value)})
    return set_


def _index(ids, value):
    """The enum index of ``value`` (0 for what the enum does not list, e.g. a layer's MIXED)."""
    return ids.index(value) if value in ids else 0


def _get_kind(self):
    return _index(_KIND_IDS, parameters(self.id_data)["kind"])


def _set_kind(self, value):
    kind = _KIND_IDS[value]
    mat = self.id_data
    p = parameters(mat)
    if kind == p["kind"]:
        return
    changes = {"kind": kind}
    if p["distribution"] not in NODE_DISTRIBUTIONS[kind]:
        changes["distribution"] = "GGX"
    if p["kind"] == "CONDUCTOR":  # remember the edge tint; dielectrics have none
        self.edge_tint_memory = p["edge_tint"]
    if kind == "CONDUCTOR":
        changes["edge_tint"] = tuple(self.edge_tint_memory)
    _set(self, **changes)


def _get_distribution(self):
    return _index(_DIST_IDS, parameters(self.id_data)["distribution"])


def _set_distribution(self, value):
    _set(self, distribution=_DIST_IDS[value])


def _get_tangent(self):
    return _index(_TANGENT_IDS, parameters(self.id_data)["tangent"])


def _set_tangent(self, value):
    _set(self, tangent=_TANGENT_IDS[value])


def _get_extent(axis):
    def get(self):
        return _finite(parameters(self.id_data)["haze_extent"][axis], 5.0)
    return get


def _set_extent(axis):
    def set_(self, value):
        x, y = parameters(self.id_data)["haze_extent"]
        if self.haze_extent_linked:
            x = y = float(value)
        elif axis == 0:
            x = float(value)
        else:
            y = float(value)
        _set(self, haze_extent=(x, y))
    return set_


def _set_linked(self, value):
    self["haze_extent_linked_"] = bool(value)
    if value:  # linking makes the halo isotropic: y follows x
        x, y = parameters(self.id_data)["haze_extent"]
        if x != y and material_read.is_hazy(self.id_data):
            _set(self, haze_extent=(x, x))


def _get_linked(self):
    """Linked when the user linked them (the default) and the extents are equal: a preset or a
    script that makes the halo anisotropic shows as unlinked."""
    x, y = parameters(self.id_data)["haze_extent"]
    return bool(self.get("haze_extent_linked_", True)) and x == y


def _get_use_smooth(self):
    return parameters(self.id_data)["smoothness"] is not None


def _set_use_smooth(self, value):
    w = parameters(self.id_data)["smoothness"]
    if bool(value) == (w is not None):
        return
    if value:
        _set(self, smoothness=float(self.smoothness_memory))
    else:
        self.smoothness_memory = w
        _set(self, smoothness=None)


def _get_smoothness(self):
    w = parameters(self.id_data)["smoothness"]
    return min(_finite(w, 1e6), 1e6) if w is not None else float(self.smoothness_memory)


def _set_smoothness(self, value):
    if parameters(self.id_data)["smoothness"] is None:
        self.smoothness_memory = float(value)
    else:
        _set(self, smoothness=float(value))


def _get_bool(key):
    def get(self):
        return bool(parameters(self.id_data).get(key, HAZE_DEFAULTS.get(key, False)))
    return get


def _set_bool(key):
    def set_(self, value):
        _set(self, **{key: bool(value)})
    return set_


EEVEE_ITEMS = (("FULL", "Full Layer", "EEVEE renders the layer's lobes as Cycles does (a "
                 "coated layer is noisy at few TAA samples)"),
               ("AUTO", "Simplify Where Noisy", "A folded EEVEE-only output where EEVEE would "
                "pick lobes at random (a Principled BSDF with a coat)"),
               ("ALWAYS", "Always Simplify", "A folded EEVEE-only output for any layer (one "
                "BSDF to shade in EEVEE)"))


def _get_eevee(self):
    mode = eevee_output.requested_mode(self.id_data)
    return {"auto": 1, "always": 2}.get(mode, 0)


def _set_eevee(self, value):
    mat = self.id_data
    try:
        if value == 0:
            eevee_output.remove_eevee_output(mat)
        else:
            eevee_output.add_eevee_output(mat, mode=("auto", "always")[value - 1])
        messages.clear_error(mat)
    except ValueError as exc:
        messages.set_error(mat, plain_message(exc))
        print(f"Hazy Gloss: {mat.name}: {messages.error_for(mat)}")


_NO_ANIM = set()  # rebuilding node trees per frame is not what anyone wants (and farms
#                   without the add-on would not do it): parameters are not animatable


class HazyGlossMaterialSettings(bpy.types.PropertyGroup):
    """Perceptual hazy-gloss parameters of a material (a view on mat["hazy_gloss"])"""

    kind: EnumProperty(name="Kind", items=KIND_ITEMS, get=_get_kind, set=_set_kind,
                       options=_NO_ANIM)
    distribution: EnumProperty(name="Distribution", items=DISTRIBUTION_ITEMS,
                               get=_get_distribution, set=_set_distribution, options=_NO_ANIM,
                               description="Microfacet distribution of both lobes")
    core_reflectivity: FloatVectorProperty(
        name="Core Reflectivity", subtype="COLOR", size=3, soft_min=0.0, soft_max=1.0,
        get=_get_rgb("core_reflectivity"), set=_set_rgb("core_reflectivity"), options=_NO_ANIM,
        description="r_c: reflectivity of the sharp core at normal incidence (linear RGB). "
                    "Haze never changes the brightness of the highlight's peak")
    edge_tint: FloatVectorProperty(
        name="Edge Tint", subtype="COLOR", size=3, soft_min=0.0, soft_max=1.0,
        get=_get_rgb("edge_tint"), set=_set_rgb("edge_tint"), options=_NO_ANIM,
        description="g: colour towards grazing angles (Gulbrandsen 2014); black = "
                    "dielectric-like Fresnel")
    roughness: FloatProperty(
        name="Roughness", min=0.0, max=1.0, subtype="FACTOR", precision=3,
        get=_get_float("roughness"), set=_set_float("roughness"), options=_NO_ANIM,
        description="Core roughness, Blender's convention R = √α (the paper's α_n is R²)")
    anisotropy: FloatProperty(
        name="Anisotropy", min=0.0, max=1.0, subtype="FACTOR",
        get=_get_float("anisotropy"), set=_set_float("anisotropy"), options=_NO_ANIM,
        description="Stretch of the core along the tangent (Metallic BSDF convention, "
                    "at most 10:1)")
    rotation: FloatProperty(
        name="Rotation", min=0.0, max=1.0, subtype="FACTOR",
        get=_get_float("rotation"), set=_set_float("rotation"), options=_NO_ANIM,
        description="Rotation of the tangent, in turns")
    tangent: EnumProperty(name="Tangent", items=TANGENT_ITEMS, get=_get_tangent,
                          set=_set_tangent, options=_NO_ANIM,
                          description="Tangent used by anisotropic lobes")
    haziness: FloatProperty(
        name="Haziness", min=0.0, max=K.MAX_HAZINESS, soft_min=0.0, soft_max=0.99, subtype="FACTOR",
        precision=3, get=_get_float("haziness"), set=_set_float("haziness"), options=_NO_ANIM,
        description="β_h: proportion of the halo the energy and positivity bounds allow. "
                    "About 0-0.1 for dielectrics, up to 0.99 for metals")
    haze_extent_x: FloatProperty(
        name="Haze Extent", min=0.0, max=1000.0, soft_max=20.0,
        get=_get_extent(0), set=_set_extent(0), options=_NO_ANIM,
        description="λ_h: width of the halo in units of the core's roughness "
                    "(α_w = α_n + λ_h √(α_n^x α_n^y)); along the tangent when unlinked")
    haze_extent_y: FloatProperty(
        name="Haze Extent Y", min=0.0, max=1000.0, soft_max=20.0,
        get=_get_extent(1), set=_set_extent(1), options=_NO_ANIM,
        description="λ_h^y: width of the halo across the tangent")
    haze_extent_linked: BoolProperty(
        name="Link Haze Extents", get=_get_linked, set=_set_linked, options=_NO_ANIM,
        description="One haze extent for both directions (isotropic halo)")
    use_smoothness: BoolProperty(
        name="Smooth Haze", get=_get_use_smooth, set=_set_use_smooth, options=_NO_ANIM,
        description="Use the rational Bézier mapping (Eqs. 12-15) instead of the piecewise "
                    "linear Eq. 7: no kink where r_c = p (useful with textured reflectivity)")
    smoothness: FloatProperty(
        name="Smoothness", min=K.MIN_SMOOTHNESS, max=1e6, soft_min=0.5, soft_max=16.0,
        get=_get_smoothness, set=_set_smoothness, options=_NO_ANIM,
        description="w: weight of the Bézier; larger is closer to Eq. 7, smaller is smoother "
                    "but reaches less haze")
    shader_mapping: BoolProperty(
        name="In-Shader Mapping", get=_get_bool("shader_mapping"), set=_set_bool("shader_mapping"),
        options=_NO_ANIM,
        description="Compute the mapping in the shader (a node group whose inputs take "
                    "textures) instead of constants computed here (leaner, faster to render)")
    base_color: FloatVectorProperty(
        name="Base Color", subtype="COLOR", size=3, soft_min=0.0, soft_max=1.0,
        get=_get_rgb("base_color"), set=_set_rgb("base_color"), options=_NO_ANIM,
        description="Diffuse colour under a dielectric's specular layer")
    transmission: FloatProperty(
        name="Transmission", min=0.0, max=1.0, subtype="FACTOR",
        get=_get_float("transmission"), set=_set_float("transmission"), options=_NO_ANIM,
        description="Transmission weight of a dielectric (the BTDF shares β, η and α)")
    # a haze layer on the user's Principled BSDF (Make Hazy)
    coat_haziness: FloatProperty(
        name="Coat Haziness", min=0.0, max=K.MAX_HAZINESS, soft_max=0.99, subtype="FACTOR",
        precision=3, get=_get_float("coat_haziness"), set=_set_float("coat_haziness"),
        options=_NO_ANIM,
        description="β_h of the coat: a halo around the clear coat's reflection (lacquer, "
                    "varnish, car paint), mapped on the coat's own Fresnel (Coat IOR); the "
                    "coat's peak stays")
    coat_haze_extent: FloatProperty(
        name="Coat Haze Extent", min=0.0, max=1000.0, soft_max=20.0,
        get=_get_float("coat_haze_extent"), set=_set_float("coat_haze_extent"), options=_NO_ANIM,
        description="λ_h of the coat: width of the coat's halo in units of the coat roughness")
    keep_body_colour: BoolProperty(
        name="Keep Body Colour", get=_get_bool("keep_body_colour"),
        set=_set_bool("keep_body_colour"), options=_NO_ANIM,
        description="Brighten the base colour under a hazy dielectric so that the diffuse "
                    "colour stays what it was (haze raises the reflectivity, which lets less "
                    "light reach the base); where a colour cannot get brighter, the rest is "
                    "reported")
    eevee_output: EnumProperty(
        name="EEVEE", items=EEVEE_ITEMS, get=_get_eevee, set=_set_eevee, options=_NO_ANIM,
        description="An EEVEE-only output with each layer's two lobes folded into one that keeps "
                    "its peak: noise-free EEVEE previews of a coated layer; Cycles renders the "
                    "full layer either way")
    # plain stored UI state
    edge_tint_memory: FloatVectorProperty(size=3, default=(0.0, 0.0, 0.0), options={"HIDDEN"})
    smoothness_memory: FloatProperty(default=2.0, min=K.MIN_SMOOTHNESS, options={"HIDDEN"})


#: Names of the parameter properties, in the order a preset sets them.
PRESET_PROPERTIES = ("kind", "distribution", "shader_mapping", "core_reflectivity", "edge_tint",
                     "roughness", "anisotropy", "rotation", "tangent", "haziness",
                     "haze_extent_linked", "haze_extent_x", "haze_extent_y", "use_smoothness",
                     "smoothness", "base_color", "transmission")
#: The properties a preset sets on a haze layer (Make Hazy): the core is the user's node.
LAYER_PRESET_PROPERTIES = ("haziness", "haze_extent_linked", "haze_extent_x", "haze_extent_y",
                           "use_smoothness", "smoothness", "coat_haziness", "coat_haze_extent",
                           "keep_body_colour")

classes = (HazyGlossMaterialSettings,)

register, unregister = bpy.utils.register_classes_factory(classes)


def attach():
    """Material.hazy_gloss_settings (after the PropertyGroup is registered)."""
    setattr(bpy.types.Material, PROPERTY_NAME, PointerProperty(type=HazyGlossMaterialSettings))


def detach():
    if hasattr(bpy.types.Material, PROPERTY_NAME):
        delattr(bpy.types.Material, PROPERTY_NAME)
    messages.last_error.clear()
    edit.forget_busy()
