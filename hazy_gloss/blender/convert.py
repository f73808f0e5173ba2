# SPDX-License-Identifier: GPL-3.0-or-later
"""Texture batch conversion through bpy: read perceptual maps, write physical maps, wire them.

The numeric part (validation, Blender's conventions, haze mapping over whole images, PNG
encodings) is bpy-free in ``hazy_gloss/convert.py``; this module does what needs Blender:

- reading images (files loaded privately with ``check_existing=False``, or datablocks read in
  place, packed and unsaved ones included) and decoding them: colour maps to linear, data maps
  raw (Non-Color), as measured in Blender 4.5 / 5.0 (``Image.pixels`` of an 8-bit image holds the
  file's encoded values whatever its colour space; float images are already scene-linear);
- writing float OpenEXR (default, lossless ZIP) or 16-bit PNG through ``Image.save_render`` of a
  Non-Color image with a private scene's format settings, atomically (temp file + os.replace);
- wiring the written maps into a material's lean node tree (Image Texture nodes into the two
  lobes and the mix, via node_groups.lobes.build_lobes);
- the operator HAZY_GLOSS_OT_convert_maps.
"""
from __future__ import annotations

import glob
import os
import re
import tempfile
import time
import uuid

import bpy
import numpy as np
from bpy.props import (BoolProperty, EnumProperty, FloatProperty, FloatVectorProperty,
                       StringProperty)

from .. import convert as core
from ..convert import ConversionError

UDIM_TOKEN = "<UDIM>"
STAMP = "hazy_gloss_maps"
from ..api import NODE_PREFIX, _output_node, _remove_ours  # noqa: E402  (one definition)
_LINEAR_NAMES = ("Linear Rec.709", "Linear", "Linear BT.709")
_EXT = {"OPEN_EXR": ".exr", "PNG": ".png"}


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------


def _abspath(path, library=None):
    path = os.fspath(path)
    if path.startswith("//"):
        if not bpy.data.filepath and library is None:
            raise ConversionError(f"relative path {path!r} needs a saved .blend file")
        path = bpy.path.abspath(path, library=library)
    return os.path.normpath(os.path.abspath(path))


def _label(name, source):
    if isinstance(source, bpy.types.Image):
        return f"{name} (image {source.name!r})"
    if isinstance(source, np.ndarray):
        return f"{name} (array)"
    try:
        return f"{name} ({os.path.basename(os.fspath(source))})"
    except TypeError:
        raise ConversionError(f"{name}: expected an image path, an image datablock, a numpy "
                              f"array or a constant, got {type(source).__name__}") from None


def _tile_paths(pattern):
    """{tile number: path} of the files matching a path with the <UDIM> token."""
    head, tail = pattern.split(UDIM_TOKEN, 1)
    rx = re.compile(re.escape(head) + r"(\d{4})" + re.escape(tail) + r"\Z")
    tiles = {}
    for p in glob.glob(glob.escape(head) + "[0-9][0-9][0-9][0-9]" + glob.escape(tail)):
        m = rx.match(p)
        if m and 1001 <= int(m.group(1)) <= 2000:
            tiles[int(m.group(1))] = p
    return tiles


