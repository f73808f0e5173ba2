# SPDX-License-Identifier: GPL-3.0-or-later
"""Write docs/parameters.md's tables from the one parameter schema (hazy_gloss/schema.py).

    python scripts/parameter_table.py [--check]

Three tables, each between its markers (the text around them is hand-written and left alone):
the controls of a hazy material, those of a haze layer, and the words of kinds, distributions
and tangents (constants.KIND_TERMS, ...).  Symbol, range, default and "what it does" come from
each :class:`hazy_gloss.schema.Parameter`; change them there, never in the doc.

``--check``: write nothing, exit 1 with a one-line reason when the file differs from what would
be written (tests/pure/test_docs_generated.py runs it).
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from hazy_gloss import constants as K  # noqa: E402  (bpy-free, numpy-free)
from hazy_gloss import schema as S  # noqa: E402

sys.path.insert(0, str(ROOT / "scripts"))
import generated_doc  # noqa: E402

DOC = ROOT / "docs" / "parameters.md"
BLOCKS = ("parameters", "haze parameters", "vocabulary")


def markers(block):
    return (f"<!-- {block}: begin (scripts/parameter_table.py) -->", f"<!-- {block}: end -->")


def _num(x):
    return f"{x:g}"


def _kinds(kinds):
    return ", ".join(K.label(K.KIND_TERMS, k).lower() for k in kinds)


def range_text(p):
    """The "range" column: what the API accepts (and the slider's range, where it has one)."""
    if p.type == "enum":
        return ", ".join(f"{t.label} (`{t.id}`" + (f"; {_kinds(t.kinds)}" if t.kinds and
                                                     set(t.kinds) != set(K.KINDS) else "") + ")"
                         for t in p.terms)
    if p.type == "bool":
        return "True / False"
    lo, hi = p.range
    if p.type == "colour":
        text = f"linear RGB, [{_num(lo)}, {_num(hi)}]"
    elif math.isinf(lo) and hi is not None and math.isinf(hi):
        text = "any finite number"
    elif hi is None or math.isinf(hi):
        text = f"≥ {_num(lo)}"
    else:
        text = f"[{_num(lo)}, {_num(hi)}]"
    if p.type == "extent":
        text += ", or (x, y)"
    if p.default is None:
        text += ", or None"
    if p.soft is not None and p.type != "colour":
        smin = p.soft[0] if p.soft[0] is not None else p.limits[0]
        text += f"; slider {_num(smin)}-{_num(p.soft[1])}"
    if p.range_note:
        text += f"; {p.range_note}"
    return text


def default_text(value):
    if value is None or isinstance(value, bool):
        return str(value)
    if isinstance(value, str):
        return f"`{value}`"
    if isinstance(value, tuple):
        return "(" + ", ".join(_num(v) for v in value) + ")"
    return _num(value)


def control_text(p):
    kinds = f", {_kinds(p.kinds)}" if set(p.kinds) != set(K.KINDS) else ""
    return f"{p.label} (`{p.name}`{kinds})"


def table(where):
    layer = where == S.LAYER
    rows = ["| control (API keyword) | symbol | range | default | what it does |",
            "|---|---|---|---|---|"]
    for p in S.SCHEMA:
        if not (p.on_layer if layer else p.on_material):
            continue
        default = p.haze_default if layer else p.default
        what = (p.doc_layer or p.doc) if layer else p.doc
        rows.append(f"| {control_text(p)} | {p.symbol} | {range_text(p)} | "
                    f"{default_text(default)} | {what} |")
    return "\n".join(rows)


def vocabulary():
    rows = ["| word | value (`id`) | label | what it means |", "|---|---|---|---|"]
    for word, terms in (("kind", K.KIND_TERMS), ("distribution", K.DISTRIBUTION_TERMS),
                        ("tangent", K.TANGENT_TERMS)):
        for t in terms:
            rows.append(f"| {word} | `{t.id}` | {t.label} | {t.description} |")
    return "\n".join(rows)


def blocks():
    return {"parameters": table(S.MATERIAL), "haze parameters": table(S.LAYER),
            "vocabulary": vocabulary()}


def render(text, generated):
    """``text`` with each block between its markers (ValueError when some are missing)."""
    for block, body in generated.items():
        text = generated_doc.render(text, body, *markers(block), DOC.relative_to(ROOT))
    return text


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true",
                    help="exit 1 when docs/parameters.md differs from what would be written")
    args = ap.parse_args(argv)
    return generated_doc.write_or_check(DOC, ROOT, lambda old: render(old, blocks()),
                                        check=args.check, script="parameter_table.py",
                                        source="hazy_gloss/schema.py")


if __name__ == "__main__":
    sys.exit(main())
