# SPDX-License-Identifier: GPL-3.0-or-later
"""Convert a PBR texture set (base colour, metallic, roughness, normal, coat, alpha, as any
texture library ships them) plus haze maps into a Principled material with a baked haze layer.

The set goes into a Principled BSDF (a new material, or the user's own: its empty inputs take
the maps; an input the user linked to something else is refused, never replaced).  The haze
layer is the one Make Hazy builds (blender.model.layer): its outputs (the raised IOR / Base Color, the
wide roughness, β per part, the coat's) are computed by the layer's own graph (core.layer_graph:
the node math of the in-shader layer, evaluated by core.graph in numpy with Blender's float32 semantics) over
every texel and written as maps, all or nothing (blender.model.convert_outputs' transaction); the
layer then reads those maps instead of node math.  A Metallic map splits the material per texel into its
dielectric and metal parts, each with its own β map.
"""
from __future__ import annotations

import os
import time

import bpy
import numpy as np

from ... import constants as K
from ...conversion import convert as conversion
from ...conversion import imagestream as stream
from ...conversion.convert import ConversionError, did_you_mean
from ...core import layer_graph
from ...core.graph import evaluate
from ...core.parameters import HAZE_DEFAULTS, RANGES
from ...schema import HAZE_MAP_INPUTS, HAZE_SOCKETS, LAYER_MAP_INPUTS
from .. import compat
from ..model import layer, layer_group, layer_values
from .convert import check_prefix, check_targets
from ...conversion.oiio import openimageio
from ..model.convert_inputs import UDIM_TOKEN, Source, os_reason, udim_tiles
from ..model.convert_outputs import (EXTENSIONS, MapFile, Transaction, check_codec, final_path,
                                     out_path)
from ..model.convert_wiring import image_for, load_image
from .make_hazy import find_core_bsdf

__all__ = ("PBR_MAPS", "HAZE_MAPS", "PBR_KEYS", "is_pbr", "convert_pbr", "convert_pbr_steps",
           "attach_baked_layer", "convert_set_steps", "LibraryReport", "library_sets",
           "convert_library_steps")

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
#: Haze maps (or constants) of the layer (the schema's; an extent also per axis).
HAZE_MAPS = HAZE_MAP_INPUTS
#: Inputs that mark a conversion as a PBR set (api.convert_maps routes them here).
PBR_KEYS = ("base_color", "metallic", "normal", "coat", "coat_roughness", "opacity") + \
    LAYER_MAP_INPUTS
_RANGE = {"base_color": (0.0, 1.0), "metallic": (0.0, 1.0), "roughness": (0.0, 1.0),
          "coat": (0.0, 1.0), "coat_roughness": (0.0, 1.0), "alpha": (0.0, 1.0),
          **{k: RANGES[k if k in RANGES else k[:-2]] for k in HAZE_MAPS}}
#: The layer's scalar haze sockets (not an extent's axes, not the optional smoothness).
_SCALAR_HAZE = tuple(k for k in HAZE_SOCKETS
                     if k in HAZE_DEFAULTS and HAZE_DEFAULTS[k] is not None)


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
        raise ConversionError(f"{name} must be {'in ' if hi is not None else ''}{rng}{hint}, "
                              f"got {v!r}")
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
    return load_image(os.path.abspath(os.fsdecode(os.fspath(src))), label)


def convert_pbr(inputs, out_dir, **options):
    """See hazy_gloss.api.convert_maps (the PBR-set form).  Returns a ConversionResult whose
    ``.material`` is the material.  Blocking: runs :func:`convert_pbr_steps` to its end."""
    return conversion.drain(convert_pbr_steps(inputs, out_dir, **options))