class _Source:
    """One image input: a file, a datablock, or a UDIM set of files."""

    def __init__(self, name, role, source):
        self.name = name
        self.role = role
        self.image = None
        self.path = None
        self.tiles = None
        self.label = _label(name, source)
        self.array = None
        if isinstance(source, np.ndarray):  # in memory: linear colour (H, W, 3) or data (H, W)
            want = 3 if role == "colour" else 2
            if source.ndim != want or (role == "colour" and source.shape[-1] != 3):
                raise ConversionError(f"{self.label}: expected shape "
                                      f"{'(H, W, 3)' if role == 'colour' else '(H, W)'}, got {source.shape}")
            self.array = np.asarray(source, dtype=np.float32)
        elif isinstance(source, bpy.types.Image):
            img = source
            if img.source == "TILED":
                if img.packed_file is not None or getattr(img, "packed_files", None):
                    raise ConversionError(f"{self.label}: packed UDIM images are not supported; "
                                          "unpack them (File > External Data > Unpack Resources)")
                pattern = _abspath(img.filepath, img.library)
                if UDIM_TOKEN not in pattern:
                    raise ConversionError(f"{self.label}: tiled image without {UDIM_TOKEN} in its path")
                on_disk = _tile_paths(pattern)
                numbers = [t.number for t in img.tiles]
                missing = [n for n in numbers if n not in on_disk]
                if missing:
                    raise ConversionError(f"{self.label}: UDIM tile file(s) missing: "
                                          + ", ".join(pattern.replace(UDIM_TOKEN, str(n)) for n in missing))
                self.tiles = {n: on_disk[n] for n in numbers}
                self.colourspace = img.colorspace_settings.name
            else:
                self.image = img
        else:
            path = _abspath(source)
            if UDIM_TOKEN in path:
                self.tiles = _tile_paths(path)
                if not self.tiles:
                    raise ConversionError(f"{self.label}: no UDIM tile matches {path}")
                self.colourspace = None
            else:
                self.path = path

    def files(self):
        if self.array is not None:
            return []
        if self.path:
            return [self.path]
        if self.tiles:
            return list(self.tiles.values())
        img = self.image
        if img.packed_file is None and img.source == "FILE" and img.filepath:
            return [_abspath(img.filepath, img.library)]
        return []

    def read(self, tile, warnings):
        """(H, W[, 3]) float32 values: linear for colour maps, raw for data maps."""
        if self.array is not None:
            return self.array
        if self.image is not None:
            return _read_datablock(self.image, self.role, self.label, warnings)
        path = self.path if self.tiles is None else self.tiles.get(tile, None)
        if path is None:
            raise ConversionError(f"{self.label}: UDIM tile {tile} is missing")
        label = self.label if self.tiles is None else f"{self.label} tile {tile}"
        colourspace = getattr(self, "colourspace", None)
        return _read_file(path, self.role, label, warnings, colourspace)


def _pixels(img, label):
    w, h = img.size
    if w == 0 or h == 0 or img.channels == 0:
        where = img.filepath_raw or img.name
        raise ConversionError(f"{label}: no pixels in {where} (missing, empty or unsupported image)")
    c = img.channels
    buf = np.empty(w * h * c, dtype=np.float32)
    img.pixels.foreach_get(buf)
    return buf.reshape(h, w, c)


def _channels(px, role):
    c = px.shape[-1]
    if role == "colour":
        rgb = px[..., :3] if c >= 3 else np.repeat(px[..., :1], 3, axis=-1)
        return np.ascontiguousarray(rgb, dtype=np.float32)
    return np.ascontiguousarray(px[..., 0], dtype=np.float32)


def _decode_colour(values, img, label, warnings):
    """Image.pixels -> linear RGB.  Float images are scene-linear already; 8-bit ones hold the
    encoded file values (measured in 4.5 and 5.0), decoded here."""
    cs = img.colorspace_settings
    if img.is_float:
        if cs.is_data or cs.name == "Non-Color":
            warnings.append(f"{label}: colour map tagged Non-Color; its values are used as linear")
        return values
    if cs.name == "sRGB":
        return core.srgb_bytes_to_linear(values)
    if cs.is_data or cs.name == "Non-Color":
        warnings.append(f"{label}: colour map tagged Non-Color; its values are used as linear")
        return values
    if cs.name in _LINEAR_NAMES:
        return values
    raise ConversionError(f"{label}: 8-bit colour maps in colour space {cs.name!r} are not "
                          "supported; use sRGB, Linear Rec.709 or a float (EXR/16-bit) image")


def _read_file(path, role, label, warnings, colourspace=None):
    if not os.path.isfile(path):
        raise ConversionError(f"{label}: file not found: {path}")
    if os.path.getsize(path) == 0:
        raise ConversionError(f"{label}: file is empty: {path}")
    try:
        img = bpy.data.images.load(path, check_existing=False)
    except RuntimeError as exc:
        raise ConversionError(f"{label}: cannot read {path}: {str(exc).strip()}") from None
    try:
        img.alpha_mode = "CHANNEL_PACKED"  # no premultiplication of colour by alpha
        if colourspace:
            img.colorspace_settings.name = colourspace
        detected = img.colorspace_settings.name
        if role == "data":
            if not img.colorspace_settings.is_data and detected not in _LINEAR_NAMES:
                warnings.append(f"{label}: data map tagged {detected}; its raw values are used "
                                "(data maps are Non-Color)")
            img.colorspace_settings.name = "Non-Color"
            return _channels(_pixels(img, label), role)
        values = _channels(_pixels(img, label), role)
        return _decode_colour(values, img, label, warnings)
    finally:
        bpy.data.images.remove(img)


