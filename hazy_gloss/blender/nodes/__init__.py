# SPDX-License-Identifier: GPL-3.0-or-later
"""Node trees built from code: layout and socket helpers (builder), node math from core.graph
(emit), the lobes of Eq. 1 (lobes), which nodes are the add-on's (ownership)."""
