# SPDX-License-Identifier: GPL-3.0-or-later
"""The artist's operators (all ``hazy_gloss.*``, undoable, reporting in plain words).

- ``make_hazy``: a haze layer on the active material's own Principled / Metallic / Glossy BSDF
  (blender.model.layer): the node and everything else in the tree stay; ``remove_haze`` takes the
  layer off again.
- ``new_material``: a new hazy material (optionally from a preset) on the active object.
- ``apply_preset``: the paper's Table 3 and figure examples; ``preset_add`` saves / removes
  user presets the Blender way (AddPresetBase, listed in the preset menu).
- ``import_two_lobe_mix``: a Mix Shader of two Glossy or two Metallic lobes -> perceptual
  parameters (core.inverse_haze_mapping), with a report of what is not exactly representable.
- ``plot_to_image``: the panel's plots as float images (hidden data-blocks, never saved).

Every operator takes an optional ``material`` name (scripts, tests); by default it acts on the
material shown in the Properties editor / Shader Editor, else the active object's material.
Reports are also appended to :data:`reports.last_reports` (tests, scripts).  The operators have no
context poll (Blender polls cannot see the ``material`` property); they check in execute() and
report in plain words.
"""
import bpy
from bl_operators.presets import AddPresetBase
from bpy.props import BoolProperty, EnumProperty, StringProperty

from ... import constants as K
from ...core.parameters import HAZE_PARAMETERS, PARAMETERS
from ...schema import SCHEMA_BY_NAME
from ...utils import looks, presets
from ..actions import edit
from ..model import layer, material, material_read, stamp
from . import plots, preferences, properties
from .context import PRESET_SUBDIR, no_material, target_material
from ..actions.looks import create_look
from ..actions.messages import plain_message
from .reports import finish, report
from ..actions.make_hazy import (CORE_NODES, add_haziness_map, import_two_lobe_mix, make_hazy,
                                 remove_haze, upgrade_layers)

__all__ = ("HAZY_GLOSS_OT_make_hazy", "HAZY_GLOSS_OT_remove_haze", "HAZY_GLOSS_OT_upgrade_layers",
           "HAZY_GLOSS_OT_add_haziness_map", "HAZY_GLOSS_OT_import_two_lobe_mix", "assign_to_object",
           "HAZY_GLOSS_OT_new_material", "HAZY_GLOSS_OT_apply_preset", "HAZY_GLOSS_OT_preset_add",
           "HAZY_GLOSS_OT_plot_to_image", "register", "unregister", "classes")

_MATERIAL_PROP = dict(name="Material", default="", options={"HIDDEN", "SKIP_SAVE"},
                      description="Act on this material (default: the active one)")


# --------------------------------------------------------------------------------------------
# Operators
# --------------------------------------------------------------------------------------------


class HAZY_GLOSS_OT_make_hazy(bpy.types.Operator):
    """Put a haze layer on the material's own Principled, Metallic or Glossy BSDF: every input,
    link and layer of it stays; at haziness 0 it renders exactly as before"""

    bl_idname = "hazy_gloss.make_hazy"
    bl_label = "Make Hazy"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(**_MATERIAL_PROP)
    haziness: properties.operator_property(
        "haziness", 0.0, description="Haziness to start with (0: renders exactly as before)")
    haze_extent: properties.operator_property("haze_extent_x", 5.0)
    node: StringProperty(name="Node", default="", options={"SKIP_SAVE"},
                         description="The BSDF to put the layer on (default: the active node of "
                                     "the Shader Editor if it is one, else the BSDF closest to "
                                     "the Material Output)")

    def execute(self, context):
        mat = target_material(context, self.material)
        if mat is None:
            report(self, "ERROR", no_material(context, self.material))
            return {"CANCELLED"}
        node = self.node or None
        active = getattr(context, "active_node", None)
        if node is None and active is not None and getattr(active, "id_data", None) == mat.node_tree \
                and active.bl_idname in CORE_NODES and not material.is_ours(active):
            node = active.name
        given = {k: getattr(self, k) for k in ("haziness", "haze_extent")
                 if self.properties.is_property_set(k)}  # (a layer keeps what is not given)
        return finish(self, *make_hazy(mat, node=node, **given))


