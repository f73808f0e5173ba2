#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Generate the asset library of Hazy Gloss node groups.

    .venv/bin/python node_groups/build_library.py [--out DIR]   # default: node_groups/library/

Writes ``hazy_gloss_nodes.blend`` (every group configuration of
``hazy_gloss.blender.model.groups``, each marked as an asset with a description and a catalog
under "Hazy Gloss") and ``blender_assets.cats.txt`` into DIR.  ``scripts/build.py`` calls
:func:`build_library` on the staged package to put the library into the extension (``assets/``),
where the add-on registers it as an asset library; the output here is for inspection (it is
generated, not committed).  Nothing in the package imports this file.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys
import tempfile
import tomllib
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]


def build_library(package, asset_dir, manifest):
    """Write the asset .blend and catalogs of the imported add-on ``package`` (its module name)
    into ``asset_dir``; returns the names of the groups written.  Needs a bpy session."""
    import bpy

    bpy.ops.wm.read_homefile(use_empty=True)
    for ng in list(bpy.data.node_groups):
        bpy.data.node_groups.remove(ng)
    groups = importlib.import_module(f"{package}.blender.model.groups")
    menus = importlib.import_module(f"{package}.blender.ui.menus")
    asset_dir = Path(asset_dir)
    asset_dir.mkdir(parents=True, exist_ok=True)
    (asset_dir / menus.CATALOG_FILE).write_text(menus.catalog_definitions(), encoding="utf-8")
    built = []
    for config in groups.all_configurations():
        ng = groups.ensure_group(*config)
        if ng in built:
            raise RuntimeError(f"two configurations share the group {ng.name!r}")
        kind = config[0]
        ng.asset_mark()
        data = ng.asset_data
        data.description = menus.describe(*config)
        data.catalog_id = menus.catalog_id(menus.catalog_path(kind))
        for attr, value in (("author", manifest.get("maintainer", "")),
                            ("license", ", ".join(manifest.get("license", ()))),
                            ("copyright", ", ".join(manifest.get("copyright", ())))):
            if hasattr(data, attr):
                setattr(data, attr, value)
        for tag in ("Hazy Gloss", menus.KIND_LABELS[kind]):
            data.tags.new(tag, skip_if_exists=True)
        built.append(ng)
    blend = asset_dir / menus.ASSET_BLEND
    bpy.data.libraries.write(str(blend), set(built), fake_user=True, compress=True)
    if not blend.is_file():
        raise RuntimeError(f"{blend} was not written")
    return [ng.name for ng in built]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(REPO_ROOT / "node_groups" / "library"))
    args = parser.parse_args(argv)
    os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="hazy_gloss_lib_"))
    sys.path.insert(0, str(REPO_ROOT))
    import bpy  # noqa: F401
    with open(REPO_ROOT / "blender_manifest.toml", "rb") as fh:
        manifest = tomllib.load(fh)
    names = build_library("hazy_gloss", args.out, manifest)
    print(f"{len(names)} node groups -> {Path(args.out) / 'hazy_gloss_nodes.blend'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
