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
from ...core.parameters import HAZE_DEFAULTS, HAZE_PARAMETERS, PARAMETERS, normalise
from ... import schema
from ...schema import LAYER, MATERIAL, SCHEMA, SCHEMA_BY_NAME, preset_properties, property_specs
from ..actions import edit, eevee_output, messages
from ..model import material, material_read
from ..actions.messages import plain_message

__all__ = ("PROPERTY_NAME", "GROUP_NODE", "NODE_DISTRIBUTIONS", "KIND_ITEMS", "operator_property",
           "settings", "has_hazy_nodes", "parameters", "stamp_problem", "begin_preset", "end_preset",
           "strict_settings", "EEVEE_ITEMS", "HazyGlossMaterialSettings", "PRESET_PROPERTIES",
           "LAYER_PRESET_PROPERTIES", "attach", "detach", "register", "unregister", "classes")

PROPERTY_NAME = "hazy_gloss_settings"
GROUP_NODE = material.GROUP_NODE
NODE_DISTRIBUTIONS = K.NODE_DISTRIBUTIONS

#: The kinds' enum items (constants' vocabulary; the property's are hazy_gloss.schema's).
KIND_ITEMS = K.enum_items(K.KIND_TERMS)
_KIND_IDS = list(K.KINDS)



# --------------------------------------------------------------------------------------------
# Reading and editing
# --------------------------------------------------------------------------------------------


def operator_property(prop, default, **keywords):
    """An operator's bpy property for the schema's parameter ``prop`` (schema.operator_property:
    the panel's label, range and tooltip), ``keywords`` overriding (the operator's own tooltip)."""
    ctor, kw = schema.operator_property(prop, default)
    return getattr(bpy.props, ctor)(**dict(kw, **keywords))


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


#: While a user preset runs (begin_preset .. end_preset): material session_uid -> (material,
#: the parameters it set that the material does not have).
_preset_run = None


def begin_preset():
    """A user preset starts: until :func:`end_preset` each material takes only what it has (a
    haze layer its haze, a whole hazy material no layer's own values) and the rest is noted, not
    refused once per value."""
    global _preset_run
    _preset_run = {}


def end_preset(name):
    """A user preset ended: each material that did not take all of it says so in one line (the
    panel's message, api.last_error, the console)."""
    global _preset_run
    run, _preset_run = _preset_run or {}, None
    for mat, left_out in run.values():
        if not left_out:
            continue
        labels = [SCHEMA_BY_NAME[k].label for k in left_out]
        listed = ", ".join(labels[:-1]) + " and " + labels[-1] if len(labels) > 1 else labels[0]
        why = ("a haze layer takes a preset's haze only; the rest is its BSDF node's"
               if parameters(mat).get("layered") else "they are a haze layer's own")
        msg = f"Preset “{name}”: {listed} {'were' if len(labels) > 1 else 'was'} not applied ({why})"
        messages.set_error(mat, msg)
        print(f"Hazy Gloss: {mat.name}: {msg}")


def _preset_filter(mat, changes):
    """The changes a running user preset may make to ``mat`` (the others are noted)."""
    if _preset_run is None:
        return changes
    _, left_out = _preset_run.setdefault(mat.session_uid, (mat, []))
    has = HAZE_PARAMETERS if parameters(mat).get("layered") else PARAMETERS
    left_out.extend(k for k in changes if k not in has and k not in left_out)
    return {k: v for k, v in changes.items() if k in has}


def _set(pg, **changes):
    """A setter: Blender prints and swallows exceptions raised in a property setter, so a
    refused change is recorded (``messages.last_error``, api.last_error) and collected by an open
    :func:`strict_settings` block, which raises when it closes."""
    mat = pg.id_data
    changes = _preset_filter(mat, changes)
    if not changes:
        return
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


def _get_enum(key, ids):
    def get(self):
        return _index(ids, parameters(self.id_data)[key])
    return get


def _set_enum(key, ids):
    def set_(self, value):
        _set(self, **{key: ids[value]})
    return set_


def _get_extent(key, axis):
    def get(self):
        return _finite(parameters(self.id_data)[key][axis], HAZE_DEFAULTS[key][axis])
    return get


def _set_extent(key, axis):
    def set_(self, value):
        x, y = parameters(self.id_data)[key]
        if getattr(self, f"{key}_linked"):
            x = y = float(value)
        elif axis == 0:
            x = float(value)
        else:
            y = float(value)
        _set(self, **{key: (x, y)})
    return set_


def _set_linked(key):
    def set_(self, value):
        self[f"{key}_linked_"] = bool(value)
        if value:  # linking makes the halo isotropic: y follows x
            x, y = parameters(self.id_data)[key]
            if x != y and material_read.is_hazy(self.id_data):
                _set(self, **{key: (x, x)})
    return set_


