# SPDX-License-Identifier: GPL-3.0-or-later
"""The one registration point: each module lists its own ``classes`` and register/unregister."""
import importlib

# Order matters: properties before the operators and panels that use them.
_MODULE_NAMES = ("preferences", "properties", "operators", "convert", "composite_ops", "panels",
                 "menus")

_modules = []


def register():
    _modules.clear()
    for name in _MODULE_NAMES:
        mod = importlib.import_module(f"{__package__}.{name}")
        mod.register()
        _modules.append(mod)


def unregister():
    for mod in reversed(_modules):
        mod.unregister()
    _modules.clear()
