# SPDX-License-Identifier: GPL-3.0-or-later
"""Shader node groups generated from code (imported as ``hazy_gloss.node_groups``)."""