def convert_pbr_steps(inputs, out_dir, *, material=None, name=None, prefix="",
                      file_format="OPEN_EXR", exr_codec="ZIP", interpolation="Linear",
                      distribution="MULTI_GGX", smoothness=None, keep_body_colour=False,
                      progress=None):
    """The PBR-set conversion as a generator (yields after every strip; returns the result):
    UDIM maps (a ``<UDIM>`` path) convert tile by tile into UDIM outputs."""
    t0, started = time.perf_counter(), time.time()
    prog = progress if isinstance(progress, conversion.Progress) else conversion.Progress(progress)
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
    prefix = check_prefix(prefix)
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
    # every map checked before anything is created or written
    sources = {}
    for k, v in maps.items():
        if k == "normal":
            continue  # linked, not evaluated
        role = "colour" if k == "base_color" else "data"
        sources[k] = Source(k, role, v)
    if not sources:
        raise ConversionError("a PBR set needs at least one map (all inputs are constants: use "
                              "Make Hazy on a material instead)")
    tiles = udim_tiles(sources)
    for src in sources.values():
        src.check()
    jobs = tiles or [None]
    oiio = openimageio()
    # each tile's size, before anything is written (all maps of a tile must agree)
    sizes = {}
    for tile in jobs:
        named = []
        for k, s in sources.items():
            r = s.strips(tile, warnings, oiio)
            named.append((s.label + (f" tile {tile}" if tile else ""), (r.width, r.height)))
            r.close()
        conversion.check_sizes(named)
        sizes[tile] = named[0][1]
    w, h = sizes[jobs[0]]
    out_dir = out_path(out_dir)
    created = mat is None
    if created:
        mat = compat.new_material(name or (prefix.rstrip("_") or "Hazy PBR"))
        bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == layer.PRINCIPLED)
        bsdf.distribution = distribution
    tree = mat.node_tree
    images, nodes = {}, {}
    txn = Transaction(out_dir, started)
    files = {}
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
            if key in sources or "haze_extent" in sources:
                ext[axis] = layer.TEXTURE
        haze["haze_extent"] = tuple(ext)
        for key in _SCALAR_HAZE:
            haze[key] = layer.TEXTURE if key in sources else constants.get(key, HAZE_DEFAULTS[key])
        if "haziness" not in sources and "haziness" not in constants and "coat_haziness" not in \
                sources and "coat_haziness" not in constants:
            warnings.append("no haziness given: the layer holds no haze (haziness 0)")
        # the live layer's graph, evaluated strip by strip over the texels
        settings = layer_group.settings_of(bsdf)
        lay = layer_graph.build(layer_group.config_for("PRINCIPLED", settings,
                                                       smooth=smoothness is not None))
        g = lay.graph
        feeds = {f"in:{PBR_MAPS[k][0]}": k for k in sources if k in PBR_MAPS}
        consts = {}
        for key in HAZE_SOCKETS:
            src = key if key in sources else "haze_extent" if key.startswith("haze_extent_") else None
            if src in sources:
                feeds[f"haze:{key}"] = src
            elif key == "smoothness":
                consts["haze:smoothness"] = HAZE_SOCKETS["smoothness"][1] if smoothness is None \
                    else float(smoothness)
            else:
                v = haze["haze_extent"]["xy".index(key[-1])] if key.startswith("haze_extent_") \
                    else haze[key]
                consts[f"haze:{key}"] = float(v)
        needed = {e.name for e in g.used(lay.baked) if e.op == "input"}
        own = {}  # the user's own image textures linked into the BSDF are maps too (read whole)
        for n in sorted(needed - set(feeds) - set(consts)):
            sock = bsdf.inputs.get(n[3:]) if n.startswith("in:") else None
            if sock is None:
                raise ConversionError(f"the layer needs {n}, which conversion cannot give")
            if not sock.is_linked:
                v = sock.default_value
                consts[n] = tuple(float(x) for x in v)[:3] if hasattr(v, "__len__") else float(v)
                continue
            node = sock.links[0].from_node
            from_id = sock.links[0].from_socket.identifier
            if node.bl_idname == "ShaderNodeTexImage" and node.image is not None and \
                    from_id in ("Color", "Alpha") and not node.inputs["Vector"].is_linked:
                if node.image.source == "TILED":
                    raise ConversionError(f"“{node.name}” ({node.image.name}, linked into {n[3:]}) "
                                          f"is a UDIM image: give {n[3:]} as a map of the set")
                colour = g.inputs[n].vector
                a = Source(n[3:], "colour" if colour and not node.image.colorspace_settings.is_data
                            else "data", node.image)
                a.check()
                v = a.read(None, warnings)
                if from_id == "Alpha":
                    v = _alpha_of(node.image)
                if v.shape[:2] != (h, w) or len(jobs) > 1 and any(s != (w, h) for s in sizes.values()):
                    raise ConversionError(f"“{node.name}” ({node.image.name}, linked into "
                                          f"{n[3:]}) is {v.shape[1]}x{v.shape[0]}, the set "
                                          f"{w}x{h}: give {n[3:]} as a map of the set's size")
                own[n] = stream.ArrayStrips(v, n)
                continue
            raise ConversionError(f"{n[3:]} of “{bsdf.name}” is linked to a node conversion cannot "
                                  f"evaluate: give it as a map, or unlink it")
        for k, v in consts.items():  # vectors as 3 numbers, scalars as a number
            e = g.inputs.get(k)
            a = np.asarray(v, np.float32)
            if e is not None and e.vector and a.ndim == 0:
                a = np.repeat(a, 3)
            elif e is not None and not e.vector and a.ndim == 1:
                a = a[0]
            consts[k] = a
        live = lay.baked  # every Converted Maps input of the baked group reads a map
        ext_ = EXTENSIONS["OPEN_EXR"]
        first = {}  # one map per distinct value
        for k, e in live.items():
            first.setdefault(id(e), k)
        finals = {k: {t: final_path(out_dir, prefix, _slug(k), t, ext_) for t in jobs}
                  for k in first.values()}
        paths = {k: final_path(out_dir, prefix, _slug(k), UDIM_TOKEN if tiles else None, ext_)
                 for k in first.values()}
        check_targets([p for per in finals.values() for p in per.values()],
                       {os.path.realpath(p) for s in sources.values() for p in s.files()}, txn,
                       material)
        codec = check_codec("OPEN_EXR", exr_codec)
        txn.make_folder()
        bad = {}
        for tile in jobs:
            tw, th = sizes[tile]
            if tile:
                prog.next_item(jobs.index(tile), len(jobs), tile, key="tile")
            readers = {k: s.strips(tile, warnings, oiio) for k, s in sources.items()}
            files = {k: MapFile("OPEN_EXR", codec, txn.temp(finals[k][tile]), finals[k][tile],
                                 tw, th) for k in first.values()}
            try:
                yield from _bake_strips(readers, own, feeds, consts, g, live, first, files,
                                        (tw, th), bad, prog)
                for k, f in files.items():
                    f.finish()
                    prog.advance(0, f"wrote {os.path.basename(f.final)}")
            finally:
                for f in files.values():
                    f.abort()
                for r in readers.values():
                    r.close()
        for k, n in bad.items():
            warnings.append(f"{sources[k].label}: {n} texel(s) not finite, read as 0")
        prog.check()  # the last point where a cancel undoes the run
        txn.commit()
        images_out = {k: image_for(p) for k, p in paths.items()}
        baked = {k: images_out[first[id(e)]] for k, e in live.items()}
        attach_baked_layer(mat, bsdf, baked, vector=vector, interpolation=interpolation,
                           sources=sorted(n[3:] for n in needed if n.startswith("in:")),
                           haze=haze)
    except BaseException as exc:
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
            raise ConversionError(f"could not write the maps ({os_reason(exc)}); the output "
                                  f"folder is unchanged") from None
        if problems and isinstance(exc, ConversionError):
            raise ConversionError(f"{exc}; " + "; ".join(problems)) from None
        raise
    report = conversion.ConversionReport(kind="PBR", distribution=settings["distribution"],
                                   file_format="OPEN_EXR", size=(w, h), tiles=list(tiles),
                                   texels=sum(a * b for a, b in sizes.values()),
                                   warnings=list(dict.fromkeys(warnings)))
    report.seconds = time.perf_counter() - t0
    result = conversion.ConversionResult({_slug(k): p for k, p in paths.items()}, report, [])
    result.material = mat
    return result


