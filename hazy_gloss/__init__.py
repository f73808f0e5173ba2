# SPDX-License-Identifier: GPL-3.0-or-later
"""Hazy Gloss: artist control over hazy reflections (Barla, Pacanowski & Vangorp 2018).

Layout (in the spirit of glTF-Blender-IO):
- ``core/``      bpy-free numpy: the haze mapping and its inverse.
- ``utils/``     bpy-free helpers (BRDF evaluation for plots and checks).
- ``node_groups/`` builds the Cycles/EEVEE shader node groups (bpy).
- ``blender/``   thin bpy glue: version compatibility, properties, operators, panels.
- ``api.py``     the scripting API used by operators, tests and pipelines.

Importing this package does not import bpy; ``register()`` does.
"""


def register():
    from .blender.ui import registration
    registration.register()


def unregister():
    from .blender.ui import registration
    registration.unregister()
