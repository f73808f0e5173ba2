# SPDX-License-Identifier: GPL-3.0-or-later
"""bpy glue. Everything under here may import bpy."""