class _OneMaterialOperator:
    """An undoable operator on one material (``material`` by name, else the context's):
    ``apply(mat)`` does the work and returns what :func:`reports.finish` reports."""
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        mat = target_material(context, self.material)
        if mat is None:
            report(self, "ERROR", no_material(context, self.material))
            return {"CANCELLED"}
        return finish(self, *self.apply(mat))


class HAZY_GLOSS_OT_remove_haze(_OneMaterialOperator, bpy.types.Operator):
    """Take the haze layer off: the material's BSDF gets its own values and links back"""

    bl_idname = "hazy_gloss.remove_haze"
    bl_label = "Remove Haze"
    material: StringProperty(**_MATERIAL_PROP)

    def apply(self, mat):
        return remove_haze(mat)


class HAZY_GLOSS_OT_upgrade_layers(bpy.types.Operator):
    """Move haze layer nodes whose group another Blender or an earlier Hazy Gloss made to this
    one's group (the first haze change of such a layer does it too)"""

    bl_idname = "hazy_gloss.upgrade_layers"
    bl_label = "Upgrade Haze Layers"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(**_MATERIAL_PROP)

    def execute(self, context):
        if self.material:
            mat = bpy.data.materials.get(self.material)
            if mat is None:
                report(self, "ERROR", no_material(context, self.material))
                return {"CANCELLED"}
            return finish(self, *upgrade_layers([mat]))
        return finish(self, *upgrade_layers(list(bpy.data.materials), every=True))


class HAZY_GLOSS_OT_add_haziness_map(_OneMaterialOperator, bpy.types.Operator):
    """Link a new paintable image to the haze layer's Haziness (or Coat Haziness), filled with
    its current value and made the active Texture Paint slot"""

    bl_idname = "hazy_gloss.add_haziness_map"
    bl_label = "Add Haziness Map"

    material: StringProperty(**_MATERIAL_PROP)
    target: EnumProperty(name="Input", items=(("haziness", "Haziness", "The base's haziness"),
                                              ("coat_haziness", "Coat Haziness", "The coat's")))
    size: bpy.props.IntProperty(name="Size", default=1024, soft_min=16, soft_max=16384,
                                description="Width and height of the map in pixels, 16 to 16384 "
                                            "(a size outside is refused, not clamped)")

    def apply(self, mat):
        return add_haziness_map(mat, size=self.size, param=self.target)


class HAZY_GLOSS_OT_import_two_lobe_mix(_OneMaterialOperator, bpy.types.Operator):
    """Read a Mix Shader of two Glossy or two Metallic BSDFs as a hazy material (the inverse
    haze mapping): the sharper lobe becomes the core, the other the halo"""

    bl_idname = "hazy_gloss.import_two_lobe_mix"
    bl_label = "Import Two-Lobe Mix"
    material: StringProperty(**_MATERIAL_PROP)

    def apply(self, mat):
        return import_two_lobe_mix(mat)


_KIND_ITEMS = [("DEFAULT", "Default", "The kind set in the add-on preferences")] + [
    (k, n, d) for k, n, d, _ in properties.KIND_ITEMS]
_KIND_LABELS = {k: n for k, n, _d, _i in properties.KIND_ITEMS}
_PRESET_ITEMS = [("NONE", "None", "Default parameters")] + looks.enum_items() + presets.enum_items()


def assign_to_object(obj, mat):
    """Put ``mat`` in the active slot of ``obj`` (adding a slot when there is none)."""
    if obj is None or not hasattr(obj.data, "materials"):
        return False
    if len(obj.material_slots) == 0:
        obj.data.materials.append(mat)
    else:
        obj.material_slots[obj.active_material_index].material = mat
    return True


