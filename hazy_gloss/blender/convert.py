# SPDX-License-Identifier: GPL-3.0-or-later
"""Texture batch conversion through bpy: read perceptual maps, write physical maps, wire them.

The numeric part (validation, Blender's conventions, haze mapping, PNG encodings) is bpy-free
in ``hazy_gloss/convert.py``, the strip readers and writers in ``hazy_gloss/imagestream.py``;
this module does what needs Blender:

- reading images in strips: files through Blender's own OpenImageIO module (:func:`openimageio`)
  and decoded as Blender would (colour maps to linear, data maps raw); datablocks (packed and
  unsaved ones included) read in place, whole, as measured in Blender 4.5 / 5.x
  (``Image.pixels`` of an 8-bit image holds the file's encoded values whatever its colour
  space; float images are already scene-linear).  Every file is checked
  (:func:`check_readable`: exists, an image format, not cut off) before it is read: Blender
  5.0.1 segfaults on a truncated EXR;
- writing float OpenEXR (default, lossless ZIP) or 16-bit PNG strip by strip, **all or
  nothing** (:class:`_Transaction`): every target is checked before anything is written, every
  map goes to a temporary name in the output folder and is proved by its bytes read back
  (:class:`_MapFile`), then all are renamed into place; on any failure, interruption or cancel
  (KeyboardInterrupt, the CLI's SIGTERM, Progress.cancel) the run's files are removed and the
  maps it replaced restored.  The conversion is a generator (:func:`convert_maps_steps`) that
  yields after every strip: the modal operator steps it between events;
- wiring the written maps into a material's lean node tree (Image Texture nodes into the two
  lobes and the mix, via nodes.lobes.build_lobes).

The operator is ``convert_ops.HAZY_GLOSS_OT_convert_maps``.
"""
from __future__ import annotations

import glob
import hashlib
import os
import re
import shutil
import signal
import stat
import sys
import tempfile
import threading
import time
import uuid

import bpy
import numpy as np

from .. import constants as K
from .. import convert as core
from .. import imagestream as stream
from ..convert import ConversionError
from ..imagecheck import FORMAT_NAMES, ImageFileError, check_image_file
from ..core.graph import Graph
from . import compat, material
from .nodes.builder import TreeBuilder
from .nodes.emit import emit
from .nodes.lobes import build_lobes, tangent as tangent_node

UDIM_TOKEN = "<UDIM>"
STAMP = K.MAPS_STAMP
_LINEAR_NAMES = ("Linear Rec.709", "Linear", "Linear BT.709")
_DATA_NAMES = ("Non-Color", "Raw", "Generic Data")
_EXT = {"OPEN_EXR": ".exr", "PNG": ".png"}


# --------------------------------------------------------------------------------------------
# Checking files before Blender reads them
# --------------------------------------------------------------------------------------------


def check_readable(path, label):
    """The one check before Blender reads a file (:func:`hazy_gloss.imagecheck.check_image_file`:
    a non-empty regular file, an image format Blender reads, an OpenEXR, PNG or JPEG not cut
    off or damaged, no header claiming more than the file can hold): Blender 5.0.1 segfaults on
    a truncated EXR.  Raises ConversionError (one line naming ``label`` and ``path``); returns
    the format's name ("OpenEXR", "PNG", "JPEG", …)."""
    try:
        info = check_image_file(path)
    except ImageFileError as exc:
        raise ConversionError(f"{label}: {exc}") from None
    except FileNotFoundError:
        raise ConversionError(f"{label}: file not found: {path}") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        raise ConversionError(f"{label}: cannot read {path}: {_reason(exc)}") from None
    return FORMAT_NAMES[info.format]


class _BlenderMessages:
    """What Blender prints (on stdout and stderr: its log goes to stdout in 5.x) while it reads
    or writes a file: passed on unchanged when the call succeeds, folded into the one-line
    error (:meth:`suffix`) when it fails."""

    _CLOG = re.compile(r"^\d+:\d+\.\d+\s+\S+\s+\|\s*(?:ERROR|WARNING|INFO)?\s*")

    def __enter__(self):
        self.raw, self._keep, self._saved = b"", False, []
        try:
            with _DeferredSignals():  # an interruption must not leave stdout/stderr redirected
                for fd, stream in ((1, sys.stdout), (2, sys.stderr)):
                    try:
                        if stream is not None:
                            stream.flush()
                        tmp = tempfile.TemporaryFile()
                        saved = os.dup(fd)
                    except (OSError, ValueError, AttributeError):  # no real fd: not captured
                        continue
                    os.dup2(tmp.fileno(), fd)
                    self._saved.append((fd, stream, saved, tmp))
        except BaseException:
            self.__exit__(*sys.exc_info())
            raise
        return self

    def swallow(self):
        """The call failed: the messages go into the error instead of the console."""
        self._keep = True

    def __exit__(self, exc_type, exc, tb):
        texts = []
        with _DeferredSignals():
            while self._saved:
                fd, stream, saved, tmp = self._saved.pop(0)
                try:
                    if stream is not None:
                        stream.flush()
                except (OSError, ValueError):
                    pass
                os.dup2(saved, fd)
                os.close(saved)
                tmp.seek(0)
                raw = tmp.read()
                tmp.close()
                texts.append(raw)
                if raw and not self._keep and exc_type is None:
                    os.write(fd, raw)
            self.raw = b"\n".join(texts)
        return False

    def suffix(self):
        lines = []
        for line in self.raw.decode("utf-8", "replace").splitlines():
            line = self._CLOG.sub("", line).strip()
            if line and line not in lines:
                lines.append(line)
        text = "; ".join(lines)
        if len(text) > 300:
            text = text[:297] + "..."
        return f" (Blender: {text})" if text else ""


def _one_line(text):
    """A Blender exception's message (sometimes several lines) as one line."""
    return "; ".join(p.strip() for p in str(text).splitlines() if p.strip())


