# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 3: in-shader mapping against baked physical maps.

Perceptual maps (float32 EXR) on the UV sphere of the performance scene, rendered (a) through
the in-shader mapping group and (b) through physical maps baked from them and stored as float32
EXR, half EXR, 16-bit PNG and 8-bit PNG.  Writes out/report/perf_maps.{json,md},
docs/img/perf_maps.png.
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import numpy as np  # noqa: E402

SIZE = (64, 128)  # (H, W) texels
SAMPLES = 64
ROUNDS = 10
if C.QUICK:
    SAMPLES, ROUNDS = 4, 1

FORMATS = {  # name -> (file_format, color_depth, label)
    "exr32": ("OPEN_EXR", "32", "float32 EXR"),
    "exr16": ("OPEN_EXR", "16", "half EXR"),
    "png16": ("PNG", "16", "16-bit PNG"),
    "png8": ("PNG", "8", "8-bit PNG"),
}


def perceptual_maps(h, w):
    """Smoothly varying perceptual parameters (row 0 = bottom), every range exercised."""
    u = (np.arange(w) + 0.5) / w
    v = (np.arange(h) + 0.5) / h
    U, V = np.meshgrid(u, v)
    tau = 2 * np.pi
    rc = np.stack([0.5 + 0.45 * np.sin(tau * U), 0.45 + 0.35 * np.sin(tau * (U + V)),
                   0.3 + 0.25 * np.cos(tau * V)], axis=-1)
    g = np.stack([0.9 + 0.1 * np.sin(tau * V), 0.5 + 0.4 * np.cos(tau * U),
                  0.3 + 0.3 * np.sin(tau * 2 * U)], axis=-1)
    rough = 0.06 + 0.25 * (0.5 + 0.5 * np.sin(2 * tau * V + tau * U))
    haziness = 0.95 * np.mod(3 * U, 1.0)
    extent = 2.0 + 10.0 * V
    return {"core_reflectivity": rc.astype(np.float32), "edge_tint": g.astype(np.float32),
            "roughness": rough.astype(np.float32), "haziness": haziness.astype(np.float32),
            "haze_extent": extent.astype(np.float32)}


