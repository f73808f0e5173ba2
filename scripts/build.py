#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Build the installable extension: ``dist/hazy_gloss-<version>.zip``.

    .venv/bin/python scripts/build.py [--output-dir DIR] [--keep-stage]

Steps (in one bpy session, plus one process per Blender version for step 2's layer groups;
about 25 seconds):
1. stage the package in a temp dir: ``hazy_gloss/`` plus the top-level ``blender_manifest.toml``,
   no ``__pycache__``/``*.pyc``, no tests, docs, benchmarks or caches;
2. generate the asset library with the staged code (``node_groups/build_library.py``):
   ``assets/hazy_gloss_nodes.blend`` holding every node group, each marked as an asset with a
   description and a catalog under "Hazy Gloss", and ``assets/blender_assets.cats.txt``;
   then the haze layer's groups of the common configurations (``layer_group.SHIPPED``) into
   ``layer_groups/``, built by every bpy found here (this one, then setup.sh's .venv52
   and .venv45), so a first Make Hazy appends its group instead of building it for seconds;
3. build the zip with Blender's own tooling, ``bl_pkg.cli_extension(["build", ...])`` (what
   ``blender --command extension build`` runs), then ``["validate", ZIP]``;
4. check the zip: the files we expect, nothing we exclude, no symlinks.

Exit status 0 only if everything succeeded.  Blender's user resources point at a temp dir, so
no user configuration is read or written.
"""
from __future__ import annotations

import argparse
import fnmatch
import os
import shutil
import stat
import subprocess
import sys
import tempfile
import time
import tomllib
import zipfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
PACKAGE_DIR = REPO_ROOT / "hazy_gloss"
MANIFEST = REPO_ROOT / "blender_manifest.toml"

#: Never shipped (matched against every file and directory name while staging).
EXCLUDE_NAMES = ("__pycache__", "*.pyc", "*.pyo", ".pytest_cache", ".hypothesis", ".mypy_cache",
                 ".ruff_cache", ".git", ".gitignore", ".DS_Store", "*.blend1", "*.orig", "*.rej",
                 "*~", "tests", "docs", "benchmarks", "dist", "out")
#: Written by the build, so a stale copy in the source must not leak in.
GENERATED_DIRS = ("assets", "layer_groups")

ASSET_DIRNAME = "assets"
LAYER_GROUPS_DIR = "layer_groups"
#: The venvs (scripts/setup.sh) whose bpy also builds the shipped layer groups, if present.
SHIP_VENVS = (".venv", ".venv52", ".venv45")
#: Run by each of them with the staged package: its layer groups into the stage, where the
#: package looks for them (layer_group.SHIPPED_DIR).
_SHIP_HELPER = """
import os, sys
sys.dont_write_bytecode = True
sys.path.insert(0, {parent!r})
import bpy
import {package} as pkg
from {package}.blender.model import layer_group
if not pkg.__file__.startswith({stage!r}):
    raise SystemExit("imported " + pkg.__file__ + ", not the staged package")