def _reason(exc):
    """An OSError (or the ValueError of a NUL in a path) as a short reason."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return _one_line(exc) or type(exc).__name__


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------


def _abspath(path, library=None, what="path"):
    path = os.fspath(path)
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if "\x00" in path:
        raise ConversionError(f"{what} {path!r} contains a NUL character")
    if path.startswith("//"):
        if not bpy.data.filepath and library is None:
            raise ConversionError(f"relative path {path!r} needs a saved .blend file")
        path = bpy.path.abspath(path, library=library)
    try:
        return os.path.normpath(os.path.abspath(path))
    except OSError as exc:  # a relative path and the current folder was deleted
        raise ConversionError(f"{what} {path!r} is relative and the current folder cannot be "
                              f"read ({_reason(exc)}); give an absolute path") from None


def _label(name, source):
    if isinstance(source, bpy.types.Image):
        return f"{name} (image {source.name!r})"
    if isinstance(source, np.ndarray):
        return f"{name} (array)"
    try:
        return f"{name} ({os.path.basename(os.fsdecode(os.fspath(source)))})"
    except TypeError:
        hint = ""
        if isinstance(source, (list, tuple)):
            hint = " (a constant is a number, or (r, g, b) for a colour)"
        raise ConversionError(f"{name}: expected an image path, an image datablock, a numpy "
                              f"array or a constant, got {type(source).__name__} "
                              f"{_short(source)}{hint}") from None


def _short(value, n=40):
    text = repr(value)
    return text if len(text) <= n else text[:n - 3] + "..."


def _looks_like_constant(text):
    """'0.5' or '0.9,0.6,0.3' (what the CLI accepts as a constant)."""
    try:
        return [float(p) for p in text.replace(" ", "").strip("()[]").split(",")]
    except ValueError:
        return None


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
                hint = ""
                if role == "colour" and source.ndim == 3 and source.shape[-1] == 4:
                    hint = " (drop alpha: array[..., :3])"
                elif role == "colour" and source.ndim == 2:
                    hint = " (a grey map: np.repeat(array[..., None], 3, axis=-1))"
                elif role == "data" and source.ndim == 3:
                    hint = " (one channel: array[..., 0])"
                raise ConversionError(f"{self.label}: expected shape "
                                      f"{'(H, W, 3)' if role == 'colour' else '(H, W)'}, got "
                                      f"{source.shape}{hint}")
            if source.dtype.kind not in "biuf":
                raise ConversionError(f"{self.label}: expected a float array, got dtype {source.dtype}")
            if source.dtype.kind in "iu" and source.size and name in _UNIT_RANGE and \
                    int(source.max()) > 1:
                raise ConversionError(f"{self.label}: integer array ({source.dtype}) with values up "
                                      f"to {int(source.max())}; {name} is in [0, 1]: pass floats "
                                      "(for 8-bit values divide by 255)")
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
            text = os.fsdecode(os.fspath(source))
            path = _abspath(source, what=f"{name}:")
            if not os.path.exists(path) and UDIM_TOKEN not in path and \
                    _looks_like_constant(text) is not None:
                nums = _looks_like_constant(text)
                const = nums[0] if len(nums) == 1 else tuple(nums)
                raise ConversionError(f"{name}: {text!r} is a string and no such file exists; give "
                                      f"a constant as a number or a tuple, e.g. {name}={const!r}")
            if UDIM_TOKEN in path:
                self.tiles = _tile_paths(path)
                if not self.tiles:
                    raise ConversionError(f"{self.label}: no UDIM tile matches {path}")
                self.colourspace = None
            else:
                self.path = path

    def check(self):
        """Check every file of this input before anything is read or written."""
        if self.path:
            check_readable(self.path, self.label)
        elif self.tiles:
            for n, p in self.tiles.items():
                check_readable(p, f"{self.label} tile {n}")
        elif self.image is not None:
            _check_datablock_file(self.image, self.label)

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
        with _BlenderMessages() as said:
            try:
                return self._read(tile, warnings)
            except ConversionError as exc:
                said.swallow()
                error = exc
        raise ConversionError(f"{error}{said.suffix()}") from None

    def strips(self, tile, warnings, oiio):
        """A row reader (_Decoded) of this input for ``tile``: files stream through
        OpenImageIO; arrays are served in place; datablocks (and files without OpenImageIO,
        or in a colour space only Blender converts) are read whole through Blender."""
        if self.array is not None:
            return _Decoded(stream.ArrayStrips(self.array, self.label), self.role)
        path = None
        if self.image is None:
            path = self.path if self.tiles is None else self.tiles.get(tile, None)
            if path is None:
                raise ConversionError(f"{self.label}: UDIM tile {tile} is missing")
        label = self.label if self.tiles is None else f"{self.label} tile {tile}"
        if path is not None and oiio is not None:
            check_readable(path, label)
            try:
                reader = stream.OiioStrips(oiio, path, label)
            except stream.StripError:
                reader = None  # a file OpenImageIO does not read: Blender's loader below
            if reader is not None:
                try:
                    mode = self._mode(reader, label, warnings)
                except BaseException:
                    reader.close()
                    raise
                if mode is not None:
                    return _Decoded(reader, self.role, mode)
                reader.close()
        return _Decoded(stream.ArrayStrips(self.read(tile, warnings), label), self.role)

    def _mode(self, reader, label, warnings):
        """How a file's values become the conversion's (docs/textures.md "Colour spaces"),
        from the colour space Blender gives such a file (8- and 16-bit integer formats sRGB,
        float formats scene linear) or a tiled datablock's; None: only Blender converts it."""
        tag = getattr(self, "colourspace", None) or ("Linear Rec.709" if reader.is_float
                                                     else "sRGB")
        data = tag == "Non-Color" or tag in _DATA_NAMES
        if self.role == "data":
            if not data and tag not in _LINEAR_NAMES:
                warnings.append(f"{label}: data map tagged {tag}; its raw values are used "
                                "(data maps are Non-Color)")
            return "raw"
        if data:
            warnings.append(f"{label}: colour map tagged Non-Color; its values are used as linear")
            return "raw"
        if tag in _LINEAR_NAMES:
            return "raw"
        if tag == "sRGB":
            return "bytes" if reader.byte else "srgb"
        if reader.byte:
            raise ConversionError(f"{label}: 8-bit colour maps in colour space {tag!r} are not "
                                  "supported; use sRGB, Linear Rec.709 or a float (EXR/16-bit) image")
        return None

    def _read(self, tile, warnings):
        if self.image is not None:
            return _read_datablock(self.image, self.role, self.label, warnings)
        path = self.path if self.tiles is None else self.tiles.get(tile, None)
        if path is None:
            raise ConversionError(f"{self.label}: UDIM tile {tile} is missing")
        label = self.label if self.tiles is None else f"{self.label} tile {tile}"
        colourspace = getattr(self, "colourspace", None)
        return _read_file(path, self.role, label, warnings, colourspace)


