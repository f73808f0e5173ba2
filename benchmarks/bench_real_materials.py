# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md "Real materials": the peak and the halo per class of material built from
measured values (tests/data/measured_materials.py, the materials of
tests/blender/test_real_materials.py), in Cycles with a delta sun on a flat plane.

Per material and distribution (GGX, Multiscatter GGX), at haziness 0.3, 0.6 and 0.9:
- the peak (light and view along the normal, glossy pass): |hazy / haze-free - 1|;
- the halo: the glossy pass with the light 15° off the normal, hazy / haze-free at 0.6;
- transmissive classes: the light through the plane from 5° behind it, hazy / haze-free at 0.6,
  and the white furnace (R + T) of four of them, hazy - haze-free;
- what the layer's notes say (no room, a film's peak change, a body colour it cannot keep).

    .venv/bin/python benchmarks/bench_real_materials.py     # also run by benchmarks/report.py

Writes out/report/bench_real_materials.{json,md}; run alone, it replaces its section of
docs/performance.md (between the bench_real_materials markers).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

BEGIN, END = "<!-- bench_real_materials:begin -->", "<!-- bench_real_materials:end -->"
HAZINESS = (0.3, 0.6, 0.9)
FURNACE = ("water", "N-BK7 crown glass", "diamond", "frosted window (Transmission 0.6)")
#: Notes that say the peak moves or no haze shows (the peak is not judged there).
PEAK_NOTES = ("no haze shows", "thin film", "the peak cannot hold")


def measure(api, layer, layer_notes, read_exr, R):
    import numpy as np
    out = {}
    cases = R.cases()
    for name, (cls, build, dists, haze) in cases.items():
        for dist in dists:
            C.clean_file()
            mat = build(dist)
            api.make_hazy(mat, **haze)
            before = R.peak(read_exr, mat)
            off0 = R.render(read_exr, mat, (15.0, 0.0), passes=("glossy",))
            trans = cls.startswith("transmissive")
            t0 = R.render(read_exr, mat, (175.0, 0.0), bounces=1) if trans else None
            row = {"cls": cls, "dist": dist, "peak": {}, "notes": {}}
            for h in HAZINESS:
                notes = list(api.update_material(mat, haziness=h))
                row["peak"][h] = R.rel(R.peak(read_exr, mat), before)
                row["notes"][h] = notes
                if h == 0.6:
                    off = R.render(read_exr, mat, (15.0, 0.0), passes=("glossy",))
                    row["halo"] = float(off.max() / max(off0.max(), 1e-30))
                    if trans:
                        t = R.render(read_exr, mat, (175.0, 0.0), bounces=1)
                        row["transmitted"] = float(t.max() / max(t0.max(), 1e-30))
            if cls == "metal with film":
                api.update_material(mat, haziness=0.6)
                row["film_said"] = layer_notes.film_peak_change(layer.layer_node(mat))
            out[f"{name} [{dist}]"] = row
    furnace = {}
    for name in FURNACE:
        C.clean_file()
        mat = cases[name][1]("MULTI_GGX")
        bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
        bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        api.make_hazy(mat)
        e0 = R.furnace(mat)
        furnace[name] = {"original": e0.tolist()}
        for h in HAZINESS:
            api.update_material(mat, haziness=h)
            furnace[name][h] = (R.furnace(mat) - e0).tolist()
        print(f"[bench_real_materials] furnace {name}: {furnace[name]}", flush=True)
    return out, furnace


def main():
    t0 = time.perf_counter()
    C.start_blender()
    import bpy
    from hazy_gloss import api
    from hazy_gloss.conversion import imagecheck
    from hazy_gloss.blender.model import layer, layer_notes
    import real_materials as R
    rows, furnace = measure(api, layer, layer_notes, imagecheck.read_exr, R)
    res = {"rows": rows, "furnace": furnace, "blender": bpy.app.version_string,
           "machine": C.machine(), "seconds": time.perf_counter() - t0,
           "date": C.utc_date()}
    C.publish("bench_real_materials", res, markdown(res), BEGIN, END)
    print(f"[bench_real_materials] {len(rows)} materials in {res['seconds']:.0f} s", flush=True)


