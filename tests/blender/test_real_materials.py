# SPDX-License-Identifier: GPL-3.0-or-later
"""Haze on real materials (issue 21): Principled and Metallic BSDFs built from measured values
(tests/data/measured_materials.py: metals' n, k and F0, dielectrics' IOR, liquids and glass,
thin films, ColorChecker bases), made hazy at 0.3, 0.6 and 0.9, in Cycles with a delta sun on a
flat plane (every pixel the BSDF at one pair of directions).  Per class:

- haziness 0 renders bit-identically;
- the peak (light and view along the normal, glossy pass) holds: <= 1e-5 with GGX, <= 1e-3
  with Multiscatter GGX, or the layer's notes say which part cannot hold and by how much (a
  metal's film), or that no haze shows (a colour at 1), with the setting that fixes it;
- light through a transmissive material keeps its direction and lobe (the hazy / original
  ratio of the transmitted light is one number at every angle) and loses exactly what the
  reflection gains (white furnace: R + T as the original's, Multiscatter GGX);
- a refracting sphere's transmitted highlight stays at its pixel."""
import importlib
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import bpy
import numpy as np
import pytest

import scenes
from measurements import record

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "data"))
import measured_materials as M  # noqa: E402

HAZINESS = (0.3, 0.6, 0.9)
PIXEL = (1, 2)  # off the plane's diagonal (the two triangles' shared edge)
THIN_WALL = bpy.app.version >= (5, 2, 0)


@pytest.fixture
def env(hg, clean_file):
    def mod(name):
        return importlib.import_module(f"{hg.__name__}.{name}")
    return SimpleNamespace(api=mod("api"), layer=mod("blender.layer"), exr=mod("exr"))


# --------------------------------------------------------------------------------------------
# The materials
# --------------------------------------------------------------------------------------------


def _principled(name, distribution, **inputs):
    mat = scenes.new_material(name)
    b = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    b.distribution = distribution
    for k, v in inputs.items():
        if isinstance(v, tuple) and len(v) == 3:
            v = v + (1.0,)
        b.inputs[k].default_value = v
    return mat


def _metallic(name, distribution, n, k, roughness):
    return scenes.metallic_material(name, roughness=roughness, ior=n, extinction=k,
                                    distribution=distribution)


def _cases():
    """name -> (class, build(distribution) -> material, distributions, haze keywords)."""
    out = {}
    both = ("GGX", "MULTI_GGX")
    for name, (n, k) in M.METALS.items():
        out[f"{name} (Metallic, n k)"] = (
            "metal", lambda d, n=n, k=k, nm=name: _metallic(nm, d, n, k, 0.25), both, {})
        out[f"{name} (Principled, F0)"] = (
            "metal", lambda d, nm=name: _principled(nm, d, **{"Metallic": 1.0, "Roughness": 0.3,
                                                            "Base Color": M.metal_f0(nm)}),
            ("MULTI_GGX",), {})
    for name, f0 in M.BRIGHT_METALS.items():
        f0 = f0 or M.metal_f0("silver")
        out[name] = ("bright metal", lambda d, f0=f0, nm=name: _principled(
            nm, d, **{"Metallic": 1.0, "Roughness": 0.3, "Base Color": f0}), both, {})
    for name, (ior, patch, rough) in M.OPAQUE.items():
        out[name] = ("opaque dielectric", lambda d, i=ior, p=patch, r=rough, nm=name: _principled(
            nm, d, **{"IOR": i, "Base Color": M.base_colour(p), "Roughness": r}), both, {})
    for name, (ior, tint, rough) in M.TRANSMISSIVE.items():
        out[name] = ("transmissive", lambda d, i=ior, t=tint, r=rough, nm=name: _principled(
            nm, d, **{"Transmission Weight": 1.0, "IOR": i, "Base Color": t, "Roughness": r}),
            both, {})
    out["metallic map over glass (m 0.5)"] = ("transmissive", lambda d: _principled(
        "glass under metal", d, **{"Transmission Weight": 1.0, "IOR": 1.52, "Metallic": 0.5,
                                  "Base Color": M.metal_f0("gold"), "Roughness": 0.2}), both, {})
    out["frosted window (Transmission 0.6)"] = ("transmissive", lambda d: _principled(
        "frosted", d, **{"Transmission Weight": 0.6, "IOR": 1.52, "Roughness": 0.3,
                         "Specular IOR Level": 0.7, "Base Color": (0.9, 0.9, 0.9)}), both, {})
    if THIN_WALL:
        for name in ("soda-lime glass", "polycarbonate"):
            ior, tint, rough = M.TRANSMISSIVE[name]
            out[f"{name}, thin wall"] = ("transmissive", lambda d, i=ior, t=tint, r=rough: _principled(
                "thin wall", d, **{"Transmission Weight": 1.0, "Thin Wall": True, "IOR": i,
                                   "Base Color": t, "Roughness": r}), both, {})
    for name, (sub, thick, film_ior) in M.FILMS.items():
        film = {"Thin Film Thickness": thick, "Thin Film IOR": film_ior}
        if sub in M.METALS:
            out[name] = ("metal with film", lambda d, s=sub, f=film, nm=name: _principled(
                nm, d, **{"Metallic": 1.0, "Roughness": 0.3, "Base Color": M.metal_f0(s), **f}),
                both, {})
        elif sub in ("glass", "water"):
            ior = M.TRANSMISSIVE["N-BK7 crown glass" if sub == "glass" else "water"][0]
            out[name] = ("transmissive with film", lambda d, i=ior, f=film, nm=name: _principled(
                nm, d, **{"Transmission Weight": 1.0, "IOR": i, "Roughness": 0.1,
                          "Base Color": (1.0, 1.0, 1.0), **f}), both, {})
        else:
            out[name] = ("dielectric with film", lambda d, s=sub, f=film, nm=name: _principled(
                nm, d, **{"IOR": 1.5, "Roughness": 0.25, "Base Color": M.base_colour(s), **f}),
                both, {})
    for patch in ("white", "light skin"):
        out[f"bright base {patch}, Keep Body Colour"] = (
            "bright base", lambda d, p=patch: _principled(
                f"body {p}", d, **{"IOR": 1.5, "Roughness": 0.3, "Base Color": M.base_colour(p)}),
            both, {"keep_body_colour": True})
    out["skin (subsurface), light skin"] = ("subsurface", lambda d: _principled(
        "skin", d, **{"IOR": 1.4, "Roughness": 0.45, "Subsurface Weight": 1.0,
                      "Base Color": M.base_colour("light skin")}), both, {})
    return out


