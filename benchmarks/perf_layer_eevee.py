# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 7: Make Hazy's layer in EEVEE.

A. Closures (run in every installed Blender: .venv 5.3, .venv52 5.2, .venv45 4.5, each in its own
   process): a flat plane under a delta sun (black world, orthographic camera; halo: light 30°,
   view 0°; peak: light 30°, view 30° mirrored), every layered material rendered by EEVEE at 1, 4
   and 16 TAA samples against 64 (noise = RMS over pixels of the difference, relative to the
   mean), and its mean against the sum of renders of each of its BSDF copies alone (the copy
   kept in its Mix Shaders, the others unlinked): linearity, i.e. no closure dropped and no
   weight lost when several closures share EEVEE's bins.  The same for the EEVEE-only output of
   blender.actions.eevee_output (mode "always") and for the original material.
B. Against Cycles (5.3): a smooth UV sphere under a delta sun, black world, orthographic camera;
   Cycles at 1 sample is exact there (each pixel evaluates the BSDF once at its centre); EEVEE
   at 64 TAA samples.  Relative RMSE and mean bias over the sphere against the Cycles render of
   the layered material, for EEVEE's full layer, its EEVEE-only output and the original (no
   haze); EEVEE's own error on the original against Cycles' original for scale.
C. Cost (5.3): EEVEE render time (CPU time of this process: EEVEE runs on a software OpenGL
   driver here, in-process) of the original, the full layer and the EEVEE-only output at 16 TAA
   samples, interleaved; and the first render of a fresh copy of each (shader compilation).

    .venv/bin/python benchmarks/perf_layer_eevee.py     # also run by benchmarks/report.py

Writes out/report/perf_layer_eevee*.json, perf_layer_eevee.md, docs/img/perf_layer_eevee.png
and, run standalone, replaces its section of docs/performance.md (between its markers).
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import numpy as np  # noqa: E402

BEGIN, END = "<!-- perf_layer_eevee:begin -->", "<!-- perf_layer_eevee:end -->"
PLANE_RES = (16, 16)
SPHERE_RES = (96, 96)
NOISE_SAMPLES = (1, 4, 16)
REF_SAMPLES = 64
TIME_SAMPLES = 16
ROUNDS = 5
VENVS = {"5.3": ".venv", "5.2": ".venv52", "4.5": ".venv45"}
#: HG_EEVEE_VERSIONS=5.3 measures A in fewer versions (each takes ~20 min on 2 cores)
VENVS = {k: v for k, v in VENVS.items()
         if k in os.environ.get("HG_EEVEE_VERSIONS", ",".join(VENVS)).split(",")}
if C.QUICK:
    NOISE_SAMPLES, REF_SAMPLES, TIME_SAMPLES, ROUNDS = (1,), 4, 2, 1

PAINT = {"Metallic": 1.0, "Base Color": (0.6, 0.05, 0.05, 1.0), "Roughness": 0.35,
         "Coat Weight": 1.0, "Coat Roughness": 0.03, "Coat IOR": 1.5}
METALLIC_MAP = np.array([[0.0, 1.0, 0.25, 0.5], [0.75, 0.1, 0.9, 0.0],
                         [1.0, 0.33, 0.0, 0.6], [0.05, 1.0, 0.4, 0.95]])
