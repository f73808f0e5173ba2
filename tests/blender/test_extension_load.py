# SPDX-License-Identifier: GPL-3.0-or-later
"""hazy_gloss loads as a Blender extension, as a plain package, and unloads cleanly."""
import os
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import addon_utils
import bpy
import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
PACKAGE_DIR = REPO_ROOT / "hazy_gloss"
ADDON_ID = "hazy_gloss"
MODULE_NAME = f"bl_ext.test_repo.{ADDON_ID}"

SUBPROCESS_TIMEOUT = 300


def _manifest():
    with open(REPO_ROOT / "blender_manifest.toml", "rb") as fh:
        return tomllib.load(fh)


def _subprocess_env(tmp_path):
    env = dict(os.environ)
    env["BLENDER_USER_RESOURCES"] = str(tmp_path / "user_resources")
    env.pop("PYTHONPATH", None)
    return env


def _run(script, tmp_path):
    path = tmp_path / "script.py"
    path.write_text(textwrap.dedent(script))
    proc = subprocess.run([sys.executable, str(path)], cwd=str(tmp_path), env=_subprocess_env(tmp_path),
                          capture_output=True, text=True, timeout=SUBPROCESS_TIMEOUT)
    assert proc.returncode == 0 and "RESULT OK" in proc.stdout, (
        f"exit {proc.returncode}\n--- stdout ---\n{proc.stdout[-4000:]}\n"
        f"--- stderr ---\n{proc.stderr[-4000:]}")
    return proc


def test_loaded_as_extension(addon_module, hg):
    assert addon_module.name == MODULE_NAME == "bl_ext.test_repo.hazy_gloss"
    assert MODULE_NAME in sys.modules
    assert hg is sys.modules[MODULE_NAME]
    assert hg.__name__ == MODULE_NAME
    assert addon_utils.check(MODULE_NAME) == (True, True)
    assert MODULE_NAME in bpy.context.preferences.addons
    # Our temp repository holds exactly one extension: the repo's package files (links) and
    # the top-level manifest, as scripts/build.py stages them.
    repo = next(r for r in bpy.context.preferences.extensions.repos if r.module == "test_repo")
    assert repo.enabled and repo.use_custom_directory
    assert os.listdir(repo.directory) == [ADDON_ID]
    assert os.path.realpath(hg.__file__) == os.path.realpath(PACKAGE_DIR / "__init__.py")
    # Blender read our manifest (it builds bl_info from blender_manifest.toml for extensions).
    manifest = _manifest()
    info = addon_utils.module_bl_info(hg)
    assert info["name"] == manifest["name"]
    assert tuple(info["version"]) == tuple(int(x) for x in manifest["version"].split("."))
    # Its subpackages load under the extension's name, from the extension directory (the
    # package symlinks such as node_groups -> ../node_groups resolve elsewhere: no realpath).
    ext_dir = os.path.join(repo.directory, ADDON_ID) + os.sep
    for name, mod in list(sys.modules.items()):
        if name.startswith(MODULE_NAME + ".") and getattr(mod, "__file__", None):
            assert os.path.abspath(mod.__file__).startswith(ext_dir), (name, mod.__file__)


def test_extension_does_not_import_top_level_package(tmp_path):
    """Loaded the extension way in a fresh process without the repo on sys.path, nothing may
    import ``hazy_gloss`` by its top-level name (absolute imports break installed extensions)."""
    script = f"""
        import os, sys, tempfile
        assert "bpy" not in sys.modules
        import bpy, addon_utils
        repo_dir = tempfile.mkdtemp(dir={str(tmp_path)!r})
        os.symlink({str(PACKAGE_DIR)!r}, os.path.join(repo_dir, {ADDON_ID!r}))
        bpy.context.preferences.use_preferences_save = False
        bpy.context.preferences.extensions.repos.new(
            name="Sub Repo", module="sub_repo", custom_directory=repo_dir, source="USER")
        errors = []
        mod = addon_utils.enable("bl_ext.sub_repo.{ADDON_ID}", default_set=True,
                                 handle_error=errors.append)
        assert mod is not None and not errors, errors
        assert addon_utils.check("bl_ext.sub_repo.{ADDON_ID}") == (True, True)
        leaked = sorted(n for n in sys.modules if n == {ADDON_ID!r} or n.startswith({ADDON_ID!r} + "."))
        assert not leaked, leaked
        addon_utils.disable("bl_ext.sub_repo.{ADDON_ID}", default_set=True)
        print("RESULT OK")
    """
    _run(script, tmp_path)


