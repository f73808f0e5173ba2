# SPDX-License-Identifier: GPL-3.0-or-later
"""Moved to hazy_gloss.core.tables.bsdf_interfaces (this path warns, for one release)."""
from ._moved import moved

__getattr__ = moved(__name__, "hazy_gloss.core.tables.bsdf_interfaces")
