# SPDX-License-Identifier: GPL-3.0-or-later
"""docs/performance.md section 5: mapping speed (per material, and texture conversion).

Writes out/report/perf_mapping.{json,md}.
"""
from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import numpy as np  # noqa: E402

N_MAP = 2000
N_UPDATE = 100
TEX = 1024
if C.QUICK:
    N_MAP, N_UPDATE, TEX = 100, 10, 256


def _per_call(fn, n, repeats=5):
    """Median over ``repeats`` batches of the mean time of one call (s)."""
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        out.append((time.perf_counter() - t0) / n)
    return statistics.median(out), min(out), max(out)


def main():
    C.start_blender()
    from hazy_gloss import api
    from hazy_gloss.conversion import convert as hconv
    from hazy_gloss.core import haze_mapping
    import perf_scene as P

    C.clean_file()
    res = {"materials": {}, "n_map": N_MAP, "n_update": N_UPDATE}
    for cls, params in P.CLASSES.items():
        p = api.normalise_parameters(dict(params))
        t_map = _per_call(lambda: api.map_parameters(p), N_MAP // 5)
        t_norm = _per_call(lambda: api.map_parameters(api.normalise_parameters(dict(params))),
                           N_MAP // 5)
        mat = api.create_material(f"speed {cls}", **params)
        hz = [params["haziness"] * 0.9, params["haziness"]]
        k = [0]

        def update():
            k[0] ^= 1
            api.update_material(mat, haziness=hz[k[0]])

        t_upd = _per_call(update, N_UPDATE // 5)
        mat_s = api.create_material(f"speed {cls} in-shader", shader_mapping=True, **params)

        def update_s():
            k[0] ^= 1
            api.update_material(mat_s, haziness=hz[k[0]])

        t_upd_s = _per_call(update_s, N_UPDATE // 5)
        n_create = max(N_UPDATE // 5, 2)

        def create():
            api.create_material("speed tmp", **params)

        t_create = _per_call(create, n_create, repeats=3)
        res["materials"][cls] = {"map_parameters": t_map, "normalise+map": t_norm,
                                 "update_material": t_upd, "update_material_in_shader": t_upd_s,
                                 "create_material": t_create}
        print(f"[perf_mapping] {cls}: map {t_map[0] * 1e6:.0f} us, update {t_upd[0] * 1e3:.2f} ms",
              flush=True)

    # ---- texture conversion throughput ----------------------------------------------------------
    rng = np.random.default_rng(1)
    h = w = TEX
    arrays = {"core_reflectivity": rng.uniform(0, 1, (h, w, 3)).astype(np.float32),
              "edge_tint": rng.uniform(0, 1, (h, w, 3)).astype(np.float32),
              "roughness": rng.uniform(0.01, 0.6, (h, w)).astype(np.float32),
              "anisotropy": np.float32(0.0), "rotation": np.float32(0.0),
              "haziness": rng.uniform(0, 0.99, (h, w)).astype(np.float32)}
    lam = rng.uniform(0, 20, (h, w)).astype(np.float32)
    arrays["haze_extent_x"] = arrays["haze_extent_y"] = lam
    conv = {}
    t0 = time.perf_counter()
    hconv.map_textures({n: arrays[n] for n in hconv.PARAMETERS}, kind="CONDUCTOR")
    conv["map_textures_iso"] = time.perf_counter() - t0
    arrays_a = dict(arrays)
    arrays_a["anisotropy"] = rng.uniform(0, 1, (h, w)).astype(np.float32)
    arrays_a["haze_extent_y"] = rng.uniform(0, 20, (h, w)).astype(np.float32)
    t0 = time.perf_counter()
    hconv.map_textures({n: arrays_a[n] for n in hconv.PARAMETERS}, kind="CONDUCTOR")
    conv["map_textures_aniso"] = time.perf_counter() - t0
    for dt, name in ((np.float32, "haze_mapping_f32"), (np.float64, "haze_mapping_f64")):
        t0 = time.perf_counter()
        haze_mapping(arrays["core_reflectivity"].astype(dt), arrays["edge_tint"].astype(dt),
                     (arrays["roughness"] ** 2).astype(dt), arrays["haziness"].astype(dt),
                     lam.astype(dt), alpha_max=1.0, max_aspect=10.0, strict=False)
        conv[name] = time.perf_counter() - t0
    res["texels"] = h * w
    res["convert"] = conv
    res["convert_maps"] = _convert_maps(api, arrays, h, w)
    C.write_json("perf_mapping", res)
    (C.OUT / "perf_mapping.md").write_text(_markdown(res, P))


def _convert_maps(api, arrays, h, w):
    """End-to-end api.convert_maps (read images, map, write EXR), when the API has it."""
    if not hasattr(api, "convert_maps"):
        return {"available": False}
    import bpy
    tmp = Path(tempfile.mkdtemp(prefix="hg_conv_"))
    inputs = {}
    for name in ("core_reflectivity", "edge_tint", "roughness", "haziness", "haze_extent_x"):
        a = np.asarray(arrays[name], np.float32)
        rgb = a if a.ndim == 3 else np.repeat(a[..., None], 3, axis=-1)
        img = bpy.data.images.new(f"conv_{name}", w, h, alpha=True, float_buffer=True,
                                  is_data=name not in ("core_reflectivity", "edge_tint"))
        rgba = np.concatenate([rgb, np.ones((h, w, 1), np.float32)], axis=-1)
        img.pixels.foreach_set(rgba.ravel())
        inputs["haze_extent" if name == "haze_extent_x" else name] = img
    try:
        t0 = time.perf_counter()
        api.convert_maps(inputs, str(tmp / "out"), kind="CONDUCTOR")
        return {"available": True, "seconds": time.perf_counter() - t0}
    except Exception as exc:  # the API is someone else's and may be mid-change: report it
        return {"available": True, "error": f"{type(exc).__name__}: {exc}"}


def _markdown(res, P):
    L = ["## 5. Mapping speed\n"]
    L.append("Per material: mean time of one call, median of 5 batches (min-max in brackets). "
             "`map_parameters` is the haze mapping of one material as Cycles renders it (numpy "
             "on 0-d arrays, strict validation); `update_material` changes the haziness and "
             "rebuilds the material's hazy nodes (what a UI edit costs); `create_material` "
             "creates a new material.\n")
    header = ["class", "map_parameters (µs)", "normalise + map (µs)", "update_material lean (ms)",
              "update_material in-shader (ms)", "create_material (ms)"]
    rows = []

    def us(t):
        return f"{t[0] * 1e6:.0f} ({t[1] * 1e6:.0f}-{t[2] * 1e6:.0f})"

    def ms(t):
        return f"{t[0] * 1e3:.2f} ({t[1] * 1e3:.2f}-{t[2] * 1e3:.2f})"

    for cls, d in res["materials"].items():
        rows.append([P.LABELS[cls], us(d["map_parameters"]), us(d["normalise+map"]),
                     ms(d["update_material"]), ms(d["update_material_in_shader"]),
                     ms(d["create_material"])])
    L.append(C.md_table(header, rows) + "\n")
    n = res["texels"]
    c = res["convert"]
    L.append(f"Texture conversion, {n:,} texels of random perceptual values (one run each):\n")
    rows = [["`conversion.convert.map_textures` (float32, isotropic conductor)", f"{c['map_textures_iso']:.2f}",
             f"{n / c['map_textures_iso'] / 1e6:.1f}"],
            ["`conversion.convert.map_textures` (float32, anisotropic conductor)", f"{c['map_textures_aniso']:.2f}",
             f"{n / c['map_textures_aniso'] / 1e6:.1f}"],
            ["`core.haze_mapping` float32 (no node conventions)", f"{c['haze_mapping_f32']:.2f}",
             f"{n / c['haze_mapping_f32'] / 1e6:.1f}"],
            ["`core.haze_mapping` float64", f"{c['haze_mapping_f64']:.2f}",
             f"{n / c['haze_mapping_f64'] / 1e6:.1f}"]]
    cm = res["convert_maps"]
    if not cm["available"]:
        note = "`api.convert_maps` did not exist when this ran: end-to-end conversion not measured."
    elif "error" in cm:
        note = f"`api.convert_maps` exists but failed here: {cm['error']} (not measured)."
    else:
        rows.append(["`api.convert_maps` end to end (images in memory -> float EXR files)",
                     f"{cm['seconds']:.2f}", f"{n / cm['seconds'] / 1e6:.2f}"])
        note = ""
    L.append(C.md_table(["path", "seconds", "Mtexel/s"], rows) + "\n")
    if note:
        L.append(note + "\n")
    return "\n".join(L)


if __name__ == "__main__":
    main()
