# SPDX-License-Identifier: GPL-3.0-or-later
"""Converted maps in Blender: image datablocks for map files, and a material's lean physical tree wired to them.

:func:`wire_material` puts one Image Texture (Non-Color) per map into the two lobes and the mix
(nodes.lobes.build_lobes) and stamps the material with the conversion's settings.
"""
from __future__ import annotations

import os

import bpy

from ... import constants as K
from ...conversion.convert import ConversionError
from ...core.graph import Graph
from .. import compat
from . import material
from .convert_inputs import UDIM_TOKEN, one_line, tile_paths, check_readable
from ..nodes.builder import TreeBuilder
from ..nodes.emit import emit
from ..nodes.lobes import build_lobes, tangent as tangent_node

__all__ = ("STAMP", "load_image", "image_for", "wire_material")

STAMP = K.MAPS_STAMP

# --------------------------------------------------------------------------------------------
# Wiring into a material
# --------------------------------------------------------------------------------------------


def load_image(path, label, check_existing=True):
    """A datablock of a file, or of a UDIM set (a ``<UDIM>`` path: its first tile loaded,
    then tiled), after the file check of every file."""
    first = path
    if UDIM_TOKEN in path:
        tiles = tile_paths(path)
        if not tiles:
            raise ConversionError(f"{label}: no UDIM tile matches {path}")
        for n, p in sorted(tiles.items()):
            check_readable(p, f"{label} tile {n}")
        first = tiles[min(tiles)]
    else:
        check_readable(path, label)
    try:
        img = bpy.data.images.load(first, check_existing=check_existing)
    except RuntimeError as exc:
        raise ConversionError(f"{label}: cannot read {first}: {one_line(exc)}") from None
    if UDIM_TOKEN in path:
        img.source = "TILED"
    return img


def image_for(path):
    """An image datablock for a written map (reused and reloaded when it exists), Non-Color."""
    want = os.path.normpath(path)
    img = None
    for im in bpy.data.images:
        if im.library is None and im.filepath and os.path.normpath(
                bpy.path.abspath(im.filepath)) == want:
            img = im
            break
    if img is None:
        img = load_image(path, os.path.basename(path), check_existing=False)
    else:
        img.reload()
    img.colorspace_settings.name = "Non-Color"
    img.alpha_mode = "CHANNEL_PACKED"
    if bpy.data.filepath:
        try:
            img.filepath = bpy.path.relpath(path)
        except ValueError:  # another drive
            pass
    return img


def wire_material(mat, result, *, interpolation="Linear", base_color=(0.0, 0.0, 0.0),
                  transmission=0.0, tangent="UV_MAP"):
    """Build ``mat``'s lean physical tree from converted maps: one Image Texture (Non-Color) per
    map into the two lobes and the mix (node_groups.lobes.build_lobes with sockets).  Replaces the
    add-on's own nodes (names starting "HG "); other nodes are kept.  Returns the BSDF socket."""
    report = result.report
    kind, distribution = report.kind, report.distribution
    if mat.library is not None:
        raise ConversionError(f"material {mat.name!r} is linked from a library and cannot be edited")
    if compat.VERSION < (5, 0, 0) and not mat.use_nodes:
        mat.use_nodes = True
    tree = mat.node_tree
    material.remove_ours(tree)
    tb = TreeBuilder(tree, x0=-200.0, roles=True)
    g = Graph()
    decoded = {}
    sources = {}
    for name, path in result.items():
        spec = result.specs[name]
        tex = tb.node("ShaderNodeTexImage", name=f"Map {name}", label=name.replace("_", " "),
                      depth=0)
        tex.image = image_for(path)
        tex.interpolation = interpolation
        tex.extension = "REPEAT"
        sources[name] = tex.outputs["Color"]
        x = g.input(name, vector=True)  # an Image Texture gives a colour
        if spec.channels == 1:
            x = g.separate(x)[0]
        if os.path.splitext(path)[1].lower() == ".png":  # the documented PNG encodings
            if spec.png == "ratio":
                x = (g.vmath("DIVIDE", x, g.vmath("SUBTRACT", 1.0, x)) if spec.channels == 3
                     else g.div(x, g.sub(1.0, x)))
            elif spec.png == "negate":
                x = g.mul(x, -1.0)
        decoded[name] = x
    socks = emit(tb, g, decoded, sources)
    shared = {"tangent": tangent_node(tb, tangent, 2) if report.anisotropic else None}
    narrow = dict(roughness=socks["roughness"], anisotropy=None, rotation=None)
    wide = dict(roughness=socks["roughness_wide"], anisotropy=None, rotation=None)
    if report.anisotropic:
        narrow.update(anisotropy=socks["anisotropy"], rotation=socks["rotation"])
        wide.update(anisotropy=socks["anisotropy_wide"], rotation=socks["rotation_wide"])
    if kind == "CONDUCTOR":
        fresnel = dict(ior=socks["ior"], extinction=socks["extinction"])
    elif kind == "DIELECTRIC":
        fresnel = dict(ior=socks["ior"], specular_tint=socks["specular_tint"],
                       base_color=tuple(base_color), transmission=float(transmission))
    else:
        fresnel = dict(colour_narrow=socks["weight_narrow"], colour_wide=socks["weight_wide"])
    depth = 1 + tb.max_depth
    bsdf = build_lobes(tb, kind, distribution, beta=socks["beta"], narrow=narrow, wide=wide,
                       fresnel=fresnel, shared=shared, depth=depth)
    out = material.output_node(tree)
    tree.links.new(bsdf, out.inputs["Surface"])
    if K.STAMP in mat:  # its constants no longer describe this texture-driven tree
        del mat[K.STAMP]
    mat[STAMP] = {"version": 1, "kind": kind, "distribution": distribution,
                  "anisotropic": int(report.anisotropic), "maps": dict(result)}
    return bsdf
