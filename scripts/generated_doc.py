# SPDX-License-Identifier: GPL-3.0-or-later
"""Write (or ``--check``) the generated block of a doc between its markers: what
scripts/architecture.py and scripts/parameter_table.py share."""
from __future__ import annotations

import sys


def render(text, block, begin, end, where):
    """``text`` with ``block`` between the markers (ValueError naming ``where`` when they are
    missing)."""
    i, j = text.find(begin), text.find(end)
    if i < 0 or j < i:
        raise ValueError(f"{where} has no '{begin}' ... '{end}' markers")
    return text[:i + len(begin)] + "\n" + block + "\n" + text[j:]


def write_or_check(doc, root, new_text, *, check, script, source):
    """Rewrite ``doc`` with ``new_text(old)``, or with ``check`` only compare (exit status 1 and
    one line naming what it is out of date with, ``source``)."""
    try:
        old = doc.read_text(encoding="utf-8")
        new = new_text(old)
    except (OSError, ValueError) as exc:
        print(f"{script}: {exc}", file=sys.stderr)
        return 1
    if check:
        if new != old:
            print(f"{doc.relative_to(root)} is out of date with {source}: run "
                  f"python scripts/{script}", file=sys.stderr)
            return 1
        return 0
    if new != old:
        doc.write_text(new, encoding="utf-8")
        print(f"wrote {doc.relative_to(root)}")
    return 0
