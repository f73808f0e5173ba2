# SPDX-License-Identifier: GPL-3.0-or-later
"""Measured figures from the Blender tests (the tests assert; this keeps the numbers for docs).

Each call merges ``data`` into out/measurements/<name>.json under the running Blender version."""
import json
from pathlib import Path

import bpy

OUT = Path(__file__).resolve().parents[2] / "out" / "measurements"


def record(name, data):
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{name}.json"
    old = json.loads(path.read_text()) if path.exists() else {}
    old.setdefault(f"blender {bpy.app.version_string}", {}).update(data)
    path.write_text(json.dumps(old, indent=1, default=float))
