# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 6: what Make Hazy's layer node costs in Cycles (issue 20 item 6).

For representative materials an artist builds (a constant dielectric, a textured dielectric
with Base Color and Roughness images, a metal, a metallic map, a car paint with a hazy coat, and
the largest layer: a metallic map under a hazy coat) four variants are rendered interleaved on
the performance scene (benchmarks/perf_scene.py):

- ``original``: the artist's Principled BSDF, no haze;
- ``layered``:  the same material after ``api.make_hazy`` (haze on): one layer node whose group
  holds the BSDF copies the haze needs and their node math;
- ``floor``:    the original plus one Glossy BSDF per hazy layer (base, coat) in Mix Shaders:
  the least any second lobe can cost (not the same image);
- ``hand``:     the layer's closures typed in by hand (constant materials only): a Principled BSDF
  per BSDF slot the group renders, with the values its node math gives, and Mix Shaders with
  the factors it gives: what the group's math costs once Cycles has folded it.

Timing: CPU time of the rendering process per 64-spp render, variants in alternating order,
one warm-up round dropped, median of the per-round ratios (benchmarks/_common.interleaved).
The layered and hand-wired renders at the same seed are also compared pixel by pixel (they must
be the same image).  The largest layer is profiled against its original with
``perf record -e cpu-clock``: the symbols where the extra time goes.

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
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import numpy as np  # noqa: E402

SAMPLES = 64
ROUNDS = 12
#: issue 20 item 6: layered / original for one hazy layer, for base + coat
TARGET_ONE, TARGET_COAT = 1.10, 1.25
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
VARIANTS = ("original", "layered", "floor", "hand")


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


def hazy_layers(label):
    """How many hazy layers a class has (the base's, the coat's)."""
    inputs, _, haze = CLASSES[label]
    return int(haze.get("haziness", 0) > 0) + int(haze.get("coat_haziness", 0) > 0
                                                  and inputs.get("Coat Weight", 0) > 0)


def floor(bpy, label, images):
    """The original with one Glossy BSDF per hazy layer mixed in (factor 0.5: nothing folds)."""
    mat = original(bpy, label, images)
    mat.name = label + " floor"
    tree = mat.node_tree
    out = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    top = out.inputs["Surface"].links[0].from_socket
    for _ in range(hazy_layers(label)):
        glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
        glossy.inputs["Roughness"].default_value = 0.5
        mix = tree.nodes.new("ShaderNodeMixShader")
        mix.inputs["Fac"].default_value = 0.5
        tree.links.new(top, mix.inputs[1])
        tree.links.new(glossy.outputs[0], mix.inputs[2])
        top = mix.outputs[0]
    tree.links.new(top, out.inputs["Surface"])
    return mat


def hand_wired(bpy, layered):
    """The layer node's Cycles closure tree typed in: a fresh Principled BSDF per slot with the
    node's inputs and the values the group's math gives it, Mix Shaders with the factors it
    gives (layer_probe.slot_values / the group's graph evaluated: constant inputs only)."""
    import layer_probe
    from hazy_gloss.blender.model import layer, layer_values
    from hazy_gloss.core import layer_graph
    node = layer.layer_node(layered)
    lay = layer_values.graph_of(node)
    core = layer.original_node(layered)
    mat = bpy.data.materials.new(layered.name + " hand-wired")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new("ShaderNodeOutputMaterial")

    def build(t):
        if isinstance(t, layer_graph.Slot):
            b = tree.nodes.new(PRINCIPLED)
            b.distribution, b.subsurface_method = core.distribution, core.subsurface_method
            for s in node.inputs:
                if s.name in b.inputs and hasattr(s, "default_value"):
                    v = s.default_value
                    b.inputs[s.name].default_value = tuple(v) if hasattr(v, "__len__") else v
            for k, v in layer_probe.slot_values(layer_values, node, t.role).items():
                sock = b.inputs[k]
                if isinstance(v, tuple) and len(sock.default_value) == 4:
                    v = v[:3] + (1.0,)
                sock.default_value = v
            return b.outputs[0]
        f = layer_values.evaluate(node, {"f": t.factor})[0]["f"] if not t.add else None
        if f == 0.0:
            return build(t.a)
        if f == 1.0:
            return build(t.b)
        m = tree.nodes.new("ShaderNodeAddShader" if t.add else "ShaderNodeMixShader")
        off = 0 if t.add else 1
        if not t.add:
            m.inputs[0].default_value = f
        tree.links.new(build(t.a), m.inputs[off])
        tree.links.new(build(t.b), m.inputs[off + 1])
        return m.outputs[0]

    tree.links.new(build(lay.cycles), out.inputs["Surface"])
    return mat


