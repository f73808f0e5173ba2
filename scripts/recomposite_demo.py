# SPDX-License-Identifier: GPL-3.0-or-later
"""Edit haziness after the render (docs/compositing.md): the before/after picture and the cost.

    .venv/bin/python scripts/recomposite_demo.py [--samples 64] [--scale 1.0] [--out docs/img]

Renders a small scene (a hazy metal sphere, a hazy plastic sphere, a plain diffuse sphere on a
diffuse floor, a sun and a horizon-band environment) three ways and times each:
  1. the ordinary render only;
  2. with hazy_gloss.setup_recomposite (original layer + the four recomposite layers, non-hazy
     objects held out there) — the extra cost of the passes;
  3. the same without the holdout;
then recomposites with new haziness values (numpy and the compositor group, from the saved
EXR), re-renders directly at those values for comparison, and writes
``<out>/recomposite_before_after.png``: original | recomposite | direct re-render.
Measurements go to out/measurements/recomposite_cost.json and stdout.
"""
import argparse
import json
import math
import os
import struct
import sys
import tempfile
import time
import zlib

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import hazy_gloss  # noqa: E402
from hazy_gloss import recomposite as rc  # noqa: E402  (bpy-free)
from hazy_gloss.conversion.oiio import openimageio  # noqa: E402
from gallery import analytic_sphere, band_world  # noqa: E402  (scripts/ is on sys.path)

ORIGINAL = {"metal": 0.15, "plastic": 0.02}
EDITED = {"metal": 0.9, "plastic": 0.2}




def _diffuse(name, colour):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*colour, 1.0)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    return mat


def _world(scene):
    band_world(scene, "HG demo", [(0.0, (0.02, 0.02, 0.025, 1)), (0.5, (0.05, 0.07, 0.12, 1)),
                                  (0.62, (1.6, 1.6, 1.7, 1)),  # a bright band 14-30° above the horizon
                                  (0.75, (0.04, 0.06, 0.1, 1))])


def build_scene(api, samples, scale):
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = samples
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.seed = 1
    cy.max_bounces = cy.glossy_bounces = cy.diffuse_bounces = 4
    cy.sample_clamp_indirect = 0.0
    cy.blur_glossy = 0.0
    cy.caustics_reflective = False  # no sun caustics from the metal on the floor (fireflies)
    scene.render.resolution_x = int(360 * scale)
    scene.render.resolution_y = int(200 * scale)
    scene.render.resolution_percentage = 100
    scene.render.use_compositing = False
    scene.view_settings.view_transform = "Standard"
    _world(scene)
    mats = {
        "metal": api.create_material("Demo metal", kind="CONDUCTOR", core_reflectivity=(0.95, 0.75, 0.45),
                                     edge_tint=(1.0, 0.9, 0.7), roughness=0.1,
                                     haziness=ORIGINAL["metal"], haze_extent=8.0),
        "plastic": api.create_material("Demo plastic", kind="DIELECTRIC", core_reflectivity=0.04,
                                       roughness=0.1, haziness=ORIGINAL["plastic"], haze_extent=8.0,
                                       base_color=(0.02, 0.05, 0.12)),
    }
    analytic_sphere("Metal", (-1.15, 0.0, 0.5), mats["metal"])
    analytic_sphere("Plastic", (0.0, 0.25, 0.5), mats["plastic"])
    analytic_sphere("Plain", (1.15, 0.0, 0.5), _diffuse("Plain", (0.6, 0.25, 0.15)))
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-20, -20, 0), (20, -20, 0), (20, 20, 0), (-20, 20, 0)], [], [(0, 1, 2, 3)])
    floor = bpy.data.objects.new("Floor", mesh)
    scene.collection.objects.link(floor)
    floor.data.materials.append(_diffuse("Floor", (0.35, 0.35, 0.35)))
    cam_data = bpy.data.cameras.new("Cam")
    cam_data.lens = 50
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -5.2, 1.1)
    cam.rotation_euler = (math.radians(84.0), 0.0, 0.0)
    scene.camera = cam
    sun_data = bpy.data.lights.new("Sun", "SUN")
    sun_data.energy = 3.0
    sun_data.angle = math.radians(1.0)
    sun = bpy.data.objects.new("Sun", sun_data)
    scene.collection.objects.link(sun)
    sun.rotation_euler = (math.radians(50.0), 0.0, math.radians(35.0))
    return scene, mats