CASES = _cases()
PARAMS = [pytest.param(name, dist, id=f"{name} [{dist}]")
          for name, (_, _, dists, _) in CASES.items() for dist in dists]


# --------------------------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------------------------


def _render(env, mat, light, passes=("combined",), bounces=0, key=None):
    scenes.setup_render("CYCLES", samples=1, resolution=(4, 4), bounces=bounces)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.flat_plane_scene(mat, light_dir=light)
    out = scenes.render_passes(env.exr.read_exr, passes)
    return out[key or passes[0]][PIXEL].astype(np.float64)


def _peak(env, mat):
    return _render(env, mat, (0.0, 0.0), passes=("glossy",))


def _transmitted(env, mat, angles=(175.0, 170.0, 165.0)):
    """Light from behind the plane (the view along its normal): bounces 1 (Cycles counts the
    transmission event)."""
    return np.array([_render(env, mat, (a, 0.0), bounces=1) for a in angles])


def _rel(a, b):
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-12))


# --------------------------------------------------------------------------------------------
# The tests
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name,dist", PARAMS)
def test_real_material(env, name, dist):
    cls, build, _, haze = CASES[name]
    mat = build(dist)
    original = _render(env, mat, (30.0, 0.0))
    env.api.make_hazy(mat, **haze)
    assert np.array_equal(_render(env, mat, (30.0, 0.0)), original), "haziness 0 changed it"
    before = _peak(env, mat)
    assert before.max() > 1e-4
    trans = cls.startswith("transmissive")
    t0 = _transmitted(env, mat) if trans else None
    tol = 1e-5 if dist == "GGX" else 1e-3
    worst, rows = 0.0, {}
    for h in HAZINESS:
        notes = env.api.update_material(mat, haziness=h)
        after = _peak(env, mat)
        err = _rel(after, before)
        rows[h] = dict(peak=err, notes=list(notes))
        if cls == "bright metal" and any("no haze shows" in n for n in notes):
            # said, with the fix: the cap allows haze, at the peak the note announces
            assert err <= tol, (h, err)
            note = next(n for n in notes if "no haze shows" in n)
            said = float(note.split("drops by ")[1].split("%")[0]) / 100.0
            capped = env.api.update_material(mat, reflectivity_cap=0.98)
            moved = 1.0 - float(_peak(env, mat).max() / before.max())
            assert not any("no haze shows" in n for n in capped), capped
            assert abs(moved - said) <= 1e-3 + tol, (moved, said)
            rows[h].update(capped_peak_drop=moved, said=said)
            env.api.update_material(mat, reflectivity_cap=1.0)
            continue
        if cls == "metal with film" and any("thin film" in n for n in notes):
            said = env.layer.film_peak_change(env.layer.layer_node(mat))
            ch = int(np.argmax(np.abs(after - before)))
            moved = float(after[ch] / before[ch] - 1.0)
            assert abs(moved - said) <= 0.05 * abs(said) + 2e-5, (moved, said)
            rows[h].update(said=said)
            continue
        if cls == "dielectric with film" and any("cannot hold" in n for n in notes):
            rows[h].update(said="cannot hold")
            continue
        assert not any("no haze shows" in n or "cannot hold" in n for n in notes), notes
        assert err <= tol, (h, err, notes)
        if cls == "bright base" and h == 0.9:  # the body cannot be kept: said, with the fix
            assert any("too bright to keep" in n and "at most" in n for n in notes), notes
        worst = max(worst, err)
        if trans and h == 0.6:
            t = _transmitted(env, mat)
            ratio = t / np.maximum(t0, 1e-30)
            # the same lobe and direction: one ratio at every angle, per channel (a film's
            # transmittance varies with the angle, and its raised reflectance with it: 5 %)
            spread = 0.05 if "film" in cls else 1e-4
            for c in range(3):
                r = ratio[:, c][t0[:, c] > 1e-3 * t0.max()]
                assert r.max() - r.min() <= spread * r.max(), ratio
            assert ratio.max() <= 1.0 + 1e-6, ratio  # dimmed, never brighter
            rows[h]["transmitted"] = float(ratio.mean())
            rows[h]["transmitted_spread"] = float((ratio.max(0) / ratio.min(0) - 1.0).max())
    record("real_materials", {f"{name} [{dist}]": dict(cls=cls, worst_peak=worst, **{
        str(h): v for h, v in rows.items()})})


