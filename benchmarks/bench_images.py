# SPDX-License-Identifier: GPL-3.0-or-later
"""Image files: the strip writers, their proof, the strip reader and the file check, per size and
format, in a checkout (this one, or another given with ``--tree``: the hand-written codecs of
the tree before OpenImageIO replaced them), for docs/architecture.md ("Image files through
OpenImageIO"):

    .venv/bin/python benchmarks/bench_images.py                         # this checkout
    .venv/bin/python benchmarks/bench_images.py --tree /tmp/old --label "hand-written (14be10a)"
    HG_IMAGE_SIZES=1024,4096 .venv/bin/python benchmarks/bench_images.py

Every measurement runs in a fresh process (wall time; peak RSS above the process's resting
size, VmHWM after clearing it through /proc/self/clear_refs): one map of N x N, 3 channels,
smooth patterns plus noise (what a conversion writes), written strip by strip on the strip
pool as the conversion writes it (**write**), then proved as the conversion proves it
(**proof**: a hash of the bytes read back for the hand-written writers, one decode for
OpenImageIO's), read back in strips by OpenImageIO (**read**, the reader both trees use), and
checked by the tree's ``check_image_file`` (**check**).  Results: out/report/bench_images.json
(one entry per label) and the table between the markers in docs/architecture.md.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
import _common as C  # noqa: E402

BEGIN = "<!-- bench_images: begin (benchmarks/bench_images.py) -->"
END = "<!-- bench_images: end -->"
SIZES = [int(s) for s in os.environ.get("HG_IMAGE_SIZES", "1024,4096,8192").split(",")]

_CHILD = r"""
import json, os, sys, time
tree, what, fmt, path, n = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], int(sys.argv[5])
sys.path.insert(0, tree)
import numpy as np
try:  # this tree, or one from before conversion/ (the image modules at the package's top)
    from hazy_gloss.conversion import imagestream as S, imagecheck
except ImportError:
    from hazy_gloss import imagestream as S, imagecheck
try:
    from hazy_gloss.conversion.oiio import openimageio
except ImportError:
    try:
        from hazy_gloss.oiio import openimageio
    except ImportError:  # the tree before oiio.py: Blender's copy, found the same way
        sys.path.insert(0, os.environ["HG_BENCH_ROOT"])
        from hazy_gloss_bench_oiio import openimageio

def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key + ":"):
            return int(line.split()[1]) * 1024

oiio = openimageio()
rows = S.strip_rows(n)
x = np.arange(n, dtype=np.float32) / np.float32(n)
rng = np.random.default_rng(35)
noise = rng.normal(0, 0.01, (rows, n, 3)).astype(np.float32)

def strip(y0, y1):
    y = (np.arange(y0, y1, dtype=np.float32) / np.float32(n))[:, None, None]
    v = np.float32(0.5) + np.float32(0.4) * np.sin(np.float32(6.2832) * (3 * x[None, :, None] + 2 * y
                                                     + np.float32([0, 0.3, 0.7])))
    return np.clip(v + noise[:y1 - y0], 0, 1).astype(np.float32)

def writer():
    if hasattr(S, "OiioStripWriter"):
        return S.OiioStripWriter(oiio, path, n, n, fmt, "ZIP")
    if fmt == "PNG":
        return S.PngStripWriter(path, n, n)
    return S.ExrStripWriter(path, n, n, codec="ZIP")

base = status("VmRSS")
open("/proc/self/clear_refs", "w").write("5")
t = time.perf_counter()
if what == "write":
    w = writer()
    for _ in S.run_strips(n, rows, lambda a, b: None, lambda a, b, _: w.encode(a, strip(a, b)),
                          lambda a, b, e: w.append(e)):
        pass
    w.close()
    t_write = time.perf_counter() - t
    t = time.perf_counter()
    w.verify()
    out = {"write": t_write, "proof": time.perf_counter() - t}
elif what == "read":
    r = S.OiioStrips(oiio, path)
    for y0 in range(0, n, rows):
        r.rows(y0, min(n, y0 + rows))
    r.close()
    out = {"read": time.perf_counter() - t}
else:
    imagecheck.check_image_file(path)
    out = {"check": time.perf_counter() - t}
