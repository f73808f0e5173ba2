# SPDX-License-Identifier: GPL-3.0-or-later
"""The wall-clock limits the tests do not assert: measured here, on an idle machine.

A test's verdict must not depend on the machine's load, so the tests bound work by counting it
(tests/pure/work_bound.py) and leave the seconds to this script:

- plots: one redraw of the panel's two plots (haze plot + BRDF slice, 160 x 160) < 0.25 s;
- mtlx: every case of tests/pure/test_fuzz_mtlx.py's MaterialX reader fuzz < 5 s;
- file_check: every case of the file-check fuzz of tests/blender/test_convert_safety.py < 1 s,
  all 4000 < 60 s (bpy);
- stamps: every driver call of the stamp fuzz (tests/blender/stamp_fuzz.py, every seventh
  case) < 5 s (bpy).

    .venv/bin/python benchmarks/time_limits.py [plots mtlx file_check stamps]

Prints one line per limit and exits 1 if any is over.  Not run by the tests.
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
for _p in (ROOT, ROOT / "tests" / "pure"):
    if str(_p) not in sys.path:
        sys.path.insert(0, str(_p))

LIMITS = {"plots": 0.25, "mtlx": 5.0, "file_check": 1.0, "file_check_all": 60.0, "stamps": 5.0}


def plots():
    from hazy_gloss.utils import plots as P
    m = P.mapping_for(dict(kind="CONDUCTOR", core_reflectivity=(0.6, 0.4, 0.2), roughness=0.2,
                           anisotropy=0.0, haziness=0.7, haze_extent=6.0,
                           edge_tint=(0.9, 0.7, 0.5)))
    P.haze_plot(0.6, float(m.peak_ratio), 0.7)  # warm up
    t = time.perf_counter()
    for _ in range(5):
        P.haze_plot(0.6, float(m.peak_ratio), 0.7, size=(160, 160))
        P.brdf_plot(m, "CONDUCTOR", size=(160, 160))
    return {"plots": (time.perf_counter() - t) / 5}


def mtlx():
    import test_fuzz_mtlx as F
    from hazy_gloss.interchange import materialx as M
    from test_interchange import _sources
    with tempfile.TemporaryDirectory() as d:
        base = M.write(_sources(), Path(d) / "base.mtlx", validate_with_package=False).path
        path = str(Path(d) / "case.mtlx")
        slowest = 0.0
        for _, doc in F.mutations(Path(base).read_text()):
            Path(path).write_text(doc)
            t = time.perf_counter()
            try:
                M.read(path)
            except Exception:  # noqa: BLE001 (outcomes are the test's)
                pass
            slowest = max(slowest, time.perf_counter() - t)
    return {"mtlx": slowest}


def _blender():
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _common as C
    C.start_blender()
    sys.path.insert(0, str(ROOT / "tests" / "blender"))


def file_check():
    _blender()
    import importlib

    import numpy as np
    import test_convert_safety as T
    from test_convert import write_png
    binputs = importlib.import_module("hazy_gloss.blender.model.convert_inputs")
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        rng = np.random.default_rng(14)
        exr = T._exr_bytes(tmp, n=40)
        png = Path(write_png(tmp / "f.png", np.arange(1600).reshape(40, 40) % 256, 8)).read_bytes()
        jpg = T._jpeg_bytes(tmp)
        p = tmp / "fuzz.bin"
        slowest, t0 = 0.0, time.perf_counter()
        for i in range(4000):  # the test's mutations, in its order
            p.write_bytes(T.fuzzed((exr, png, jpg)[i % 3], rng))
            t = time.perf_counter()
            try:
                binputs.check_readable(str(p), "fuzz")
            except binputs.ConversionError:
                pass
            slowest = max(slowest, time.perf_counter() - t)
    return {"file_check": slowest, "file_check_all": time.perf_counter() - t0}


def stamps():
    _blender()
    import stamp_fuzz
    slowest = [0.0]
    drive = stamp_fuzz.Fuzz.drive

    def timed(self, *args):
        t = time.perf_counter()
        try:
            return drive(self, *args)
        finally:
            slowest[0] = max(slowest[0], time.perf_counter() - t)

    stamp_fuzz.Fuzz.drive = timed
    with tempfile.TemporaryDirectory() as d:
        stamp_fuzz.Fuzz("hazy_gloss", d).run(stride=7)
    return {"stamps": slowest[0]}


def main(names):
    over = False
    for name in names or ("plots", "mtlx", "file_check", "stamps"):
        for key, seconds in globals()[name]().items():
            bad = seconds >= LIMITS[key]
            over |= bad
            print(f"{key}: {seconds:.3f} s (limit {LIMITS[key]} s){'  OVER' if bad else ''}")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