paths = layer_group.write_shipped(os.path.join({stage!r}, *layer_group.SHIPPED_DIR))
print(bpy.app.version_string, len(paths))
"""


def log(msg):
    print(f"[build] {msg}", flush=True)


def read_manifest():
    with open(MANIFEST, "rb") as fh:
        return tomllib.load(fh)


def _ignore(directory, names):
    top = Path(directory).resolve() == PACKAGE_DIR.resolve()
    skip = {n for n in names if any(fnmatch.fnmatch(n, pat) for pat in EXCLUDE_NAMES)}
    if top:
        skip.update(n for n in names if n in GENERATED_DIRS)
    return skip


def stage_package(stage_root):
    """Copy the package and the manifest to ``stage_root/hazy_gloss``."""
    stage = Path(stage_root) / PACKAGE_DIR.name
    shutil.copytree(PACKAGE_DIR, stage, symlinks=False, ignore=_ignore)
    shutil.copyfile(MANIFEST, stage / MANIFEST.name)
    for path in stage.rglob("*"):
        if path.is_symlink():
            raise RuntimeError(f"staged a symlink: {path}")
    return stage


def _purge_bytecode(root):
    for cache in list(Path(root).rglob("__pycache__")):
        shutil.rmtree(cache)
    for pyc in list(Path(root).rglob("*.py[co]")):
        pyc.unlink()


def build_asset_library(stage):
    """Write assets/hazy_gloss_nodes.blend (+ catalogs) with the *staged* code."""
    sys.dont_write_bytecode = True  # importing the staged package must not write into it
    sys.path.insert(0, str(stage.parent))
    sys.path.insert(0, str(REPO_ROOT / "node_groups"))
    try:
        for name in [n for n in sys.modules if n == stage.name or n.startswith(stage.name + ".")]:
            del sys.modules[name]
        import importlib
        from build_library import build_library
        pkg = importlib.import_module(stage.name)
        if not Path(pkg.__file__).resolve().is_relative_to(stage.resolve()):
            raise RuntimeError(f"imported {pkg.__file__}, not the staged package")
        names = build_library(stage.name, stage / ASSET_DIRNAME, read_manifest())
        blend = stage / ASSET_DIRNAME / "hazy_gloss_nodes.blend"
        log(f"asset library: {len(names)} node groups -> {blend.relative_to(stage)} "
            f"({blend.stat().st_size} bytes)")
        return names
    finally:
        sys.path.remove(str(stage.parent))
        sys.path.remove(str(REPO_ROOT / "node_groups"))
        for name in [n for n in sys.modules if n == stage.name or n.startswith(stage.name + ".")]:
            del sys.modules[name]
        _purge_bytecode(stage)


def ship_layer_groups(stage, user_resources):
    """Build the staged package's shipped layer groups (layer_group.SHIPPED) with each bpy
    here, into ``stage/layer_groups``; returns the Blender versions built.  A version
    with no bpy here builds its groups on first use (and caches them per user)."""
    out = stage / LAYER_GROUPS_DIR
    # this interpreter's venv, then setup.sh's others (told apart by their venv directories:
    # two venvs may share one base Python)
    venvs = [Path(sys.prefix)] + [REPO_ROOT / v for v in SHIP_VENVS]
    code = _SHIP_HELPER.format(parent=str(stage.parent), package=stage.name, stage=str(stage))
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(user_resources), PYTHONDONTWRITEBYTECODE="1")
    env.pop("PYTHONPATH", None)
    built, seen = [], set()
    for venv in venvs:
        python = sys.executable if venv == Path(sys.prefix) else str(venv / "bin" / "python")
        if venv.resolve() in seen:
            continue
        if not os.path.exists(python):
            log(f"WARNING: no {venv.name} here: the zip ships no layer groups of its Blender "
                "(they are built on first use); bash scripts/setup.sh makes every venv")
            continue
        seen.add(venv.resolve())
        proc = subprocess.run([python, "-c", code], cwd=str(stage.parent), env=env,
                              capture_output=True, text=True, timeout=900)
        last = proc.stdout.strip().splitlines()[-1:] or [""]
        if proc.returncode != 0:
            raise RuntimeError(f"building the layer groups with {python} failed:\n"
                               f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}")
        version = last[0].rsplit(" ", 1)[0]
        if version not in built:
            built.append(version)
    _purge_bytecode(stage)
    files = sorted(out.glob("*.blend"))
    log(f"layer groups: {len(files)} files for bpy {', '.join(built)} -> {LAYER_GROUPS_DIR} "
        f"({sum(f.stat().st_size for f in files)} bytes)")
    return built


def bl_pkg_command(args):
    """Run ``blender --command extension <args>`` in this bpy session; return its exit code."""
    import bl_pkg
    return bl_pkg.cli_extension(list(args))


def check_zip(zip_path, stage):
    """The zip holds exactly the staged files, as regular files, and nothing excluded."""
    with zipfile.ZipFile(zip_path) as zf:
        infos = zf.infolist()
    names = {i.filename for i in infos if not i.filename.endswith("/")}
    problems = []
    for info in infos:
        if stat.S_ISLNK(info.external_attr >> 16):
            problems.append(f"symlink in zip: {info.filename}")
        parts = info.filename.rstrip("/").split("/")
        if any(fnmatch.fnmatch(p, pat) for p in parts for pat in EXCLUDE_NAMES):
            problems.append(f"excluded path in zip: {info.filename}")
    staged = {p.relative_to(stage).as_posix() for p in stage.rglob("*") if p.is_file()}
    if names != staged:
        problems.append(f"zip differs from the stage: missing {sorted(staged - names)}, "
                        f"extra {sorted(names - staged)}")
    for required in ("__init__.py", "blender_manifest.toml", "blender/model/groups.py",
                     f"{ASSET_DIRNAME}/hazy_gloss_nodes.blend",
                     f"{ASSET_DIRNAME}/blender_assets.cats.txt"):
        if required not in names:
            problems.append(f"missing from zip: {required}")
    if not any(n.startswith(LAYER_GROUPS_DIR + "/") and n.endswith(".blend") for n in names):
        problems.append(f"missing from zip: the layer groups ({LAYER_GROUPS_DIR}/*.blend)")
    if problems:
        raise RuntimeError("bad zip:\n  " + "\n  ".join(problems))
    return sorted(names)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output-dir", default=str(REPO_ROOT / "dist"),
                        help="where to write hazy_gloss-<version>.zip (default: dist/)")
    parser.add_argument("--keep-stage", action="store_true",
                        help="keep the staging directory (printed) for inspection")
    args = parser.parse_args(argv)
    t0 = time.monotonic()

    manifest = read_manifest()
    zip_name = f"{manifest['id']}-{manifest['version']}.zip"
    out_dir = Path(args.output_dir).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    zip_path = out_dir / zip_name

    tmp = Path(tempfile.mkdtemp(prefix="hazy_gloss_build_"))
    # Before bpy is imported: no user config read or written.
    os.environ["BLENDER_USER_RESOURCES"] = str(tmp / "user_resources")
    (tmp / "user_resources").mkdir()
    try:
        stage = stage_package(tmp / "stage")
        log(f"staged {PACKAGE_DIR} -> {stage}")
        import bpy
        log(f"bpy {bpy.app.version_string}")
        bpy.context.preferences.use_preferences_save = False
        build_asset_library(stage)
        ship_layer_groups(stage, tmp / "user_resources")

        if zip_path.exists():
            zip_path.unlink()
        rc = bl_pkg_command(["build", "--source-dir", str(stage), "--output-dir", str(out_dir)])
        if rc != 0 or not zip_path.is_file():
            log(f"FAILED: bl_pkg build exited {rc}")
            return 1
        rc = bl_pkg_command(["validate", str(zip_path)])
        if rc != 0:
            log(f"FAILED: bl_pkg validate exited {rc}")
            return 1
        names = check_zip(zip_path, stage)
        log(f"{zip_path} ({zip_path.stat().st_size} bytes, {len(names)} files) built and "
            f"validated in {time.monotonic() - t0:.1f} s")
        return 0
    finally:
        if args.keep_stage:
            log(f"stage kept in {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
