# SPDX-License-Identifier: GPL-3.0-or-later
"""Add-on preferences (Edit > Preferences > Add-ons > Hazy Gloss).

``bl_idname`` is the add-on's package (``bl_ext.<repo>.hazy_gloss`` when installed as an
extension).  When the package is registered by a script (``import hazy_gloss;
hazy_gloss.register()``) it is not an add-on, Blender stores no preferences for it, and
:func:`get` returns the defaults.
"""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty

from ... import constants as K
from .. import compat

__all__ = ("ADDON_PACKAGE", "HAZY_GLOSS_AP_preferences", "get", "register", "unregister", "classes")

ADDON_PACKAGE = compat.ADDON_PACKAGE

_KIND_TEXT = {"CONDUCTOR": "Metal", "DIELECTRIC": "Plastic, varnish",
              "LEGACY": "Glossy BSDF lobes without Fresnel"}
_KINDS = tuple((t.id, t.label, _KIND_TEXT[t.id]) for t in K.KIND_TERMS)


class HAZY_GLOSS_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_PACKAGE

    default_kind: EnumProperty(name="New Materials", items=_KINDS, default="CONDUCTOR",
                               description="Kind of material New Hazy Material creates")
    prefer_shader_mapping: BoolProperty(
        name="Prefer In-Shader Mapping", default=False,
        description="New and converted materials compute the mapping in the shader (ready for "
                    "textures). Off: constants computed by the add-on (leaner shaders); Make "
                    "Hazy still switches to in-shader mapping when the original had textures")
    show_plots: BoolProperty(name="Show Plots", default=True,
                             description="Draw the haze-intensity plot and the BRDF slice in "
                                         "the material panels")
    plot_log_scale: BoolProperty(name="Logarithmic BRDF Plot", default=True,
                                 description="BRDF slice on a log scale (off: linear, zoomed "
                                             "on the halo as in the paper's Figure 2)")
    plot_incidence: FloatProperty(name="Light Angle", default=0.0, min=0.0, max=80.0,
                                  subtype="NONE", precision=0,
                                  description="Angle of the light from the normal for the BRDF "
                                              "slice, in degrees (0: the halo vanishes exactly "
                                              "at the peak)")
    dielectric_warning: FloatProperty(
        name="Dielectric Warning", default=0.17, min=0.0, max=1.0,
        description="Warn when a dielectric's global reflectivity r exceeds this: it starts to "
                    "look like a metal (the paper's Discussion). Default: diamond's 0.17 "
                    "(IOR 2.42), the most reflective common dielectric")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        col = layout.column()
        col.prop(self, "default_kind")
        col.prop(self, "prefer_shader_mapping")
        col.separator()
        col.prop(self, "show_plots")
        sub = col.column()
        sub.active = self.show_plots
        sub.prop(self, "plot_log_scale")
        sub.prop(self, "plot_incidence")
        col.separator()
        col.prop(self, "dielectric_warning")


class _Defaults:
    """Stand-in with the defaults when no preferences are stored (script registration)."""

    def __getattr__(self, name):
        prop = HAZY_GLOSS_AP_preferences.__annotations__[name]
        return prop.keywords.get("default")


def get(context=None):
    context = context or bpy.context
    addon = context.preferences.addons.get(ADDON_PACKAGE)
    prefs = getattr(addon, "preferences", None) if addon is not None else None
    return prefs if prefs is not None else _Defaults()


classes = (HAZY_GLOSS_AP_preferences,)

register, unregister = bpy.utils.register_classes_factory(classes)
