# SPDX-License-Identifier: GPL-3.0-or-later
"""The input sockets of the BSDF nodes a haze layer wraps, as Blender declares them (read through
Make Group in each supported Blender; bsdf_interfaces.json, written by
scripts/extract_bsdf_interfaces.py): per version (major.minor) and node kind, {socket name:
type, subtype, limits, default, hide_value, panel} and each panel's default_closed.
blender/model/layer_group.py builds the layer group's interface from it."""
from . import load

__all__ = ("TABLES",)

TABLES = load("bsdf_interfaces")
