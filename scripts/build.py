#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Build the installable extension: ``dist/hazy_gloss-<version>.zip``.

    .venv/bin/python scripts/build.py [--output-dir DIR] [--keep-stage]

Steps (all inside one bpy session, a few seconds):
1. stage the package in a temp dir: ``hazy_gloss/`` plus the top-level ``blender_manifest.toml``,
   no ``__pycache__``/``*.pyc``, no tests, docs, benchmarks or caches;
2. generate the asset library with the staged code (``node_groups/build_library.py``):
   ``assets/hazy_gloss_nodes.blend`` holding every node group, each marked as an asset with a
   description and a catalog under "Hazy Gloss", and ``assets/blender_assets.cats.txt``;
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
GENERATED_DIRS = ("assets",)

ASSET_DIRNAME = "assets"


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