def _read_datablock(img, role, label, warnings):
    """Read an image datablock in place (packed, generated and unsaved images included); the
    datablock is not modified."""
    px = _pixels(img, label)
    if px.shape[-1] == 4 and img.alpha_mode in ("STRAIGHT", "PREMUL") and np.any(px[..., 3] < 1):
        warnings.append(f"{label}: has transparent texels and Alpha {img.alpha_mode.title()}; "
                        "colour values may be premultiplied (set Alpha to Channel Packed)")
    values = _channels(px, role)
    del px
    cs = img.colorspace_settings
    if role == "colour":
        return _decode_colour(values, img, label, warnings)
    if cs.is_data or cs.name == "Non-Color":
        return values
    if not img.is_float:  # 8-bit: pixels are the raw file values whatever the tag
        warnings.append(f"{label}: data map tagged {cs.name}; its raw values are used "
                        "(data maps are Non-Color)")
        return values
    if cs.name in _LINEAR_NAMES:
        return values  # scene linear = Linear Rec.709: identity
    # Blender decoded the file from cs.name; re-read a private Non-Color copy of the file or
    # packed data (exact raw values) unless the image was edited since it was loaded
    reloadable = not img.is_dirty and (img.packed_file is not None or (
        img.filepath and os.path.isfile(_abspath(img.filepath, img.library))))
    if reloadable:
        tmp = img.copy()
        try:
            tmp.colorspace_settings.name = "Non-Color"
            tmp.alpha_mode = "CHANNEL_PACKED"
            tmp.reload()
            warnings.append(f"{label}: data map tagged {cs.name}; its raw values are used "
                            "(data maps are Non-Color)")
            return _channels(_pixels(tmp, label), role)
        finally:
            bpy.data.images.remove(tmp)
    if cs.name == "sRGB":
        warnings.append(f"{label}: edited float data map tagged sRGB; its values are re-encoded "
                        "with the sRGB curve (data maps are Non-Color)")
        return core.linear_to_srgb(values)
    warnings.append(f"{label}: edited data map tagged {cs.name}; values used as stored "
                    "(set it to Non-Color)")
    return values


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------


class _Writer:
    """Writes float arrays as Non-Color images through a private scene's format settings
    (``Image.save_render`` honours codec and depth; a Non-Color image gets no view transform),
    atomically: a temp file in the output folder, then os.replace."""

    def __init__(self, file_format, exr_codec="ZIP"):
        self.file_format = file_format
        self.scene = bpy.data.scenes.new(".hazy_gloss_convert")
        s = self.scene.render.image_settings
        if hasattr(s, "media_type"):  # 5.0
            s.media_type = "IMAGE"
        s.file_format = file_format
        s.color_mode = "RGB"
        if file_format == "OPEN_EXR":
            s.color_depth = "32"
            try:
                s.exr_codec = exr_codec
            except TypeError:
                raise ConversionError(f"unknown EXR codec {exr_codec!r}") from None
        else:
            s.color_depth = "16"
        self._buf = None

    def write(self, values, path):
        h, w = values.shape[:2]
        n = w * h * 4
        if self._buf is None or self._buf.size != n:
            self._buf = None
            self._buf = np.empty(n, dtype=np.float32)
        view = self._buf.reshape(h, w, 4)
        view[..., :3] = values[..., None] if values.ndim == 2 else values
        view[..., 3] = 1.0
        img = bpy.data.images.new(".hazy_gloss_out", w, h, alpha=False, float_buffer=True,
                                  is_data=True)
        folder, base = os.path.split(path)
        stem, ext = os.path.splitext(base)
        tmp = os.path.join(folder, f".{stem}.{uuid.uuid4().hex[:12]}.tmp{ext}")
        try:
            img.pixels.foreach_set(self._buf)
            try:
                img.save_render(tmp, scene=self.scene)
            except RuntimeError as exc:
                raise ConversionError(f"could not write {path}: {str(exc).strip()}") from None
            if not os.path.isfile(tmp) or os.path.getsize(tmp) == 0:
                raise ConversionError(f"could not write {path}")
            os.replace(tmp, path)
        finally:
            bpy.data.images.remove(img)
            if os.path.exists(tmp):
                os.remove(tmp)

    def close(self):
        self._buf = None
        if self.scene is not None:
            bpy.data.scenes.remove(self.scene)
            self.scene = None