def udim_tiles(sources):
    """The UDIM tiles of a set of _Source inputs ([] when none is tiled); every tiled input
    must have the same tiles (else one line listing each one's)."""
    tiled = {n: s for n, s in sources.items() if s.tiles is not None}
    if not tiled:
        return []
    sets = {n: sorted(s.tiles) for n, s in tiled.items()}
    first = next(iter(sets.values()))
    if any(v != first for v in sets.values()):
        raise ConversionError("UDIM inputs have different tiles: " + "; ".join(
            f"{tiled[n].label} {', '.join(map(str, v))}" for n, v in sets.items()))
    return first


#: Inputs whose valid range is [0, 1] (integer arrays above 1 there are 8-bit values).
_UNIT_RANGE = ("core_reflectivity", "edge_tint", "roughness", "anisotropy", "haziness")


def _check_datablock_file(img, label):
    """A datablock Blender has not loaded yet (or will reload) reads its file: check it first."""
    if img.packed_file is None and img.source == "FILE" and img.filepath and not img.has_data:
        check_readable(_abspath(img.filepath, img.library), label)


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


def _load(path, label):
    """A private datablock of a file that passed :func:`check_readable` (the one place files
    are handed to Blender)."""
    check_readable(path, label)
    try:
        return bpy.data.images.load(path, check_existing=False)
    except RuntimeError as exc:
        raise ConversionError(f"{label}: cannot read {path}: {_one_line(exc)}") from None


def _read_file(path, role, label, warnings, colourspace=None):
    img = _load(path, label)
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
    _check_datablock_file(img, label)
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
        if img.packed_file is None:
            check_readable(_abspath(img.filepath, img.library), label)
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
# OpenImageIO (Blender's own) and the strip readers
# --------------------------------------------------------------------------------------------

_OIIO = []


def openimageio():
    """Blender's bundled OpenImageIO Python module, or None.

    Inside Blender ``import OpenImageIO`` works (it is in Blender's Python's site-packages);
    the ``bpy`` module from PyPI ships the same module in ``bpy/<version>/python/lib/.../
    site-packages`` without putting it on ``sys.path``: it is loaded from there by its file,
    leaving ``sys.path`` alone.  ``HAZY_GLOSS_NO_OIIO=1`` turns it off (the whole-image
    fallback through Blender's loader; for tests)."""
    if _OIIO:
        return _OIIO[0]
    mod = None
    if not os.environ.get("HAZY_GLOSS_NO_OIIO"):
        try:
            import OpenImageIO as mod  # noqa: N813
        except ImportError:
            mod = _bundled_oiio()
    _OIIO.append(mod)
    return mod


def _bundled_oiio():
    import importlib.util
    try:
        root = bpy.utils.resource_path("LOCAL")
    except (AttributeError, RuntimeError):
        return None
    pattern = os.path.join(root, "python", "lib*", "*", "site-packages", "OpenImageIO")
    found = glob.glob(pattern) + glob.glob(os.path.join(root, "python", "lib", "site-packages",
                                                        "OpenImageIO"))
    for folder in found:
        init = os.path.join(folder, "__init__.py")
        if not os.path.isfile(init):
            continue
        try:
            spec = importlib.util.spec_from_file_location("OpenImageIO", init,
                                                          submodule_search_locations=[folder])
            mod = importlib.util.module_from_spec(spec)
            sys.modules["OpenImageIO"] = mod
            spec.loader.exec_module(mod)
            return mod
        except Exception:  # an incompatible build: the whole-image fallback
            sys.modules.pop("OpenImageIO", None)
    return None


class _Decoded:
    """Rows of one input, decoded as the conversion uses them: colour maps (n, W, 3) linear,
    data maps (n, W) raw.  ``mode``: "raw" (data, linear or already decoded values), "bytes"
    (8-bit sRGB: the 256-entry IEC table), "srgb" (16-bit sRGB: the IEC curve)."""

    def __init__(self, reader, role, mode="raw"):
        self.reader, self.role, self.mode = reader, role, mode
        self.width, self.height = reader.width, reader.height
        self.label = getattr(reader, "label", "")

    def rows(self, y0, y1):
        try:
            a = self.reader.rows(y0, y1, 3 if self.role == "colour" else 1)
        except stream.StripError as exc:
            raise ConversionError(f"{self.label}: {exc}") from None
        if self.role == "colour":
            a = a[..., :3] if a.shape[-1] >= 3 else np.repeat(a[..., :1], 3, axis=-1)
            if self.mode == "bytes":
                return core.srgb_bytes_to_linear(a)
            if self.mode == "srgb":
                return core.srgb_to_linear(a)
            return np.asarray(a, np.float32)
        return np.asarray(a[..., 0], np.float32)

    def close(self):
        self.reader.close()


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------

_CODECS = []


def exr_codecs():
    """The EXR codecs Blender offers for 32-bit float (measured once: the enum items a 32-bit
    EXR format accepts; B44 is for half floats)."""
    if _CODECS:
        return _CODECS[0]
    scene = bpy.data.scenes.new(".hazy_gloss_codecs")
    try:
        s = scene.render.image_settings
        if hasattr(s, "media_type"):  # 5.0
            s.media_type = "IMAGE"
        s.file_format, s.color_mode, s.color_depth = "OPEN_EXR", "RGB", "32"
        codecs = []
        for item in s.bl_rna.properties["exr_codec"].enum_items:
            try:
                s.exr_codec = item.identifier
                codecs.append(item.identifier)
            except TypeError:
                pass
    finally:
        bpy.data.scenes.remove(scene)
    _CODECS.append(tuple(codecs))
    return _CODECS[0]


