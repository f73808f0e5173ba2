# SPDX-License-Identifier: GPL-3.0-or-later
"""Generated data tables (numbers that are data, not code): Cycles' GGX and albedo tables, the
CIE 1931 colour matching functions, the BSDF nodes' socket declarations per Blender version.

The numbers are JSON files beside the modules (``<name>.json``: where they came from, their
licence, the data), written by the scripts under scripts/ that each module names; a module
only loads its file and gives the data the names the code uses. Do not edit the JSON by hand."""
from __future__ import annotations

import json
from pathlib import Path

_HERE = Path(__file__).resolve().parent


def load(name):
    """The data of ``<name>.json`` in this folder."""
    with open(path(name), encoding="utf-8") as fh:
        return json.load(fh)["data"]


def dumps(data, source, license):
    """The text of a table file, as the scripts write it: ``source`` (what wrote it, from what),
    ``license`` (of the data), ``data``; keys sorted, one value a line, no NaN or infinity."""
    doc = {"source": source, "license": license, "data": data}
    return json.dumps(doc, indent=1, sort_keys=True, ensure_ascii=False, allow_nan=False) + "\n"


def path(name):
    """Where ``<name>.json`` is (the scripts write and ``--check`` it)."""
    return _HERE / f"{name}.json"


def files():
    """Every table file, in name order (a cache of what the code builds from them hashes them)."""
    return sorted(_HERE.glob("*.json"))