# --------------------------------------------------------------------------------------------
# Conversion
# --------------------------------------------------------------------------------------------


def resolve_out_dir(out_dir):
    """Absolute output folder ('//' is relative to the saved .blend), created if needed."""
    if out_dir is None or not os.fspath(out_dir):
        raise ConversionError("no output folder given")
    path = _abspath(out_dir)
    if os.path.exists(path) and not os.path.isdir(path):
        raise ConversionError(f"output folder is a file: {path}")
    os.makedirs(path, exist_ok=True)
    return path


def convert_maps(inputs, out_dir, *, kind="CONDUCTOR", smoothness=None, distribution="GGX",
                 file_format="OPEN_EXR", resample=False, prefix="", exr_codec="ZIP",
                 material=None, interpolation="Linear", progress=None, tile_texels=1 << 18):
    """Convert perceptual maps to physical maps; see hazy_gloss.api.convert_maps."""
    t0 = time.perf_counter()
    file_format = str(file_format).upper()
    specs, notes = core.resolve_inputs(inputs, kind=kind, distribution=distribution,
                                       smoothness=smoothness, file_format=file_format)
    kind, distribution = str(kind).upper(), str(distribution).upper()
    if prefix and (os.sep in prefix or "/" in prefix):
        raise ConversionError(f"prefix must be a plain file-name prefix, got {prefix!r}")
    sources = {n: _Source(n, s.role, s.source) for n, s in specs.items() if not s.is_constant}
    # a haze extent shared by both axes is read once
    shared_extent = (specs["haze_extent_x"].given_as == "haze_extent"
                     and not specs["haze_extent_x"].is_constant)
    if shared_extent:
        sources.pop("haze_extent_y", None)

    tiled = {n: s for n, s in sources.items() if s.tiles is not None}
    tiles = []
    if tiled:
        sets = {n: sorted(s.tiles) for n, s in tiled.items()}
        first = next(iter(sets.values()))
        if any(v != first for v in sets.values()):
            raise ConversionError("UDIM inputs have different tiles: " + "; ".join(
                f"{tiled[n].label} {', '.join(map(str, v))}" for n, v in sets.items()))
        tiles = first
    out_dir = resolve_out_dir(out_dir)
    input_files = {os.path.realpath(p) for s in sources.values() for p in s.files()}

    report = core.ConversionReport(kind=kind, distribution=distribution, file_format=file_format,
                                   tiles=list(tiles), warnings=list(notes))
    ext = _EXT[file_format]
    jobs = tiles or [None]
    n_out = len(core.output_specs(kind, True))
    total = len(jobs) * (len(sources) + 1 + n_out)
    done = [0]

    def step(message):
        done[0] += 1
        if progress is not None:
            progress(min(done[0], total), total, message)

    writer = _Writer(file_format, exr_codec)
    try:
        try:
            paths, out_specs = _run_jobs(jobs, specs, sources, shared_extent, resample, kind,
                                         distribution, smoothness, tile_texels, file_format,
                                         writer, out_dir, prefix, ext, input_files, report,
                                         step, None)
        except _AnisotropyChanged:
            # a later UDIM tile is anisotropic: redo every tile with the anisotropic map set
            report.texels, report.clamped = 0, {}
            paths, out_specs = _run_jobs(jobs, specs, sources, shared_extent, resample, kind,
                                         distribution, smoothness, tile_texels, file_format,
                                         writer, out_dir, prefix, ext, input_files, report,
                                         step, True)
    finally:
        writer.close()
    report.warnings = list(dict.fromkeys(report.warnings))
    report.seconds = time.perf_counter() - t0
    result = core.ConversionResult(paths, report, out_specs)
    if material is not None:
        wire_material(material, result, interpolation=interpolation)
    return result


class _AnisotropyChanged(Exception):
    pass