def main():
    C.start_blender()
    import bpy
    from hazy_gloss import api
    from hazy_gloss.conversion import convert as hconv
    from hazy_gloss.core.lobes import describe
    import perf_scene as P
    import scenes

    C.clean_file()
    scenes.setup_render(samples=SAMPLES, resolution=P.RESOLUTION, bounces=2)
    work = C.OUT / "maps"
    work.mkdir(parents=True, exist_ok=True)
    scene = bpy.context.scene
    h, w = SIZE
    pm = perceptual_maps(h, w)

    def write(name, rgb, fmt, depth):
        """Save an (h, w, 3) array through Image.save_render of a Non-Color image."""
        img = bpy.data.images.new(f"hg_w_{name}", w, h, alpha=False, float_buffer=True, is_data=True)
        rgba = np.concatenate([rgb, np.ones((h, w, 1), np.float32)], axis=-1).astype(np.float32)
        img.pixels.foreach_set(rgba.ravel())
        s = scene.render.image_settings
        if hasattr(s, "media_type"):
            s.media_type = "IMAGE"
        s.file_format = fmt
        s.color_mode = "RGB"
        s.color_depth = depth
        if fmt == "OPEN_EXR":
            s.exr_codec = "ZIP"
        else:
            s.compression = 15
        path = str(work / f"{name}{'.exr' if fmt == 'OPEN_EXR' else '.png'}")
        img.save_render(path, scene=scene)
        bpy.data.images.remove(img)
        return path

    def load(path):
        img = bpy.data.images.load(path, check_existing=False)
        img.colorspace_settings.name = "Non-Color"
        buf = np.empty(w * h * img.channels, np.float32)
        img.pixels.foreach_get(buf)
        return img, buf.reshape(h, w, img.channels)[..., :3]

    # ---- perceptual inputs (float32 EXR) and the in-shader material --------------------------
    packed = np.stack([pm["roughness"], pm["haziness"], pm["haze_extent"]], axis=-1)
    in_paths = {"rc": write("in_rc", pm["core_reflectivity"], "OPEN_EXR", "32"),
                "g": write("in_g", pm["edge_tint"], "OPEN_EXR", "32"),
                "s": write("in_s", packed, "OPEN_EXR", "32")}
    mat_in = api.create_material("maps in-shader", kind="CONDUCTOR", shader_mapping=True)
    tree = mat_in.node_tree
    group = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeGroup")
    tex = {k: _texture(tree, load(p)[0]) for k, p in in_paths.items()}
    tree.links.new(tex["rc"].outputs["Color"], group.inputs["Core Reflectivity"])
    tree.links.new(tex["g"].outputs["Color"], group.inputs["Edge Tint"])
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(tex["s"].outputs["Color"], sep.inputs[0])
    tree.links.new(sep.outputs[0], group.inputs["Roughness"])
    tree.links.new(sep.outputs[1], group.inputs["Haziness"])
    tree.links.new(sep.outputs[2], group.inputs["Haze Extent"])

    # ---- the conversion (the product's bpy-free texture conversion, float32) ------------------
    t0 = time.perf_counter()
    mapped = _map(hconv, pm)
    t_convert = time.perf_counter() - t0
    # float64 truth of the same inputs
    f64 = {k: v.astype(np.float64) for k, v in pm.items()}
    truth = describe("CONDUCTOR", core_reflectivity=f64["core_reflectivity"],
                     edge_tint=f64["edge_tint"], roughness=f64["roughness"],
                     haziness=f64["haziness"], haze_extent=f64["haze_extent"], strict=False)
    true_maps = {"ior": truth.fresnel["ior"], "extinction": truth.fresnel["extinction"],
                 "beta": truth.beta, "roughness_wide": truth.wide.roughness}

    res = {"size": SIZE, "samples": SAMPLES, "rounds": ROUNDS, "formats": {},
           "convert_seconds": t_convert,
           "convert_maps_api": hasattr(api, "convert_maps")}
    mats = {"in_shader": mat_in}
    specs = {s.name: s for s in mapped.specs}
    for key, (fmt, depth, label) in FORMATS.items():
        png = fmt == "PNG"
        enc = (lambda n, v: hconv.encode_png(specs[n], v)) if png else (lambda n, v: v)
        params = np.stack([mapped.maps["beta"], mapped.maps["roughness"],
                           mapped.maps["roughness_wide"]], axis=-1)
        paths = {"ior": write(f"{key}_ior", enc("ior", mapped.maps["ior"]), fmt, depth),
                 "extinction": write(f"{key}_ext", enc("extinction", mapped.maps["extinction"]),
                                     fmt, depth),
                 "params": write(f"{key}_par", params, fmt, depth)}
        imgs, decoded = {}, {}
        for n, pth in paths.items():
            imgs[n], raw = load(pth)
            decoded[n] = hconv.decode_png(specs[n], raw) if png and n != "params" else raw
        # map-level error against the float64 mapping
        errs = {}
        for n in ("ior", "extinction"):
            errs[n] = float(np.max(np.abs(decoded[n] - true_maps[n]) / np.maximum(true_maps[n], 1e-3)))
        errs["beta"] = float(np.max(np.abs(decoded["params"][..., 0] - true_maps["beta"])))
        errs["roughness_wide"] = float(np.max(np.abs(decoded["params"][..., 2]
                                                      - true_maps["roughness_wide"])))
        res["formats"][key] = {"label": label, "map_error": errs,
                               "bytes": sum(os.path.getsize(p) for p in paths.values())}
        mats[key] = _baked_material(tree_name=f"maps {key}", imgs=imgs, png=png)

    res["in_bytes"] = sum(os.path.getsize(p) for p in in_paths.values())

    # ---- the product's own conversion: api.convert_maps (float EXR and 16-bit PNG) -----------
    res["api"] = {}
    if hasattr(api, "convert_maps"):
        grey = lambda a: np.repeat(a[..., None], 3, axis=-1)  # noqa: E731
        api_in = {"core_reflectivity": in_paths["rc"], "edge_tint": in_paths["g"],
                  "roughness": write("in_R", grey(pm["roughness"]), "OPEN_EXR", "32"),
                  "haziness": write("in_bh", grey(pm["haziness"]), "OPEN_EXR", "32"),
                  "haze_extent": write("in_lam", grey(pm["haze_extent"]), "OPEN_EXR", "32")}
        for key, fmt, label in (("api_exr", "OPEN_EXR", "api.convert_maps, float EXR"),
                                ("api_png16", "PNG", "api.convert_maps, 16-bit PNG")):
            try:
                mat = api.create_material(f"maps {key}", kind="CONDUCTOR")
                t0 = time.perf_counter()
                result = api.convert_maps(api_in, str(work / key), kind="CONDUCTOR",
                                          file_format=fmt, material=mat, interpolation="Closest")
                dt = time.perf_counter() - t0
                dec = {}
                for name, pth in result.items():
                    _, raw = load(pth)
                    dec[name] = hconv.decode_png(result.specs[name], raw) if fmt == "PNG" else raw
                errs = {n: float(np.max(np.abs(dec[n] - true_maps[n])
                                        / np.maximum(true_maps[n], 1e-3)))
                        for n in ("ior", "extinction")}
                errs["beta"] = float(np.max(np.abs(dec["beta"][..., 0] - true_maps["beta"])))
                errs["roughness_wide"] = float(np.max(np.abs(dec["roughness_wide"][..., 0]
                                                              - true_maps["roughness_wide"])))
                res["api"][key] = {"label": label, "map_error": errs, "seconds": dt,
                                   "maps": len(result),
                                   "bytes": sum(os.path.getsize(p) for p in result.values())}
                mats[key] = mat
            except Exception as exc:  # someone else's API, possibly mid-change: report it
                res["api"][key] = {"label": label, "error": f"{type(exc).__name__}: {exc}"}
    info = P.lit_sphere_scene(mat_in)

    def render(mat, seed=0):
        P.assign(info, mat)
        scene.cycles.samples = SAMPLES
        scene.cycles.seed = seed
        return scenes.render_exr()

    base = render(mat_in)
    base2 = render(mat_in, seed=7)  # the noise level, for scale
    res["noise_rmse"] = _diff(base2, base)
    shots = [base]
    entries = dict(res["formats"])
    entries.update({k: v for k, v in res["api"].items() if k in mats})
    for key, entry in entries.items():
        img = render(mats[key])
        if key in FORMATS:
            shots.append(img)
        entry["image_rmse"] = _diff(img, base)
        entry["image_max"] = _maxdiff(img, base)
    fns = {k: (lambda m=m: render(m)) for k, m in mats.items()}
    times = C.interleaved(fns, ROUNDS, warmup=1)
    for key, entry in entries.items():
        entry["time_ratio"] = C.paired_ratio(times["cpu"], key, "in_shader")
        entry["wall_ratio"] = C.paired_ratio(times["wall"], key, "in_shader")
        print(f"[perf_maps] {key}: {entry['time_ratio']['median']:.3f} "
              f"rmse {entry['image_rmse']:.2e}", flush=True)
    strip = np.concatenate(shots, axis=1)
    res["fig"] = C.save_image(strip[..., :3], "perf_maps.png")
    C.write_json("perf_maps", res)
    (C.OUT / "perf_maps.md").write_text(_markdown(res))


