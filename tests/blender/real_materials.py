# SPDX-License-Identifier: GPL-3.0-or-later
"""The real materials of tests/data/measured_materials.py as Blender materials, by class, and
the renders that measure them (plain functions; import inside a bpy process).  Used by
tests/blender/test_real_materials.py and benchmarks/bench_real_materials.py."""
import sys
from pathlib import Path

import bpy
import numpy as np

import scenes

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "data"))
import measured_materials as M  # noqa: E402

PIXEL = (1, 2)  # off the plane's diagonal (the two triangles' shared edge)
THIN_WALL = bpy.app.version >= (5, 2, 0)


# --------------------------------------------------------------------------------------------
# The materials
# --------------------------------------------------------------------------------------------


def principled(name, distribution, **inputs):
    mat = scenes.new_material(name)
    b = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    b.distribution = distribution
    for k, v in inputs.items():
        if isinstance(v, tuple) and len(v) == 3:
            v = v + (1.0,)
        b.inputs[k].default_value = v
    return mat


def metallic(name, distribution, n, k, roughness):
    return scenes.metallic_material(name, roughness=roughness, ior=n, extinction=k,
                                    distribution=distribution)


def cases():
    """name -> (class, build(distribution) -> material, distributions, haze keywords)."""
    out = {}
    both = ("GGX", "MULTI_GGX")
    for name, (n, k) in M.METALS.items():
        out[f"{name} (Metallic, n k)"] = (
            "metal", lambda d, n=n, k=k, nm=name: metallic(nm, d, n, k, 0.25), both, {})
        out[f"{name} (Principled, F0)"] = (
            "metal", lambda d, nm=name: principled(nm, d, **{"Metallic": 1.0, "Roughness": 0.3,
                                                            "Base Color": M.metal_f0(nm)}),
            ("MULTI_GGX",), {})
    for name, f0 in M.BRIGHT_METALS.items():
        f0 = f0 or M.metal_f0("silver")
        out[name] = ("bright metal", lambda d, f0=f0, nm=name: principled(
            nm, d, **{"Metallic": 1.0, "Roughness": 0.3, "Base Color": f0}), both, {})
    for name, (ior, patch, rough) in M.OPAQUE.items():
        out[name] = ("opaque dielectric", lambda d, i=ior, p=patch, r=rough, nm=name: principled(
            nm, d, **{"IOR": i, "Base Color": M.base_colour(p), "Roughness": r}), both, {})
    for name, (ior, tint, rough) in M.TRANSMISSIVE.items():
        out[name] = ("transmissive", lambda d, i=ior, t=tint, r=rough, nm=name: principled(
            nm, d, **{"Transmission Weight": 1.0, "IOR": i, "Base Color": t, "Roughness": r}),
            both, {})
    out["metallic map over glass (m 0.5)"] = ("transmissive", lambda d: principled(
        "glass under metal", d, **{"Transmission Weight": 1.0, "IOR": 1.52, "Metallic": 0.5,
                                  "Base Color": M.metal_f0("gold"), "Roughness": 0.2}), both, {})
    out["frosted window (Transmission 0.6)"] = ("transmissive", lambda d: principled(
        "frosted", d, **{"Transmission Weight": 0.6, "IOR": 1.52, "Roughness": 0.3,
                         "Specular IOR Level": 0.7, "Base Color": (0.9, 0.9, 0.9)}), both, {})
    if THIN_WALL:
        for name in ("soda-lime glass", "polycarbonate"):
            ior, tint, rough = M.TRANSMISSIVE[name]
            out[f"{name}, thin wall"] = ("transmissive", lambda d, i=ior, t=tint, r=rough: principled(
                "thin wall", d, **{"Transmission Weight": 1.0, "Thin Wall": True, "IOR": i,
                                   "Base Color": t, "Roughness": r}), both, {})
    for name, (sub, thick, film_ior) in M.FILMS.items():
        film = {"Thin Film Thickness": thick, "Thin Film IOR": film_ior}
        if sub in M.METALS:
            out[name] = ("metal with film", lambda d, s=sub, f=film, nm=name: principled(
                nm, d, **{"Metallic": 1.0, "Roughness": 0.3, "Base Color": M.metal_f0(s), **f}),
                both, {})
        elif sub in ("glass", "water"):
            ior = M.TRANSMISSIVE["N-BK7 crown glass" if sub == "glass" else "water"][0]
            out[name] = ("transmissive with film", lambda d, i=ior, f=film, nm=name: principled(
                nm, d, **{"Transmission Weight": 1.0, "IOR": i, "Roughness": 0.1,
                          "Base Color": (1.0, 1.0, 1.0), **f}), both, {})
        else:
            out[name] = ("dielectric with film", lambda d, s=sub, f=film, nm=name: principled(
                nm, d, **{"IOR": 1.5, "Roughness": 0.25, "Base Color": M.base_colour(s), **f}),
                both, {})
    for patch in ("white", "light skin"):
        out[f"bright base {patch}, Keep Body Colour"] = (
            "bright base", lambda d, p=patch: principled(
                f"body {p}", d, **{"IOR": 1.5, "Roughness": 0.3, "Base Color": M.base_colour(p)}),
            both, {"keep_body_colour": True})
    out["skin (subsurface), light skin"] = ("subsurface", lambda d: principled(
        "skin", d, **{"IOR": 1.4, "Roughness": 0.45, "Subsurface Weight": 1.0,
                      "Base Color": M.base_colour("light skin")}), both, {})
    return out