class HAZY_GLOSS_OT_new_material(bpy.types.Operator):
    """Create a new hazy material and put it in the active object's active slot"""

    bl_idname = "hazy_gloss.new_material"
    bl_label = "New Hazy Material"
    bl_options = {"REGISTER", "UNDO"}

    name: StringProperty(name="Name", default="Hazy Gloss")
    kind: EnumProperty(name="Kind", items=_KIND_ITEMS, default="DEFAULT")
    preset: EnumProperty(name="Preset", items=_PRESET_ITEMS, default="NONE")
    assign: BoolProperty(name="Assign", default=True, options={"SKIP_SAVE"},
                         description="Put the material in the active object's active slot")

    def execute(self, context):
        prefs = preferences.get(context)
        if self.preset in looks.LOOKS:  # a Principled material with its haze layer
            try:
                mat = create_look(self.preset, self.name if self.name != "Hazy Gloss" else None)
            except ValueError as exc:
                report(self, "ERROR", plain_message(exc))
                return {"CANCELLED"}
            obj = getattr(context, "object", None)
            if self.assign and obj is not None and obj.library is None:
                assign_to_object(obj, mat)
            report(self, "INFO", f"New “{mat.name}”: a Principled BSDF with a haze layer")
            if self.kind != "DEFAULT":  # a look's BSDF is metal or not by its Metallic
                report(self, "WARNING", f"Kind does not apply to the look “{mat.name}”: set "
                       f"Metallic on its Principled BSDF instead")
            return {"FINISHED"}
        note = ""
        if self.preset != "NONE":
            p = presets.parameters(self.preset)
        else:
            p = {"kind": prefs.default_kind if self.kind == "DEFAULT" else self.kind}
            if p["kind"] == "DIELECTRIC":
                p.update(core_reflectivity=0.04, haziness=0.1, base_color=(0.05, 0.05, 0.05))
        if self.kind != "DEFAULT":
            if self.preset != "NONE" and p["kind"] != self.kind:
                note = self._other_kind(p, self.kind)
            p["kind"] = self.kind
            if p.get("distribution", "GGX") not in K.NODE_DISTRIBUTIONS[self.kind]:
                p["distribution"] = "GGX"
        p["shader_mapping"] = bool(prefs.prefer_shader_mapping)
        try:
            mat = material.create_material(self.name or "Hazy Gloss", **p)
        except ValueError as exc:
            report(self, "ERROR", plain_message(exc))
            return {"CANCELLED"}
        obj = getattr(context, "object", None)
        where = ""
        data = getattr(obj, "data", None)
        if self.assign and obj is not None and obj.library is None and \
                getattr(data, "library", None) is None:
            if assign_to_object(obj, mat):
                where = f" on “{obj.name}”"
        report(self, "INFO", f"New hazy {p['kind'].lower()} “{mat.name}”{where}")
        if note:
            report(self, "WARNING", note)
        return {"FINISHED"}

    def _other_kind(self, p, kind):
        """Drop the preset's values that ``kind`` has no control for (the API refuses them);
        the note names those that were not the default, as the panel labels them."""
        dropped = []
        for key in list(p):
            spec = SCHEMA_BY_NAME.get(key)
            if spec is not None and kind not in spec.kinds:
                value = p.pop(key)
                if value != spec.default:
                    dropped.append(spec.label)
        if not dropped:
            return ""
        name = presets.PRESETS[self.preset].name
        return (f"“{name}” is a {_KIND_LABELS[p['kind']]} preset: its "
                f"{' and '.join(dropped)} {'is' if len(dropped) == 1 else 'are'} left out (a "
                f"{_KIND_LABELS[kind]} has none)")


class HAZY_GLOSS_OT_apply_preset(bpy.types.Operator):
    """Set the material's hazy parameters from a built-in preset (the paper's examples)"""

    bl_idname = "hazy_gloss.apply_preset"
    bl_label = "Apply Hazy Preset"
    bl_options = {"REGISTER", "UNDO"}

    preset: EnumProperty(name="Preset", items=looks.enum_items() + presets.enum_items())
    material: StringProperty(**_MATERIAL_PROP)

    @classmethod
    def description(cls, context, properties_):
        try:
            pid = properties_.preset
            return (looks.LOOKS[pid] if pid in looks.LOOKS else presets.PRESETS[pid]).description
        except (KeyError, AttributeError):
            return cls.__doc__

    def execute(self, context):
        mat = target_material(context, self.material)
        if mat is None:
            report(self, "ERROR", no_material(context, self.material))
            return {"CANCELLED"}
        if not material_read.is_hazy(mat):
            report(self, "ERROR", "The material is not hazy: use Make Hazy or New Hazy "
                   "Material first")
            return {"CANCELLED"}
        if self.preset in looks.LOOKS:
            if not layer.is_layered(mat):
                report(self, "ERROR", f"A look's haze goes on a haze layer: use Make Hazy on "
                       f"“{mat.name}” first, or New Hazy Material with the look")
                return {"CANCELLED"}
            p = dict(looks.LOOKS[self.preset].haze)
            p = dict(layer.HAZE, **{k: v for k, v in p.items()})  # every haze parameter set
        else:
            p = presets.parameters(self.preset)
        if layer.is_layered(mat):  # a layer takes the preset's haze; its core is the user's
            p = {k: v for k, v in p.items() if k in HAZE_PARAMETERS}
            for k in stamp.damaged_haze(layer.layer_state(mat)["problems"]):
                p.setdefault(k, layer.HAZE[k])  # a preset resets what does not read
        else:
            values, problems = stamp.read_material(mat)
            damaged = PARAMETERS if "*" in problems else problems
            defaults = material_read.tree_defaults(mat)
            for k in damaged:
                p.setdefault(k, defaults[k])
        _, msg = edit.edit_material(mat, **p)
        if msg:
            report(self, "ERROR", msg)
            return {"CANCELLED"}
        pre = looks.LOOKS.get(self.preset) or presets.PRESETS[self.preset]
        report(self, "INFO", f"Applied “{pre.name}” to “{mat.name}”")
        if getattr(pre, "notes", ""):
            report(self, "INFO", pre.notes)
        return {"FINISHED"}


