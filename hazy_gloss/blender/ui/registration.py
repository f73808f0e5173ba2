# SPDX-License-Identifier: GPL-3.0-or-later
"""The one registration point.  Every module registers its classes with
``register, unregister = bpy.utils.register_classes_factory(classes)``; what is not a class
(the Material property, the plot previews, menu entries, the asset library) is added here, after
the classes, and removed first."""
from .. import compat
from . import (recomposite_ops, convert_ops, interchange_ops, menus, operators, panels, plots,
               preferences, properties, reports)
from ..actions import sync

__all__ = ("register", "unregister")

# Order matters: properties before the operators and panels that use them.
_MODULES = (preferences, properties, operators, convert_ops, recomposite_ops, interchange_ops,
            panels, menus)


def register():
    problem = compat.use_blenders_pxr()
    if problem:
        print(f"hazy_gloss: {problem}")
    for mod in _MODULES:
        mod.register()
    properties.attach()
    sync.register()
    plots.open_previews()
    menus.add_entries()
    try:
        menus.register_asset_library()
    except Exception as exc:  # the library is a convenience: never block enabling the add-on
        print(f"hazy_gloss: could not register the asset library: {exc!r}")


def unregister():
    menus.unregister_asset_library()
    menus.remove_entries()
    plots.close_previews()
    sync.unregister()
    properties.detach()
    for mod in reversed(_MODULES):
        mod.unregister()
    reports.last_reports.clear()