def _render_to(scene, path):
    scene.render.filepath = path
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t


def render_original_only(scene, comp, path):
    """The ordinary render (the recomposite layers disabled, no compositing)."""
    saved = {vl.name: vl.use for vl in scene.view_layers}
    comp_on = scene.render.use_compositing
    try:
        for vl in scene.view_layers:
            vl.use = vl.name not in rc.LAYERS
        scene.render.use_compositing = False
        seconds = _render_to(scene, path)
    finally:
        for vl in scene.view_layers:
            vl.use = saved[vl.name]
        scene.render.use_compositing = comp_on
    return seconds


def _seconds(text):
    """Blender's "MM:SS.ss" (or "HH:MM:SS.ss") time stamp -> seconds."""
    out = 0.0
    for part in text.split(":"):
        out = out * 60.0 + float(part)
    return out


def layer_times(comp, path):
    """{layer: (path tracing s, synchronisation s)} from the Cycles metadata of an EXR."""
    inp = openimageio().ImageInput.open(str(path))
    spec = inp.spec()
    inp.close()
    out = {}
    for attr in spec.extra_attribs:
        key = attr.name
        if key.startswith("cycles.") and key.endswith(".render_time"):
            layer = key[len("cycles."):-len(".render_time")]
            sync = spec.get_string_attribute(f"cycles.{layer}.synchronization_time", "0")
            out[layer] = (_seconds(str(attr.value)), _seconds(sync))
    return out


