# SPDX-License-Identifier: GPL-3.0-or-later
"""Convert a PBR texture set (base colour, metallic, roughness, normal, coat, alpha, as any
texture library ships them) plus haze maps into a Principled material with a converted haze
layer.

The set goes into a Principled BSDF (a new material, or the user's own: its empty inputs take
the maps; an input the user linked to something else is refused, never replaced), which then
becomes a layer node (blender.layer) whose group reads the haze mapping's per-texel values —
the raised IOR / Base Color, the wide roughness, β per part, the coat's (core.layer_graph.BAKED)
— from maps: the live layer's own graph (core.layer_graph, evaluated in numpy with Blender's
float32 node semantics) over every texel, written all or nothing (blender.convert's
transaction).  A Metallic map splits the material per texel into its dielectric and metal
parts, each with its own β map.  (Make Hazy gives the live layer instead: no maps, the shader
computes the same per shading point.)
"""
from __future__ import annotations

import os
import time

import bpy
import numpy as np

from .. import constants as K
from .. import convert as core
from ..convert import ConversionError, did_you_mean
from ..core import layer_graph
from ..core.graph import evaluate
from ..core.parameters import HAZE_DEFAULTS, RANGES
from . import compat, layer, layer_group
from .convert import (_EXT, _Source, _Transaction, _Writer, _check_prefix, _check_readable,
                      _check_targets, _final_path, _image_for, _out_path, _reason)
from .make_hazy import find_core_bsdf

#: PBR maps: name -> (Principled input, role of the values, colour space of the image node).
PBR_MAPS = {
    "base_color": ("Base Color", "colour", "sRGB"),
    "metallic": ("Metallic", "data", "Non-Color"),
    "roughness": ("Roughness", "data", "Non-Color"),
    "normal": ("Normal", "normal", "Non-Color"),
    "coat": ("Coat Weight", "data", "Non-Color"),
    "coat_roughness": ("Coat Roughness", "data", "Non-Color"),
    "alpha": ("Alpha", "data", "Non-Color"),
}
#: Haze maps (or constants) of the layer.
HAZE_MAPS = ("haziness", "haze_extent", "haze_extent_x", "haze_extent_y", "coat_haziness",
             "coat_haze_extent")
#: Inputs that mark a conversion as a PBR set (api.convert_maps routes them here).
PBR_KEYS = ("base_color", "metallic", "normal", "coat", "coat_roughness", "opacity",
            "coat_haziness", "coat_haze_extent")
_RANGE = {"base_color": (0.0, 1.0), "metallic": (0.0, 1.0), "roughness": (0.0, 1.0),
          "coat": (0.0, 1.0), "coat_roughness": (0.0, 1.0), "alpha": (0.0, 1.0),
          "haziness": RANGES["haziness"], "coat_haziness": RANGES["coat_haziness"],
          "haze_extent": (0.0, None), "haze_extent_x": (0.0, None), "haze_extent_y": (0.0, None),
          "coat_haze_extent": (0.0, None)}


def is_pbr(inputs):
    return any(k in inputs for k in PBR_KEYS)


def _slug(key):
    """A file name for one converted map (e.g. beta_metal, raised_base_color)."""
    return layer_graph.BAKED[key][0].lower().replace("β", "beta").replace(" ", "_")


def _is_constant(v):
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return True
    if isinstance(v, (tuple, list)) and v and all(isinstance(x, (int, float)) for x in v):
        return True
    return False


def _constant(name, v):
    lo, hi = _RANGE[name]
    vals = np.atleast_1d(np.asarray(v, np.float64))
    if name == "base_color" and vals.size not in (1, 3, 4):
        raise ConversionError(f"base_color: a colour is 1, 3 or 4 numbers, got {v!r}")
    if name != "base_color" and vals.size != 1:
        raise ConversionError(f"{name}: expected one number, got {v!r}")
    if not np.all(np.isfinite(vals)) or np.any(vals < lo) or (hi is not None and np.any(vals > hi)):
        rng = f"[{lo:g}, {hi:g}]" if hi is not None else f">= {lo:g} and finite"
        hint = " (8-bit values: divide by 255)" if hi == 1.0 and np.all(vals <= 255) and \
            np.any(vals > 1) else ""
        raise ConversionError(f"{name} must be in {rng}{hint}, got {v!r}")
    if name == "base_color":
        rgb = np.broadcast_to(vals[:3], 3) if vals.size >= 3 else np.repeat(vals, 3)
        return tuple(float(x) for x in rgb) + (1.0,)
    return float(vals[0])


