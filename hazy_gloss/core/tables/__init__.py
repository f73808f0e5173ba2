# SPDX-License-Identifier: GPL-3.0-or-later
"""Generated data tables (numbers that are data, not code): Cycles' GGX and albedo tables, the
CIE 1931 colour matching functions, the BSDF nodes' socket declarations per Blender version.
Each module names the script under scripts/ that writes it; do not edit them by hand."""
