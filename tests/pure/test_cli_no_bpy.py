# SPDX-License-Identifier: GPL-3.0-or-later
"""Exit code 3 of ``python -m hazy_gloss convert`` with a real interpreter that has no bpy.

test_convert_pure.py blocks the bpy import inside this environment; here the CLI runs under
this interpreter started without its site-packages (``-S``: no bpy, not even numpy), as a user
who forgot to install bpy would run it.  The other exit codes (0, 2, 130, 143) are tested in
tests/blender/test_convert_safety.py.
"""
import os
import subprocess
import sys
from pathlib import Path

from hazy_gloss import constants as K

ROOT = Path(__file__).resolve().parents[2]
#: this Python without site-packages: the standard library and PYTHONPATH only
BARE = [sys.executable, "-S"]


def test_cli_exits_3_under_a_python_without_bpy(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTHONHOME", None)
    probe = subprocess.run(BARE + ["-c", "import importlib.util as u; "
                                   "print(u.find_spec('bpy'), u.find_spec('numpy'))"],
                           env=env, capture_output=True, text=True, timeout=60)
    assert probe.stdout.split() == ["None", "None"], probe  # a Python without bpy indeed
    r = subprocess.run(BARE + ["-m", "hazy_gloss", "convert", "--haziness", "h.png", "--out", "o"],
                       cwd=str(tmp_path), env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == K.EXIT_NO_BPY == 3, (r.returncode, r.stderr)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hazy_gloss convert: error: bpy is not "
                                                   "importable"), r.stderr
    assert os.listdir(tmp_path) == []
    usage = subprocess.run(BARE + ["-m", "hazy_gloss", "convert", "--bogus"], cwd=str(tmp_path),
                           env=env, capture_output=True, text=True, timeout=120)
    assert usage.returncode == K.EXIT_BAD_INPUT == 2
    assert len(usage.stderr.strip().splitlines()) == 1


def test_exit_codes_are_documented():
    doc = (ROOT / "docs" / "textures.md").read_text()
    main_doc = (ROOT / "hazy_gloss" / "__main__.py").read_text()
    for code in (K.EXIT_OK, K.EXIT_BAD_INPUT, K.EXIT_NO_BPY, *K.EXIT_INTERRUPTED.values()):
        assert f"**{code}**" in doc, code
        assert f"{code}" in main_doc, code