def _bake_strips(readers, own, feeds, consts, g, live, first, files, size, bad, prog):
    """Evaluate the layer's graph on every strip of one tile and write its maps (strips on a
    thread pool; elementwise node math, so a strip gives the rows of the whole)."""
    w, h = size
    rows = stream.strip_rows(w)
    prog.begin(h)

    def read(y0, y1):
        strips = {k: r.rows(y0, y1) for k, r in readers.items()}
        for k, r in own.items():
            strips[k] = r.rows(y0, y1)
        return strips

    def compute(y0, y1, strips):
        nonfinite = {}
        for k, a in list(strips.items()):
            m = ~np.isfinite(a)
            if m.any():
                nonfinite[k] = int(m.any(axis=-1).sum() if a.ndim == 3 else m.sum())
                strips[k] = np.where(m, 0.0, a).astype(np.float32)
        inputs = dict(consts)
        for key, src in feeds.items():
            inputs[key] = strips[src]
        for key in own:
            a = strips[key]
            inputs[key] = a if a.ndim == 3 and a.shape[-1] == 3 else a[..., 0]
        for k in list(inputs):  # vectors as (n, W, 3), scalars as (n, W)
            e = g.inputs.get(k)
            a = inputs[k]
            if e is not None and e.vector and a.ndim == 2:
                inputs[k] = np.repeat(a[..., None], 3, axis=-1)
            elif e is not None and not e.vector and a.ndim == 3:
                inputs[k] = a[..., 0]
        values = evaluate({k: live[k] for k in first.values()}, inputs, g.tables)
        encoded = {}
        for k in first.values():
            v = np.asarray(values[k], np.float32)
            v = np.broadcast_to(v, (y1 - y0, w) + v.shape[2:] if v.ndim >= 2 else (y1 - y0, w))
            encoded[k] = files[k].encode(y0, v)
        return nonfinite, encoded

    def write(y0, y1, result):
        nonfinite, encoded = result
        for k, n in nonfinite.items():
            bad[k] = bad.get(k, 0) + n
        for k, e in encoded.items():
            files[k].append(e)

    done = 0
    for y1, _ in stream.run_strips(h, rows, read, compute, write):
        prog.advance(y1 - done, "baking the haze layer")
        done = y1
        yield


