# SPDX-License-Identifier: GPL-3.0-or-later
"""Everything that imports bpy, in layers that import only downward (docs/architecture.md):
ui/ -> actions/ -> model/ -> nodes/ -> compat.py, each free to use the bpy-free package."""
