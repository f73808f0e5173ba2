# SPDX-License-Identifier: GPL-3.0-or-later
"""Write the CIE 1931 2° colour matching functions that core.thin_film needs, once.

    python scripts/make_cie_cmf.py [--check]

writes ``hazy_gloss/core/tables/cie_1931.json`` (``--check``: compare with it, exit 1 if it differs).
Needs the ``colour-science`` package (PyPI, BSD-3-Clause; a development tool only, never a
dependency of the add-on): ``pip install colour-science`` into any Python 3 environment.

Source.  ``colour.colorimetry.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]``: the CIE 1931
2° standard observer x̄, ȳ, z̄ at 1 nm from 360 to 830 nm (CIE 015 / CVRL table).  Cycles'
``intern/cycles/doc/precompute/thin_film_table.py`` embeds the same table (8 of its 1413
numbers rounded to 7 significant digits, differences <= 5e-13) padded with zero rows at 359 and
831 nm; the zero padding is added in core.thin_film, not stored here.  The table Cycles builds
from it, ``ccl::table_thin_film_cmf``, is reproduced bit-exactly by core.thin_film from this
data (checked against the bpy wheels in tests/blender/test_thin_film.py).
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from hazy_gloss.core import tables  # noqa: E402  (the table files' one writer)

OUT = tables.path("cie_1931")
NAME = "CIE 1931 2 Degree Standard Observer"


def load():
    warnings.filterwarnings("ignore")  # colour warns about optional plotting packages
    import colour
    cmfs = colour.colorimetry.MSDS_CMFS[NAME]
    wl = [float(w) for w in cmfs.wavelengths]
    if wl[0] != 360.0 or wl[-1] != 830.0 or len(wl) != 471:
        raise SystemExit(f"unexpected wavelength grid {wl[0]}..{wl[-1]} ({len(wl)})")
    return [[float(v) for v in col] for col in cmfs.values.T], colour.__version__


def render(columns, version):
    data = {"start_nm": 360, "step_nm": 1,
            "x_bar": columns[0], "y_bar": columns[1], "z_bar": columns[2]}
    return tables.dumps(data, f'scripts/make_cie_cmf.py from colour-science {version} '
                        f'(MSDS_CMFS["{NAME}"]; CIE 015 / CVRL data)', "GPL-3.0-or-later")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--check", action="store_true", help="compare with the committed table")
    args = ap.parse_args(argv)
    text = render(*load())
    if args.check:
        same = OUT.exists() and OUT.read_text(encoding="utf-8") == text
        print(f"{OUT.relative_to(ROOT)}: {'up to date' if same else 'DIFFERS'}")
        return 0 if same else 1
    OUT.write_text(text, encoding="utf-8")
    print(f"wrote {OUT.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
