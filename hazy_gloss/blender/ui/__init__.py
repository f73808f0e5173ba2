# SPDX-License-Identifier: GPL-3.0-or-later
"""What the artist sees: operators (thin: they call actions/), panels, menus, properties,
preferences, plots, and the one registration point (registration)."""