def markdown(res):
    import statistics
    L = ["## Real materials: the peak and the halo per class\n"]
    L.append(f"Measured by `.venv/bin/python benchmarks/bench_real_materials.py` on {res['date']} "
             f"(bpy {res['blender']}, {C.machine_line(res['machine'])}; {res['seconds']:.0f} s). "
             "Materials built from measured values (tests/data/measured_materials.py: metals' n, k "
             "and F0 from the refractive index database, dielectrics' IOR, liquids, glass and gems, "
             "thin films, ColorChecker bases), made hazy (Make Hazy, haze extent 5), Cycles, a delta "
             "sun on a plane. **Peak**: light and view along the normal, glossy pass, the largest "
             "|hazy / haze-free - 1| over haziness 0.3, 0.6, 0.9 (target: 1e-5 with GGX, 1e-3 with "
             "Multiscatter GGX, or a note saying by how much). **Halo**: the glossy pass with the "
             "light 15° off the normal, hazy / haze-free at haziness 0.6 (the halo the haze adds). "
             "**Through**: light through the plane from 5° behind it, hazy / haze-free at 0.6 "
             "(refraction kept: the same lobe, dimmed by what the reflection gains). The tests "
             "(tests/blender/test_real_materials.py) assert these in 4.5, 5.2 and 5.3.\n")
    by = {}
    for name, r in res["rows"].items():
        by.setdefault((r["cls"], r["dist"]), []).append((name, r))
    table = []
    for (cls, dist), items in sorted(by.items()):
        said = [r for _, r in items if any(n for ns in r["notes"].values() for n in ns)]
        # the peak is judged where no note says it moves (a body-colour note is not about it)
        moves = [r for r in said if any(n.startswith(PEAK_NOTES) for ns in r["notes"].values()
                                        for n in ns)]
        held = [max(r["peak"].values()) for _, r in items if r not in moves]
        worst = max(held) if held else None
        halos = [r["halo"] for _, r in items if "halo" in r]
        through = [r["transmitted"] for _, r in items if "transmitted" in r]
        table.append([cls, "Multiscatter GGX" if dist == "MULTI_GGX" else dist, len(items),
                      C.sci(worst) if worst is not None else "-",
                      f"{statistics.median(halos):.2f} [{min(halos):.2f}, {max(halos):.2f}]"
                      if halos else "-",
                      f"{min(through):.2f} - {max(through):.2f}" if through else "-",
                      len(said)])
    L.append(C.md_table(["class", "distribution", "materials", "peak (worst, where held)",
                         "halo at 15° (median [min, max])", "through, at 0.6",
                         "with a note"], table) + "\n")
    notes = {}
    for name, r in res["rows"].items():
        for h, ns in r["notes"].items():
            for n in ns:
                key = n.split(":")[0]
                notes.setdefault(key, []).append(f"{name} at {h}")
    L.append("What the notes say (the panel, the operator's report, `read_parameters` and what "
             "`api.make_hazy` / `update_material` return):\n")
    for key, where in notes.items():
        example = next(n for r in res["rows"].values() for ns in r["notes"].values() for n in ns
                       if n.startswith(key))
        L.append(f"- *{example}* — {len(where)} case(s), e.g. {where[0]}")
    film = {n: r["film_said"] for n, r in res["rows"].items() if r.get("film_said") is not None}
    if film:
        L.append("\nA metal's film (5.x): the peak change the note states at haziness 0.6 — "
                 + ", ".join(f"{n}: {100 * v:+.1f}%" for n, v in film.items())
                 + " (the layer raises the metal's Base Color as without a film; mapping.md §12).")
    rows = [[name, ", ".join(f"{x:.4f}" for x in f["original"]),
             " / ".join(", ".join(f"{d:+.1e}" for d in f[h]) for h in HAZINESS)]
            for name, f in res["furnace"].items()]
    L.append("\n**White furnace** (the plane in a white world, views 0° and 50°, Multiscatter GGX, "
             "1024 samples, white Base Color: R + T of the closures). Hazy - haze-free at "
             "haziness 0.3 / 0.6 / 0.9 (target: within 1e-3):\n")
    L.append(C.md_table(["material", "haze-free (0°, 50°)", "hazy - haze-free (0°, 50°)"], rows)
             + "\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
