# SPDX-License-Identifier: GPL-3.0-or-later
"""What the artist sees: operators (thin: they call actions/, or a model function where no action is needed), panels, menus, properties,
preferences, plots, and the one registration point (registration)."""
