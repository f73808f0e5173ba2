# SPDX-License-Identifier: GPL-3.0-or-later
"""The generated data tables (hazy_gloss/core/tables/*.json): each is in the form its script
writes (so a hand edit shows), has its loader module, and the Cycles tables are what the bpy
wheels hold now (the extractors' ``--check``, which read the wheels as ELF files, no bpy)."""
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from hazy_gloss.core import tables

ROOT = Path(__file__).resolve().parents[2]
FILES = tables.files()


def _numbers(obj):
    if isinstance(obj, dict):
        for v in obj.values():
            yield from _numbers(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _numbers(v)
    elif isinstance(obj, float):
        yield obj


def test_every_table_has_its_loader():
    assert {p.stem for p in FILES} == {"bsdf_interfaces", "cie_1931", "cycles_albedo_tables",
                                       "cycles_ggx_tables"}
    for p in FILES:
        assert p.with_suffix(".py").exists(), p.name


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.stem)
def test_table_file_is_as_written(path):
    text = path.read_text(encoding="utf-8")
    doc = json.loads(text)
    assert set(doc) == {"source", "license", "data"}, path.name
    assert doc["source"].startswith("scripts/"), doc["source"]
    assert all(math.isfinite(x) for x in _numbers(doc["data"]))
    assert tables.dumps(doc["data"], doc["source"], doc["license"]) == text, \
        f"{path.name} is not in its script's form (edited by hand?)"


def test_dumps_refuses_non_finite_numbers():
    with pytest.raises(ValueError):
        tables.dumps({"x": [1.0, float("nan")]}, "scripts/x.py", "none")


@pytest.mark.parametrize("script", ["extract_ggx_tables.py", "extract_albedo_tables.py"])
def test_cycles_tables_match_the_wheels(script):
    missing = [w for w in (".venv", ".venv52", ".venv45") if not (ROOT / w).exists()]
    if missing:
        pytest.skip(f"no {', '.join(missing)} (scripts/setup.sh makes them)")
    run = subprocess.run([sys.executable, str(ROOT / "scripts" / script), "--check"],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "up to date" in run.stdout