def test_plain_import_register_in_subprocess(tmp_path):
    """External scripts do ``import hazy_gloss; hazy_gloss.register()`` with the repo on sys.path."""
    script = f"""
        import sys
        sys.path.insert(0, {str(REPO_ROOT)!r})
        import bpy
        before = set(dir(bpy.types))
        import hazy_gloss
        assert hazy_gloss.__file__.startswith({str(REPO_ROOT)!r}), hazy_gloss.__file__
        hazy_gloss.register()
        registered = set(dir(bpy.types)) - before
        print("registered:", sorted(registered))
        hazy_gloss.unregister()
        assert set(dir(bpy.types)) == before, set(dir(bpy.types)) ^ before
        hazy_gloss.register()   # and again: unregister must leave it re-registrable
        hazy_gloss.unregister()
        print("RESULT OK")
    """
    _run(script, tmp_path)


def _ours(names):
    return {n for n in names if "hazy_gloss" in n.lower() or "hazygloss" in n.lower()}


def _rna_snapshot():
    """Every bpy.types name and every RNA property identifier of every type (catches leftover
    classes and leftover properties added to built-in types such as Material or Scene)."""
    names = frozenset(dir(bpy.types))
    props = {}
    for name in names:
        cls = getattr(bpy.types, name, None)
        rna = getattr(cls, "bl_rna", None)
        if rna is not None:
            props[name] = frozenset(p.identifier for p in rna.properties)
    return names, props


def _handler_counts():
    return {n: len(getattr(bpy.app.handlers, n)) for n in dir(bpy.app.handlers)
            if isinstance(getattr(bpy.app.handlers, n, None), list)}


def _keymap_items():
    kc = bpy.context.window_manager.keyconfigs.addon
    if kc is None:
        return 0
    return sum(len(km.keymap_items) for km in kc.keymaps)


def _ops():
    return sorted(dir(getattr(bpy.ops, ADDON_ID)))


def test_enable_disable_cycles_leave_nothing_behind(addon_module):
    cycles = 50  # the issue-14 campaign's count
    assert addon_utils.check(MODULE_NAME) == (True, True)
    enabled = _rna_snapshot()
    enabled_ours = _ours(enabled[0])
    enabled_handlers, enabled_ops, enabled_keys = _handler_counts(), _ops(), _keymap_items()
    try:
        addon_module.disable()
        assert addon_utils.check(MODULE_NAME)[1] is False
        disabled = _rna_snapshot()
        disabled_handlers, disabled_keys = _handler_counts(), _keymap_items()
        assert not _ours(disabled[0]), f"classes left registered: {sorted(_ours(disabled[0]))}"
        assert _ops() == []
        for i in range(cycles):
            # The full RNA property snapshot costs ~0.1 s: take it on the first and last cycle
            # (leaks accumulate, so the last one catches any), type names on every cycle.
            full = i in (0, cycles - 1)
            addon_module.enable()
            now = _rna_snapshot() if full else (frozenset(dir(bpy.types)), None)
            assert now[0] == enabled[0], f"cycle {i}: types differ {sorted(now[0] ^ enabled[0])}"
            assert not full or now[1] == enabled[1], f"cycle {i}: RNA properties differ"
            assert _handler_counts() == enabled_handlers, f"cycle {i}: handlers differ"
            assert _ops() == enabled_ops and _keymap_items() == enabled_keys
            addon_module.disable()
            now = _rna_snapshot() if full else (frozenset(dir(bpy.types)), None)
            assert not _ours(now[0]), f"cycle {i}: left registered: {sorted(_ours(now[0]))}"
            assert now[0] == disabled[0], f"cycle {i}: leftover types {sorted(now[0] ^ disabled[0])}"
            assert not full or now[1] == disabled[1], f"cycle {i}: leftover RNA properties"
            assert _handler_counts() == disabled_handlers, f"cycle {i}: leftover handlers"
            assert _ops() == [] and _keymap_items() == disabled_keys
    finally:
        if not addon_utils.check(MODULE_NAME)[1]:
            addon_module.enable()
    assert addon_utils.check(MODULE_NAME) == (True, True)
    assert _rna_snapshot() == enabled


@pytest.mark.parametrize("engine", ["CYCLES", "EEVEE"])
def test_clean_file_keeps_extension(clean_file, addon_module, engine):
    """read_homefile(use_empty=True) gives an empty file and keeps the extension enabled."""
    assert len(bpy.data.objects) == 0 and len(bpy.data.materials) == 0
    assert addon_utils.check(MODULE_NAME) == (True, True)
    import scenes
    if engine == "EEVEE":  # only the settings; an EEVEE render costs ~30 s of shader compiling
        scene = scenes.eevee_setup()
        assert scene.render.engine == scenes.eevee_engine_id()
    else:
        scene = scenes.setup_render()
        assert scene.render.engine == "CYCLES"
    bpy.ops.wm.read_homefile(use_empty=True)
    assert addon_utils.check(MODULE_NAME) == (True, True)