def _check_codec(file_format, exr_codec):
    if file_format != "OPEN_EXR":
        return "ZIP"
    codecs = exr_codecs()
    codec = exr_codec.upper() if isinstance(exr_codec, str) else exr_codec
    if codec not in codecs:
        lossless = [c for c in codecs if c in K.LOSSLESS_EXR_CODECS]
        raise ConversionError(f"exr_codec must be one of {', '.join(codecs)} (lossless: "
                              f"{', '.join(lossless)}); got {_short(exr_codec)}")
    if codec not in stream.EXR_CODECS and openimageio() is None:
        raise ConversionError(f"exr_codec {codec} needs Blender's OpenImageIO module, which is "
                              f"not available here; use {', '.join(stream.EXR_CODECS)}")
    return codec


class _OiioExrWriter:
    """Codecs the add-on does not encode itself (PIZ, RLE, PXR24, DWA, HTJ2K): written by
    OpenImageIO strip by strip; the proof is then a decoded read-back (lossless codecs: the
    sha256 of the floats read equals that of the floats written; lossy: every value finite)."""

    def __init__(self, oiio, path, width, height, codec):
        self.oiio, self.path, self.width, self.height = oiio, path, width, height
        self.codec, self.row = codec, 0
        self.exact = codec in K.LOSSLESS_EXR_CODECS
        self._hash = hashlib.sha256()
        spec = oiio.ImageSpec(width, height, 3, oiio.FLOAT)
        spec.attribute("compression", codec.lower())
        self.out = oiio.ImageOutput.create(path)
        if self.out is None or not self.out.open(path, spec):
            why = self.out.geterror() if self.out is not None else oiio.geterror()
            raise ConversionError(f"could not write {path} with EXR codec {codec}: "
                                  f"{_one_line(why)}")

    def encode(self, y0, values):
        v = np.asarray(values, np.float32)
        if v.ndim == 2:
            v = np.repeat(v[..., None], 3, axis=-1)
        return y0, np.ascontiguousarray(v)

    def append(self, encoded):
        y0, v = encoded
        if not self.out.write_scanlines(y0, y0 + v.shape[0], 0, v):
            raise OSError(f"{_one_line(self.out.geterror())}")
        self._hash.update(v.tobytes())
        self.row += v.shape[0]

    def close(self):
        out, self.out = self.out, None
        if out is not None and not out.close():
            raise OSError(_one_line(out.geterror()))

    def abort(self):
        if self.out is not None:
            self.out.close()
            self.out = None

    def verify(self, check):
        check(self.path)
        reader = stream.OiioStrips(self.oiio, self.path)
        try:
            if (reader.width, reader.height) != (self.width, self.height):
                raise stream.StripError(f"{self.path} reads back as {reader.width}x"
                                        f"{reader.height}, not {self.width}x{self.height}")
            h = hashlib.sha256()
            rows = stream.strip_rows(self.width)
            for y0 in range(0, self.height, rows):
                v = reader.rows(y0, min(self.height, y0 + rows), 3)
                if not self.exact and not np.isfinite(v).all():
                    raise stream.StripError(f"{self.path} reads back with non-finite values")
                h.update(np.ascontiguousarray(v, np.float32).tobytes())
        finally:
            reader.close()
        if self.exact and h.hexdigest() != self._hash.hexdigest():
            raise stream.StripError(f"{self.path} reads back with other values than written "
                                    "(disk full or a failing device?)")


class _MapFile:
    """One output map written to its temporary in strips (hazy_gloss.imagestream) and proved
    complete at the end: the file read back as bytes hashes to the bytes encoded, and its
    structure passes the file check.  I/O errors become one-line ConversionErrors naming
    ``final``."""

    def __init__(self, file_format, codec, tmp, final, width, height):
        self.tmp, self.final = tmp, final
        try:
            if file_format == "PNG":
                self.writer = stream.PngStripWriter(tmp, width, height)
            elif codec in stream.EXR_CODECS:
                self.writer = stream.ExrStripWriter(tmp, width, height, codec=codec)
            else:
                self.writer = _OiioExrWriter(openimageio(), tmp, width, height, codec)
        except OSError as exc:
            raise ConversionError(f"could not write {final}: {_reason(exc)}") from None

    def encode(self, y0, values):
        return self.writer.encode(y0, values)

    def append(self, encoded):
        try:
            self.writer.append(encoded)
        except OSError as exc:
            raise ConversionError(f"could not write {self.final}: {_reason(exc)}") from None

    def close_file(self):
        """The one call that completes a file (a seam for the tests' full-disk simulation)."""
        self.writer.close()

    def finish(self):
        try:
            self.close_file()
        except OSError as exc:
            raise ConversionError(f"could not write {self.final}: {_reason(exc)}") from None
        try:
            self.writer.verify(lambda p: check_readable(p, "read back"))
        except (stream.StripError, ConversionError) as exc:
            raise ConversionError(f"could not write {self.final} (disk full?): {exc}") from None
        except OSError as exc:
            raise ConversionError(f"could not write {self.final}: it does not read back "
                                  f"({_reason(exc)})") from None

    def abort(self):
        try:
            self.writer.abort()
        except OSError:
            pass

# All or nothing: temporaries, backups, commit, undo
# --------------------------------------------------------------------------------------------


class _DeferredSignals:
    """Hold SIGINT and SIGTERM while files are renamed or restored.

    Only signals with a Python handler are held (KeyboardInterrupt's, the CLI's SIGTERM
    handler); :meth:`poll` runs a held handler at a safe point (between two renames, where an
    exception can still be undone), ``__exit__`` after the block unless an interruption is
    already on its way.  Outside the main thread nothing is held (Python runs handlers there
    only)."""

    SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM") if hasattr(signal, n))

    def __enter__(self):
        self.saved, self.pending = {}, []
        if threading.current_thread() is threading.main_thread():
            for sig in self.SIGNALS:
                handler = signal.getsignal(sig)
                if callable(handler):
                    try:
                        signal.signal(sig, self._hold)
                    except (ValueError, OSError):
                        continue
                    self.saved[sig] = handler
        return self

    def _hold(self, signum, frame):
        self.pending.append(signum)

    def poll(self):
        while self.pending:
            signum = self.pending.pop(0)
            self.saved[signum](signum, None)

    def __exit__(self, exc_type, exc, tb):
        for sig, handler in self.saved.items():
            signal.signal(sig, handler)
        if exc_type is None or issubclass(exc_type, Exception):
            self.poll()
        return False