def _run_jobs(jobs, specs, sources, shared_extent, resample, kind, distribution, smoothness,
              tile_texels, file_format, writer, out_dir, prefix, ext, input_files, report, step,
              anisotropic):
    paths = {}
    out_specs = None
    for tile in jobs:
        arrays = {n: s.source for n, s in specs.items() if s.is_constant}
        sizes = []
        for name, src in sources.items():
            values = src.read(tile, report.warnings)
            h, w = values.shape[:2]
            sizes.append((src.label + (f" tile {tile}" if tile else ""), (w, h), name))
            arrays[name] = values
            step(f"read {name}")
        if shared_extent:
            arrays["haze_extent_y"] = arrays["haze_extent_x"]
        target = max((s for _, s, _ in sizes), key=lambda s: s[0] * s[1])
        if resample:
            for label, size, name in sizes:
                if size != target:
                    report.warnings.append(f"{label}: resampled from {size[0]}x{size[1]} "
                                           f"to {target[0]}x{target[1]} (bilinear)")
                    arrays[name] = core.resample_bilinear(arrays[name], target)
            if shared_extent:
                arrays["haze_extent_y"] = arrays["haze_extent_x"]
        else:
            core.check_sizes([(label, size) for label, size, _ in sizes])
        mapped = core.map_textures(arrays, kind=kind, distribution=distribution,
                                   smoothness=smoothness, tile_texels=tile_texels,
                                   alpha_given=specs["roughness"].transform == "sqrt",
                                   anisotropic=anisotropic)
        del arrays
        step("mapped")
        if out_specs is None:
            out_specs = mapped.specs
            report.size = target
            report.anisotropic = mapped.anisotropic
        elif mapped.anisotropic != report.anisotropic:
            raise _AnisotropyChanged()
        report.texels += mapped.texels
        for k, v in mapped.clamped.items():
            report.clamped[k] = report.clamped.get(k, 0) + v
        for spec in mapped.specs:
            suffix = f".{tile}" if tile else ""
            path = os.path.join(out_dir, f"{prefix}{spec.name}{suffix}{ext}")
            if os.path.realpath(path) in input_files:
                raise ConversionError(f"output {path} would overwrite an input; choose "
                                      "another folder or prefix")
            values = mapped.maps.pop(spec.name)
            if file_format == "PNG":
                values = core.encode_png(spec, values)
            writer.write(values, path)
            del values
            paths[spec.name] = os.path.join(
                out_dir, f"{prefix}{spec.name}{'.' + UDIM_TOKEN if tile else ''}{ext}")
            step(f"wrote {spec.name}")
        del mapped
    return paths, out_specs


# --------------------------------------------------------------------------------------------
# Wiring into a material
# --------------------------------------------------------------------------------------------


def _image_for(path):
    """An image datablock for a written map (reused and reloaded when it exists), Non-Color."""
    tiled = UDIM_TOKEN in path
    first = path
    if tiled:
        tiles = _tile_paths(path)
        if not tiles:
            raise ConversionError(f"no tile of {path} on disk")
        first = tiles[min(tiles)]
    want = os.path.normpath(path)
    img = None
    for im in bpy.data.images:
        if im.library is None and im.filepath and os.path.normpath(
                bpy.path.abspath(im.filepath)) == want:
            img = im
            break
    if img is None:
        img = bpy.data.images.load(first, check_existing=False)
        if tiled:
            img.source = "TILED"
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
    from ..node_groups.builder import TreeBuilder
    from ..node_groups.lobes import build_lobes
    from . import compat

    report = result.report
    kind, distribution = report.kind, report.distribution
    if mat.library is not None:
        raise ConversionError(f"material {mat.name!r} is linked from a library and cannot be edited")
    if compat.VERSION < (5, 0, 0) and not mat.use_nodes:
        mat.use_nodes = True
    tree = mat.node_tree
    _remove_ours(tree)
    tb = TreeBuilder(tree, prefix=NODE_PREFIX, x0=-200.0)
    socks = {}
    for name, path in result.items():
        spec = result.specs[name]
        tex = tb.node("ShaderNodeTexImage", name=f"Map {name}", label=name.replace("_", " "),
                      depth=0)
        tex.image = _image_for(path)
        tex.interpolation = interpolation
        tex.extension = "REPEAT"
        out = tex.outputs["Color"]
        png = os.path.splitext(path)[1].lower() == ".png"
        if spec.channels == 1:
            sep = tb.node("ShaderNodeSeparateColor", name=f"Split {name}", depth=1)
            tb.link(out, sep.inputs[0])
            out = sep.outputs[0]
            if png and spec.png == "ratio":
                out = tb.div(out, tb.sub(1.0, out), label=f"{name}: e/(1-e)")
            elif png and spec.png == "negate":
                out = tb.mul(out, -1.0, label=f"{name}: -e")
        elif png and spec.png == "ratio":
            out = tb.vmath("DIVIDE", out, tb.vmath("SUBTRACT", 1.0, out), label=f"{name}: e/(1-e)")
        socks[name] = out
    shared = {"tangent": None}
    if report.anisotropic:
        t = tb.node("ShaderNodeTangent", name="Tangent", depth=2)
        if tangent == "UV_MAP":
            t.direction_type = "UV_MAP"
        else:
            t.direction_type = "RADIAL"
            t.axis = tangent[-1]
        shared["tangent"] = t.outputs[0]
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
    depth = 1 + max(tb._depth.values(), default=0)
    bsdf = build_lobes(tb, kind, distribution, beta=socks["beta"], narrow=narrow, wide=wide,
                       fresnel=fresnel, shared=shared, depth=depth)
    for n in tb.created:  # math nodes are unnamed: prefix them so a re-wire removes them
        if not n.name.startswith(NODE_PREFIX + " "):
            n.name = f"{NODE_PREFIX} {n.name}"
    out = _output_node(tree)
    tree.links.new(bsdf, out.inputs["Surface"])
    if "hazy_gloss" in mat:  # its constants no longer describe this texture-driven tree
        del mat["hazy_gloss"]
    mat[STAMP] = {"version": 1, "kind": kind, "distribution": distribution,
                  "anisotropic": int(report.anisotropic), "maps": dict(result)}
    return bsdf


