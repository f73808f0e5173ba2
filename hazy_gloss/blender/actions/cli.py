# SPDX-License-Identifier: GPL-3.0-or-later
"""What the command line (``python -m hazy_gloss``, bpy-free) needs from Blender: importing this
module imports bpy, so ``from .blender.actions import cli`` failing with ImportError is "bpy is not
importable" (exit 3)."""
import os

import bpy

from ..model import material_read

__all__ = ("open_blend", "empty_file", "save_blend", "hazy_parameters")


def open_blend(path):
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path))


def empty_file():
    bpy.ops.wm.read_homefile(use_empty=True)


def save_blend(path, keep=()):
    """Save the open file as ``path``; datablocks in ``keep`` get a fake user (kept without an
    object using them).  Blender keeps the previous version as <name>.blend1."""
    for idblock in keep:
        idblock.use_fake_user = True
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(path))


def hazy_parameters():
    """({material name: perceptual parameters} of the open file's hazy materials made with New
    Hazy Material, {name: why skipped} of the others: haze layers on the artist's own BSDF,
    whose lobes are the BSDF's (engine fits are for the mapping's own lobes), and damaged ones)."""
    out, skipped = {}, {}
    for m in bpy.data.materials:
        try:
            p = material_read.read_parameters(m)
        except ValueError as exc:
            skipped[m.name] = str(exc)
            continue
        if p is not None and p.get("layered"):
            skipped[m.name] = material_read.engine_problem(m)
        elif p is not None:
            out[m.name] = p
    return out, skipped