#: label -> (Principled inputs, metallic map?, haze keywords)
MATERIALS = {
    "dielectric": ({"Base Color": (0.05, 0.12, 0.35, 1.0), "Roughness": 0.2, "IOR": 1.5}, False,
                   dict(haziness=0.6)),
    "metal": ({"Metallic": 1.0, "Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.25}, False,
              dict(haziness=0.6)),
    "metallic map": ({"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.25, "IOR": 1.6}, True,
                     dict(haziness=0.6)),
    "car paint, hazy base + coat": (PAINT, False, dict(haziness=0.5, coat_haziness=0.6)),
    "car paint, hazy coat": (PAINT, False, dict(coat_haziness=0.6)),
    "car paint, hazy base": (PAINT, False, dict(haziness=0.5)),
    "metallic map, hazy coat": ({"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.25, "IOR": 1.6,
                                 "Coat Weight": 1.0, "Coat Roughness": 0.1}, True,
                                dict(haziness=0.6, coat_haziness=0.5)),
}
CONFIGS = {"halo": ((30.0, 0.0), (0.0, 0.0)), "peak": ((30.0, 0.0), (30.0, 180.0))}


# --------------------------------------------------------------------------------------------
# Materials
# --------------------------------------------------------------------------------------------


def build(label, haze=True):
    import bpy
    from hazy_gloss import api
    inputs, mapped, h = MATERIALS[label]
    mat = bpy.data.materials.new(label)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    b = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    b.distribution = "GGX"
    for k, v in inputs.items():
        b.inputs[k].default_value = v
    if mapped:  # a 4x4 texture over the camera frame (Window coordinates, Closest)
        px = np.concatenate([np.repeat(METALLIC_MAP[..., None], 3, -1), np.ones((4, 4, 1))], -1)
        img = bpy.data.images.new(label + " metallic", 4, 4, alpha=True, float_buffer=True,
                                  is_data=True)
        img.pixels.foreach_set(px.astype(np.float32).ravel())
        coord = tree.nodes.new("ShaderNodeTexCoord")
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image, tex.interpolation, tex.extension = img, "Closest", "EXTEND"
        tree.links.new(coord.outputs["Window"], tex.inputs["Vector"])
        tree.links.new(tex.outputs["Color"], b.inputs["Metallic"])
    if haze:
        api.make_hazy(mat, **h)
    return mat


def copies(mat):
    """One material per BSDF copy of the layer: the copy kept, the others unlinked from their
    Mix Shaders; the stamp removed (else the add-on's handler rebuilds the layer)."""
    out = []
    names = [n.name for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]
    for keep in names:
        m = mat.copy()
        del m["hazy_gloss"]
        for n in m.node_tree.nodes:
            if n.bl_idname == "ShaderNodeBsdfPrincipled" and n.name != keep:
                for link in list(n.outputs[0].links):
                    m.node_tree.links.remove(link)
        out.append(m)
    return out


def with_eevee_output(label):
    """The layered material built afresh with blender.actions.eevee_output's EEVEE-only output (mode
    "always").  Not a copy of another layered material: a copy has a new session id, so the
    add-on's depsgraph handler reruns its layer at the first render, and a rebuilding layer
    removes the EEVEE output's nodes (which then fall back to the full layer)."""
    from hazy_gloss.blender.actions import eevee_output as eevee_layer
    mat = build(label)
    info = eevee_layer.add_eevee_output(mat, mode="always")
    assert info["added"], info
    return mat


def variants_of(label):
    return {"layer": build(label), "eevee_output": with_eevee_output(label),
            "original": build(label, haze=False)}


# --------------------------------------------------------------------------------------------
# A. closures (any version)
# --------------------------------------------------------------------------------------------


def plane_render(mat, engine, samples, light, view):
    import scenes
    return scenes.render_plane(mat, engine=engine, samples=samples, resolution=PLANE_RES,
                               light_dir=light, view_dir=view)


def closures():
    C.start_blender()
    import bpy
    C.clean_file()
    res = {"blender": bpy.app.version_string, "materials": {}}
    for label in MATERIALS:
        t0 = time.perf_counter()
        variants = variants_of(label)
        layered = variants["layer"]
        parts = copies(layered)
        row = {"bsdfs": len(parts)}
        for cname, (light, view) in CONFIGS.items():
            r = {}
            for key, mat in variants.items():
                ref = plane_render(mat, "EEVEE", REF_SAMPLES, light, view)
                mean = float(ref.mean())
                r[key] = {"mean": mean, "noise": {
                    n: float(np.sqrt(np.mean((plane_render(mat, "EEVEE", n, light, view) - ref) ** 2))
                             / max(mean, 1e-12)) for n in NOISE_SAMPLES}}
            total = sum(plane_render(p, "EEVEE", REF_SAMPLES, light, view) for p in parts)
            r["sum_of_copies"] = float(total.mean())
            r["cycles"] = float(plane_render(layered, "CYCLES", 1, light, view).mean())
            r["cycles_original"] = float(plane_render(variants["original"], "CYCLES", 1, light,
                                                      view).mean())
            row[cname] = r
        res["materials"][label] = row
        print(f"[perf_layer_eevee] closures {label} ({bpy.app.version_string}): "
              f"{time.perf_counter() - t0:.0f} s", flush=True)
    # two identical lobes in a Mix Shader (one per reflection bin) against the lobe alone
    res["two_bins"] = {}
    for label in ("dielectric", "metal"):
        one = build(label, haze=False)
        two = one.copy()
        tree = two.node_tree
        b = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
        c = tree.nodes.new("ShaderNodeBsdfPrincipled")
        c.distribution = b.distribution
        for x, y in zip(b.inputs, c.inputs):
            if hasattr(x, "default_value"):
                y.default_value = x.default_value
        mix = tree.nodes.new("ShaderNodeMixShader")
        mix.inputs[0].default_value = 0.5
        tree.links.new(b.outputs[0], mix.inputs[1])
        tree.links.new(c.outputs[0], mix.inputs[2])
        out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
        tree.links.new(mix.outputs[0], out.inputs["Surface"])
        res["two_bins"][label] = {
            cname: float(plane_render(two, "EEVEE", REF_SAMPLES, light, view).mean()
                         / plane_render(one, "EEVEE", REF_SAMPLES, light, view).mean() - 1.0)
            for cname, (light, view) in CONFIGS.items()}
    version = ".".join(str(x) for x in bpy.app.version[:2])
    C.write_json(f"perf_layer_eevee_closures_{version}", res)


# --------------------------------------------------------------------------------------------
# B, C (5.3)
# --------------------------------------------------------------------------------------------


def sphere_scene(mat):
    import bpy
    import perf_scene as P
    import scenes
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    bpy.context.scene.render.film_transparent = True
    obj = P.uv_sphere()
    obj.data.materials.append(mat)
    scenes._ortho_camera("HG Camera", scenes.spherical_direction(0.0, 0.0), 2.3)
    scenes._sun(scenes.spherical_direction(40.0, 20.0), 3.0)
    return obj


def sphere_render(engine, mat, samples):
    import scenes
    if engine == "EEVEE":
        scenes.eevee_setup(samples=samples, resolution=SPHERE_RES)
    else:
        scenes.setup_render("CYCLES", samples=1, resolution=SPHERE_RES, bounces=0)
    sphere_scene(mat)
    t0, c0 = time.perf_counter(), time.process_time()
    img = scenes.render_exr()
    return img, time.perf_counter() - t0, time.process_time() - c0


def _errors(img, ref):
    mask = ref[..., 3] > 0.999
    a, b = img[..., :3][mask].astype(np.float64), ref[..., :3][mask].astype(np.float64)
    m = float(b.mean())
    return {"rmse": float(np.sqrt(np.mean((a - b) ** 2)) / m),
            "mae": float(np.mean(np.abs(a - b)) / m), "bias": float(a.mean() / m - 1.0)}


def main():
    C.start_blender()
    import bpy
    C.clean_file()
    res = {"blender": bpy.app.version_string, "machine": C.machine(), "materials": {},
           "date": C.utc_date(),
           "settings": dict(plane=PLANE_RES, sphere=SPHERE_RES, noise=NOISE_SAMPLES,
                            ref=REF_SAMPLES, time=TIME_SAMPLES, rounds=ROUNDS)}
    strips = []
    for label in MATERIALS:
        t0 = time.perf_counter()
        variants = variants_of(label)
        layered = variants["layer"]
        cyc, _, _ = sphere_render("CYCLES", layered, 1)
        cyc_orig, _, _ = sphere_render("CYCLES", variants["original"], 1)
        row = {"vs_cycles": {}, "first_render": {}}
        imgs = {}
        for key, mat in variants.items():
            img, _, _ = sphere_render("EEVEE", mat, REF_SAMPLES)
            imgs[key] = img
            row["vs_cycles"][key] = _errors(img, cyc)
        row["eevee_original_vs_cycles_original"] = _errors(imgs["original"], cyc_orig)
        strips.append((cyc, imgs["layer"], imgs["eevee_output"], imgs["original"]))
        # C. cost: first render of a freshly built material (compiles its shaders), then
        # interleaved renders
        for key, mat in variants_of(label).items():
            _, wall, cpu = sphere_render("EEVEE", mat, TIME_SAMPLES)
            row["first_render"][key] = {"wall": wall, "cpu": cpu}
        fns = {k: (lambda m=m: sphere_render("EEVEE", m, TIME_SAMPLES)) for k, m in variants.items()}
        times = C.interleaved(fns, ROUNDS, warmup=1)
        row["times"] = times
        row["ratios"] = {f"{a}/{b}": C.paired_ratio(times["cpu"], a, b) for a, b in
                         (("layer", "original"), ("eevee_output", "original"),
                          ("eevee_output", "layer"))}
        row["cpu_seconds"] = {k: float(np.median(v)) for k, v in times["cpu"].items()}
        res["materials"][label] = row
        print(f"[perf_layer_eevee] {label}: {time.perf_counter() - t0:.0f} s", flush=True)
    res["fig"] = _strip(strips)
    res["closures"] = {}
    for version, venv in VENVS.items():
        py = C.ROOT / venv / "bin" / "python"
        if not py.exists():
            continue
        t0 = time.perf_counter()
        subprocess.run([str(py), "-u", __file__, "--closures"], cwd=str(C.ROOT), check=True,
                       stdout=subprocess.DEVNULL if os.environ.get("HG_QUIET") else None)
        res["closures"][version] = C.read_json(f"perf_layer_eevee_closures_{version}")
        print(f"[perf_layer_eevee] closures in {version}: {time.perf_counter() - t0:.0f} s",
              flush=True)
    C.publish("perf_layer_eevee", res, markdown(res), BEGIN, END)


def _strip(strips):
    """Columns: materials; rows (top to bottom): Cycles layered, EEVEE full layer, EEVEE-only
    output, EEVEE original."""
    cols = []
    for cyc, lay, out, orig in strips:
        cols.append(np.concatenate([orig, out, lay, cyc], axis=0))  # row 0 = bottom
    img = np.concatenate(cols, axis=1)
    return C.save_image(img[..., :3], "perf_layer_eevee.png")


# --------------------------------------------------------------------------------------------
# Markdown
# --------------------------------------------------------------------------------------------


def markdown(res):
    s = res["settings"]
    L = ["## 7. Make Hazy's layer in EEVEE\n"]
    others = [v["blender"] for k, v in res["closures"].items() if k != "5.3"]
    where = (f"closures also in {', '.join(others)}" if others else
             "A only in this version; tests/blender/test_eevee_layer.py checks EEVEE's noise "
             "with and without the EEVEE-only output in 4.5, 5.2 and 5.3")
    L.append(f"Measured by `.venv/bin/python benchmarks/perf_layer_eevee.py` on {res['date']} "
             f"(bpy {res['blender']}; {where}; {C.machine_line(res['machine'])}). EEVEE runs on "
             "a software OpenGL driver here (no GPU): its times are far from a GPU's, its "
             "images are not.\n")
    L.append(
        "**What EEVEE does with a layer** (eevee_nodetree_closures_lib and gpu_material in the "
        "4.5, 5.2 and 5.3 sources; confirmed by A below). EEVEE shades a material through at "
        "most three closure *bins* per pixel, stored in the G-buffer: bin 0 for diffuse, "
        "subsurface, refraction and translucency, then one bin for reflection, or two when the "
        "material has more than one reflection closure (two Glossy / Principled BSDFs in a mix, "
        "or a Principled BSDF with a coat: the material is then flagged *clear coat*). A "
        "Principled BSDF emits its coat, then one specular closure (metal and dielectric merged, "
        "weight = split-sum albedo), then its diffuse; with two reflection bins, successive "
        "reflection closures alternate between them in evaluation order. Every closure sent to "
        "a bin that already holds one competes with it: EEVEE keeps one per pixel and sample, "
        "chosen at random in proportion to its weight, and scales it by total / chosen weight "
        "(reservoir sampling; the random number changes with each TAA sample). So nothing is "
        "dropped and the mean is right, but closures of different roughness sharing a bin "
        "become noise that only TAA samples average out. For the layer: the dielectric and "
        "metal (2 BSDFs: narrow lobe in one bin, wide in the other) and the metallic map (4: "
        "both narrow lobes in one bin, both wide in the other) keep one roughness per bin; with "
        "a coat (hazy or not) the coat and specular closures of each copy alternate, so each "
        "bin holds a narrow and a wide lobe: noisy. A layered dielectric needs 3 bins instead "
        "of the original's 2 (the extra reflection bin); metals, coats and metallic maps keep "
        "their bin count.\n")
    # A
    L.append(f"**A. Closures** (flat plane {s['plane'][0]}x{s['plane'][1]} px, delta sun; "
             f"noise = RMS of (n TAA samples - {s['ref']}) / mean; linearity = EEVEE's full layer "
             f"at {s['ref']} samples / the sum of its BSDF copies rendered alone - 1; the "
             "EEVEE-only output is blender.actions.eevee_output's, mode \"always\"):\n")
    header = ["Blender", "material", "BSDFs", "view", "noise @1: layer / EEVEE output / original",
              f"noise @{s['noise'][-1]}: layer / output / original", "linearity (layer)"]
    rows = []
    worst_lin = 0.0
    for version, d in res["closures"].items():
        for label, r in d["materials"].items():
            for cname in CONFIGS:
                c = r[cname]
                n1 = [c[k]["noise"][str(s["noise"][0])] if str(s["noise"][0]) in c[k]["noise"]
                      else c[k]["noise"][s["noise"][0]] for k in ("layer", "eevee_output", "original")]
                nl = [c[k]["noise"].get(str(s["noise"][-1]), c[k]["noise"].get(s["noise"][-1]))
                      for k in ("layer", "eevee_output", "original")]
                lin = c["layer"]["mean"] / c["sum_of_copies"] - 1.0
                worst_lin = max(worst_lin, abs(lin))
                rows.append([d["blender"], label, str(r["bsdfs"]), cname,
                             " / ".join(f"{x:.3f}" for x in n1), " / ".join(f"{x:.3f}" for x in nl),
                             f"{lin:+.3f}"])
    L.append(C.md_table(header, rows) + "\n")
    two = "; ".join(f"{d['blender']}: " + ", ".join(
        f"{label} {100 * min(v.values()):+.1f}% to {100 * max(v.values()):+.1f}%"
        for label, v in d["two_bins"].items()) for d in res["closures"].values())
    coat = [r[c] for d in res["closures"].values() for label, r in d["materials"].items()
            if "coat" in label or "paint" in label for c in CONFIGS]
    n1 = [c["layer"]["noise"].get(str(s["noise"][0]), 0.0) for c in coat]
    nl = [c["layer"]["noise"].get(str(s["noise"][-1]), 0.0) for c in coat]
    no = [c["eevee_output"]["noise"].get(str(s["noise"][0]), 0.0) for c in coat]
    L.append(f"No closure is dropped and no weight lost: the full layer's mean is within "
             f"{100 * worst_lin:.1f}% of the sum of its copies in every version. Part of that is "
             "EEVEE's, not the layer's: the same Principled BSDF twice in a Mix Shader (one copy "
             "per reflection bin) renders, against the BSDF alone, " + two + ". The noise columns "
             f"show the breakdown: with a coat, one TAA sample of the full layer scatters by "
             f"{100 * min(n1):.0f}-{100 * max(n1):.0f}% (a sharp coat's narrow lobe, picked for a "
             f"few % of the pixels, carries the whole coat weight), {s['noise'][-1]} samples still "
             f"by {100 * min(nl):.1f}-{100 * max(nl):.1f}%; the EEVEE-only output's single sample "
             f"by {100 * min(no):.1f}-{100 * max(no):.1f}%.\n")
    # B
    L.append(f"**B. EEVEE against Cycles** (UV sphere {s['sphere'][0]}x{s['sphere'][1]} px, "
             f"delta sun, black world; Cycles 1 sample = exact; EEVEE {s['ref']} TAA samples; "
             "relative RMSE / relative mean absolute error / mean bias over the sphere, against "
             "Cycles' render of the layered material; last column: EEVEE's own error on the "
             "original material, against Cycles' original):\n")
    header = ["material", "EEVEE full layer", "EEVEE-only output", "EEVEE original (no haze)",
              "EEVEE vs Cycles, original"]
    rows = []
    fmt = lambda e: f"{e['rmse']:.3f} / {e['mae']:.3f} / {e['bias']:+.3f}"  # noqa: E731
    for label, r in res["materials"].items():
        v = r["vs_cycles"]
        rows.append([label, fmt(v["layer"]), fmt(v["eevee_output"]), fmt(v["original"]),
                     fmt(r["eevee_original_vs_cycles_original"])])
    L.append(C.md_table(header, rows) + "\n")
    L.append(f"![Cycles layered (top), EEVEE full layer, EEVEE-only output, EEVEE original "
             f"(bottom)]({res['fig']})\n")
    L.append("Top to bottom: Cycles (layered), EEVEE full layer, EEVEE-only output, EEVEE "
             "original; left to right: " + ", ".join(res["materials"]) + ".\n")
    # C
    L.append(f"**C. Cost in EEVEE** (the sphere of B, {s['time']} TAA samples; CPU time of the "
             f"process, interleaved, {s['rounds']} rounds, median ratio [IQR]; first render = a "
             "freshly built material, whose shaders EEVEE compiles unless the same shader code "
             "was compiled earlier in the run: EEVEE caches shaders by their code, and most "
             "socket values are uniforms, not code):\n")
    header = ["material", "layer / original", "EEVEE output / original", "EEVEE output / layer",
              "CPU s per render (orig., layer, output)", "first render wall s (orig., layer, output)"]
    rows = []
    for label, r in res["materials"].items():
        q, cs, fr = r["ratios"], r["cpu_seconds"], r["first_render"]
        rows.append([label, C.fmt_ratio(q["layer/original"]), C.fmt_ratio(q["eevee_output/original"]),
                     C.fmt_ratio(q["eevee_output/layer"]),
                     f"{cs['original']:.2f}, {cs['layer']:.2f}, {cs['eevee_output']:.2f}",
                     f"{fr['original']['wall']:.1f}, {fr['layer']['wall']:.1f}, "
                     f"{fr['eevee_output']['wall']:.1f}"])
    L.append(C.md_table(header, rows) + "\n")
    return "\n".join(L)


if __name__ == "__main__":
    if "--closures" in sys.argv:
        closures()
        sys.stdout.flush()
        os._exit(0)  # bpy 4.5 can hang in its exit handlers after EEVEE renders (seen here)
    else:
        main()
