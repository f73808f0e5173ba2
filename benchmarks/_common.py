# SPDX-License-Identifier: GPL-3.0-or-later
"""Shared helpers of the measured report (benchmarks/report.py): starting bpy with the add-on,
describing the machine, interleaved timing, JSON / PNG output.

Nothing here is part of the add-on; matplotlib is a dev-only dependency (requirements-dev.txt).
"""
from __future__ import annotations

import datetime
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "out" / "report"
OUT.mkdir(parents=True, exist_ok=True)
IMG = ROOT / "docs" / "img"
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT / "tests" / "blender"))
from layer_probe import count_nodes  # noqa: E402,F401  (one count of a group's nodes)
#: HG_REPORT_QUICK=1: tiny sample counts, to check the scripts run (never for committed docs).
QUICK = os.environ.get("HG_REPORT_QUICK", "") not in ("", "0")


def start_blender():
    """Import bpy with a throw-away user-resources dir and register the add-on from the checkout.

    Returns the ``hazy_gloss`` package (``hazy_gloss.api`` is then importable)."""
    if "bpy" not in sys.modules:
        os.environ["BLENDER_USER_RESOURCES"] = tempfile.mkdtemp(prefix="hg_report_")
    import bpy  # noqa: F401
    for p in (str(ROOT), str(ROOT / "tests" / "blender"), str(HERE)):
        if p not in sys.path:
            sys.path.insert(0, p)
    bpy.context.preferences.use_preferences_save = False
    import hazy_gloss
    try:
        hazy_gloss.register()
    except ValueError:  # already registered in this process
        pass
    return hazy_gloss


def clean_file():
    import bpy
    bpy.ops.wm.read_homefile(use_empty=True)


def machine():
    """A plain description of this machine (stated in the generated docs)."""
    info = {"platform": platform.platform(), "python": platform.python_version(),
            "cpus": os.cpu_count()}
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                info["cpu"] = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                info["memory_gib"] = round(int(line.split()[1]) / 2 ** 20, 1)
    except OSError:
        pass
    try:
        info["loadavg"] = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        pass
    try:
        import bpy
        info["blender"] = bpy.app.version_string
    except ImportError:
        pass
    import numpy
    info["numpy"] = numpy.__version__
    if "KVM" in _read("/sys/class/dmi/id/sys_vendor") + _read("/proc/cpuinfo"):
        info["virtualised"] = True
    return info


def _read(path):
    try:
        return Path(path).read_text(errors="ignore")
    except OSError:
        return ""


def machine_line(info):
    parts = [f"{info.get('cpu', 'unknown CPU')}, {info.get('cpus')} logical CPUs",
             f"{info.get('memory_gib', '?')} GiB RAM", info.get("platform", "")]
    if info.get("virtualised"):
        parts.append("virtual machine (KVM)")
    parts.append(f"Python {info.get('python')}, numpy {info.get('numpy')}, "
                 f"bpy {info.get('blender', '?')}")
    return "; ".join(p for p in parts if p)


# --------------------------------------------------------------------------------------------
# Timing
# --------------------------------------------------------------------------------------------


def interleaved(fns, rounds, *, warmup=1):
    """Run each callable of ``fns`` (name -> fn) once per round, in an order that alternates
    (A B C, C B A, A B C, ...) so slow drifts of the machine's load hit all alike.
    Returns {"wall": name -> [s per round], "cpu": name -> [s per round]} (warm-up dropped).
    "cpu" is this process's CPU time (all its threads: Cycles renders in-process), which other
    processes competing for the cores disturb far less than wall time."""
    names = list(fns)
    wall = {n: [] for n in names}
    cpu = {n: [] for n in names}
    for k in range(warmup + rounds):
        order = names if k % 2 == 0 else names[::-1]
        for n in order:
            c0, t0 = time.process_time(), time.perf_counter()
            fns[n]()
            dt, dc = time.perf_counter() - t0, time.process_time() - c0
            if k >= warmup:
                wall[n].append(dt)
                cpu[n].append(dc)
    return {"wall": wall, "cpu": cpu}


def paired_ratio(times, a, b):
    """Median of the per-round ratios a/b (A and B run next to each other in every round),
    with their interquartile range and min/max."""
    ratios = sorted(x / y for x, y in zip(times[a], times[b]))
    n = len(ratios)
    q = statistics.quantiles(ratios, n=4) if n >= 2 else [ratios[0]] * 3
    return {"median": statistics.median(ratios), "q1": q[0], "q3": q[2], "min": ratios[0],
            "max": ratios[-1], "n": n}


def fmt_ratio(r):
    return f"{r['median']:.3f} [{r['q1']:.3f}, {r['q3']:.3f}]"


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------


def write_json(name, data):
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / f"{name}.json"
    path.write_text(json.dumps(data, indent=1, default=_jsonable))
    return path


def read_json(name):
    return json.loads((OUT / f"{name}.json").read_text())


def _jsonable(x):
    import numpy as np
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, np.bool_):
        return bool(x)
    return str(x)


def pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plt.rcParams.update({"figure.dpi": 100, "savefig.dpi": 100, "font.size": 9,
                         "axes.grid": True, "grid.alpha": 0.3})
    return plt


def save_fig(fig, name):
    IMG.mkdir(parents=True, exist_ok=True)
    path = IMG / name
    fig.savefig(path, bbox_inches="tight", metadata={"Software": None})
    import matplotlib.pyplot as plt
    plt.close(fig)
    return f"img/{name}"


def save_image(rgb, name, *, exposure=1.0):
    """Save a linear (H, W, 3) float image (row 0 = bottom, Blender order) as an sRGB PNG."""
    import numpy as np
    plt = pyplot()
    x = np.clip(np.nan_to_num(np.asarray(rgb, dtype=np.float64)) * exposure, 0, None)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.minimum(x, 1.0), 1 / 2.4) - 0.055)
    IMG.mkdir(parents=True, exist_ok=True)
    plt.imsave(IMG / name, np.clip(x[::-1], 0, 1), metadata={"Software": None})
    return f"img/{name}"


def utc_date():
    """The date and minute a measurement was made, as the generated docs state it."""
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def publish(name, res, md, begin, end):
    """Write out/report/<name>.json and <name>.md; run alone (not from benchmarks/report.py,
    which assembles the docs itself), also replace the section of docs/performance.md between
    the markers ``begin`` and ``end``."""
    write_json(name, res)
    (OUT / f"{name}.md").write_text(md)
    if os.environ.get("HG_REPORT_SECTION") != "1":
        write_section(begin, end, md)


def write_section(begin, end, md):
    """Replace the text between the markers ``begin`` and ``end`` of docs/performance.md with
    ``md`` (appended with its markers when they are not there yet): a section one benchmark
    regenerates alone."""
    path = ROOT / "docs" / "performance.md"
    text = path.read_text()
    block = f"{begin}\n{md.rstrip()}\n{end}"
    if begin in text and end in text:
        text = text[:text.index(begin)] + block + text[text.index(end) + len(end):]
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    path.write_text(text)


def md_table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def sci(x, digits=1):
    """Compact scientific notation for error tables (0 stays 0, inf/nan as words)."""
    import math
    if x is None:
        return "-"
    x = float(x)
    if x == 0:
        return "0"
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "inf"
    return f"{x:.{digits}e}"