def _link_map(tree, bsdf, name, img, vector, interpolation, nodes):
    """An Image Texture of ``img`` into ``bsdf``'s input for ``name`` (Normal via a Normal Map
    node); an input the user linked to something else is refused."""
    socket_name, _, cs = PBR_MAPS[name]
    sock = bsdf.inputs[socket_name]
    if sock.is_linked:
        src = sock.links[0].from_node
        if src.bl_idname == "ShaderNodeTexImage" and src.image == img:
            return src
        if name == "normal" and src.bl_idname == "ShaderNodeNormalMap":
            inner = src.inputs["Color"].links[0].from_node if src.inputs["Color"].is_linked else None
            if inner is not None and getattr(inner, "image", None) == img:
                return inner
        raise ConversionError(f"{socket_name} of “{bsdf.name}” is already linked to "
                              f"“{src.name}”: conversion does not replace your links (unlink it, "
                              f"or leave {name} out)")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation, tex.label = img, interpolation, name.replace("_", " ").title()
    tex.location = (bsdf.location.x - 700.0, bsdf.location.y - 280.0 * len(nodes))
    img.colorspace_settings.name = cs if not (img.is_float and cs == "sRGB") else \
        img.colorspace_settings.name
    if vector is not None:
        tree.links.new(vector, tex.inputs["Vector"])
    if name == "normal":
        nm = tree.nodes.new("ShaderNodeNormalMap")
        nm.location = (bsdf.location.x - 300.0, tex.location.y)
        tree.links.new(tex.outputs["Color"], nm.inputs["Color"])
        tree.links.new(nm.outputs["Normal"], sock)
    else:
        tree.links.new(tex.outputs["Color"], sock)  # (an alpha map is a grey map)
    nodes[name] = tex
    return tex


def _alpha_of(img):
    w, h = img.size
    px = np.empty(w * h * img.channels, np.float32)
    img.pixels.foreach_get(px)
    return px.reshape(h, w, img.channels)[..., -1].copy()


def _datablock(src, label):
    """An Image datablock for a map given as a path or a datablock (arrays: a packed image)."""
    if isinstance(src, bpy.types.Image):
        return src
    if isinstance(src, np.ndarray):
        a = np.asarray(src, np.float32)
        h, w = a.shape[:2]
        img = bpy.data.images.new(label, w, h, alpha=True, float_buffer=True)
        px = np.ones((h, w, 4), np.float32)
        px[..., :3] = a[..., None] if a.ndim == 2 else a[..., :3]
        img.pixels.foreach_set(px.ravel())
        img.pack()
        return img
    path = os.path.abspath(os.fsdecode(os.fspath(src)))
    _check_readable(path, label)
    try:
        return bpy.data.images.load(path, check_existing=True)
    except RuntimeError as exc:
        raise ConversionError(f"{label}: cannot read {path}: {exc}") from None


