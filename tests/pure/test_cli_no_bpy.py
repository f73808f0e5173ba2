# SPDX-License-Identifier: GPL-3.0-or-later
"""Exit code 3 of ``python -m hazy_gloss convert`` with a real interpreter that has no bpy.

test_convert_pure.py blocks the bpy import inside this environment; here the CLI runs under
another Python of this machine (the system python3: no bpy, not even numpy), as a user who
forgot to install bpy would run it.  The other exit codes (0, 2, 130, 143) are tested in
tests/blender/test_convert_safety.py.
"""
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from hazy_gloss import constants as K

ROOT = Path(__file__).resolve().parents[2]


def _python_without_bpy():
    seen = set()
    for cand in ("/usr/bin/python3", shutil.which("python3"), "/usr/bin/python3.11",
                 "/usr/bin/python3.12", "/usr/bin/python3.13", shutil.which("python")):
        if not cand or cand in seen or not os.path.exists(cand):
            continue
        seen.add(cand)
        r = subprocess.run([cand, "-c", "import sys; assert sys.version_info >= (3, 9); "
                                        "import importlib.util as u; "
                                        "sys.exit(0 if u.find_spec('bpy') is None else 1)"],
                           capture_output=True, timeout=60)
        if r.returncode == 0:
            return cand
    return None


def test_cli_exits_3_under_a_python_without_bpy(tmp_path):
    py = _python_without_bpy()
    if py is None:
        pytest.skip("no Python without bpy on this machine (test_convert_pure.py covers exit 3 "
                    "by blocking the import)")
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTHONHOME", None)
    r = subprocess.run([py, "-m", "hazy_gloss", "convert", "--haziness", "h.png", "--out", "o"],
                       cwd=str(tmp_path), env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == K.EXIT_NO_BPY == 3, (py, r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hazy_gloss convert: error: bpy is not "
                                                   "importable"), r.stderr
    assert os.listdir(tmp_path) == []
    usage = subprocess.run([py, "-m", "hazy_gloss", "convert", "--bogus"], cwd=str(tmp_path),
                           env=env, capture_output=True, text=True, timeout=120)
    assert usage.returncode == K.EXIT_BAD_INPUT == 2
    assert len(usage.stderr.strip().splitlines()) == 1


def test_exit_codes_are_documented():
    doc = (ROOT / "docs" / "textures.md").read_text()
    main_doc = (ROOT / "hazy_gloss" / "__main__.py").read_text()
    for code in (K.EXIT_OK, K.EXIT_BAD_INPUT, K.EXIT_NO_BPY, *K.EXIT_INTERRUPTED.values()):
        assert f"**{code}**" in doc, code
        assert f"{code}" in main_doc, code
