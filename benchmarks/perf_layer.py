# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 6: what Make Hazy's layer costs in Cycles (issue 13 item 9).

For representative materials an artist builds (a constant dielectric, a textured dielectric
with Base Color and Roughness images, a metal, a metallic map, a car paint with a hazy coat, and
the largest layer: a metallic map under a hazy coat, 8 Principled BSDFs)
three variants are rendered interleaved on the performance scene (benchmarks/perf_scene.py):

- ``original``: the artist's Principled BSDF, no haze;
- ``layered``:  the same material after ``api.make_hazy`` (haze on; the add-on's layer);
- ``hand``:     the same closures wired by hand: fresh Principled BSDFs and Mix Shaders with the
  layered tree's socket values typed in, the same texture nodes, and where the layer computes
  an input with node math from a texture (the textured dielectric), that math precomputed per
  texel into float images (the haze mapping of hazy_gloss.core in float64, read with Closest
  interpolation like every texture here, so both variants see the same texels).

Timing: CPU time of the rendering process per 64-spp render, variants in alternating order,
one warm-up round dropped, median of the per-round ratios (benchmarks/_common.interleaved).
The layered and hand-wired renders at the same seed are also compared pixel by pixel (they must
be the same image).  When the layer is above 1.05x the hand-wired equivalent, both are profiled
with ``perf record -e cpu-clock`` and the symbols where the extra time goes are listed.

    .venv/bin/python benchmarks/perf_layer.py          # also run by benchmarks/report.py

Writes out/report/perf_layer.{json,md} and, run standalone, replaces its section of
docs/performance.md (between the perf_layer markers).
"""
from __future__ import annotations

import datetime
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import numpy as np  # noqa: E402

SAMPLES = 64
ROUNDS = 12
TARGET = 1.05
TEX = 256  # texels per side of the images
PROFILE_RENDERS = 6
#: always profiled against its original: where the largest layer's extra time goes
PROFILE_CLASS = "metallic map under a hazy coat"
if C.QUICK:
    SAMPLES, ROUNDS, PROFILE_RENDERS = 4, 1, 1

PRINCIPLED = "ShaderNodeBsdfPrincipled"
BEGIN, END = "<!-- perf_layer:begin -->", "<!-- perf_layer:end -->"

#: label -> (Principled inputs, textured inputs -> image name, haze keywords)
CLASSES = {
    "dielectric": ({"Base Color": (0.05, 0.12, 0.35, 1.0), "Roughness": 0.2, "IOR": 1.5}, {},
                   dict(haziness=0.5, haze_extent=5.0)),
    "textured dielectric": ({"IOR": 1.5}, {"Base Color": "colour", "Roughness": "roughness"},
                            dict(haziness=0.5, haze_extent=5.0)),
    "metal": ({"Metallic": 1.0, "Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.25}, {},
              dict(haziness=0.6, haze_extent=5.0)),
    "metallic map": ({"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.25, "IOR": 1.6},
                     {"Metallic": "metallic"}, dict(haziness=0.6, haze_extent=5.0)),
    "car paint, hazy coat": ({"Metallic": 1.0, "Base Color": (0.6, 0.05, 0.05, 1.0),
                              "Roughness": 0.35, "Coat Weight": 1.0, "Coat Roughness": 0.03,
                              "Coat IOR": 1.5}, {},
                             dict(haziness=0.5, haze_extent=5.0, coat_haziness=0.6,
                                  coat_haze_extent=5.0)),
    "metallic map under a hazy coat": ({"Base Color": (0.9, 0.6, 0.3, 1.0), "Roughness": 0.25,
                                        "IOR": 1.6, "Coat Weight": 1.0, "Coat Roughness": 0.05},
                                       {"Metallic": "metallic"},
                                       dict(haziness=0.6, haze_extent=5.0, coat_haziness=0.5,
                                            coat_haze_extent=5.0)),
}
VARIANTS = ("original", "layered", "hand")


def textures(n=TEX):
    """The artist's images (row 0 = bottom): a colour pattern, a roughness map 0.1-0.5, a
    metallic map of metal and dielectric patches with fractional borders."""
    u = (np.arange(n) + 0.5) / n
    U, V = np.meshgrid(u, u)
    tau = 2 * np.pi
    colour = np.stack([0.35 + 0.3 * np.sin(tau * 3 * U), 0.25 + 0.2 * np.sin(tau * (U + 2 * V)),
                       0.15 + 0.1 * np.cos(tau * 4 * V)], -1)
    rough = 0.3 + 0.2 * np.sin(tau * 5 * U) * np.cos(tau * 3 * V)
    metallic = np.clip(2.0 * np.sin(tau * 4 * U) * np.sin(tau * 2 * V) + 0.5, 0.0, 1.0)
    grey = lambda a: np.repeat(a[..., None], 3, -1)  # noqa: E731
    return {"colour": (colour, False), "roughness": (grey(rough), True),
            "metallic": (grey(metallic), True)}


def new_image(bpy, name, rgb, data=True):
    h, w = rgb.shape[:2]
    img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True, is_data=data)
    rgba = np.concatenate([rgb, np.ones((h, w, 1))], -1).astype(np.float32)
    img.pixels.foreach_set(rgba.ravel())
    return img


def image_node(tree, img):
    t = tree.nodes.new("ShaderNodeTexImage")
    t.image = img
    t.interpolation = "Closest"
    return t


def original(bpy, label, images):
    inputs, tex, _ = CLASSES[label]
    mat = bpy.data.materials.new(label)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    b = next(n for n in tree.nodes if n.bl_idname == PRINCIPLED)
    b.distribution = "GGX"
    for k, v in inputs.items():
        b.inputs[k].default_value = v
    for sock, name in tex.items():
        tree.links.new(image_node(tree, images[name]).outputs["Color"], b.inputs[sock])
    return mat


def baked(bpy, label, images):
    """The layer's per-texel node math precomputed (hazy_gloss.core in float64), by the input
    it feeds: {"IOR": image, "Roughness": image (the wide lobe's), "Fac": image (β)}."""
    from hazy_gloss.core.lobes import describe
    inputs, tex, haze = CLASSES[label]
    if "Roughness" not in tex:
        return {}
    rough = images[tex["Roughness"]].pixels[:]
    n = images[tex["Roughness"]].size[0]
    r = np.asarray(rough, np.float64).reshape(n, n, 4)[..., 0]
    f0 = ((inputs["IOR"] - 1.0) / (inputs["IOR"] + 1.0)) ** 2
    d = describe("DIELECTRIC", "GGX", core_reflectivity=np.full(r.shape + (3,), f0),
                 roughness=r, haziness=np.full(r.shape, haze["haziness"]),
                 haze_extent=haze["haze_extent"])
    grey = lambda a: np.repeat(np.asarray(a, np.float64).reshape(r.shape)[..., None], 3, -1)  # noqa: E731
    return {"IOR": new_image(bpy, f"{label} IOR", grey(d.fresnel["ior"])),
            "Roughness": new_image(bpy, f"{label} wide roughness", grey(d.wide.roughness)),
            "Fac": new_image(bpy, f"{label} beta", grey(d.beta))}


def _is_ours(node):
    return isinstance(node.get("hazy_gloss_role"), str)


def hand_wired(bpy, layered, bakes):
    """Fresh nodes reproducing ``layered``'s closures: every Principled BSDF and Mix Shader the
    layered tree renders, with its settings and unlinked socket values; links from the artist's
    texture nodes re-made; links from the layer's node math replaced by ``bakes`` (by input)."""
    mat = bpy.data.materials.new(layered.name + " hand-wired")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    made, tex = {}, {}

    def source(sock):
        link = sock.links[0]
        node = link.from_node
        if node.bl_idname == "ShaderNodeTexImage" and not _is_ours(node):
            if node.name not in tex:
                tex[node.name] = image_node(tree, node.image)
            return tex[node.name].outputs[link.from_socket.identifier]
        key = "Fac" if sock.node.bl_idname == "ShaderNodeMixShader" else sock.name
        if key not in bakes:
            raise RuntimeError(f"{sock.node.name}.{sock.name} is computed by {node.name}: "
                               "nothing baked for it")
        k = ("bake", key)
        if k not in tex:
            tex[k] = image_node(tree, bakes[key])
        return tex[k].outputs["Color"]

    def build(node):
        if node.name in made:
            return made[node.name]
        if node.bl_idname == PRINCIPLED:
            n = tree.nodes.new(PRINCIPLED)
            n.distribution, n.subsurface_method = node.distribution, node.subsurface_method
        elif node.bl_idname == "ShaderNodeMixShader":
            n = tree.nodes.new("ShaderNodeMixShader")
        else:
            raise RuntimeError(f"unexpected node {node.bl_idname} in the layered tree")
        for src, dst in zip(node.inputs, n.inputs):
            if src.is_linked:
                from_node = src.links[0].from_node
                if src.type == "SHADER":
                    tree.links.new(build(from_node).outputs[0], dst)
                else:
                    tree.links.new(source(src), dst)
            elif hasattr(src, "default_value"):
                v = src.default_value
                dst.default_value = tuple(v) if hasattr(v, "__len__") else v
        made[node.name] = n
        return n

    lo = next(n for n in layered.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"
              and n.is_active_output)
    tree.links.new(build(lo.inputs["Surface"].links[0].from_node).outputs[0], out.inputs["Surface"])
    return mat


def counts(mat):
    nodes = mat.node_tree.nodes
    return {"principled": sum(n.bl_idname == PRINCIPLED for n in nodes),
            "mix_shaders": sum(n.bl_idname == "ShaderNodeMixShader" for n in nodes),
            "math": sum(n.bl_idname in ("ShaderNodeMath", "ShaderNodeVectorMath", "ShaderNodeMix",
                                        "ShaderNodeSeparateXYZ", "ShaderNodeCombineXYZ")
                        for n in nodes),
            "images": sum(n.bl_idname == "ShaderNodeTexImage" for n in nodes)}


# --------------------------------------------------------------------------------------------
# Profiling
# --------------------------------------------------------------------------------------------


def _perf():
    return shutil.which("perf")


def profile(render, label, variant):
    """perf record -e cpu-clock on this process while it renders; returns {symbol: share}."""
    data = C.OUT / f"perf_layer_{re.sub(r'[^a-z]+', '_', label)}_{variant}.data"
    proc = subprocess.Popen([_perf(), "record", "-e", "cpu-clock", "-F", "2000", "-p",
                             str(os.getpid()), "-o", str(data)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.0)
    for _ in range(PROFILE_RENDERS):
        render()
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=60)
    rep = subprocess.run([_perf(), "report", "-i", str(data), "--stdio", "--no-children",
                          "--sort", "symbol", "--percent-limit", "0.3"],
                         capture_output=True, text=True).stdout
    shares = {}
    for line in rep.splitlines():
        m = re.match(r"\s*([\d.]+)%\s+\[\.\]\s+(.*?)\s*$", line)
        if m:
            shares[_short(m.group(2))] = shares.get(_short(m.group(2)), 0.0) + float(m.group(1)) / 100
    return shares


def _short(sym):
    """ccl::svm_eval_nodes<...>(...) [clone .constprop.0] -> svm_eval_nodes."""
    s = re.sub(r"\s+-\s+-\s*$", "", sym)  # perf's IPC columns
    s = re.sub(r"\[clone[^\]]*\]", "", s).strip()
    s = re.sub(r"\(.*$", "", s)
    depth, out = 0, []
    for ch in s:
        if ch == "<":
            depth += 1
        elif ch == ">":
            depth -= 1
        elif depth == 0:
            out.append(ch)
    return "".join(out).replace("ccl::", "").strip() or sym


# --------------------------------------------------------------------------------------------


def main():
    C.start_blender()
    import bpy
    from hazy_gloss import api
    import perf_scene as P
    import scenes

    C.clean_file()
    scenes.setup_render(samples=SAMPLES, resolution=P.RESOLUTION, bounces=2)
    images = {k: new_image(bpy, k, rgb, data) for k, (rgb, data) in textures().items()}
    mats = {}
    for label, (_, _, haze) in CLASSES.items():
        o = original(bpy, label, images)
        lay = original(bpy, label, images)
        lay.name = label + " layered"
        api.make_hazy(lay, **haze)
        mats[label] = {"original": o, "layered": lay,
                       "hand": hand_wired(bpy, lay, baked(bpy, label, images))}
    info = P.lit_sphere_scene(mats["dielectric"]["original"])
    scene = bpy.context.scene

    def render(mat, seed=0):
        P.assign(info, mat)
        scene.cycles.samples = SAMPLES
        scene.cycles.seed = seed
        return scenes.render_exr()

    res = {"samples": SAMPLES, "rounds": ROUNDS, "resolution": P.RESOLUTION, "target": TARGET,
           "texels": TEX, "blender": bpy.app.version_string, "classes": {}}
    for label, v in mats.items():
        t0 = time.perf_counter()
        a, b = render(v["layered"]), render(v["hand"])
        o = render(v["original"])
        same = P.rel_rmse(b, a)
        times = C.interleaved({k: (lambda m=v[k]: render(m)) for k in VARIANTS}, ROUNDS, warmup=1)
        row = {"counts": {k: counts(v[k]) for k in VARIANTS},
               "image_rmse_hand_vs_layered": same,
               "image_rmse_layered_vs_original": P.rel_rmse(a, o),
               "times": times,
               "ratios": {f"{x}/{y}": C.paired_ratio(times["cpu"], x, y)
                          for x, y in (("layered", "hand"), ("layered", "original"),
                                       ("hand", "original"))},
               "wall_ratios": {f"{x}/{y}": C.paired_ratio(times["wall"], x, y)
                               for x, y in (("layered", "hand"), ("layered", "original"))},
               "cpu_seconds": {k: float(np.median(times["cpu"][k])) for k in VARIANTS}}
        if _perf() and not C.QUICK:
            who = ()
            if row["ratios"]["layered/hand"]["median"] > TARGET:
                who += ("layered", "hand")
            if label == PROFILE_CLASS:
                who += ("layered", "original")
            row["profile"] = {k: profile(lambda m=v[k]: render(m), label, k)
                              for k in dict.fromkeys(who)}
        res["classes"][label] = row
        print(f"[perf_layer] {label}: layered/hand {row['ratios']['layered/hand']['median']:.3f}, "
              f"layered/original {row['ratios']['layered/original']['median']:.3f} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    res["machine"] = C.machine()
    res["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    C.write_json("perf_layer", res)
    md = markdown(res)
    (C.OUT / "perf_layer.md").write_text(md)
    if os.environ.get("HG_REPORT_SECTION") != "1":  # standalone: update the docs in place
        C.write_section(BEGIN, END, md)


def markdown(res):
    L = ["## 6. Make Hazy's layer in Cycles: the cost\n"]
    L.append(f"Measured by `.venv/bin/python benchmarks/perf_layer.py` on {res['date']} "
             f"(bpy {res['blender']}, {C.machine_line(res['machine'])}).\n")
    L.append("The materials an artist builds, as they are (**original**), after Make Hazy with haze "
             "on (**layered**: `api.make_hazy`), and the same closures **hand-wired**: fresh "
             "Principled BSDFs and Mix Shaders with the layered tree's socket values typed in and "
             "the same texture nodes; where the layer computes an input with node math from a "
             "texture (the textured dielectric: the wide lobe's Roughness, both lobes' IOR and β "
             "depend on the Roughness image), the hand-wired tree reads that math precomputed per "
             "texel into float images instead (hazy_gloss.core in float64; every image read with "
             f"Closest interpolation, {res['texels']}x{res['texels']} texels). Scene of section 1 "
             f"({res['resolution'][0]}x{res['resolution'][1]} px, {res['samples']} spp, 2 bounces); "
             "CPU time of the rendering process, variants interleaved, one warm-up round dropped, "
             f"{res['rounds']} rounds, median of the per-round ratios [interquartile range]. The "
             "layered and hand-wired images at the same seed are compared pixel by pixel "
             "(relative RMSE over the sphere: they are the same closures).\n")
    header = ["material", "BSDFs / Mix Shaders", "layer's math nodes", "layered / hand-wired "
              f"(target <= {res['target']:.2f})", "layered / original", "hand-wired / original",
              "(layered / original - 1) per added BSDF",
              "CPU s per render (orig., layered, hand)", "image RMSE layered vs hand"]
    rows = []
    over = []
    for label, r in res["classes"].items():
        c = r["counts"]["layered"]
        q = r["ratios"]
        cs = r["cpu_seconds"]
        rows.append([label, f"{c['principled']} / {c['mix_shaders']}", str(c["math"]),
                     C.fmt_ratio(q["layered/hand"]), C.fmt_ratio(q["layered/original"]),
                     C.fmt_ratio(q["hand/original"]),
                     f"{(q['layered/original']['median'] - 1) / max(c['principled'] - 1, 1):.3f}",
                     f"{cs['original']:.2f}, {cs['layered']:.2f}, {cs['hand']:.2f}",
                     C.sci(r["image_rmse_hand_vs_layered"])])
        if q["layered/hand"]["median"] > res["target"]:
            over.append(label)
    L.append(C.md_table(header, rows) + "\n")
    L.append("Wall-time medians of the same renders, layered / hand-wired: " + ", ".join(
        f"{label} {r['wall_ratios']['layered/hand']['median']:.3f}"
        for label, r in res["classes"].items()) + ".\n")
    worst = max(r["ratios"]["layered/hand"]["median"] for r in res["classes"].values())
    per = [(r["ratios"]["layered/original"]["median"] - 1)
           / max(r["counts"]["layered"]["principled"] - 1, 1) for r in res["classes"].values()]
    two = [r["ratios"]["layered/original"]["median"] for r in res["classes"].values()
           if r["counts"]["layered"]["principled"] == 2]
    lo = min(two) if two else float("nan")
    big = max(res["classes"].values(), key=lambda r: r["counts"]["layered"]["principled"])
    hi, hi_bsdfs = big["ratios"]["layered/original"]["median"], big["counts"]["layered"]["principled"]
    L.append(f"The layer's own machinery costs nothing measurable: layered / hand-wired is "
             f"{min(r['ratios']['layered/hand']['median'] for r in res['classes'].values()):.3f}-"
             f"{worst:.3f} (same closures, same images; with a Roughness texture the layer's "
             "node math per shading point costs about what reading the three precomputed images "
             "costs). What the layer costs against the original is its closures: "
             f"{min(per):.2f}-{max(per):.2f} of the original's render time per added Principled "
             f"copy in this scene, from {lo:.2f}x for the two-BSDF layers to {hi:.2f}x for the "
             f"{hi_bsdfs}-BSDF one.\n")
    if not over:
        L.append(f"Target (layered <= {res['target']:.2f}x the hand-wired closures): **met** for "
                 "every material.\n")
    else:
        L.append(f"Target (layered <= {res['target']:.2f}x the hand-wired closures): **not met** "
                 f"for {', '.join(over)}; met for the others.\n")
    for label, r in res["classes"].items():
        for other in ("hand", "original"):
            if other not in r.get("profile", {}):
                continue
            lay, ref = r["profile"]["layered"], r["profile"][other]
            t_lay, t_ref = r["cpu_seconds"]["layered"], r["cpu_seconds"][other]
            extra = {s: lay.get(s, 0) * t_lay - ref.get(s, 0) * t_ref for s in set(lay) | set(ref)}
            syms = sorted(extra, key=lambda s: -extra[s])
            what = "hand-wired" if other == "hand" else "original"
            L.append(f"**Where the time goes ({label}, layered against {what})**: `perf record -e "
                     f"cpu-clock` over {PROFILE_RENDERS} renders of each; share of the samples and "
                     "CPU seconds per render (share x median CPU time), the symbols that gain most "
                     f"first (total extra: {t_lay - t_ref:+.3f} s per render):\n")
            prow = [[f"`{s}`", f"{100 * lay.get(s, 0):.1f}%", f"{100 * ref.get(s, 0):.1f}%",
                     f"{extra[s]:+.3f}"] for s in syms[:10]]
            L.append(C.md_table(["symbol", "layered", what, "extra CPU s / render"], prow) + "\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