out["peak_" + what] = status("VmHWM") - base
out["bytes"] = os.path.getsize(path)
print(json.dumps(out))
"""

#: For a tree without oiio.py: the bpy wheel's OpenImageIO, loaded by its file.
_OIIO_SHIM = '''
import glob, importlib.util, os, sys
def openimageio():
    spec = importlib.util.find_spec("bpy")
    for init in glob.glob(os.path.join(spec.submodule_search_locations[0], "*", "python", "lib*",
                                       "python3*", "site-packages", "OpenImageIO", "__init__.py")):
        m = importlib.util.spec_from_file_location("OpenImageIO", init,
                                                   submodule_search_locations=[os.path.dirname(init)])
        mod = importlib.util.module_from_spec(m)
        sys.modules["OpenImageIO"] = mod
        m.loader.exec_module(mod)
        return mod
'''


def _child(tree, what, fmt, path, n, shim):
    r = subprocess.run([sys.executable, "-c", _CHILD, str(tree), what, fmt, str(path), str(n)],
                       capture_output=True, text=True, cwd=str(tree),
                       env=dict(os.environ, HG_BENCH_ROOT=str(shim), PYTHONDONTWRITEBYTECODE="1"))
    if r.returncode != 0:
        raise SystemExit(f"child failed: {r.stderr[-3000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def measure(tree):
    out = {}
    with tempfile.TemporaryDirectory(prefix="hg_images_") as tmp:
        shim = Path(tmp) / "shim"
        shim.mkdir()
        (shim / "hazy_gloss_bench_oiio.py").write_text(_OIIO_SHIM)
        for n in SIZES:
            for fmt in ("OPEN_EXR", "PNG"):
                path = Path(tmp) / ("map.exr" if fmt == "OPEN_EXR" else "map.png")
                row = {}
                for what in ("write", "read", "check"):
                    row.update(_child(tree, what, fmt, path, n, shim))
                out[f"{n} {fmt}"] = row
                print(f"[images] {n} {fmt}: " + ", ".join(
                    f"{k} {v:.2f}" for k, v in row.items() if not k.startswith(("peak", "bytes"))),
                    flush=True)
                path.unlink()
    return out


def markdown(results):
    gib = 2 ** 30
    names = {"OPEN_EXR": "EXR 32-bit ZIP", "PNG": "PNG 16-bit"}
    rows = []
    for label, res in results.items():
        for key, r in res["sizes"].items():
            n, fmt = key.split()
            rows.append([label, f"{n}x{n}", names[fmt], f"{r['write']:.2f}", f"{r['proof']:.2f}",
                         f"{r['read']:.2f}", f"{r['check']:.2f}",
                         f"{max(r['peak_write'], r['peak_read'], r['peak_check']) / gib:.2f}",
                         f"{r['bytes'] / 2**20:.1f}"])
    loads = ", ".join(f"{label}: {' / '.join(map(str, r['loadavg']))}" for label, r in
                      results.items())
    return "\n".join([
        C.md_table(["codecs", "size", "format", "write (s)", "proof (s)", "read (s)",
                    "check (s)", "peak (GiB)", "file (MiB)"], rows), "",
        f"Measured by `benchmarks/bench_images.py` ({C.machine().get('cpu', 'this machine')}; "
        f"load average at the start {loads}: the machine was shared, times are indicative)."])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tree", default=str(ROOT), help="the checkout whose codecs are measured")
    ap.add_argument("--label", default="OpenImageIO")
    args = ap.parse_args()
    t = time.perf_counter()
    load = [round(x, 2) for x in os.getloadavg()]
    res = {"sizes": measure(Path(args.tree).resolve()), "loadavg": load,
           "seconds": time.perf_counter() - t}
    path = C.OUT / "bench_images.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    results[args.label] = res
    path.write_text(json.dumps(results, indent=1))
    md = markdown(results)
    doc = ROOT / "docs" / "architecture.md"
    text = doc.read_text()
    if BEGIN in text and END in text:
        text = text[:text.index(BEGIN)] + f"{BEGIN}\n{md}\n{END}" + text[text.index(END) + len(END):]
        doc.write_text(text)
    print(md)


if __name__ == "__main__":
    main()