def srgb8(rgb):
    x = np.clip(rgb, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (x * 255.0 + 0.5).astype(np.uint8)


def write_png(path, rgb8):
    """A minimal RGB PNG writer (rows top first)."""
    h, w, _ = rgb8.shape
    raw = b"".join(b"\0" + rgb8[y].tobytes() for y in range(h))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data))

    with open(path, "wb") as fh:
        fh.write(b"\x89PNG\r\n\x1a\n")
        fh.write(chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)))
        fh.write(chunk(b"IDAT", zlib.compress(raw, 9)))
        fh.write(chunk(b"IEND", b""))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--out", default=os.path.join(REPO, "docs", "img"))
    args = ap.parse_args(argv)

    hazy_gloss.register()
    from hazy_gloss import api
    from hazy_gloss.blender.model import recomposite as comp

    tmp = tempfile.mkdtemp(prefix="hg_recomposite_")
    scene, mats = build_scene(api, args.samples, args.scale)
    t = {}
    comp.setup_recomposite(scene, holdout=False)
    comp._set_multilayer_exr(scene)
    t["original render only"] = render_original_only(scene, comp, os.path.join(tmp, "orig.exr"))
    t["original + 4 layers, no holdout"] = _render_to(scene, os.path.join(tmp, "noholdout.exr"))
    report = comp.setup_recomposite(scene, holdout=True)
    t["original + 4 layers, holdout"] = _render_to(scene, os.path.join(tmp, "passes.exr"))
    passes = rc.passes_from_exr(os.path.join(tmp, "passes.exr"))
    hazy = passes["mask"] > 0

    # the edit: keyed on the core-reflectivity AOV (metal r_c ~ 0.95, plastic 0.04)
    rc = passes["core_reflectivity"] / np.maximum(passes["mask"], 1e-6)[..., None]
    haziness = np.where(rc.max(axis=-1) > 0.2, EDITED["metal"], EDITED["plastic"]).astype(np.float32)
    t0 = time.perf_counter()
    edited = rc.recomposite(passes, haziness=haziness)
    t["numpy recomposite"] = time.perf_counter() - t0

    # the compositor group on the saved EXR (no scene render), same edit through a keyed map
    group = comp.build_compositor(scene, source=os.path.join(tmp, "passes.exr"))
    tree = group.id_data
    h, w = hazy.shape
    key = bpy.data.images.new("HG haziness map", w, h, float_buffer=True, is_data=True)
    key.pixels.foreach_set(np.repeat(haziness[..., None], 4, axis=-1).astype(np.float32).ravel())
    key.pack()
    node = tree.nodes.new("CompositorNodeImage")
    node.name = "HG RC Haziness map"
    node.image = key
    tree.links.new(node.outputs["Alpha"], group.inputs["New Haziness"])
    group.inputs["Haziness Factor"].default_value = 1.0
    s = scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format = "OPEN_EXR"
    s.color_mode = "RGBA"
    s.color_depth = "32"
    t["compositor recomposite (from EXR, no render)"] = _render_to(scene, os.path.join(tmp, "comp.exr"))
    ch = rc.read_exr(os.path.join(tmp, "comp.exr"))
    comp_img = np.stack([ch[c] for c in "RGBA"], axis=-1)

    # direct re-render at the edited values
    for kind, mat in mats.items():
        api.update_material(mat, haziness=EDITED[kind])
        comp.convert_material(mat)
    comp._set_multilayer_exr(scene)
    render_original_only(scene, comp, os.path.join(tmp, "direct.exr"))
    ch = rc.read_exr(os.path.join(tmp, "direct.exr"))
    layer = report["template"]
    direct = np.stack([ch[f"{layer}.Combined.{c}"] for c in "RGBA"], axis=-1)

    def tm(x):
        return x[..., :3] / (1.0 + x[..., :3])

    per_layer = {name: layer_times(comp, os.path.join(tmp, f"{name}.exr"))
                 for name in ("orig", "noholdout", "passes")}
    base_trace = per_layer["orig"][report["template"]][0]

    def extra(name):
        layers = per_layer[name]
        trace = sum(v[0] for k, v in layers.items() if k in rc.LAYERS)
        sync = sum(v[1] for k, v in layers.items() if k in rc.LAYERS)
        return {"path tracing s (4 layers)": trace, "x original path tracing":
                trace / base_trace if base_trace > 0 else None,  # tiny renders time as 0 s
                "synchronisation s (4 layers)": sync}

    m = {
        "resolution": [scene.render.resolution_x, scene.render.resolution_y],
        "samples": args.samples,
        "hazy pixel fraction": float(hazy.mean()),
        "seconds": t,
        "original layer: path tracing s, synchronisation s": per_layer["orig"][report["template"]],
        "extra layers, holdout": extra("passes"),
        "extra layers, no holdout": extra("noholdout"),
        "wall clock x original, holdout": t["original + 4 layers, holdout"] / t["original render only"],
        "wall clock x original, no holdout":
            t["original + 4 layers, no holdout"] / t["original render only"],
        "compositor vs numpy, max abs": float(np.abs(comp_img - edited).max()),
        "recomposite vs direct re-render, rms of x/(1+x) on hazy pixels":
            float(np.sqrt(np.mean((tm(edited) - tm(direct))[hazy] ** 2))),
        "original vs direct re-render, rms of x/(1+x) on hazy pixels (size of the edit)":
            float(np.sqrt(np.mean((tm(passes["original"]) - tm(direct))[hazy] ** 2))),
        "recomposite vs direct re-render, relative mean on hazy pixels":
            float(edited[..., :3][hazy].mean() / direct[..., :3][hazy].mean() - 1.0),
        "blender": bpy.app.version_string,
    }

    os.makedirs(args.out, exist_ok=True)
    gap = np.ones((h, 4, 3), np.float32)
    panel = np.concatenate([passes["original"][..., :3], gap, edited[..., :3], gap, direct[..., :3]],
                           axis=1)
    path = os.path.join(args.out, "recomposite_before_after.png")
    write_png(path, srgb8(panel[::-1]))  # row 0 of the arrays is the bottom row
    meas = os.path.join(REPO, "out", "measurements")
    os.makedirs(meas, exist_ok=True)
    with open(os.path.join(meas, "recomposite_cost.json"), "w") as fh:
        json.dump(m, fh, indent=1)
    print(json.dumps(m, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
