# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender test harness: loads hazy_gloss exactly the way Blender loads an installed extension.

Import time (before any test module imports bpy):
1. ``BLENDER_USER_RESOURCES`` -> a fresh temp dir, so no real user config/extension is read or
   written (and preferences are never auto-saved);
2. ``import bpy``; if that fails the whole directory is skipped with a message — unless
   ``HAZY_GLOSS_REQUIRE_BPY=1`` (set by scripts/test.sh), which turns that into an error;
3. a temp extension repository directory holding ``hazy_gloss/``: links to the repo's package
   files plus the top-level ``blender_manifest.toml`` (what scripts/build.py stages), registered
   with ``preferences.extensions.repos.new(module="test_repo", ...)``;
4. ``addon_utils.enable("bl_ext.test_repo.hazy_gloss", default_set=True)``.

So the add-on's package is ``bl_ext.test_repo.hazy_gloss`` (its ``__package__``), NOT
``hazy_gloss``.  Get its modules through the fixtures, e.g.::

    def test_something(hg, clean_file):
        api = importlib.import_module(hg.__name__ + ".api")

(importing the top-level ``hazy_gloss`` would give a second, unregistered copy of the code).

Fixtures: ``addon_module`` (session: ``.name``, ``.module``), ``hg`` (the loaded package
module; re-enables the add-on if a test disabled it), ``clean_file`` (an empty file via
``wm.read_homefile(use_empty=True)``; read_factory_settings would disable the extension).
"""
from __future__ import annotations

import atexit
import importlib
import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[2]
PACKAGE_DIR = REPO_ROOT / "hazy_gloss"
ADDON_ID = "hazy_gloss"
REPO_MODULE = "test_repo"
MODULE_NAME = f"bl_ext.{REPO_MODULE}.{ADDON_ID}"

HERE = str(Path(__file__).resolve().parent)
if HERE not in sys.path:  # helper modules: scenes, analytic
    sys.path.insert(0, HERE)

_REQUIRE_BPY = os.environ.get("HAZY_GLOSS_REQUIRE_BPY", "") not in ("", "0")

# -- 1. user resources in a temp dir, before bpy is imported -------------------------------------
_TMP_ROOT = tempfile.mkdtemp(prefix="hazy_gloss_bltest_")
atexit.register(shutil.rmtree, _TMP_ROOT, True)
_USER_RESOURCES = os.path.join(_TMP_ROOT, "user_resources")
os.makedirs(_USER_RESOURCES)
_BPY_WAS_IMPORTED = "bpy" in sys.modules
if not _BPY_WAS_IMPORTED:
    os.environ["BLENDER_USER_RESOURCES"] = _USER_RESOURCES

# -- 2. bpy ----------------------------------------------------------------------------------------
_BPY_ERROR = None
try:
    import bpy  # noqa: E402
    import addon_utils  # noqa: E402  (ships with bpy)
    # Blender's own pxr before a test module imports pip's usd-core: Blender's USD export
    # hands the add-on's USDHook its stage in it (the add-on's register() does the same, too
    # late for a module that imported pxr already); pip's MaterialX stays first
    _PATH = list(sys.path)
    bpy.utils.expose_bundled_modules()
    import pxr.Usd  # noqa: E402,F401
    sys.path[:] = _PATH
except ImportError as exc:  # pure-only environment
    if _REQUIRE_BPY:
        raise RuntimeError(
            f"HAZY_GLOSS_REQUIRE_BPY is set but bpy cannot be imported ({exc}); "
            "run scripts/setup.sh") from exc
    _BPY_ERROR = exc

_SKIP_MESSAGE = (f"bpy is not importable ({_BPY_ERROR}): Blender tests skipped "
                 "(scripts/setup.sh installs bpy==5.0.1 into .venv)")

if _BPY_ERROR is not None:
    # Test modules import bpy at import time: do not collect them; report one skipped item
    # instead, so both ``pytest tests`` and ``pytest tests/blender`` say why (a module-level
    # pytest.skip in a conftest only works when the conftest is found during collection).
    collect_ignore_glob = ["test_*.py"]

    class _BpyMissingItem(pytest.Item):
        def runtest(self):
            pytest.skip(_SKIP_MESSAGE)

        def reportinfo(self):
            return self.path, None, "Blender tests (bpy missing)"

    class _BpyMissingFile(pytest.File):
        def collect(self):
            yield _BpyMissingItem.from_parent(self, name="bpy_not_importable")

    def pytest_collect_file(file_path, parent):
        if file_path.name == "conftest.py" and file_path.parent.resolve() == Path(HERE):
            return _BpyMissingFile.from_parent(parent, path=file_path)
        return None

if _BPY_WAS_IMPORTED and _BPY_ERROR is None:
    import warnings
    warnings.warn("bpy was imported before tests/blender/conftest.py: BLENDER_USER_RESOURCES "
                  "could not be redirected, the real user config dir is in use")

# -- 3. a temp extension repository holding only our package -------------------------------------
_EXT_REPO_DIR = os.path.join(_TMP_ROOT, "extensions", REPO_MODULE)
_EXT_DIR = os.path.join(_EXT_REPO_DIR, ADDON_ID)
os.makedirs(_EXT_DIR)
for _entry in PACKAGE_DIR.iterdir():  # the repo's code stays live; the manifest is staged
    if _entry.name != "__pycache__":
        os.symlink(_entry, os.path.join(_EXT_DIR, _entry.name),
                   target_is_directory=_entry.is_dir())
shutil.copyfile(REPO_ROOT / "blender_manifest.toml", os.path.join(_EXT_DIR, "blender_manifest.toml"))


def _add_repo():
    repos = bpy.context.preferences.extensions.repos
    for repo in repos:
        if repo.module == REPO_MODULE:
            return repo
    # Signature (4.5 and 5.0): new(name="", module="", custom_directory="", remote_url="",
    # source='USER').  A custom directory makes it a local repo without a remote.
    return repos.new(name="Hazy Gloss Test Repo", module=REPO_MODULE,
                     custom_directory=_EXT_REPO_DIR, source="USER")


def _enable():
    """Enable the extension, raising with Blender's own error if that fails."""
    errors = []
    mod = addon_utils.enable(MODULE_NAME, default_set=True, persistent=False,
                             handle_error=errors.append)
    if errors:
        raise RuntimeError(f"enabling {MODULE_NAME} failed: {errors[0]!r}") from errors[0]
    loaded_default, loaded_state = addon_utils.check(MODULE_NAME)
    if mod is None or not (loaded_default and loaded_state):
        raise RuntimeError(f"{MODULE_NAME} is not enabled after addon_utils.enable "
                           f"(check -> {loaded_default}, {loaded_state})")
    return sys.modules[MODULE_NAME]


