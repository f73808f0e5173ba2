# SPDX-License-Identifier: GPL-3.0-or-later
"""The core is usable without Blender: in a fresh interpreter where ``bpy`` (and Blender's
other modules) cannot be imported, ``import hazy_gloss`` and ``from hazy_gloss.core import
haze_mapping`` work, a call works, and nothing tries to import bpy on the way."""
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BLENDER_MODULES = ("bpy", "bmesh", "mathutils", "gpu", "bl_ui", "bl_operators", "bpy_extras",
                   "_bpy")

_PRELUDE = textwrap.dedent(f"""
    import importlib.abc, sys
    sys.path.insert(0, {str(ROOT)!r})
    BLOCKED = {BLENDER_MODULES!r}
    ATTEMPTS = []

    class BlockBlender(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in BLOCKED:
                ATTEMPTS.append(name)
                raise ImportError(f"blocked for the test: {{name}}")
            return None

    sys.meta_path.insert(0, BlockBlender())
    for m in list(sys.modules):
        if m.split(".")[0] in BLOCKED:
            del sys.modules[m]
""")


def _run(body, extra_path=None):
    env = None
    if extra_path is not None:
        import os
        env = dict(os.environ, PYTHONPATH=str(extra_path))
    proc = subprocess.run([sys.executable, "-c", body], capture_output=True, text=True,
                          timeout=120, env=env, cwd=str(ROOT))
    assert proc.returncode == 0, f"stdout:\n{proc.stdout}\nstderr:\n{proc.stderr}"
    return proc.stdout


def test_import_package_does_not_import_bpy():
    out = _run(_PRELUDE + textwrap.dedent("""
        import hazy_gloss
        assert not ATTEMPTS, ATTEMPTS
        assert not any(m.split(".")[0] in BLOCKED for m in sys.modules)
        # importing the package must not pull in the bpy glue either
        assert "hazy_gloss.blender" not in sys.modules, sorted(sys.modules)
        print("OK")
    """))
    assert out.strip().endswith("OK")


def test_core_works_without_bpy():
    out = _run(_PRELUDE + textwrap.dedent("""
        from hazy_gloss.core import haze_mapping, inverse_haze_mapping
        import numpy as np
        m = haze_mapping((0.9, 0.6, 0.3), 0.5, (0.02, 0.05), 0.3, 7.0, smoothness=4.0,
                         distribution="GGX")
        assert 0 < float(m.beta) < 1 and np.all(np.isfinite(m.ior))
        t = haze_mapping(np.full((4, 4, 3), 0.04), 0.0, 0.01, np.linspace(0, 0.9, 16).reshape(4, 4),
                         5.0, distribution="ASHIKHMIN_SHIRLEY")
        assert t.beta.shape == (4, 4)
        inv = inverse_haze_mapping(m.beta, (0.02, 0.05), m.alpha_wide, ior=m.ior,
                                   extinction=m.extinction, smoothness=4.0)
        assert abs(float(inv.haziness) - 0.3) < 1e-9
        assert not ATTEMPTS, ATTEMPTS
        assert not any(m.split(".")[0] in BLOCKED for m in sys.modules)
        assert "hazy_gloss.blender" not in sys.modules
        print("OK")
    """))
    assert out.strip().endswith("OK")


def test_core_works_with_a_poisoned_bpy_on_the_path(tmp_path):
    """Second mechanism: a fake ``bpy`` package first on sys.path that raises on import."""
    fake = tmp_path / "bpy"
    fake.mkdir()
    (fake / "__init__.py").write_text("raise RuntimeError('bpy must not be imported by the core')\n")
    (tmp_path / "mathutils.py").write_text("raise RuntimeError('mathutils must not be imported')\n")
    out = _run(textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(ROOT)!r})
        sys.path.insert(0, {str(tmp_path)!r})
        import hazy_gloss
        from hazy_gloss.core import haze_mapping
        assert float(haze_mapping(0.04, 0.0, 0.01, 0.1, 5.0).beta) > 0
        assert "bpy" not in sys.modules and "mathutils" not in sys.modules
        print("OK")
    """))
    assert out.strip().endswith("OK")


def test_blocker_really_blocks():
    """Guard: the meta-path blocker itself makes ``import bpy`` fail (so the tests above are
    meaningful even on a machine where a bpy wheel is installed)."""
    out = _run(_PRELUDE + textwrap.dedent("""
        try:
            import bpy  # noqa: F401
        except ImportError:
            print("BLOCKED")
    """))
    assert "BLOCKED" in out


@pytest.mark.parametrize("module", ["hazy_gloss.core", "hazy_gloss.core.mapping", "hazy_gloss.conversion.oiio",
                                    "hazy_gloss.conversion.imagecheck", "hazy_gloss.conversion.imagestream",
                                    "hazy_gloss.recomposite",
                                    "hazy_gloss.core.body_colour"])
def test_core_modules_have_no_blender_imports_in_source(module):
    """Static check: the core sources never mention an import of a Blender module."""
    import importlib
    import re
    mod = importlib.import_module(module)
    src = Path(mod.__file__).read_text(encoding="utf-8")
    pattern = r"^\s*(import|from)\s+(" + "|".join(BLENDER_MODULES) + r")\b"
    assert not re.search(pattern, src, re.MULTILINE)