def _remove(path):
    try:
        os.remove(path)
    except FileNotFoundError:
        pass
    except OSError:
        return False
    return True


class _Transaction:
    """The files of one conversion, all or nothing.

    Maps are written to temporaries ``.<name>.<run>.tmp<ext>`` in the output folder (same file
    system: renames are atomic) and verified; :meth:`commit` then backs up every map it replaces
    (a hard link ``.<name>.<run>.bak<ext>``, a copy where links are not supported), renames the
    temporaries into place and deletes the backups only once every map is in place.  On any
    failure or interruption :meth:`rollback` restores the replaced maps from their backups,
    deletes the maps new in this run and every temporary, and removes the folders the run
    created.  Temporaries and backups left by a killed earlier run are deleted by
    :meth:`clean_stale` (only names of this pattern, older than this run)."""

    def __init__(self, out_dir, started):
        self.out_dir = out_dir
        self.started = started
        self.run = uuid.uuid4().hex[:K.CONVERT_RUN_ID_HEX]
        self.created = []  # folders made by this run, parents first
        self.temps = {}  # final path -> temporary path
        self.backups = {}  # final path -> backup of the file it replaces
        self.renamed = []  # finals renamed into place by this run
        self.retired = {}  # stale file moved aside at commit -> its backup
        self.committed = False
        self.problems = []

    def side(self, final, tag):
        folder, base = os.path.split(final)
        stem, ext = os.path.splitext(base)
        return os.path.join(folder, f".{stem}.{self.run}.{tag}{ext}")

    def temp(self, final):
        """The temporary for ``final``, recorded before it exists (a failure while it is being
        written still removes it)."""
        return self.temps.setdefault(final, self.side(final, "tmp"))

    def make_folder(self):
        """Create the output folder and its missing parents (recorded for the rollback), then
        check that files can be created in it."""
        missing, p = [], self.out_dir
        while not os.path.isdir(p):
            if os.path.lexists(p):
                raise ConversionError(f"output folder {self.out_dir}: {p} is not a folder")
            missing.append(p)
            parent = os.path.dirname(p)
            if parent == p:
                break
            p = parent
        for d in reversed(missing):
            try:
                os.mkdir(d)
            except FileExistsError:
                if not os.path.isdir(d):
                    raise ConversionError(f"output folder {self.out_dir}: {d} is not a folder") from None
                continue
            except OSError as exc:
                raise ConversionError(f"cannot create the output folder {self.out_dir}: "
                                      f"{_reason(exc)}") from None
            self.created.append(d)
        probe = self.side(os.path.join(self.out_dir, "hazy_gloss_probe.png"), "tmp")
        try:
            fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except OSError as exc:
            raise ConversionError(f"the output folder {self.out_dir} is not writable: "
                                  f"{_reason(exc)}") from None
        os.close(fd)
        _remove(probe)

    def clean_stale(self, names):
        """Delete temporaries and backups of earlier runs: ``.<prefix><map>[.<tile>].<hex>.(tmp|
        bak).<ext>`` for a map name in ``names``, last modified before this run started."""
        rx = re.compile(r"\.(?P<stem>.+)\.(?P<run>[0-9a-f]{%d})\.(?:tmp|bak)(?:%s)\Z" % (
            K.CONVERT_RUN_ID_HEX, "|".join(re.escape(e) for e in _EXT.values())))
        removed = []
        try:
            entries = list(os.scandir(self.out_dir))
        except OSError:
            return removed
        for entry in entries:
            m = rx.match(entry.name)
            if m is None or m["run"] == self.run:
                continue
            stem = re.sub(r"\.\d{4}\Z", "", m["stem"])
            if stem != "hazy_gloss_probe" and not any(stem.endswith(n) for n in names):
                continue
            try:
                if not entry.is_file(follow_symlinks=False) or \
                        entry.stat(follow_symlinks=False).st_mtime >= self.started:
                    continue
            except OSError:
                continue
            if _remove(entry.path):
                removed.append(entry.name)
        return removed

    def commit(self, retire=()):
        """Move ``retire`` (stale files of an earlier set) aside, rename every temporary into
        place, then delete the backups.  Interruptions are handled between renames (undone)."""
        with _DeferredSignals() as sig:
            try:
                for path in retire:
                    bak = self.side(path, "bak")
                    os.replace(path, bak)
                    self.retired[path] = bak
                    sig.poll()
                for final, tmp in self.temps.items():
                    if os.path.lexists(final):
                        bak = self.side(final, "bak")
                        try:
                            os.link(final, bak, follow_symlinks=False)
                        except OSError:  # no hard links here: a copy
                            shutil.copy2(final, bak, follow_symlinks=False)
                        self.backups[final] = bak
                    os.replace(tmp, final)
                    self.renamed.append(final)
                    sig.poll()
                sig.poll()  # the last point where the whole set can still be undone
            except BaseException:
                self._undo()
                raise
            self.committed = True
            for bak in [*self.backups.values(), *self.retired.values()]:
                _remove(bak)

    def rollback(self):
        """Undo everything this run did to the folder; returns what could not be undone."""
        with _DeferredSignals():
            self._undo()
        return self.problems

    def _undo(self):
        for final in reversed(self.renamed):
            bak = self.backups.pop(final, None)
            try:
                if bak is not None:
                    os.replace(bak, final)
                else:
                    os.remove(final)
            except OSError as exc:
                self.problems.append(f"could not restore {final} ({_reason(exc)})"
                                     + (f"; its previous version is {bak}" if bak else ""))
        self.renamed.clear()
        for path, bak in list(self.retired.items()):
            try:
                os.replace(bak, path)
                del self.retired[path]
            except OSError as exc:
                self.problems.append(f"could not restore {path} ({_reason(exc)}); it is {bak}")
        for tmp in self.temps.values():
            _remove(tmp)
        self.temps.clear()
        for bak in self.backups.values():  # backups of finals that were not replaced yet
            _remove(bak)
        self.backups.clear()
        for d in reversed(self.created):
            try:
                os.rmdir(d)
            except OSError:
                break
        self.created.clear()


