# SPDX-License-Identifier: GPL-3.0-or-later
"""The inputs of a texture conversion, read through bpy: perceptual maps as strips of linear or raw values.

Files are read through Blender's own OpenImageIO module (:mod:`conversion.oiio`) and decoded as
Blender would (colour maps to linear, data maps raw); datablocks (packed and unsaved ones
included) are read in place, whole, as measured in Blender 4.5 / 5.x (``Image.pixels`` of an
8-bit image holds the file's encoded values whatever its colour space; float images are already
scene-linear).  Every file is checked (:func:`check_readable`: exists, an image format, not cut
off; one decode through OpenImageIO) before anything is written or Blender reads it: Blender
5.0.1 segfaults on a truncated EXR.

Also here, shared with the writing side (blender/model/convert_outputs.py): Blender's messages while
it reads or writes a file (:class:`_BlenderMessages`), signals held during renames
(:class:`DeferredSignals`) and the one-line error texts.
"""
from __future__ import annotations

import glob
import os
import re
import signal
import sys
import tempfile
import threading

import bpy
import numpy as np

from ...conversion import convert as conversion
from ...conversion import imagestream as stream
from ...conversion.convert import ConversionError
from ...conversion.imagecheck import FORMAT_NAMES, ImageFileError, check_image_file

__all__ = ("UDIM_TOKEN", "check_readable", "DeferredSignals", "one_line", "os_reason",
           "absolute_path", "short_repr", "tile_paths", "Source", "udim_tiles")

UDIM_TOKEN = "<UDIM>"
_LINEAR_NAMES = ("Linear Rec.709", "Linear", "Linear BT.709")
_DATA_NAMES = ("Non-Color", "Raw", "Generic Data")


# --------------------------------------------------------------------------------------------
# Checking files before Blender reads them
# --------------------------------------------------------------------------------------------


def check_readable(path, label):
    """The one check before Blender reads a file (:func:`conversion.imagecheck.check_image_file`:
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
        raise ConversionError(f"{label}: cannot read {path}: {os_reason(exc)}") from None
    return FORMAT_NAMES[info.format]


class DeferredSignals:
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


class _BlenderMessages:
    """What Blender prints (on stdout and stderr: its log goes to stdout in 5.x) while it reads
    or writes a file: passed on unchanged when the call succeeds, folded into the one-line
    error (:meth:`suffix`) when it fails."""

    _CLOG = re.compile(r"^\d+:\d+\.\d+\s+\S+\s+\|\s*(?:ERROR|WARNING|INFO)?\s*")

    def __enter__(self):
        self.raw, self._keep, self._saved = b"", False, []
        try:
            with DeferredSignals():  # an interruption must not leave stdout/stderr redirected
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
        with DeferredSignals():
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


def one_line(text):
    """A Blender exception's message (sometimes several lines) as one line."""
    return "; ".join(p.strip() for p in str(text).splitlines() if p.strip())


def os_reason(exc):
    """An OSError (or the ValueError of a NUL in a path) as a short reason."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return one_line(exc) or type(exc).__name__


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------


def absolute_path(path, library=None, what="path"):
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
                              f"read ({os_reason(exc)}); give an absolute path") from None


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
                              f"{short_repr(source)}{hint}") from None


def short_repr(value, n=40):
    text = repr(value)
    return text if len(text) <= n else text[:n - 3] + "..."


def _looks_like_constant(text):
    """'0.5' or '0.9,0.6,0.3' (what the CLI accepts as a constant)."""
    try:
        return [float(p) for p in text.replace(" ", "").strip("()[]").split(",")]
    except ValueError:
        return None


def tile_paths(pattern):
    """{tile number: path} of the files matching a path with the <UDIM> token."""
    head, tail = pattern.split(UDIM_TOKEN, 1)
    rx = re.compile(re.escape(head) + r"(\d{4})" + re.escape(tail) + r"\Z")
    tiles = {}
    for p in glob.glob(glob.escape(head) + "[0-9][0-9][0-9][0-9]" + glob.escape(tail)):
        m = rx.match(p)
        if m and 1001 <= int(m.group(1)) <= 2000:
            tiles[int(m.group(1))] = p
    return tiles


class Source:
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
                pattern = absolute_path(img.filepath, img.library)
                if UDIM_TOKEN not in pattern:
                    raise ConversionError(f"{self.label}: tiled image without {UDIM_TOKEN} in its path")
                on_disk = tile_paths(pattern)
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
            path = absolute_path(source, what=f"{name}:")
            if not os.path.exists(path) and UDIM_TOKEN not in path and \
                    _looks_like_constant(text) is not None:
                nums = _looks_like_constant(text)
                const = nums[0] if len(nums) == 1 else tuple(nums)
                raise ConversionError(f"{name}: {text!r} is a string and no such file exists; give "
                                      f"a constant as a number or a tuple, e.g. {name}={const!r}")
            if UDIM_TOKEN in path:
                self.tiles = tile_paths(path)
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
            return [absolute_path(img.filepath, img.library)]
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
            try:  # checked before anything was written (check); a strip read wrong is an error
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
    """The UDIM tiles of a set of Source inputs ([] when none is tiled); every tiled input
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
        check_readable(absolute_path(img.filepath, img.library), label)


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
        return conversion.srgb_bytes_to_linear(values)
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
        raise ConversionError(f"{label}: cannot read {path}: {one_line(exc)}") from None


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
        img.filepath and os.path.isfile(absolute_path(img.filepath, img.library))))
    if reloadable:
        if img.packed_file is None:
            check_readable(absolute_path(img.filepath, img.library), label)
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
        return conversion.linear_to_srgb(values)
    warnings.append(f"{label}: edited data map tagged {cs.name}; values used as stored "
                    "(set it to Non-Color)")
    return values


# --------------------------------------------------------------------------------------------
# The strip readers
# --------------------------------------------------------------------------------------------


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
                return conversion.srgb_bytes_to_linear(a)
            if self.mode == "srgb":
                return conversion.srgb_to_linear(a)
            return np.asarray(a, np.float32)
        return np.asarray(a[..., 0], np.float32)

    def close(self):
        self.reader.close()
