# SPDX-License-Identifier: GPL-3.0-or-later
"""CIE 1931 2° standard observer colour matching functions x̄, ȳ, z̄ at 1 nm, 360 - 830 nm
(cie_1931.json, written by scripts/make_cie_cmf.py from colour-science; CIE 015 / CVRL data).
Used by core.thin_film to rebuild Cycles' thin-film sensitivity table."""
from . import load

__all__ = ("START_NM", "STEP_NM", "X_BAR", "Y_BAR", "Z_BAR")

_DATA = load("cie_1931")
START_NM = _DATA["start_nm"]
STEP_NM = _DATA["step_nm"]
X_BAR = tuple(_DATA["x_bar"])
Y_BAR = tuple(_DATA["y_bar"])
Z_BAR = tuple(_DATA["z_bar"])
