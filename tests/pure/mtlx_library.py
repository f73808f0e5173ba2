# SPDX-License-Identifier: GPL-3.0-or-later
"""A generated MaterialX material library, for the importer's speed benchmark and progress
tests: documents in the shapes public libraries write (tests/pure/mtlx_fixtures/README.md) —
OpenPBR, standard_surface, gltf_pbr and UsdPreviewSurface shaders with a handful of inputs,
one in ten driven by a node graph of images — with random values, and the damage such files
carry (one in two hundred has a colour written into a float input)."""
import random

_SURFACES = ("open_pbr_surface", "standard_surface", "gltf_pbr", "UsdPreviewSurface")


def _c(rng):
    return ", ".join(f"{rng.uniform(0.02, 0.98):.4f}" for _ in range(3))


def _f(rng, lo=0.0, hi=1.0):
    return f"{rng.uniform(lo, hi):.4f}"


def _inputs(kind, rng, damaged):
    if kind == "open_pbr_surface":
        rows = [("base_color", "color3", _c(rng)), ("base_metalness", "float", rng.choice(("0", "1"))),
                ("specular_roughness", "float", _f(rng, 0.05, 0.8)), ("specular_ior", "float", _f(rng, 1.3, 1.8))]
        if rng.random() < 0.3:
            rows += [("coat_weight", "float", "1"), ("coat_roughness", "float", _f(rng, 0.0, 0.2))]
        if rng.random() < 0.2:
            rows.append(("specular_roughness_anisotropy", "float", _f(rng, 0.0, 0.8)))
    elif kind == "standard_surface":
        rows = [("base", "float", "1"), ("base_color", "color3", _c(rng)),
                ("metalness", "float", rng.choice(("0", "1"))), ("specular_color", "color3", _c(rng)),
                ("specular_roughness", "float", _f(rng, 0.05, 0.8)), ("specular_IOR", "float", _f(rng, 1.3, 1.8))]
        if rng.random() < 0.2:
            rows += [("coat", "float", "1"), ("coat_roughness", "float", _f(rng, 0.0, 0.2))]
    elif kind == "gltf_pbr":
        rows = [("base_color", "color3", _c(rng)), ("metallic", "float", rng.choice(("0", "1"))),
                ("roughness", "float", _f(rng, 0.05, 0.9)), ("emissive", "color3", "0, 0, 0")]
    else:
        rows = [("diffuseColor", "color3", _c(rng)), ("metallic", "float", rng.choice(("0", "1"))),
                ("roughness", "float", _f(rng, 0.05, 0.9)), ("ior", "float", _f(rng, 1.3, 1.8))]
    if damaged:
        name, _, _ = rows[-1] if rows[-1][1] == "float" else rows[2]
        rows = [(n, t, (_c(rng) if n == name else v)) for n, t, v in rows]
    return rows


def library_text(n_materials, seed=1):
    """The XML text of a library of ``n_materials`` materials."""
    rng = random.Random(seed)
    out = ['<?xml version="1.0"?>', '<materialx version="1.39" colorspace="lin_rec709">']
    for i in range(n_materials):
        kind = _SURFACES[i % len(_SURFACES)]
        damaged = rng.random() < 0.005
        rows = _inputs(kind, rng, damaged)
        shader = f"SR_{kind}_{i}"
        textured = rng.random() < 0.1 and kind in ("open_pbr_surface", "standard_surface")
        if textured:
            g = f"NG_tex_{i}"
            out.append(f'  <nodegraph name="{g}">')
            out.append(f'    <image name="color_{i}" type="color3">')
            out.append(f'      <input name="file" type="filename" value="textures/m{i}_basecolor.png" colorspace="srgb_texture" />')
            out.append('    </image>')
            out.append(f'    <image name="rough_{i}" type="float">')
            out.append(f'      <input name="file" type="filename" value="textures/m{i}_roughness.png" />')
            out.append('    </image>')
            out.append(f'    <output name="color_out" type="color3" nodename="color_{i}" />')
            out.append(f'    <output name="rough_out" type="float" nodename="rough_{i}" />')
            out.append('  </nodegraph>')
            rough = "specular_roughness"
            rows = [r for r in rows if r[0] not in ("base_color", rough)]
        out.append(f'  <{kind} name="{shader}" type="surfaceshader">')
        for name, typ, val in rows:
            out.append(f'    <input name="{name}" type="{typ}" value="{val}" />')
        if textured:
            out.append(f'    <input name="base_color" type="color3" nodegraph="{g}" output="color_out" />')
            out.append(f'    <input name="specular_roughness" type="float" nodegraph="{g}" output="rough_out" />')
        out.append(f'  </{kind}>')
        out.append(f'  <surfacematerial name="Material_{i}" type="material">')
        out.append(f'    <input name="surfaceshader" type="surfaceshader" nodename="{shader}" />')
        out.append('  </surfacematerial>')
    out.append("</materialx>")
    return "\n".join(out) + "\n"


def write_library(path, target_bytes, seed=1):
    """Write a library of about ``target_bytes`` to ``path``; returns its material count."""
    probe = library_text(200, seed)
    n = max(1, int(200 * target_bytes / len(probe.encode())))
    with open(path, "w", encoding="utf-8") as f:
        f.write(library_text(n, seed))
    return n
