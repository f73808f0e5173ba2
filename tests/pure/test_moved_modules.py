# SPDX-License-Identifier: GPL-3.0-or-later
"""Public paths stay or say (issue 23): a module that moved keeps its old import path for one
release, which warns once with the new path and gives the same objects.  Each case runs in a
fresh interpreter (a warning is issued at the first import only)."""
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MOVED = {"hazy_gloss.core.cie_1931": "hazy_gloss.core.tables.cie_1931",
         "hazy_gloss.core.cycles_ggx_tables": "hazy_gloss.core.tables.cycles_ggx_tables",
         "hazy_gloss.core.cycles_albedo_tables": "hazy_gloss.core.tables.cycles_albedo_tables",
         "hazy_gloss.core.bsdf_interfaces": "hazy_gloss.core.tables.bsdf_interfaces"}

MOVED_STEMS = {m.rpartition(".")[2] for m in MOVED}

_PROBE = """
import importlib, sys, warnings
old, new = sys.argv[1], sys.argv[2]
with warnings.catch_warnings(record=True) as seen:
    warnings.simplefilter("always")
    a = importlib.import_module(old)
    importlib.import_module(old)
b = importlib.import_module(new)
names = [n for n in vars(b) if not n.startswith("__")]
assert names, new
assert all(getattr(a, n) is getattr(b, n) for n in names), "different objects"
msgs = [str(w.message) for w in seen if issubclass(w.category, DeprecationWarning)]
print(len(msgs)); print(msgs[0] if msgs else "")
"""


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_path_warns_once_and_gives_the_same_objects(old):
    out = subprocess.run([sys.executable, "-c", _PROBE, old, MOVED[old]], cwd=ROOT,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    count, message = out.stdout.splitlines()[:2]
    assert count == "1"
    assert message == f"{old} moved to {MOVED[old]}; the old path goes in the next release"


def test_nothing_in_the_repository_imports_an_old_path():
    """The package, tests, scripts and benchmarks use the new paths (the Blender tests turn
    DeprecationWarning into an error)."""
    names = "|".join(m.rpartition(".")[2] for m in MOVED)
    old = re.compile(rf"core\.({names})\b|core import .*\b({names})\b|^from \.({names}) import",
                     re.M)
    found = []
    for folder in ("hazy_gloss", "tests", "scripts", "benchmarks", "node_groups"):
        for path in (ROOT / folder).rglob("*.py"):
            if path.name == "test_moved_modules.py" or path.parent == ROOT / "hazy_gloss" / "core" \
                    and path.stem in MOVED_STEMS:
                continue
            for m in old.finditer(path.read_text(encoding="utf-8")):
                found.append(f"{path.relative_to(ROOT)}: {m.group(0)}")
    assert not found, found
