# SPDX-License-Identifier: GPL-3.0-or-later
"""bpy-free helpers with their own plain unit tests."""
