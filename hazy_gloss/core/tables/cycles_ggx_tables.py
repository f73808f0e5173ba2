# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: Blender Foundation (Cycles, intern/cycles/scene/shader.tables)
"""Cycles' Multiscatter GGX albedo tables, as far as the hazy gloss peak needs them
(cycles_ggx_tables.json, read from the bpy wheels' ccl::table_ggx_E and ccl::table_ggx_Eavg by
scripts/extract_ggx_tables.py, which says how they were read and checked; Cycles data, Apache
License 2.0).

Roughness index x = R = (α_x α_y)^¼ at the nodes i/31, i = 0..31.
- E_MU1: E(μ = 1, R), the single-scatter GGX albedo for a view along the normal: the last row of
  the 32 x 32 table_ggx_E, bit-identical in every version (the other rows are on different μ
  grids in 4.5/5.2 and 5.3 and are not shipped: the peak is seen along the normal).
- EAVG_V4 (Blender 4.5 - 5.2) and EAVG_V53 (5.3): table_ggx_Eavg, E_avg(R) = ∫ 2μ E(μ, R) dμ
  (the two generations differ by about 1e-6).
"""
from . import load

__all__ = ("E_MU1", "EAVG_V4", "EAVG_V53")

_DATA = load("cycles_ggx_tables")
E_MU1 = tuple(_DATA["E_MU1"])
EAVG_V4 = tuple(_DATA["EAVG_V4"])
EAVG_V53 = tuple(_DATA["EAVG_V53"])
