# SPDX-License-Identifier: GPL-3.0-or-later
"""What the operators and the API do, as plain functions: Make Hazy (make_hazy), edits (edit,
sync), texture conversion (convert, convert_pbr), MaterialX/USD (interchange, and the USD
hook's work, usd_hook), looks, the EEVEE-only output (eevee_output), the command line's needs
(cli), messages to the user."""