def _map(hconv, pm):
    """Perceptual arrays -> physical maps with the product's texture-conversion core."""
    import inspect
    arrays = dict(pm)
    arrays.setdefault("anisotropy", np.float32(0.0))
    arrays.setdefault("rotation", np.float32(0.0))
    lam = arrays.pop("haze_extent")
    arrays["haze_extent_x"] = lam
    arrays["haze_extent_y"] = lam
    params = hconv.PARAMETERS
    for name in params:
        arrays.setdefault(name, np.float32(0.0))
    kw = {}
    if "kind" in inspect.signature(hconv.map_textures).parameters:
        kw["kind"] = "CONDUCTOR"
    return hconv.map_textures({n: arrays[n] for n in params}, **kw)


def _texture(tree, image):
    t = tree.nodes.new("ShaderNodeTexImage")
    t.image = image
    t.interpolation = "Closest"
    t.extension = "EXTEND"
    return t


def _baked_material(tree_name, imgs, png):
    """Two Metallic lobes + mix, every physical value from the baked maps (x/(1+x) decoded for
    PNG: η, κ >= 0 do not fit in [0, 1])."""
    import perf_scene as P
    mat, tree, out = P.empty_material(tree_name)
    tex = {k: _texture(tree, im) for k, im in imgs.items()}

    def decoded(k):
        s = tex[k].outputs["Color"]
        if not png:
            return s
        one_minus = tree.nodes.new("ShaderNodeVectorMath")
        one_minus.operation = "SUBTRACT"
        one_minus.inputs[0].default_value = (1.0, 1.0, 1.0)
        tree.links.new(s, one_minus.inputs[1])
        div = tree.nodes.new("ShaderNodeVectorMath")
        div.operation = "DIVIDE"
        tree.links.new(s, div.inputs[0])
        tree.links.new(one_minus.outputs[0], div.inputs[1])
        return div.outputs[0]

    ior, ext = decoded("ior"), decoded("extinction")
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(tex["params"].outputs["Color"], sep.inputs[0])
    lobes = []
    for rough in (sep.outputs[1], sep.outputs[2]):
        n = tree.nodes.new("ShaderNodeBsdfMetallic")
        n.distribution = "GGX"
        n.fresnel_type = "PHYSICAL_CONDUCTOR"
        tree.links.new(ior, n.inputs["IOR"])
        tree.links.new(ext, n.inputs["Extinction"])
        tree.links.new(rough, n.inputs["Roughness"])
        lobes.append(n)
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(sep.outputs[0], mix.inputs[0])
    tree.links.new(lobes[0].outputs[0], mix.inputs[1])
    tree.links.new(lobes[1].outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    return mat


def _diff(img, ref):
    m = ref[..., 3] > 0.999
    d = img[..., :3][m].astype(np.float64) - ref[..., :3][m]
    return float(np.sqrt(np.mean(d * d)) / np.mean(ref[..., :3][m]))


def _maxdiff(img, ref):
    m = ref[..., 3] > 0.999
    d = np.abs(img[..., :3][m].astype(np.float64) - ref[..., :3][m])
    return float(d.max() / np.mean(ref[..., :3][m]))


def _markdown(res):
    L = ["## 3. In-shader mapping against baked physical maps\n"]
    src = ("`hazy_gloss.api.convert_maps` exists and is measured as the product's path (one "
           "file per physical map, wired into the lean tree by `material=`, Closest "
           "interpolation), in the two formats it writes (float EXR, 16-bit PNG). To compare all "
           "four formats with one layout, the first four rows convert with the same bpy-free "
           "core (`hazy_gloss.conversion.convert.map_textures`, float32, its `encode_png` x/(1+x) encoding "
           "of η and κ), pack the maps into 3 RGB images and write them with "
           "`Image.save_render`." if res["convert_maps_api"] else
           "`hazy_gloss.api.convert_maps` did not exist when this ran, so the maps are baked "
           "here: the product's bpy-free conversion core (`hazy_gloss.conversion.convert.map_textures`, "
           "float32, its x/(1+x) PNG encoding of η and κ) and `Image.save_render`.")
    L.append(f"Perceptual maps ({res['size'][1]}x{res['size'][0]} texels: colour r_c and g, "
             "roughness, haziness ramps 0-0.95, haze extent 2-12) on the UV sphere of section 1, "
             "read with Closest interpolation (so every format is compared texel for texel; "
             "with Linear interpolation, interpolating physical maps also differs from mapping "
             "interpolated perceptual values). " + src + " The baked material is the lean tree "
             "with Image Texture inputs: 3 images (η RGB, κ RGB, β/R/R_w), plus two Vector Math "
             "nodes per PNG map to undo the encoding. In-shader: 3 float32 EXR perceptual images "
             "into the mapping group.\n")
    L.append(f"Image error: relative RMSE (over the sphere, / mean radiance) between the baked "
             f"and the in-shader render at the same seed and {res['samples']} spp, so the "
             f"sampling noise largely cancels; for scale, two in-shader renders with different "
             f"seeds differ by {res['noise_rmse']:.2e}. Map error: worst relative error of the "
             "decoded η, κ (absolute for β and R_w) against the float64 mapping of the same "
             "perceptual texels. Time: interleaved A B A B renders, ratio of the rendering "
             "process's CPU time baked / in-shader (median and interquartile range over "
             f"{res['rounds']} rounds; wall-time medians in the last column).\n")
    header = ["format", "bytes", "η max rel err", "κ max rel err", "β max abs err",
              "R_w max abs err", "image rel RMSE", "image max rel diff", "CPU time / in-shader",
              "wall / in-shader"]
    rows = []
    for key, f in res["formats"].items():
        e = f["map_error"]
        rows.append([f["label"], f"{f['bytes']:,}", C.sci(e["ior"]), C.sci(e["extinction"]),
                     C.sci(e["beta"]), C.sci(e["roughness_wide"]), C.sci(f["image_rmse"]),
                     C.sci(f["image_max"]), C.fmt_ratio(f["time_ratio"]),
                     f"{f['wall_ratio']['median']:.3f}"])
    for key, f in res.get("api", {}).items():
        if "error" in f:
            rows.append([f["label"], "-", "-", "-", "-", "-", f"failed: {f['error']}", "-", "-", "-"])
            continue
        e = f["map_error"]
        rows.append([f"{f['label']} ({f['maps']} maps)", f"{f['bytes']:,}", C.sci(e["ior"]),
                     C.sci(e["extinction"]), C.sci(e["beta"]), C.sci(e["roughness_wide"]),
                     C.sci(f["image_rmse"]), C.sci(f["image_max"]), C.fmt_ratio(f["time_ratio"]),
                     f"{f['wall_ratio']['median']:.3f}"])
    L.append(C.md_table(header, rows) + "\n")
    L.append(f"Perceptual inputs for the in-shader material: {res['in_bytes']:,} bytes (float32 "
             f"EXR). Converting the {res['size'][0] * res['size'][1]:,} texels took "
             f"{res['convert_seconds'] * 1e3:.1f} ms.\n")
    L.append(f"![in-shader, float32 EXR, half EXR, 16-bit PNG, 8-bit PNG]({res['fig']})\n")
    L.append("Left to right: in-shader mapping, baked float32 EXR, half EXR, 16-bit PNG, 8-bit "
             "PNG.\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