# -- 4. enable ------------------------------------------------------------------------------------
_LOAD_ERROR = None
if _BPY_ERROR is None:
    bpy.context.preferences.use_preferences_save = False  # never write the temp prefs
    try:
        _REPO = _add_repo()
        _enable()
    except Exception as exc:  # reported by the fixtures, so each test says why
        _LOAD_ERROR = exc


def is_enabled():
    return MODULE_NAME in bpy.context.preferences.addons and all(addon_utils.check(MODULE_NAME))


class AddonModule:
    """What the ``addon_module`` fixture returns: the extension's module name and module."""

    name = MODULE_NAME
    addon_id = ADDON_ID
    repo_module = REPO_MODULE
    repo_dir = _EXT_REPO_DIR
    package_dir = str(PACKAGE_DIR)
    user_resources = _USER_RESOURCES

    @property
    def module(self):
        """The currently loaded package (disable/enable may replace the module object)."""
        return sys.modules[MODULE_NAME]

    def submodule(self, name):
        return importlib.import_module(f"{MODULE_NAME}.{name}")

    def enable(self):
        return _enable()

    def disable(self):
        addon_utils.disable(MODULE_NAME, default_set=True)

    def __repr__(self):
        return f"AddonModule({MODULE_NAME!r}, enabled={is_enabled()})"


@pytest.fixture(scope="session")
def addon_module():
    if _LOAD_ERROR is not None:
        pytest.fail(f"the hazy_gloss extension did not load: {_LOAD_ERROR!r}", pytrace=False)
    return AddonModule()


@pytest.fixture
def hg(addon_module):
    """The loaded extension package ``bl_ext.test_repo.hazy_gloss`` (enabled)."""
    if not is_enabled():
        _enable()
    return addon_module.module


@pytest.fixture
def clean_file(addon_module):
    """An empty file; the extension stays enabled (read_homefile keeps preferences)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    if not is_enabled():
        _enable()
    yield bpy.context


def pytest_configure(config):
    # The add-on's own use of deprecated Blender API is an error (Blender's RNA deprecation
    # warnings are attributed to the calling module); other modules' warnings stay warnings.
    config.addinivalue_line("filterwarnings", rf"error::DeprecationWarning:{MODULE_NAME}")