# --------------------------------------------------------------------------------------------
# Conversion
# --------------------------------------------------------------------------------------------


def _out_path(out_dir):
    """Absolute output folder ('//' is relative to the saved .blend); not created here."""
    if out_dir is None:
        raise ConversionError("out_dir: no output folder given")
    if not isinstance(out_dir, (str, bytes, os.PathLike)):
        raise ConversionError(f"out_dir must be a folder path, got {type(out_dir).__name__} "
                              f"{_short(out_dir)}")
    text = os.fspath(out_dir)
    text = os.fsdecode(text) if isinstance(text, bytes) else text
    if not text.strip():
        raise ConversionError(f"out_dir must name a folder, got {text!r}")
    path = _abspath(text, what="out_dir")
    p = path
    while not os.path.isdir(p):  # the first existing ancestor must be a folder
        if os.path.lexists(p):
            raise ConversionError(f"output folder is a file: {p}" if p == path else
                                  f"output folder {path}: {p} is a file, not a folder")
        parent = os.path.dirname(p)
        if parent == p:
            break
        p = parent
    return path


def _check_prefix(prefix):
    if prefix is None:
        return ""
    if not isinstance(prefix, str):
        raise ConversionError(f"prefix must be a string, got {type(prefix).__name__} {_short(prefix)}")
    if any(c in "/\\" or ord(c) < 32 or ord(c) == 127 for c in prefix) or \
            prefix.startswith(".") or ".." in prefix:
        raise ConversionError(f"prefix must be a plain file-name prefix (no path separator, control "
                              f"or NUL character, leading '.' or '..'), got {prefix!r}")
    return prefix


def _check_options(material, interpolation, progress, tile_texels, resample):
    """The options that are used after the maps are written: checked before anything is."""
    if material is not None:
        if not isinstance(material, bpy.types.Material):
            hint = (f" (use bpy.data.materials[{material!r}])" if isinstance(material, str) else "")
            raise ConversionError(f"material must be a bpy.types.Material or None, got "
                                  f"{type(material).__name__} {_short(material)}{hint}")
        if material.library is not None:
            raise ConversionError(f"material {material.name!r} is linked from a library and "
                                  "cannot be edited")
    items = [e.identifier for e in
             bpy.types.ShaderNodeTexImage.bl_rna.properties["interpolation"].enum_items]
    if interpolation not in items:
        raise ConversionError(f"interpolation must be one of {', '.join(items)}; got "
                              f"{_short(interpolation)}")
    if progress is not None and not callable(progress) and not isinstance(progress, core.Progress):
        raise ConversionError(f"progress must be None or a callable(done, total, message), got "
                              f"{type(progress).__name__}")
    if isinstance(tile_texels, bool) or not isinstance(tile_texels, (int, np.integer)) or \
            tile_texels < 1:
        raise ConversionError(f"tile_texels must be a positive integer, got {_short(tile_texels)}")
    if not isinstance(resample, (bool, np.bool_)):
        raise ConversionError(f"resample must be True or False, got {_short(resample)}")


def _check_targets(targets, input_files, txn):
    """Before anything is written: no target is an input (same path or same file), a folder, or
    a name too long for the file system."""
    input_ids = set()
    for p in input_files:
        try:
            st = os.stat(p)
            input_ids.add((st.st_dev, st.st_ino))
        except OSError:
            pass
    for t in targets:
        if len(os.fsencode(os.path.basename(txn.side(t, "tmp")))) > 255:
            raise ConversionError(f"output file name {os.path.basename(t)!r} is too long; use a "
                                  "shorter prefix")
        try:
            st = os.stat(t)
        except FileNotFoundError:
            st = None
        except OSError as exc:
            raise ConversionError(f"output {t}: {_reason(exc)}") from None
        if os.path.realpath(t) in input_files or (st is not None and (st.st_dev, st.st_ino) in input_ids):
            raise ConversionError(f"output {t} would overwrite an input; choose another folder "
                                  "or prefix")
        if st is not None and stat.S_ISDIR(st.st_mode):
            raise ConversionError(f"output {t} is a folder; remove it or choose another folder "
                                  "or prefix")


def _all_map_names():
    return sorted({s.name for k in K.KINDS for s in core.output_specs(k, True)},
                  key=len, reverse=True)


def convert_maps(inputs, out_dir, **options):
    """Convert perceptual maps to physical maps, all or nothing; see hazy_gloss.api.convert_maps.
    Blocking: runs :func:`convert_maps_steps` to its end."""
    return core.drain(convert_maps_steps(inputs, out_dir, **options))