FURNACE = ("water", "N-BK7 crown glass", "diamond", "frosted window (Transmission 0.6)")


@pytest.mark.parametrize("name", FURNACE)
def test_white_furnace_keeps_the_energy(env, name):
    """A single interface in a white world: every pixel is R + T of the closures.  With
    Multiscatter GGX (energy-preserving lobes) the hazy material's is the original's."""
    _, build, _, _ = CASES[name]
    mat = build("MULTI_GGX")
    node = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    node.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)  # no absorption
    env.api.make_hazy(mat)

    def furnace():
        vals = []
        for view in (0.0, 50.0):
            for o in list(bpy.data.objects):
                bpy.data.objects.remove(o)
            scenes.setup_render("CYCLES", samples=1024, resolution=(4, 4), bounces=2)
            scenes.flat_plane_scene(mat, view_dir=(view, 0.0), strength=0.0)
            scenes.uniform_world(1.0)
            vals.append(float(scenes.render_exr()[..., :3].mean()))
        return np.array(vals)
    e0 = furnace()
    out = {}
    for h in HAZINESS:
        env.api.update_material(mat, haziness=h)
        e = furnace()
        out[str(h)] = (e - e0).tolist()
        assert np.abs(e - e0).max() <= 1e-3, (h, e, e0)
    record("real_materials_furnace", {name: dict(original=e0.tolist(), change=out)})


def _sphere_scene(mat, sun_theta):
    scene = scenes.setup_render("CYCLES", samples=64, resolution=(24, 24), bounces=8)
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    scenes.analytic_sphere("HG Lens", (0.0, 0.0, 0.0), mat, radius=0.5)
    cam = bpy.data.objects.new("HG Cam", bpy.data.cameras.new("HG Cam"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 1.2
    scene.collection.objects.link(cam)
    cam.location = (0.0, -5.0, 0.0)
    cam.rotation_euler = (math.radians(90.0), 0.0, 0.0)
    scene.camera = cam
    # the sun behind the sphere, tilted: the spot it focuses sits where the IOR puts it
    scenes._sun(scenes.spherical_direction(90.0 + sun_theta, 90.0), 5.0)
    return scene


@pytest.mark.parametrize("name", ("water", "SF11 flint glass"))
def test_sphere_keeps_its_transmitted_highlight(env, name):
    _, build, _, _ = CASES[name]
    mat = build("MULTI_GGX")
    env.api.make_hazy(mat)
    _sphere_scene(mat, 12.0)
    before = scenes.render_exr()[..., :3].sum(-1)
    env.api.update_material(mat, haziness=0.5)
    after = scenes.render_exr()[..., :3].sum(-1)
    spot_b = np.unravel_index(np.argmax(before), before.shape)
    spot_a = np.unravel_index(np.argmax(after), after.shape)
    assert spot_a == spot_b, (spot_b, spot_a)
    assert after[spot_a] <= before[spot_b] * 1.05  # dimmed (within the render's noise)
    record("real_materials_sphere", {name: dict(spot=[int(x) for x in spot_b],
                                                ratio=float(after[spot_a] / before[spot_b]))})
