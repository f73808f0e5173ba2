# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy Gloss: artist control over hazy reflections (Barla, Pacanowski & Vangorp 2018).

Layout (in the spirit of glTF-Blender-IO: a bpy-free core beside the Blender half):
- bpy-free: ``constants.py`` and ``schema.py`` (the parameters), ``core/`` (the haze mapping,
  its node math, Multiscatter, thin film), ``conversion/`` (texture conversion, image files),
  ``recomposite.py``, ``node_layout.py``, ``interchange/`` (MaterialX, USD, other engines), ``utils/`` (presets,
  looks, plots).
- ``blender/``: everything that imports bpy, in layers that import downward: ``ui/``
  (operators, panels, registration), ``actions/`` (what they do), ``model/`` (hazy materials
  and their node groups), ``nodes/`` (tree builders), ``compat.py`` (Blender versions).
- ``api.py`` the scripting facade; ``__main__.py`` the command line.

docs/architecture.md has the map.  Importing this package does not import bpy; ``register()``
does.
"""


def register():
    from .blender.ui import registration
    registration.register()


def unregister():
    from .blender.ui import registration
    registration.unregister()