# --------------------------------------------------------------------------------------------
# Rendering: a plane, an orthographic camera along its normal, a delta sun
# --------------------------------------------------------------------------------------------


def render(read_exr, mat, light, passes=("combined",), bounces=0):
    """One pixel of ``passes[0]`` (RGB, float64) with the sun at ``light`` = (θ, φ)."""
    scenes.setup_render("CYCLES", samples=1, resolution=(4, 4), bounces=bounces)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.flat_plane_scene(mat, light_dir=light)
    out = scenes.render_passes(read_exr, passes)
    return out[passes[0]][PIXEL].astype(np.float64)


def peak(read_exr, mat):
    """The glossy pass with light and view along the normal."""
    return render(read_exr, mat, (0.0, 0.0), passes=("glossy",))


def transmitted(read_exr, mat, angles=(175.0, 170.0, 165.0)):
    """Light from behind the plane (the view along its normal): bounces 1 (Cycles counts the
    transmission event)."""
    return np.array([render(read_exr, mat, (a, 0.0), bounces=1) for a in angles])


def rel(a, b):
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-12))


def _furnace_scene(mat, view, samples):
    """Only a plane of ``mat`` seen at ``view`` degrees, lit by a white world."""
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.setup_render("CYCLES", samples=samples, resolution=(4, 4), bounces=2)
    scenes.flat_plane_scene(mat, view_dir=(view, 0.0), strength=0.0)
    scenes.uniform_world(1.0)


def furnace(mat, views=(0.0, 50.0), samples=1024):
    """The plane in a white world: per view the mean pixel, R + T of the closures."""
    vals = []
    for view in views:
        _furnace_scene(mat, view, samples)
        vals.append(float(scenes.render_exr()[..., :3].mean()))
    return np.array(vals)


def furnace_passes(read_exr, mat, views=(0.0, 50.0), samples=1024):
    """:func:`furnace` split by Cycles' light passes: per view the mean pixel of the reflection
    ("glossy"), the transmission and the diffuse light ((direct + indirect) x colour each) and
    of the combined pass; {name: (views,) array}."""
    kinds = ("glossy", "transmission", "diffuse")
    names = ["combined"] + [f"{k}_{p}" for k in kinds for p in ("direct", "indirect", "color")]
    out = {k: [] for k in kinds + ("combined",)}
    for view in views:
        _furnace_scene(mat, view, samples)
        ps = scenes.render_passes(read_exr, names)
        out["combined"].append(float(ps["combined"].mean()))
        for k in kinds:
            light = (ps[f"{k}_direct"] + ps[f"{k}_indirect"]) * ps[f"{k}_color"]
            out[k].append(float(light.mean()))
    return {k: np.array(v) for k, v in out.items()}