class HAZY_GLOSS_OT_preset_add(AddPresetBase, bpy.types.Operator):
    """Save the material's hazy parameters as a preset (or remove the selected one)"""

    bl_idname = "hazy_gloss.preset_add"
    bl_label = "Add Hazy Gloss Preset"
    bl_options = {"REGISTER", "UNDO"}
    preset_menu = "HAZY_GLOSS_MT_presets"
    preset_subdir = PRESET_SUBDIR
    preset_defines = [
        "mat = getattr(bpy.context, 'material', None) or bpy.context.object.active_material",
        f"hazy = mat.{properties.PROPERTY_NAME}",
    ]
    @property
    def preset_values(self):
        """A haze layer's preset holds haze only (its core is the user's BSDF)."""
        names = properties.PRESET_PROPERTIES
        if layer.is_layered(target_material(bpy.context)):
            names = properties.LAYER_PRESET_PROPERTIES
        return [f"hazy.{name}" for name in names]

    @classmethod
    def poll(cls, context):
        mat = target_material(context)
        return mat is not None and material_read.is_hazy(mat)


class HAZY_GLOSS_OT_plot_to_image(bpy.types.Operator):
    """Write the material's haze plot and BRDF slice into float images (hidden data-blocks
    named “.Hazy Gloss …”, never saved) to inspect them in the Image Editor"""

    bl_idname = "hazy_gloss.plot_to_image"
    bl_label = "Plots to Images"
    bl_options = {"REGISTER", "UNDO"}

    material: StringProperty(**_MATERIAL_PROP)
    size: bpy.props.IntProperty(name="Size", default=512, min=64, max=2048)

    def execute(self, context):
        mat = target_material(context, self.material)
        if mat is None:
            report(self, "ERROR", no_material(context, self.material))
            return {"CANCELLED"}
        if not material_read.is_hazy(mat):
            report(self, "ERROR", "The material is not hazy")
            return {"CANCELLED"}
        if layer.is_layered(mat):
            report(self, "ERROR", f"“{mat.name}” is a haze layer on its own BSDF: its parts' "
                   f"values are in the panel (plots are drawn for hazy materials)")
            return {"CANCELLED"}
        problem = properties.stamp_problem(mat)
        if problem is not None:
            report(self, "ERROR", problem)
            return {"CANCELLED"}
        names = []
        try:
            plotted = plots.compute_plots(mat, preferences.get(context), size=self.size)
        except ValueError as exc:
            report(self, "ERROR", plain_message(exc))
            return {"CANCELLED"}
        for which, rgba in plotted.items():
            img = plots.plot_image(which, rgba)
            names.append(img.name)
        report(self, "INFO", "Plots written to " + ", ".join(f"“{n}”" for n in names))
        return {"FINISHED"}


classes = (
    HAZY_GLOSS_OT_make_hazy,
    HAZY_GLOSS_OT_remove_haze,
    HAZY_GLOSS_OT_upgrade_layers,
    HAZY_GLOSS_OT_add_haziness_map,
    HAZY_GLOSS_OT_import_two_lobe_mix,
    HAZY_GLOSS_OT_new_material,
    HAZY_GLOSS_OT_apply_preset,
    HAZY_GLOSS_OT_preset_add,
    HAZY_GLOSS_OT_plot_to_image,
)


register, unregister = bpy.utils.register_classes_factory(classes)