def _get_linked(key):
    """Linked when the user linked them (the default) and the extents are equal: a preset or a
    script that makes the halo anisotropic shows as unlinked."""
    def get(self):
        x, y = parameters(self.id_data)[key]
        return bool(self.get(f"{key}_linked_", True)) and x == y
    return get


def _get_use(key):
    """An optional parameter's toggle (smoothness: the Bézier on, None: Eq. 7)."""
    def get(self):
        return parameters(self.id_data)[key] is not None
    return get


def _set_use(key):
    def set_(self, value):
        w = parameters(self.id_data)[key]
        if bool(value) == (w is not None):
            return
        if value:
            _set(self, **{key: float(getattr(self, f"{key}_memory"))})
        else:
            setattr(self, f"{key}_memory", w)
            _set(self, **{key: None})
    return set_


def _get_optional(key):
    def get(self):
        w = parameters(self.id_data)[key]
        hi = SCHEMA_BY_NAME[key].limits[1]
        return min(_finite(w, hi), hi) if w is not None else float(getattr(self, f"{key}_memory"))
    return get


def _set_optional(key):
    def set_(self, value):
        if parameters(self.id_data)[key] is None:
            setattr(self, f"{key}_memory", float(value))
        else:
            _set(self, **{key: float(value)})
    return set_


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


_PROPS = {"EnumProperty": EnumProperty, "BoolProperty": BoolProperty,
          "FloatProperty": FloatProperty, "FloatVectorProperty": FloatVectorProperty}


def _accessors(name):
    """(get, set) of the panel property ``name`` of the schema's parameters."""
    if name == "kind":  # remembers the edge tint, picks a distribution the new kind's node has
        return _get_kind, _set_kind
    for p in SCHEMA:
        if p.type == "extent" and name in (f"{p.name}_x", p.more[0][0], p.more[1][0]):
            if name == p.more[1][0]:
                return _get_linked(p.name), _set_linked(p.name)
            axis = 0 if name == f"{p.name}_x" else 1
            return _get_extent(p.name, axis), _set_extent(p.name, axis)
        if p.default is None and p.more and name == p.more[0][0]:
            return _get_use(p.name), _set_use(p.name)
    p = SCHEMA_BY_NAME[name]
    if p.type == "enum":
        ids = [t.id for t in p.terms]
        return _get_enum(name, ids), _set_enum(name, ids)
    if p.type == "colour":
        return _get_rgb(name), _set_rgb(name)
    if p.type == "bool":
        return _get_bool(name), _set_bool(name)
    if p.default is None:
        return _get_optional(name), _set_optional(name)
    return _get_float(name), _set_float(name)


def _annotations():
    """The schema's properties (views on the stamp; hazy_gloss.schema.property_specs), the EEVEE
    setting, and the stored UI state (what a switch remembers)."""
    out = {}
    specs = property_specs()
    for name, ctor, kw in specs:
        if name.endswith("_memory"):
            continue
        get, set_ = _accessors(name)
        out[name] = _PROPS[ctor](**kw, get=get, set=set_, options=_NO_ANIM)
    out["eevee_output"] = EnumProperty(
        name="EEVEE", items=EEVEE_ITEMS, get=_get_eevee, set=_set_eevee, options=_NO_ANIM,
        description="An EEVEE-only output with each layer's two lobes folded into one that keeps "
                    "its peak: noise-free EEVEE previews of a coated layer; Cycles renders the "
                    "full layer either way")
    cap = SCHEMA_BY_NAME["reflectivity_cap"]  # a layer socket, not drawn here: for presets
    out[cap.name] = FloatProperty(
        name=cap.label, min=cap.limits[0], max=cap.limits[1], subtype="FACTOR",
        description=cap.sockets[0][1], get=_get_float(cap.name), set=_set_float(cap.name),
        options=_NO_ANIM)
    out["edge_tint_memory"] = FloatVectorProperty(size=3, default=(0.0, 0.0, 0.0),
                                                  options={"HIDDEN"})
    for name, ctor, kw in specs:
        if name.endswith("_memory"):
            out[name] = _PROPS[ctor](**kw, options={"HIDDEN"})
    return out


#: Perceptual hazy-gloss parameters of a material (a view on mat["hazy_gloss"]); built with
#: type() so that the annotations Blender registers are the generated ones in every Python.
HazyGlossMaterialSettings = type("HazyGlossMaterialSettings", (bpy.types.PropertyGroup,), {
    "__doc__": 'Perceptual hazy-gloss parameters of a material (a view on mat["hazy_gloss"])',
    "__module__": __name__, "__annotations__": _annotations()})


#: Names of the parameter properties, in the order a preset sets them.
PRESET_PROPERTIES = preset_properties(MATERIAL)
#: The properties a preset sets on a haze layer (Make Hazy): the core is the user's node.
LAYER_PRESET_PROPERTIES = preset_properties(LAYER) + ("reflectivity_cap",)

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