def convert_maps_steps(inputs, out_dir, *, kind="CONDUCTOR", smoothness=None, distribution="GGX",
                       file_format="OPEN_EXR", resample=False, prefix="", exr_codec="ZIP",
                       material=None, interpolation="Linear", progress=None,
                       tile_texels=K.STRIP_TEXELS, threads=None):
    """The conversion as a generator: it yields after every strip (the modal operator steps it
    between events) and returns the ConversionResult.  ``progress``: a callable(done, total,
    message) or a core.Progress (whose cancel() stops the run, undone, at the next strip)."""
    t0 = time.perf_counter()
    started = time.time()
    file_format = str(file_format).upper()
    specs, notes = core.resolve_inputs(inputs, kind=kind, distribution=distribution,
                                       smoothness=smoothness, file_format=file_format)
    kind, distribution = str(kind).upper(), str(distribution).upper()
    prefix = _check_prefix(prefix)
    _check_options(material, interpolation, progress, tile_texels, resample)
    codec = _check_codec(file_format, exr_codec)
    prog = progress if isinstance(progress, core.Progress) else core.Progress(progress)
    sources = {n: _Source(n, s.role, s.source) for n, s in specs.items() if not s.is_constant}
    # a haze extent shared by both axes is read once
    shared_extent = (specs["haze_extent_x"].given_as == "haze_extent"
                     and not specs["haze_extent_x"].is_constant)
    if shared_extent:
        sources.pop("haze_extent_y", None)

    tiles = udim_tiles(sources)
    for src in sources.values():  # every input file, before anything is written
        src.check()
    out_dir = _out_path(out_dir)
    input_files = {os.path.realpath(p) for s in sources.values() for p in s.files()}

    report = core.ConversionReport(kind=kind, distribution=distribution, file_format=file_format,
                                   tiles=list(tiles), warnings=list(notes))
    ext = _EXT[file_format]
    jobs = tiles or [None]
    txn = _Transaction(out_dir, started)
    _check_targets([_final_path(out_dir, prefix, s.name, tile, ext)
                    for tile in jobs for s in core.output_specs(kind, True)], input_files, txn)
    alpha_given = specs["roughness"].transform == "sqrt"
    run = _Run(specs, sources, shared_extent, resample, report, prog, alpha_given, tile_texels)
    try:
        txn.make_folder()
        stale = txn.clean_stale(_all_map_names())
        if stale:
            report.warnings.append(f"removed {len(stale)} temporary file(s) left in "
                                   f"{out_dir} by an interrupted earlier conversion")
        anisotropic = yield from run.anisotropy(jobs)
        out_specs = core.output_specs(kind, anisotropic)
        report.anisotropic = anisotropic
        paths = {s.name: _final_path(out_dir, prefix, s.name, UDIM_TOKEN if tiles else None, ext)
                 for s in out_specs}
        for tile in jobs:
            if tile:
                prog.next_item(jobs.index(tile), len(jobs), tile, key="tile")
            finals = {s.name: _final_path(out_dir, prefix, s.name, tile, ext) for s in out_specs}
            yield from run.tile(tile, finals, txn, out_specs, kind, distribution, smoothness,
                                anisotropic, file_format, codec, threads)
        retire = []
        if tiles:  # tiles of an earlier, larger set would join this one in a tiled image
            for s in out_specs:
                on_disk = _tile_paths(_final_path(out_dir, prefix, s.name, UDIM_TOKEN, ext))
                retire += [p for t, p in sorted(on_disk.items()) if t not in tiles]
            if retire:
                report.warnings.append("removed UDIM tiles of an earlier conversion that are not "
                                       "in this set: " + ", ".join(os.path.basename(p) for p in retire))
        prog.check()  # the last point where a cancel undoes the run
        txn.commit(retire)
    except BaseException as exc:
        _undo(txn, exc)
        raise
    report.warnings = list(dict.fromkeys(report.warnings))
    report.seconds = time.perf_counter() - t0
    result = core.ConversionResult(paths, report, out_specs)
    if material is not None:
        wire_material(material, result, interpolation=interpolation)
    return result


def _undo(txn, exc):
    """After a failure or an interruption: undo the run's files; OSErrors and failed undos become
    the one-line ConversionError (raised from here), anything else is re-raised by the caller."""
    if txn.committed:  # a signal held during the last clean-up: the set is complete
        exc.committed = True
        return
    problems = txn.rollback()
    extra = ("; " + "; ".join(problems)) if problems else ""
    if isinstance(exc, OSError):
        where = getattr(exc, "filename2", None) or exc.filename
        where = f"{where}: " if where else ""
        raise ConversionError(f"could not write the maps ({where}{_reason(exc)}); "
                              + (extra[2:] if extra else "the output folder is unchanged")) from None
    if isinstance(exc, ConversionError) and extra:
        raise ConversionError(f"{exc}{extra}") from None
    if extra and hasattr(exc, "add_note"):
        exc.add_note(extra[2:])


def _final_path(out_dir, prefix, name, tile, ext):
    return os.path.join(out_dir, f"{prefix}{name}{'.' + str(tile) if tile else ''}{ext}")


