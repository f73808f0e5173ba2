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
  lobes and the mix, via nodes.lobes.build_lobes).

The operator is ``convert_ops.HAZY_GLOSS_OT_convert_maps``.
"""
from __future__ import annotations

import glob
import os
import re
import time
import uuid

import bpy
import numpy as np

from .. import constants as K
from .. import convert as core
from ..convert import ConversionError
from ..core.graph import Graph
from . import compat, material
from .nodes.builder import TreeBuilder
from .nodes.emit import emit
from .nodes.lobes import build_lobes, tangent as tangent_node

UDIM_TOKEN = "<UDIM>"
STAMP = K.MAPS_STAMP
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
        tex.image = _image_for(path)
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