# --------------------------------------------------------------------------------------------
# Operator
# --------------------------------------------------------------------------------------------

#: (property stem, label, role) of the maps the operator offers.
_MAPS = (
    ("core_reflectivity", "Core Reflectivity", "colour"),
    ("edge_tint", "Edge Tint", "colour"),
    ("roughness", "Roughness", "data"),
    ("anisotropy", "Anisotropy", "data"),
    ("rotation", "Rotation", "data"),
    ("haziness", "Haziness", "data"),
    ("haze_extent", "Haze Extent", "data"),
    ("haze_extent_y", "Haze Extent Y", "data"),
)

_KIND_ITEMS = [("CONDUCTOR", "Conductor", "Metallic BSDF lobes, η and κ maps"),
               ("DIELECTRIC", "Dielectric", "Principled BSDF lobes, η and specular tint maps"),
               ("LEGACY", "Legacy", "Glossy BSDF lobes (no Fresnel), weight maps")]
_DIST_ITEMS = [("GGX", "GGX", ""), ("BECKMANN", "Beckmann", ""),
               ("MULTI_GGX", "Multiscatter GGX", ""), ("ASHIKHMIN_SHIRLEY", "Ashikhmin-Shirley", "")]


def _fallback_dir(mat_name):
    safe = re.sub(r"[^A-Za-z0-9_.-]+", "_", mat_name or "maps")
    return os.path.join(tempfile.gettempdir(), "hazy_gloss_maps", safe)