class _Run:
    """The inputs of one conversion, opened tile by tile as strip readers."""

    def __init__(self, specs, sources, shared_extent, resample, report, prog, alpha_given,
                 tile_texels):
        self.specs, self.sources, self.shared = specs, sources, shared_extent
        self.resample, self.report, self.prog = resample, report, prog
        self.alpha_given, self.tile_texels = alpha_given, tile_texels
        self.constants = {n: s.source for n, s in specs.items() if s.is_constant}
        self.oiio = openimageio()
        if self.oiio is None and any(s.tiles or s.path for s in sources.values()):
            report.warnings.append("Blender's OpenImageIO module was not found: files are read "
                                   "whole through Blender's loader (memory grows with the image)")

    def open(self, tile, names=None):
        """({name: _Decoded}, (w, h)) of this tile's inputs, sizes checked (or resampled)."""
        readers, sizes = {}, []
        try:
            for name, src in self.sources.items():
                if names is not None and name not in names:
                    continue
                r = src.strips(tile, self.report.warnings, self.oiio)
                readers[name] = r
                sizes.append((src.label + (f" tile {tile}" if tile else ""), (r.width, r.height), name))
            target = max((s for _, s, _ in sizes), key=lambda s: s[0] * s[1])
            if self.resample:
                for label, size, name in sizes:
                    if size != target:
                        if names is None:
                            self.report.warnings.append(
                                f"{label}: resampled from {size[0]}x{size[1]} to "
                                f"{target[0]}x{target[1]} (bilinear)")
                        readers[name] = _Resampled(readers[name], target)
            else:
                core.check_sizes([(label, size) for label, size, _ in sizes])
        except BaseException:
            for r in readers.values():
                r.close()
            raise
        return readers, target

    def _arrays(self, readers, y0, y1):
        arrays = dict(self.constants)
        for name, r in readers.items():
            arrays[name] = r.rows(y0, y1)
        if self.shared:
            arrays["haze_extent_y"] = arrays["haze_extent_x"]
        return arrays

    def anisotropy(self, jobs):
        """Whether the set needs the anisotropic maps, known before anything is written: from
        the constants, or by reading the anisotropy and haze extent maps first (all tiles:
        they must agree)."""
        c = self.constants
        names = [n for n in ("anisotropy", "haze_extent_x", "haze_extent_y") if n in self.sources]
        if "anisotropy" in c and float(c["anisotropy"]) > 0:
            return True
        if "haze_extent_x" in c and "haze_extent_y" in c:
            if float(c["haze_extent_x"]) != float(c["haze_extent_y"]):
                return True
            if "anisotropy" in c:
                return False
        if self.shared and names == ["haze_extent_x"] and "anisotropy" in c:
            return False
        for tile in jobs:
            readers, (w, h) = self.open(tile, names=names)
            try:
                rows = stream.strip_rows(w, self.tile_texels)
                for y0 in range(0, h, rows):
                    y1 = min(h, y0 + rows)
                    arrays = self._arrays(readers, y0, y1)
                    for n in core.PARAMETERS:  # inputs not read here: their defaults
                        arrays.setdefault(n, np.float32(core.DEFAULTS[n]))
                    clean = core.sanitise_inputs(arrays, {}, alpha_given=self.alpha_given)
                    self.prog.advance(0, "checking anisotropy" + (f" of tile {tile}" if tile else ""))
                    if core.is_anisotropic(clean):
                        return True
                    yield
            finally:
                for r in readers.values():
                    r.close()
        return False

    def tile(self, tile, finals, txn, out_specs, kind, distribution, smoothness, anisotropic,
             file_format, codec, threads):
        """One tile (or the single image): its maps written to temporaries and verified."""
        readers, (w, h) = self.open(tile)
        if self.report.size == (0, 0):
            self.report.size = (w, h)
        files = {}
        try:
            for s in out_specs:
                files[s.name] = _MapFile(file_format, codec, txn.temp(finals[s.name]),
                                         finals[s.name], w, h)
            yield from self.strips(readers, files, out_specs, (w, h), kind, distribution,
                                   smoothness, anisotropic, file_format, threads)
            for s in out_specs:
                files[s.name].finish()
                self.prog.advance(0, f"wrote {s.name}")
        finally:
            for f in files.values():
                f.abort()
            for r in readers.values():
                r.close()
        self.report.texels += w * h

    def strips(self, readers, files, out_specs, size, kind, distribution, smoothness,
               anisotropic, file_format, threads):
        """Map and write every strip of one tile (the strips run on a thread pool)."""
        w, h = size
        rows = stream.strip_rows(w, self.tile_texels)
        self.prog.begin(h)
        counts = []

        def read(y0, y1):
            return self._arrays(readers, y0, y1)

        def compute(y0, y1, arrays):
            clamped = {}
            clean = core.sanitise_inputs(arrays, clamped, alpha_given=self.alpha_given)
            maps, limits = core.describe_maps(clean, kind=kind, distribution=distribution,
                                              smoothness=smoothness, anisotropic=anisotropic,
                                              shape=(y1 - y0, w))
            core._add_counts(clamped, limits)
            encoded = {}
            for s in out_specs:
                values = maps[s.name]
                if file_format == "PNG":
                    values = core.encode_png(s, values)
                encoded[s.name] = files[s.name].encode(y0, values)
            return clamped, encoded

        def write(y0, y1, result):
            clamped, encoded = result
            counts.append(clamped)
            for s in out_specs:
                files[s.name].append(encoded[s.name])

        done = 0
        for y1, _ in stream.run_strips(h, rows, read, compute, write, workers=threads):
            self.prog.advance(y1 - done, "mapping and writing")
            done = y1
            yield
        for c in counts:  # in strip order: the report does not depend on the thread schedule
            core._add_counts(self.report.clamped, c)


class _Resampled:
    """Rows of a smaller (or larger) input resampled bilinearly to ``size`` (texel centres
    aligned, edges clamped: core.resample_bilinear), reading the source rows a strip needs,
    in order, keeping only those still needed."""

    def __init__(self, reader, size):
        self.reader, self.label = reader, reader.label
        self.width, self.height = int(size[0]), int(size[1])
        self.ys = core.resample_axis(self.height, reader.height)
        self.xs = core.resample_axis(self.width, reader.width)
        self._y0, self._rows = 0, None

    def _source(self, a, b):
        if self._rows is None or a < self._y0:
            self._y0, self._rows = a, self.reader.rows(a, b)
        have = self._y0 + self._rows.shape[0]
        if b > have:
            new = self.reader.rows(have, b)
            self._rows = np.concatenate([self._rows[max(0, a - self._y0):], new])
            self._y0 = max(a, self._y0)
        return self._rows[a - self._y0:b - self._y0]

    def rows(self, y0, y1):
        i0, i1, fy = (v[y0:y1] for v in self.ys)
        a, b = int(i0.min()), int(i1.max()) + 1
        block = self._source(a, b)
        return core.resample_block(block, i0 - a, i1 - a, fy, self.xs)

    def close(self):
        self.reader.close()

# --------------------------------------------------------------------------------------------
# Wiring into a material
# --------------------------------------------------------------------------------------------


def _load_image(path, label, check_existing=True):
    """A datablock of a file, or of a UDIM set (a ``<UDIM>`` path: its first tile loaded,
    then tiled), after the file check of every file."""
    first = path
    if UDIM_TOKEN in path:
        tiles = _tile_paths(path)
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
        raise ConversionError(f"{label}: cannot read {first}: {_one_line(exc)}") from None
    if UDIM_TOKEN in path:
        img.source = "TILED"
    return img


def _image_for(path):
    """An image datablock for a written map (reused and reloaded when it exists), Non-Color."""
    want = os.path.normpath(path)
    img = None
    for im in bpy.data.images:
        if im.library is None and im.filepath and os.path.normpath(
                bpy.path.abspath(im.filepath)) == want:
            img = im
            break
    if img is None:
        img = _load_image(path, os.path.basename(path), check_existing=False)
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
