# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: Blender Foundation (Cycles, intern/cycles/scene/shader.tables)
"""Cycles' tables behind the layering albedo of the Principled dielectric specular
(cycles_albedo_tables.json, read from the bpy wheels by scripts/extract_albedo_tables.py, which
says how they were read and checked; hazy_gloss/core/body_colour.py says how Cycles uses them;
Cycles data, Apache License 2.0).

Every table is a string of integer millionths, one table row a line: value = n / 10^6,
rounded to float32 (bit-exactly Cycles' value).  Layout as in the kernel: row-major,
roughness index x fastest.
- IOR_S_V4 (Blender 4.5, 5.2): ggx_gen_schlick_ior_s, 16 x 16 x 16 [z][y][x],
  x = R = (α_x α_y)^¼, y = μ, z = F0(η)^¼ at the nodes i/15.
- IOR_S_V53 (5.3): the same quantity at 32 x 32 x 32 nodes i/31, y = √μ.
- E_V4 (4.5, 5.2) and E_V53 (5.3): ggx_E, 32 x 32 [y][x], single-scatter GGX albedo,
  y = μ (V4) or √μ (V53).
- GLASS_E_MU1_V4 (16 x 16) and GLASS_E_MU1_V53 (32 x 32): ggx_glass_E at μ = 1 (its last
  y row), [z][x]: the single-scatter albedo, reflection plus refraction, of a GGX glass
  closure seen along the normal, z = F0(η)^¼ (the Multiscatter GGX glass energy factor).
"""
from . import load

__all__ = ("IOR_S_V4", "IOR_S_V53", "E_V4", "E_V53", "GLASS_E_MU1_V4", "GLASS_E_MU1_V53")

_DATA = load("cycles_albedo_tables")
IOR_S_V4 = "\n".join(_DATA["IOR_S_V4"])
IOR_S_V53 = "\n".join(_DATA["IOR_S_V53"])
E_V4 = "\n".join(_DATA["E_V4"])
E_V53 = "\n".join(_DATA["E_V53"])
GLASS_E_MU1_V4 = "\n".join(_DATA["GLASS_E_MU1_V4"])
GLASS_E_MU1_V53 = "\n".join(_DATA["GLASS_E_MU1_V53"])