class HAZY_GLOSS_OT_convert_maps(bpy.types.Operator):
    """Convert perceptual hazy-gloss maps (haziness, haze extent, core reflectivity...) into
    physical maps and wire them into the active material's lean node tree"""

    bl_idname = "hazy_gloss.convert_maps"
    bl_label = "Convert Hazy Gloss Maps"
    bl_options = {"REGISTER", "UNDO"}

    kind: EnumProperty(name="Kind", items=_KIND_ITEMS, default="CONDUCTOR")
    distribution: EnumProperty(name="Distribution", items=_DIST_ITEMS, default="GGX")

    core_reflectivity_image: StringProperty(name="Core Reflectivity Map",
                                            description="Image datablock (colour, decoded to linear)")
    core_reflectivity_path: StringProperty(name="Core Reflectivity File", subtype="FILE_PATH")
    core_reflectivity: FloatVectorProperty(name="Core Reflectivity", subtype="COLOR", size=3,
                                           min=0.0, max=1.0, default=(0.5, 0.5, 0.5))
    edge_tint_image: StringProperty(name="Edge Tint Map")
    edge_tint_path: StringProperty(name="Edge Tint File", subtype="FILE_PATH")
    edge_tint: FloatVectorProperty(name="Edge Tint", subtype="COLOR", size=3, min=0.0, max=1.0,
                                   default=(0.0, 0.0, 0.0))
    roughness_image: StringProperty(name="Roughness Map", description="Non-Color map of R = √α")
    roughness_path: StringProperty(name="Roughness File", subtype="FILE_PATH")
    roughness: FloatProperty(name="Roughness", min=0.0, max=1.0, default=0.1, subtype="FACTOR")
    anisotropy_image: StringProperty(name="Anisotropy Map")
    anisotropy_path: StringProperty(name="Anisotropy File", subtype="FILE_PATH")
    anisotropy: FloatProperty(name="Anisotropy", min=0.0, max=1.0, default=0.0, subtype="FACTOR")
    rotation_image: StringProperty(name="Rotation Map")
    rotation_path: StringProperty(name="Rotation File", subtype="FILE_PATH")
    rotation: FloatProperty(name="Rotation", default=0.0)
    haziness_image: StringProperty(name="Haziness Map")
    haziness_path: StringProperty(name="Haziness File", subtype="FILE_PATH")
    haziness: FloatProperty(name="Haziness", min=0.0, max=0.9999, default=0.5, subtype="FACTOR")
    haze_extent_image: StringProperty(name="Haze Extent Map", description="Both axes, or X")
    haze_extent_path: StringProperty(name="Haze Extent File", subtype="FILE_PATH")
    haze_extent: FloatProperty(name="Haze Extent", min=0.0, default=5.0)
    anisotropic_extent: BoolProperty(name="Separate Y Extent", default=False,
                                     description="Give the haze extent along Y separately")
    haze_extent_y_image: StringProperty(name="Haze Extent Y Map")
    haze_extent_y_path: StringProperty(name="Haze Extent Y File", subtype="FILE_PATH")
    haze_extent_y: FloatProperty(name="Haze Extent Y", min=0.0, default=5.0)
    use_smoothness: BoolProperty(name="Smooth Variation", default=False,
                                 description="Use the rational Bézier (Eqs. 12-15) instead of Eq. 7")
    smoothness: FloatProperty(name="Smoothness", min=1e-4, default=2.0)
    base_color: FloatVectorProperty(name="Base Color", subtype="COLOR", size=3, min=0.0, max=1.0,
                                    default=(0.0, 0.0, 0.0))
    transmission: FloatProperty(name="Transmission", min=0.0, max=1.0, default=0.0)

    directory: StringProperty(name="Output Folder", subtype="DIR_PATH", default="//hazy_maps/",
                              description="Where the physical maps are written ('//' = next to "
                                          "the .blend; an unsaved file uses a temp folder)")
    prefix: StringProperty(name="File Prefix", default="")
    file_format: EnumProperty(name="Format", default="OPEN_EXR", items=[
        ("OPEN_EXR", "OpenEXR (float)", "32-bit float, lossless ZIP"),
        ("PNG", "PNG 16-bit", "Unbounded maps stored with documented encodings")])
    resample: BoolProperty(name="Resample", default=False,
                           description="Resample maps of other sizes to the largest (bilinear)")
    wire: BoolProperty(name="Wire Into Active Material", default=True)
    interpolation: EnumProperty(name="Interpolation", default="Linear", items=[
        ("Linear", "Linear", ""), ("Closest", "Closest", ""), ("Cubic", "Cubic", "")])

    def _source(self, stem):
        name = getattr(self, stem + "_image")
        if name:
            img = bpy.data.images.get(name)
            if img is None:
                raise ConversionError(f"{stem}: no image datablock named {name!r}")
            return img
        path = getattr(self, stem + "_path")
        if path:
            return path
        return None

    def _inputs(self):
        inputs = {}
        for stem in ("core_reflectivity", "edge_tint", "roughness", "anisotropy", "rotation",
                     "haziness"):
            if stem == "edge_tint" and self.kind != "CONDUCTOR":
                continue
            src = self._source(stem)
            if src is None:
                value = getattr(self, stem)
                src = tuple(value) if stem in ("core_reflectivity", "edge_tint") else value
            inputs[stem] = src
        x = self._source("haze_extent")
        x = x if x is not None else self.haze_extent
        if self.anisotropic_extent:
            y = self._source("haze_extent_y")
            inputs["haze_extent_x"] = x
            inputs["haze_extent_y"] = y if y is not None else self.haze_extent_y
        else:
            inputs["haze_extent"] = x
        return inputs

    def invoke(self, context, event):
        return context.window_manager.invoke_props_dialog(self, width=420)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "kind")
        layout.prop(self, "distribution")
        for stem, label, _role in _MAPS:
            if stem == "edge_tint" and self.kind != "CONDUCTOR":
                continue
            if stem == "haze_extent_y":
                layout.prop(self, "anisotropic_extent")
                if not self.anisotropic_extent:
                    continue
            box = layout.box()
            box.label(text=label)
            box.prop_search(self, stem + "_image", bpy.data, "images", text="Image")
            box.prop(self, stem + "_path", text="File")
            if not getattr(self, stem + "_image") and not getattr(self, stem + "_path"):
                box.prop(self, stem, text="Constant")
        layout.prop(self, "use_smoothness")
        if self.use_smoothness:
            layout.prop(self, "smoothness")
        if self.kind == "DIELECTRIC":
            layout.prop(self, "base_color")
            layout.prop(self, "transmission")
        layout.separator()
        layout.prop(self, "directory")
        layout.prop(self, "prefix")
        layout.prop(self, "file_format")
        layout.prop(self, "resample")
        layout.prop(self, "wire")
        if self.wire:
            layout.prop(self, "interpolation")

    def execute(self, context):
        wm = context.window_manager
        obj = getattr(context, "object", None)
        mat = obj.active_material if obj is not None else None
        if self.wire and mat is None:
            if obj is not None and hasattr(obj.data, "materials"):
                from . import compat
                mat = compat.new_material("Hazy Maps")
                if obj.material_slots:
                    obj.active_material = mat
                else:
                    obj.data.materials.append(mat)
                self.report({"INFO"}, f"created material {mat.name!r} on {obj.name!r}")
            else:
                self.report({"WARNING"}, "no active object with materials: maps are written "
                                         "but not wired")
        directory = self.directory or "//hazy_maps/"
        if directory.startswith("//") and not bpy.data.filepath:
            directory = _fallback_dir(mat.name if mat else "maps")
            self.report({"WARNING"}, f"the .blend is not saved: maps go to {directory} "
                                     "(save the file or choose an output folder to keep them "
                                     "next to it)")
        begun = False
        try:
            wm.progress_begin(0, 100)
            begun = True
        except (RuntimeError, AttributeError):
            pass

        def progress(done, total, _message):
            if begun:
                wm.progress_update(int(100 * done / max(total, 1)))

        try:
            inputs = self._inputs()
            result = convert_maps(
                inputs, directory, kind=self.kind, distribution=self.distribution,
                smoothness=self.smoothness if self.use_smoothness else None,
                file_format=self.file_format, resample=self.resample, prefix=self.prefix,
                progress=progress)
            if self.wire and mat is not None:
                wire_material(mat, result, interpolation=self.interpolation,
                              base_color=tuple(self.base_color), transmission=self.transmission)
        except ConversionError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        finally:
            if begun:
                wm.progress_end()
        for w in result.report.warnings:
            self.report({"WARNING"}, w)
        self.report({"INFO"}, f"Hazy maps: {result.report.summary(len(result))} -> "
                              f"{os.path.dirname(next(iter(result.values())))}")
        return {"FINISHED"}


def _menu_draw(self, context):
    self.layout.operator(HAZY_GLOSS_OT_convert_maps.bl_idname, icon="IMAGE_DATA")


#: Menus the operator is added to (so F3 menu search finds it).
_MENUS = ("NODE_MT_node",)

classes = (HAZY_GLOSS_OT_convert_maps,)
_register_classes, _unregister_classes = bpy.utils.register_classes_factory(classes)


def register():
    _register_classes()
    for name in _MENUS:
        menu = getattr(bpy.types, name, None)
        if menu is not None:
            menu.append(_menu_draw)


def unregister():
    for name in _MENUS:
        menu = getattr(bpy.types, name, None)
        if menu is not None:
            try:
                menu.remove(_menu_draw)
            except (ValueError, RuntimeError):
                pass
    _unregister_classes()