def rendered_slots(layered):
    """(BSDF copies Cycles renders, exact?) of the layer node (layer_probe.rendered_slots)."""
    import layer_probe
    from hazy_gloss.blender.model import layer, layer_values
    return layer_probe.rendered_slots(layer_values, layer.layer_node(layered))


def counts(mat):
    nodes = mat.node_tree.nodes
    return {"top_level": len(nodes), "principled": sum(n.bl_idname == PRINCIPLED for n in nodes),
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
    for label, (_, tex, haze) in CLASSES.items():
        o = original(bpy, label, images)
        lay = original(bpy, label, images)
        lay.name = label + " layered"
        api.make_hazy(lay, **haze)
        mats[label] = {"original": o, "layered": lay, "floor": floor(bpy, label, images)}
        if not tex:
            mats[label]["hand"] = hand_wired(bpy, lay)
    info = P.lit_sphere_scene(mats["dielectric"]["original"])
    scene = bpy.context.scene

    def render(mat, seed=0):
        P.assign(info, mat)
        scene.cycles.samples = SAMPLES
        scene.cycles.seed = seed
        return scenes.render_exr()

    res = {"samples": SAMPLES, "rounds": ROUNDS, "resolution": P.RESOLUTION,
           "targets": {"one": TARGET_ONE, "coat": TARGET_COAT}, "texels": TEX,
           "blender": bpy.app.version_string, "classes": {}}
    for label, v in mats.items():
        t0 = time.perf_counter()
        variants = [k for k in VARIANTS if k in v]
        a, o = render(v["layered"]), render(v["original"])
        slots, exact_count = rendered_slots(v["layered"])
        times = C.interleaved({k: (lambda m=v[k]: render(m)) for k in variants}, ROUNDS, warmup=1)
        pairs = [("layered", "original"), ("floor", "original"), ("layered", "floor")]
        if "hand" in v:
            pairs += [("hand", "original"), ("layered", "hand")]
        row = {"counts": {k: counts(v[k]) for k in variants},
               "hazy_layers": hazy_layers(label), "slots": slots, "slots_exact": exact_count,
               "image_rmse_layered_vs_original": P.rel_rmse(a, o),
               "times": times,
               "ratios": {f"{x}/{y}": C.paired_ratio(times["cpu"], x, y) for x, y in pairs},
               "wall_ratios": {f"{x}/{y}": C.paired_ratio(times["wall"], x, y) for x, y in pairs},
               "cpu_seconds": {k: float(np.median(times["cpu"][k])) for k in variants}}
        if "hand" in v:
            row["image_rmse_hand_vs_layered"] = P.rel_rmse(render(v["hand"]), a)
        if _perf() and not C.QUICK and label == PROFILE_CLASS:
            row["profile"] = {k: profile(lambda m=v[k]: render(m), label, k)
                              for k in ("layered", "original")}
        res["classes"][label] = row
        print(f"[perf_layer] {label}: layered/original {row['ratios']['layered/original']['median']:.3f}, "
              f"floor/original {row['ratios']['floor/original']['median']:.3f} "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
    res["machine"] = C.machine()
    res["date"] = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    C.write_json("perf_layer", res)
    md = markdown(res)
    (C.OUT / "perf_layer.md").write_text(md)
    if os.environ.get("HG_REPORT_SECTION") != "1":  # standalone: update the docs in place
        C.write_section(BEGIN, END, md)


def _target(res, r):
    return res["targets"]["coat" if r["hazy_layers"] > 1 else "one"]


def markdown(res):
    L = ["## 6. Make Hazy's layer in Cycles: the cost\n"]
    L.append(f"Measured by `.venv/bin/python benchmarks/perf_layer.py` on {res['date']} "
             f"(bpy {res['blender']}, {C.machine_line(res['machine'])}).\n")
    L.append("The materials an artist builds, as they are (**original**), after Make Hazy with haze "
             "on (**layered**: `api.make_hazy`, one layer node), the **floor** (the original plus "
             "one Glossy BSDF per hazy layer in a Mix Shader: the least a second lobe can cost, "
             "not the same image) and, for the constant materials, the layer's closures "
             "**hand-wired** (a Principled BSDF per BSDF slot the group renders, with the values "
             "its node math gives, and the Mix factors it gives: what the group's math costs once "
             "Cycles has folded it; same image as the layer). Textured materials have no "
             "hand-wired form: their group computes per shading point. Scene of section 1 "
             f"({res['resolution'][0]}x{res['resolution'][1]} px, {res['samples']} spp, 2 bounces, "
             f"{res['texels']}x{res['texels']}-texel images read with Closest); CPU time of the "
             "rendering process, variants interleaved, one warm-up round dropped, "
             f"{res['rounds']} rounds, median of the per-round ratios [interquartile range].\n")
    header = ["material", "hazy layers", "BSDF copies rendered", "top-level nodes (orig., layered)",
              "layered / original (target)", "floor / original", "layered / floor",
              "hand-wired / original", "CPU s per render (orig., layered, floor)",
              "image RMSE hand vs layered"]
    rows, met, missed = [], [], []
    for label, r in res["classes"].items():
        q, cs, c = r["ratios"], r["cpu_seconds"], r["counts"]
        t = _target(res, r)
        lo = q["layered/original"]["median"]
        (met if lo <= t else missed).append(label)
        rows.append([label, str(r["hazy_layers"]),
                     f"{r['slots']}" + ("" if r["slots_exact"] else " (at most)"),
                     f"{c['original']['top_level']}, {c['layered']['top_level']}",
                     f"{C.fmt_ratio(q['layered/original'])} (<= {t:.2f})",
                     C.fmt_ratio(q["floor/original"]), C.fmt_ratio(q["layered/floor"]),
                     C.fmt_ratio(q["hand/original"]) if "hand/original" in q else "—",
                     f"{cs['original']:.2f}, {cs['layered']:.2f}, {cs['floor']:.2f}",
                     C.sci(r["image_rmse_hand_vs_layered"]) if "image_rmse_hand_vs_layered" in r
                     else "—"])
    L.append(C.md_table(header, rows) + "\n")
    L.append("Wall-time medians of the same renders, layered / original: " + ", ".join(
        f"{label} {r['wall_ratios']['layered/original']['median']:.3f}"
        for label, r in res["classes"].items()) + ".\n")
    hands = [r["ratios"]["layered/hand"]["median"] for r in res["classes"].values()
             if "layered/hand" in r["ratios"]]
    if hands:
        L.append(f"The group's node math costs nothing measurable with constant inputs: layered / "
                 f"hand-wired is {min(hands):.3f}-{max(hands):.3f} (Cycles folds it; the same "
                 "closures render). What the layer costs is its BSDF copies: each slot is a full "
                 "Principled BSDF, because the narrow and wide lobes share the Principled's "
                 "Fresnel and its layering of the diffuse, sheen and coat (Eqs. 1-2: one Fresnel "
                 "for both lobes; a Glossy BSDF lobe would leave the diffuse under it unattenuated "
                 "and its Fresnel angle-independent). The floor column is what a non-exact "
                 "Glossy lobe would cost; the layer uses the exact copies.\n")
    if missed:
        L.append(f"Target (layered / original <= {res['targets']['one']:.2f} for one hazy layer, "
                 f"<= {res['targets']['coat']:.2f} for base + coat): **not met** for "
                 f"{', '.join(missed)}" + (f"; met for {', '.join(met)}" if met else "") + ".\n")
    else:
        L.append("Target (layered / original <= "
                 f"{res['targets']['one']:.2f} for one hazy layer, <= {res['targets']['coat']:.2f} "
                 "for base + coat): **met** for every material.\n")
    for label, r in res["classes"].items():
        if "profile" not in r:
            continue
        lay, ref = r["profile"]["layered"], r["profile"]["original"]
        t_lay, t_ref = r["cpu_seconds"]["layered"], r["cpu_seconds"]["original"]
        extra = {s: lay.get(s, 0) * t_lay - ref.get(s, 0) * t_ref for s in set(lay) | set(ref)}
        syms = sorted(extra, key=lambda s: -extra[s])
        L.append(f"**Where the time goes ({label}, layered against original)**: `perf record -e "
                 f"cpu-clock` over {PROFILE_RENDERS} renders of each; share of the samples and "
                 "CPU seconds per render (share x median CPU time), the symbols that gain most "
                 f"first (total extra: {t_lay - t_ref:+.3f} s per render):\n")
        prow = [[f"`{s}`", f"{100 * lay.get(s, 0):.1f}%", f"{100 * ref.get(s, 0):.1f}%",
                 f"{extra[s]:+.3f}"] for s in syms[:10]]
        L.append(C.md_table(["symbol", "layered", "original", "extra CPU s / render"], prow) + "\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
