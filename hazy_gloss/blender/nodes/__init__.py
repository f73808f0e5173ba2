# SPDX-License-Identifier: GPL-3.0-or-later
"""Node trees built from code: layout (builder), node math from core.graph (emit), the lobes
of Eq. 1 (lobes) and the perceptual shader groups (groups)."""
