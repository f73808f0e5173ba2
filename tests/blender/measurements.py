# SPDX-License-Identifier: GPL-3.0-or-later
"""Measured figures from the Blender tests (the tests assert; this keeps the numbers for docs).

Each call merges ``data`` into out/measurements/<name>.json under the running Blender version."""
import fcntl
import json
import os
from pathlib import Path

import bpy

OUT = Path(__file__).resolve().parents[2] / "out" / "measurements"


def record(name, data):
    """Merge under a lock, written whole (scripts/test.sh runs the Blender versions side by
    side: two processes may record into one file at once)."""
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{name}.json"
    with open(OUT / f".{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            old = json.loads(path.read_text()) if path.exists() else {}
        except ValueError:  # a file left half-written by a killed run: start it again
            old = {}
        old.setdefault(f"blender {bpy.app.version_string}", {}).update(data)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(old, indent=1, default=float))
        os.replace(tmp, path)