def convert_pbr(inputs, out_dir, *, material=None, name=None, prefix="", file_format="OPEN_EXR",
                exr_codec="ZIP", interpolation="Linear", distribution="MULTI_GGX",
                smoothness=None, keep_body_colour=False, progress=None):
    """See hazy_gloss.api.convert_maps (the PBR-set form).  Returns a ConversionResult whose
    ``.material`` is the material."""
    t0, started = time.perf_counter(), time.time()
    inputs = dict(inputs)
    if "opacity" in inputs:  # (the perceptual maps' "alpha" is the core roughness α)
        inputs["alpha"] = inputs.pop("opacity")
    unknown = sorted(set(inputs) - set(PBR_MAPS) - set(HAZE_MAPS))
    if unknown:
        raise ConversionError("unknown map " + ", ".join(
            f"{u!r}{did_you_mean(u, list(PBR_MAPS) + list(HAZE_MAPS))}" for u in unknown)
            + f"; a PBR set takes {', '.join(PBR_MAPS)} and {', '.join(HAZE_MAPS)}")
    if file_format.upper() != "OPEN_EXR":
        raise ConversionError("a PBR set's haze maps are written as OpenEXR (float IOR and β "
                              "maps do not fit 16-bit PNG)")
    if interpolation not in ("Linear", "Closest", "Cubic", "Smart"):
        raise ConversionError(f"interpolation must be Linear, Closest, Cubic or Smart, got "
                              f"{interpolation!r}")
    prefix = _check_prefix(prefix)
    warnings = []
    constants, maps = {}, {}
    for k, v in inputs.items():
        if v is None:
            continue
        if _is_constant(v):
            constants[k] = _constant(k, v)
        elif isinstance(v, (str, os.PathLike, bpy.types.Image, np.ndarray)):
            maps[k] = v
        else:
            raise ConversionError(f"{k}: expected an image path, a bpy Image, an array or a "
                                  f"constant, got {type(v).__name__}")
    for k, v in maps.items():
        if isinstance(v, (str, os.PathLike)) and "<UDIM>" in os.fsdecode(v):
            raise ConversionError(f"{k}: UDIM sets are not supported for PBR sets yet; convert "
                                  f"each tile as its own set")
    # the material and its Principled BSDF
    if material is not None:
        if material.library is not None:
            raise ConversionError(f"material {material.name!r} is linked from a library and "
                                  f"cannot be edited")
        if layer.is_layered(material) and not layer.is_baked(material):
            raise ConversionError(f"“{material.name}” already has a haze layer set in Blender: "
                                  f"Remove Haze first (conversion bakes its own)")
        mat = material
        if layer.is_layered(mat):  # converted before: its BSDF takes the new set
            layer.remove(mat)
        bsdf = find_core_bsdf(mat.node_tree)
        if bsdf is None or bsdf.bl_idname != layer.PRINCIPLED:
            raise ConversionError(f"“{mat.name}” has no Principled BSDF on its Material Output "
                                  f"to take the PBR set")
    else:
        mat, bsdf = None, None
    # read every map before anything is created or written
    sources = {}
    for k, v in maps.items():
        if k == "normal":
            continue  # linked, not evaluated
        role = "colour" if k == "base_color" else "data"
        sources[k] = _Source(k, role, v)
    for src in sources.values():
        src.check()
    arrays = {k: s.read(None, warnings) for k, s in sources.items()}
    if not arrays:
        raise ConversionError("a PBR set needs at least one map (all inputs are constants: use "
                              "Make Hazy on a material instead)")
    core.check_sizes([(sources[k].label, a.shape[1::-1]) for k, a in arrays.items()])
    h, w = next(iter(arrays.values())).shape[:2]
    for k, a in arrays.items():
        bad = ~np.isfinite(a)
        if bad.any():
            warnings.append(f"{sources[k].label}: {int(bad.any(axis=-1).sum() if a.ndim == 3 else bad.sum())} "
                            f"texel(s) not finite, read as 0")
            arrays[k] = np.where(bad, 0.0, a).astype(np.float32)
    out_dir = _out_path(out_dir)
    created = mat is None
    if created:
        mat = compat.new_material(name or (prefix.rstrip("_") or "Hazy PBR"))
        bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == layer.PRINCIPLED)
        bsdf.distribution = distribution
    tree = mat.node_tree
    images, nodes, written = {}, {}, []
    txn = _Transaction(out_dir, started)
    writer = None
    try:
        for k, v in constants.items():
            if k in PBR_MAPS:
                sock = bsdf.inputs[PBR_MAPS[k][0]]
                if sock.is_linked:
                    raise ConversionError(f"{sock.name} of “{bsdf.name}” is linked: a constant "
                                          f"{k} would replace your link")
                sock.default_value = v
        vector = None
        for k, v in maps.items():
            if k not in PBR_MAPS:
                continue  # haze maps are baked, not linked
            img = _datablock(v, f"{prefix}{k}")
            images[k] = img
            _link_map(tree, bsdf, k, img, vector, interpolation, nodes)
        # the haze: constants or maps
        haze = dict(HAZE_DEFAULTS, keep_body_colour=bool(keep_body_colour), smoothness=smoothness)
        ext = [constants.get("haze_extent_x", constants.get("haze_extent", 5.0)),
               constants.get("haze_extent_y", constants.get("haze_extent", 5.0))]
        for axis, key in ((0, "haze_extent_x"), (1, "haze_extent_y")):
            if key in arrays or "haze_extent" in arrays:
                ext[axis] = layer.TEXTURE
        haze["haze_extent"] = tuple(ext)
        for key in ("haziness", "coat_haziness", "coat_haze_extent"):
            haze[key] = layer.TEXTURE if key in arrays else constants.get(key, HAZE_DEFAULTS[key])
        if "haziness" not in arrays and "haziness" not in constants and "coat_haziness" not in \
                arrays and "coat_haziness" not in constants:
            warnings.append("no haziness given: the layer holds no haze (haziness 0)")
        # evaluate the live layer's graph over the texels
        settings = layer_group.settings_of(bsdf)
        lay = layer_graph.build(layer_group.config_for("PRINCIPLED", settings,
                                                       smooth=smoothness is not None))
        g = lay.graph
        feeds = {f"in:{PBR_MAPS[k][0]}": arrays[k] for k in arrays if k in PBR_MAPS}
        for key in ("haziness", "coat_haziness", "coat_haze_extent", "haze_extent_x", "haze_extent_y",
                    "smoothness"):
            src = key if key in arrays else "haze_extent" if key.startswith("haze_extent_") else None
            if src in arrays:
                feeds[f"haze:{key}"] = arrays[src]
            elif key == "smoothness":
                feeds["haze:smoothness"] = 2.0 if smoothness is None else float(smoothness)
            else:
                v = haze["haze_extent"]["xy".index(key[-1])] if key.startswith("haze_extent_") \
                    else haze[key]
                feeds[f"haze:{key}"] = float(v)
        needed = {e.name for e in g.used(lay.baked) if e.op == "input"}
        for n in sorted(needed - set(feeds)):
            sock = bsdf.inputs.get(n[3:]) if n.startswith("in:") else None
            if sock is None:
                raise ConversionError(f"the layer needs {n}, which conversion cannot give")
            if not sock.is_linked:
                v = sock.default_value
                feeds[n] = tuple(float(x) for x in v)[:3] if hasattr(v, "__len__") else float(v)
                continue
            node = sock.links[0].from_node  # the user's own image textures are maps too
            from_id = sock.links[0].from_socket.identifier
            if node.bl_idname == "ShaderNodeTexImage" and node.image is not None and \
                    from_id in ("Color", "Alpha") and not node.inputs["Vector"].is_linked:
                colour = g.inputs[n].vector
                a = _Source(n[3:], "colour" if colour and not node.image.colorspace_settings.is_data
                            else "data", node.image)
                a.check()
                v = a.read(None, warnings)
                if from_id == "Alpha":
                    v = _alpha_of(node.image)
                if v.shape[:2] != (h, w):
                    raise ConversionError(f"“{node.name}” ({node.image.name}, linked into "
                                          f"{n[3:]}) is {v.shape[1]}x{v.shape[0]}, the set "
                                          f"{w}x{h}: give {n[3:]} as a map of the set's size")
                feeds[n] = v
                continue
            raise ConversionError(f"{n[3:]} of “{bsdf.name}” is linked to a node conversion cannot "
                                  f"evaluate: give it as a map, or unlink it")
        for k in list(feeds):  # vectors as (H, W, 3) or 3 numbers, scalars as (H, W) or a number
            e = g.inputs.get(k)
            a = np.asarray(feeds[k], np.float32)
            if e is not None and e.vector and a.ndim == 2:
                a = np.repeat(a[..., None], 3, axis=-1)
            elif e is not None and e.vector and a.ndim == 0:
                a = np.repeat(a, 3)
            elif e is not None and not e.vector and a.ndim == 3:
                a = a[..., 0]
            elif e is not None and not e.vector and a.ndim == 1:
                a = a[0]
            feeds[k] = a
        values = evaluate(lay.baked, feeds, g.tables)
        ext_ = _EXT["OPEN_EXR"]
        paths = {k: _final_path(out_dir, prefix, _slug(k), None, ext_) for k in lay.baked}
        _check_targets(list(paths.values()), {os.path.realpath(p) for s in sources.values()
                                               for p in s.files()}, txn)
        writer = _Writer("OPEN_EXR", exr_codec)
        txn.make_folder()
        for i, (k, path) in enumerate(paths.items()):
            v = np.asarray(values[k], np.float32)
            full = (h, w) + ((3,) if layer_graph.BAKED[k][1] else ())
            v = np.broadcast_to(v, full)
            writer.write(np.ascontiguousarray(v), txn.temp(path), path)
            written.append(path)
            if progress is not None:
                progress(i + 1, len(paths), f"wrote {os.path.basename(path)}")
        writer.close()
        writer = None
        txn.commit()
        images_out = {k: _image_for(p) for k, p in paths.items()}
        attach_converted_layer(mat, bsdf, images_out, vector, interpolation,
                               sorted(n[3:] for n in needed if n.startswith("in:")))
    except BaseException as exc:
        if writer is not None:
            writer.close()
        problems = [] if txn.committed else txn.rollback()
        if created and mat is not None:
            bpy.data.materials.remove(mat)
        else:
            for n in nodes.values():  # what this run linked into the user's material
                if n.name in tree.nodes:
                    if n.outputs["Color"].is_linked:
                        for l in list(n.outputs["Color"].links):
                            if l.to_node.bl_idname == "ShaderNodeNormalMap":
                                tree.nodes.remove(l.to_node)
                    tree.nodes.remove(n)
        if isinstance(exc, OSError):
            raise ConversionError(f"could not write the maps ({_reason(exc)}); the output "
                                  f"folder is unchanged") from None
        if problems and isinstance(exc, ConversionError):
            raise ConversionError(f"{exc}; " + "; ".join(problems)) from None
        raise
    report = core.ConversionReport(kind="PBR", distribution=settings["distribution"],
                                   file_format="OPEN_EXR", size=(w, h), texels=w * h,
                                   warnings=list(dict.fromkeys(warnings)))
    report.seconds = time.perf_counter() - t0
    result = core.ConversionResult({_slug(k): p for k, p in paths.items()}, report, [])
    result.material = mat
    return result


def attach_converted_layer(mat, bsdf, images, vector, interpolation, sources=()):
    """``bsdf`` becomes a layer node whose group reads the converted maps ``images`` (BAKED key
    -> Image), linked through Image Textures into its Converted Maps (the one place the
    conversion wires the layer).  ``sources``: the BSDF inputs the maps were computed from
    (what they held is recorded: layer.notes says when they change)."""
    record = layer.input_record(bsdf, sources)
    node = layer.wrap(mat, bsdf, {}, baked=True)
    layer.record_baked_sources(mat, record)
    tree = mat.node_tree
    for i, (key, img) in enumerate(sorted(images.items())):
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image, tex.interpolation = img, interpolation
        tex.label = f"Converted {layer_graph.BAKED[key][0]}"
        tex.hide = True
        tex.location = (node.location.x - 420.0, node.location.y - 400.0 - 40.0 * i)
        if vector is not None:
            tree.links.new(vector, tex.inputs["Vector"])
        tree.links.new(tex.outputs["Color"], node.inputs[layer_graph.BAKED[key][0]])
    return node