def attach_baked_layer(mat, bsdf, images, *, vector=None, interpolation="Linear", sources=(),
                       haze=None):
    """``bsdf`` becomes a layer node whose group reads the converted maps ``images`` (BAKED key
    -> Image), linked through Image Textures into its Converted Maps (the one place the
    conversion wires the layer).  ``sources``: the BSDF inputs the maps were computed from
    (what they held is recorded: layer.notes says when they change); ``haze``: the haze they
    were computed with (read_parameters reports it)."""
    record = layer_values.input_record(bsdf, sources)
    node = layer.wrap(mat, bsdf, {}, baked=True)
    layer.record_baked_sources(mat, record, haze)
    tree = mat.node_tree
    for i, (key, img) in enumerate(sorted(images.items())):
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image, tex.interpolation = img, interpolation
        tex.label = f"Converted {layer_graph.BAKED[key][0]}"
        tex[K.ROLE] = f"{K.CONVERTED_ROLE}{key}"  # (ours: Remove Haze takes it with the layer)
        tex.hide = True
        tex.location = (node.location.x - 420.0, node.location.y - 400.0 - 40.0 * i)
        if vector is not None:
            tree.links.new(vector, tex.inputs["Vector"])
        tree.links.new(tex.outputs["Color"], node.inputs[layer_graph.BAKED[key][0]])
    return node


# --------------------------------------------------------------------------------------------
# Sets in folders, and libraries of sets
# --------------------------------------------------------------------------------------------


def convert_set_steps(folder, out_dir, *, haze, material=None, name=None, overrides=None,
                      interpolation="Linear", progress=None):
    """The PBR set in ``folder`` (maps found by their names, conversion.detect_pbr_set, UDIM tiles
    included; ``overrides`` {map: path} win) into a Principled material with a baked haze
    layer; a generator like :func:`convert_pbr_steps`."""
    try:
        found = conversion.detect_pbr_set(os.listdir(folder)) if folder else {}
    except ConversionError:
        if not overrides:
            raise
        found = {}
    except OSError as exc:
        raise ConversionError(f"set folder {folder}: {exc.strerror or exc}") from None
    inputs = {k: os.path.join(folder, f) for k, f in found.items()}
    inputs.update(overrides or {})
    for k, v in haze.items():
        if k not in inputs:
            inputs[k] = v
    return (yield from convert_pbr_steps(inputs, out_dir, material=material, name=name,
                                         interpolation=interpolation, progress=progress))


class LibraryReport:
    """What a library batch did: ``done`` [(set, ConversionResult)], ``failed`` [(set,
    one-line reason)], ``cancelled`` (the set being converted then was undone; the sets done
    before it stay)."""

    def __init__(self, sets):
        self.sets = list(sets)
        self.done, self.failed, self.cancelled = [], [], False
        self.seconds = 0.0

    def summary(self):
        text = (f"converted {len(self.done)} of {len(self.sets)} set(s) in "
                f"{conversion.format_seconds(self.seconds)}")
        if self.failed:
            text += f"; {len(self.failed)} failed: " + ", ".join(n for n, _ in self.failed)
        if self.cancelled:
            text += "; cancelled (the set being converted was undone)"
        return text


def library_sets(folder):
    """The sets of a library: its subfolders, sorted (hidden ones skipped)."""
    try:
        names = sorted(os.listdir(folder))
    except OSError as exc:
        raise ConversionError(f"library folder {folder}: {exc.strerror or exc}") from None
    return [n for n in names if not n.startswith(".") and os.path.isdir(os.path.join(folder, n))]


def convert_library_steps(folder, out_dir, *, haze, interpolation="Linear", progress=None):
    """Every subfolder of ``folder`` is a set and becomes a material (maps into
    ``out_dir/<set>``); each set all or nothing, a set that fails is reported and the others
    go on.  A generator; returns a :class:`LibraryReport`."""
    t0 = time.perf_counter()
    prog = progress if isinstance(progress, conversion.Progress) else conversion.Progress(progress)
    sets = library_sets(folder)
    if not sets:
        raise ConversionError(f"library folder {folder} has no subfolders (one set per subfolder)")
    report = LibraryReport(sets)
    for i, sub in enumerate(sets):
        prog.next_item(i, len(sets), sub)
        try:
            res = yield from convert_set_steps(os.path.join(folder, sub), os.path.join(out_dir, sub),
                                               haze=haze, name=sub, interpolation=interpolation,
                                               progress=prog)
        except conversion.ConversionCancelled:
            report.cancelled = True
            break
        except ConversionError as exc:
            report.failed.append((sub, str(exc)))
            continue
        res.material.use_fake_user = True  # kept in the file without an object
        report.done.append((sub, res))
    report.seconds = time.perf_counter() - t0
    return report
