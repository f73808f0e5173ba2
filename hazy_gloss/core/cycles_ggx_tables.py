# SPDX-License-Identifier: GPL-3.0-or-later
"""Moved to hazy_gloss.core.tables.cycles_ggx_tables (this path warns, for one release)."""
from ._moved import moved

__getattr__ = moved(__name__, "hazy_gloss.core.tables.cycles_ggx_tables")
