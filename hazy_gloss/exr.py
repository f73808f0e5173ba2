# SPDX-License-Identifier: GPL-3.0-or-later
"""A bounded, bpy-free reader of the OpenEXR files Blender writes, and a structure check.

- :func:`read_exr`: every channel of a scanline file (single- or multi-part; NONE, RLE, ZIPS,
  ZIP) as float32 arrays, for the recomposite passes;
- :func:`exr_header_check`: the structure of any scanline or tiled EXR (every codec) without
  decoding pixels, to refuse a damaged file before it is handed to Blender (a truncated ZIP EXR
  segfaults bpy 5.0.1's loader).

Both validate everything they use against the file and against fixed limits before trusting
it: attribute names, types and sizes; the channel list; data and display windows; the part
count; the offset table (every entry, and every chunk's header, coordinates and size within
the file, chunks not overlapping); for :func:`read_exr` also the exact decoded size of each
chunk (zlib with a bounded output, RLE bounded by the expected size).  Memory is bounded by
the file's size (x 1100 for ZIP, x 64 for RLE, x 1 for NONE; the largest expansions those
codecs allow) and by :data:`MAX_DECODED_BYTES`; the time by the file's size.  Every defect
raises :class:`ExrError` (a ``ValueError``) with a one-line message naming the file and what
is wrong; I/O errors stay ``OSError``.
"""
from __future__ import annotations

import math
import os
import struct
import zlib
from dataclasses import dataclass

import numpy as np

from . import constants as K
from .filebytes import FileBytes, FileShrankError

__all__ = ("ExrError", "ExrPart", "read_exr", "exr_header_check", "MAX_DECODED_BYTES")


class ExrError(ValueError):
    """A malformed or unsupported OpenEXR file (a ``ValueError``); ``str()`` is one line,
    ``"<path>: <defect>"``.  ``kind`` says what :func:`exr_header_check` found: "truncated"
    (something lies beyond the end of the file: cut off, or a corrupt length or offset),
    "corrupt", or "unsupported" (a valid file Blender cannot load: deep data, another
    version); ``detail`` is the defect without the path."""
    kind = "corrupt"
    detail = None


_MAGIC = K.EXR_MAGIC
#: Version field: bit 9 single-part tiled, 10 long names, 11 deep data, 12 multi-part.
_TILED, _DEEP, _MULTIPART = 0x200, 0x800, 0x1000
#: compression id -> (name, scanlines per chunk); OpenEXR 3.4's ids.
_COMPRESSION = {0: ("NONE", 1), 1: ("RLE", 1), 2: ("ZIPS", 1), 3: ("ZIP", 16), 4: ("PIZ", 32),
                5: ("PXR24", 16), 6: ("B44", 32), 7: ("B44A", 32), 8: ("DWAA", 32),
                9: ("DWAB", 256), 10: ("HTJ2K256", 256), 11: ("HTJ2K32", 32)}
#: Codecs read_exr decodes -> the largest ratio decoded/stored one chunk can have: deflate
#: expands at most 1032:1, OpenEXR's RLE 64:1 (2 bytes -> 128), NONE stores raw bytes.
_DECODED_RATIO = {0: 1, 1: 64, 2: K.MAX_DEFLATE_RATIO, 3: K.MAX_DEFLATE_RATIO}
_PIXEL_TYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}
_PIXEL_TYPE_NAMES = {0: "UINT", 1: "HALF", 2: "FLOAT"}
_PART_TYPES = ("scanlineimage", "tiledimage", "deepscanline", "deeptile")

#: Decoded pixel data read_exr accepts (hazy_gloss.constants, as every other limit here): its
#: float32 result is at most twice this (HALF channels).
MAX_DECODED_BYTES = K.MAX_EXR_DECODED_BYTES

#: Attribute type and size that the parser relies on (others are skipped unread).
_ATTR_TYPES = {"channels": ("chlist", None), "compression": ("compression", 1),
               "dataWindow": ("box2i", 16), "displayWindow": ("box2i", 16),
               "lineOrder": ("lineOrder", 1), "pixelAspectRatio": ("float", 4),
               "screenWindowWidth": ("float", 4), "screenWindowCenter": ("v2f", 8),
               "tiles": ("tiledesc", 9), "chunkCount": ("int", 4), "type": ("string", None),
               "name": ("string", None)}


@dataclass(frozen=True)
class ExrPart:
    """One part of an EXR as :func:`exr_header_check` found it."""
    name: object  #: the part's ``name`` attribute (multi-part files), else None
    type: str  #: "scanlineimage" or "tiledimage"
    compression: str  #: e.g. "ZIP"
    data_window: tuple  #: (x0, y0, x1, y1), inclusive
    width: int
    height: int
    channels: tuple  #: ((name, "HALF" | "FLOAT" | "UINT", x sampling, y sampling), ...)
    chunks: int  #: number of chunks (offset table entries)


class _Reader:
    """Bounds-checked access to the file's bytes (``bytes`` or a
    :class:`~hazy_gloss.filebytes.FileBytes`: both slice and ``find``)."""

    def __init__(self, buf, path):
        self.buf, self.path, self.n = buf, path, len(buf)

    def error(self, what, kind="corrupt", prefix=""):
        exc = ExrError(f"{self.path}: {prefix}{what}")
        exc.kind, exc.detail = kind, what
        return exc

    def cut(self, what, sure=False):
        """Something lies beyond the end of the file (``sure``: nothing but a cut explains it)."""
        return self.error(what, "truncated", "truncated: " if sure else "truncated or corrupt: ")

    def need(self, pos, size, what):
        if pos < 0 or size < 0 or pos + size > self.n:
            raise self.cut(f"{what} needs bytes {pos}..{pos + size} but the file has {self.n}")

    def unpack(self, fmt, pos, what):
        size = struct.calcsize(fmt)
        self.need(pos, size, what)
        return struct.unpack_from(fmt, self.buf[pos:pos + size])

    def cstring(self, pos, what, limit=K.MAX_EXR_NAME, end=None):
        """A NUL-terminated string of at most ``limit`` bytes starting at ``pos``."""
        stop = min(self.n if end is None else end, pos + limit + 1)
        nul = self.buf.find(b"\0", pos, stop)
        if nul < 0:
            if stop >= (self.n if end is None else end):
                raise self.cut(f"{what} at byte {pos} has no terminating NUL")
            raise self.error(f"{what} at byte {pos} is longer than {limit} bytes")
        return bytes(self.buf[pos:nul]).decode("latin-1"), nul + 1


def _parse_header(rd, pos, part):
    """One header: {name: (type, value bytes)}; returns (attrs, position after its NUL)."""
    attrs = {}
    where = f"header of part {part}"
    while True:
        if len(attrs) > K.MAX_EXR_ATTRIBUTES:
            raise rd.error(f"{where} has more than {K.MAX_EXR_ATTRIBUTES} attributes")
        name, pos = rd.cstring(pos, f"attribute name in the {where}")
        if not name:
            return attrs, pos
        typ, pos = rd.cstring(pos, f"type of attribute {name!r}")
        if not typ:
            raise rd.error(f"attribute {name!r} in the {where} has an empty type name")
        (size,) = rd.unpack("<i", pos, f"size of attribute {name!r}")
        pos += 4
        if size < 0:
            raise rd.error(f"attribute {name!r} has a negative size {size}")
        rd.need(pos, size, f"attribute {name!r} ({size} bytes)")
        if name in attrs:
            raise rd.error(f"attribute {name!r} appears twice in the {where}")
        want = _ATTR_TYPES.get(name)
        if want is not None:
            if typ != want[0]:
                raise rd.error(f"attribute {name!r} has type {typ!r}, expected {want[0]!r}")
            if want[1] is not None and size != want[1]:
                raise rd.error(f"attribute {name!r} has {size} bytes, expected {want[1]}")
        attrs[name] = (typ, bytes(rd.buf[pos:pos + size]))
        pos += size


def _parse_channels(rd, raw):
    """[(name, pixel type, x sampling, y sampling)] of a ``chlist`` attribute."""
    out, p, names = [], 0, set()
    while True:
        if p >= len(raw):
            raise rd.error("channel list is not terminated (attribute 'channels')")
        if raw[p] == 0:
            if p != len(raw) - 1:
                raise rd.error(f"channel list has {len(raw) - p - 1} bytes after its end")
            break
        if len(out) >= K.MAX_EXR_CHANNELS:
            raise rd.error(f"more than {K.MAX_EXR_CHANNELS} channels")
        nul = raw.find(b"\0", p, p + K.MAX_EXR_NAME + 1)
        if nul < 0:
            raise rd.error(f"channel name at byte {p} of the channel list is not terminated "
                           f"within {K.MAX_EXR_NAME} bytes")
        name = raw[p:nul].decode("utf-8", "replace")
        if nul + 17 > len(raw):
            raise rd.error(f"channel {name!r}: the channel list is cut off")
        ptype, _linear, xs, ys = struct.unpack_from("<iB3xii", raw, nul + 1)
        if ptype not in _PIXEL_TYPES:
            raise rd.error(f"channel {name!r} has an invalid pixel type {ptype}")
        if not (1 <= xs <= 1 << 16 and 1 <= ys <= 1 << 16):
            raise rd.error(f"channel {name!r} has invalid sampling ({xs}, {ys})")
        if name in names:
            raise rd.error(f"channel {name!r} appears twice")
        names.add(name)
        out.append((name, ptype, xs, ys))
        p = nul + 17
    if not out:
        raise rd.error("no channels")
    return out


def _box(rd, attrs, key):
    x0, y0, x1, y1 = struct.unpack("<iiii", attrs[key][1])
    if x1 < x0 or y1 < y0:
        raise rd.error(f"{key} ({x0}, {y0}) - ({x1}, {y1}) is empty or inverted")
    return x0, y0, x1, y1


def _multiples(lo, hi, s):
    """How many integers in [lo, hi] are multiples of s."""
    return hi // s - (lo - 1) // s if hi >= lo else 0


def _level_count(size, rounding):
    """OpenEXR's number of mip levels for ``size``: floor/ceil(log2(size)) + 1."""
    if rounding == 0:
        return size.bit_length()
    return (size - 1).bit_length() + 1


def _level_size(size, level, rounding):
    s = size >> level
    if rounding == 1 and s << level < size:
        s += 1
    return max(s, 1)


class _Part:
    """A validated part header, with everything needed to find and bound its chunks."""

    def __init__(self, rd, attrs, index, multipart, version):
        self.index = index
        for key in ("channels", "compression", "dataWindow"):
            if key not in attrs:
                raise rd.error(f"part {index} has no {key!r} attribute")
        self.channels = _parse_channels(rd, attrs["channels"][1])
        self.comp = attrs["compression"][1][0]
        self.window = _box(rd, attrs, "dataWindow")
        if "displayWindow" in attrs:
            _box(rd, attrs, "displayWindow")
        if "lineOrder" in attrs and attrs["lineOrder"][1][0] > 2:
            raise rd.error(f"part {index} has an invalid lineOrder {attrs['lineOrder'][1][0]}")
        if "pixelAspectRatio" in attrs:
            (par,) = struct.unpack("<f", attrs["pixelAspectRatio"][1])
            if not (math.isfinite(par) and par > 0):
                raise rd.error(f"part {index} has an invalid pixelAspectRatio {par}")
        x0, y0, x1, y1 = self.window
        self.width, self.height = x1 - x0 + 1, y1 - y0 + 1
        if self.width * self.height > K.MAX_EXR_TEXELS_PER_BYTE * rd.n:
            raise rd.error(f"part {index}: data window {self.width}x{self.height} in {rd.n} "
                           "bytes")
        if self.width * self.height > K.MAX_IMAGE_PIXELS:
            raise rd.error(f"part {index}: {self.width} x {self.height} pixels exceeds the "
                           f"limit of {K.MAX_IMAGE_PIXELS}")
        self.name = attrs["name"][1].rstrip(b"\0").decode("utf-8", "replace") \
            if "name" in attrs else None
        if "type" in attrs:
            self.type = attrs["type"][1].rstrip(b"\0").decode("latin-1")
            if self.type not in _PART_TYPES:
                raise rd.error(f"part {index} has an unknown type {self.type!r}")
        elif multipart:
            raise rd.error(f"part {index} of a multi-part file has no 'type' attribute")
        else:
            self.type = "tiledimage" if version & _TILED else "scanlineimage"
            if version & _DEEP:
                self.type = "deepscanline"
        if not multipart and (self.type == "tiledimage") != bool(version & _TILED):
            raise rd.error(f"the version flags and the part type {self.type!r} disagree")
        if self.type.startswith("deep"):
            raise rd.error(f"part {index} holds deep data, which Blender does not load",
                           "unsupported")
        self.comp_name, self.lines = _COMPRESSION.get(self.comp, (f"#{self.comp}", None))
        if self.type == "tiledimage":
            self._tiles(rd, attrs)
        else:
            if self.lines is None and "chunkCount" not in attrs:
                raise rd.error(f"part {index}: unknown compression {self.comp}")
            self.chunks = -(-self.height // self.lines) if self.lines else None
        if "chunkCount" in attrs:
            (count,) = struct.unpack("<i", attrs["chunkCount"][1])
            if self.chunks is None:
                self.chunks = count
            if count != self.chunks or count < 1:
                raise rd.error(f"part {index}: chunkCount {count} does not match its data "
                               f"window ({self.chunks} chunks)")

    def _tiles(self, rd, attrs):
        if "tiles" not in attrs:
            raise rd.error(f"tiled part {self.index} has no 'tiles' attribute")
        if any(xs != 1 or ys != 1 for _, _, xs, ys in self.channels):
            raise rd.error(f"tiled part {self.index} has subsampled channels")
        tx, ty, mode = struct.unpack("<IIB", attrs["tiles"][1])
        level_mode, rounding = mode & 0x0F, mode >> 4
        if not (1 <= tx <= 1 << 31 and 1 <= ty <= 1 << 31) or level_mode > 2 or rounding > 1:
            raise rd.error(f"tiled part {self.index} has an invalid tile description "
                           f"({tx} x {ty}, mode {mode:#x})")
        self.tile = (tx, ty)
        w, h = self.width, self.height
        if level_mode == 0:
            nx = ny = 1
        elif level_mode == 1:
            nx = ny = _level_count(max(w, h), rounding)
        else:
            nx, ny = _level_count(w, rounding), _level_count(h, rounding)
        levels = [(lx, lx) for lx in range(nx)] if level_mode != 2 else \
            [(lx, ly) for ly in range(ny) for lx in range(nx)]
        self.levels, base = {}, 0  # level -> (width, height, tiles across, down, first index)
        for lx, ly in levels:
            lw, lh = _level_size(w, lx, rounding), _level_size(h, ly, rounding)
            nx_, ny_ = -(-lw // tx), -(-lh // ty)
            self.levels[(lx, ly)] = (lw, lh, nx_, ny_, base)
            base += nx_ * ny_
            if base > K.MAX_EXR_CHUNKS:
                raise rd.error(f"tiled part {self.index} has more than {K.MAX_EXR_CHUNKS} tiles")
        self.chunks = base

    def line_bytes(self, y_lo, y_hi):
        """Bytes of pixel data for scanlines y_lo..y_hi (inclusive), with sampling."""
        x0, _, x1, _ = self.window
        return sum(_PIXEL_TYPES[t].itemsize * _multiples(x0, x1, xs) * _multiples(y_lo, y_hi, ys)
                   for _, t, xs, ys in self.channels)


def _parse(rd, keep=False):
    """(parts, multipart, chunks) with every chunk located and bounded; ``chunks`` lists
    (part, chunk index, data start, data size, raw size) when ``keep``, else is empty."""
    magic, version = rd.unpack("<ii", 0, "the magic number and version")
    if magic != _MAGIC:
        raise rd.error("not an OpenEXR file (bad magic number)")
    if version & 0xFF != 2:
        raise rd.error(f"unsupported OpenEXR version {version & 0xFF}", "unsupported")
    if version & ~0x1EFF:
        raise rd.error(f"unknown OpenEXR version flags {version:#x}")
    multipart = bool(version & _MULTIPART)
    if multipart and version & _TILED:
        raise rd.error(f"invalid OpenEXR version flags {version:#x} (multi-part and tiled)")
    pos, headers = 8, []
    while True:
        if len(headers) >= K.MAX_EXR_PARTS:
            raise rd.error(f"more than {K.MAX_EXR_PARTS} parts")
        attrs, pos = _parse_header(rd, pos, len(headers))
        if not attrs:
            raise rd.error(f"header of part {len(headers)} is empty")
        headers.append(attrs)
        if not multipart:
            break
        (nxt,) = rd.unpack("<B", pos, "the end of the header list")
        if nxt == 0:
            pos += 1
            break
    parts = [_Part(rd, attrs, i, multipart, version) for i, attrs in enumerate(headers)]

    total = sum(part.chunks for part in parts)
    if total > K.MAX_EXR_CHUNKS:
        raise rd.error(f"{total} chunks exceeds the limit of {K.MAX_EXR_CHUNKS}")
    tables = []
    for part in parts:
        n = part.chunks
        if n * 8 > rd.n - pos:
            raise rd.cut(f"the offset table of part {part.index} ({n} entries) needs {n * 8} "
                         f"bytes at byte {pos}, the file has {rd.n}", sure=True)
        tables.append(np.frombuffer(rd.buf[pos:pos + 8 * n], "<u8"))  # n <= MAX_EXR_CHUNKS
        pos += 8 * n
    table_end = pos

    chunks = []
    starts, ends = np.empty(total, np.int64), np.empty(total, np.int64)
    k = 0
    head = 4 if multipart else 0
    for part, offsets in zip(parts, tables):
        tiled = part.type == "tiledimage"
        if tiled:
            seen = np.zeros(part.chunks, bool)
            pixel_bytes = sum(_PIXEL_TYPES[t].itemsize for _, t, _, _ in part.channels)
        else:
            lines = part.lines or -(-part.height // part.chunks)
            sampled = any(xs != 1 or ys != 1 for _, _, xs, ys in part.channels)
            row = part.line_bytes(part.window[1], part.window[1])
        for i in range(len(offsets)):
            off = int(offsets[i])
            what = f"chunk {i} of part {part.index}"
            if off > rd.n:
                raise rd.cut(f"{what} is at byte {off}, the file has {rd.n}")
            if off < table_end:
                raise rd.error(f"{what}: offset {off} is outside the file's chunk data "
                               f"(bytes {table_end}..{rd.n})")
            if multipart:
                (pnum,) = rd.unpack("<i", off, what)
                if pnum != part.index:
                    raise rd.error(f"{what} is labelled part {pnum}")
            if tiled:
                tx, ty, lx, ly, size = rd.unpack("<iiiii", off + head, what)
                level = part.levels.get((lx, ly))
                index = -1 if level is None or not (0 <= tx < level[2] and 0 <= ty < level[3]) \
                    else level[4] + ty * level[2] + tx
                if index < 0 or seen[index]:
                    raise rd.error(f"{what} has invalid or repeated tile coordinates "
                                   f"({tx}, {ty}) level ({lx}, {ly})")
                seen[index] = True
                tw = min(part.tile[0], level[0] - tx * part.tile[0])
                th = min(part.tile[1], level[1] - ty * part.tile[1])
                raw = tw * th * pixel_bytes
                data = off + head + 20
            else:
                y, size = rd.unpack("<ii", off + head, what)
                want = part.window[1] + i * lines
                if y != want:
                    raise rd.error(f"{what} starts at scanline {y}, expected {want}")
                last = min(y + lines - 1, part.window[3])
                raw = part.line_bytes(y, last) if sampled else row * (last - y + 1)
                data = off + head + 8
            if size < 0 or size > rd.n - data:
                raise rd.cut(f"{what} claims {size} bytes at byte {data}: it needs "
                             f"{data + size} bytes, the file has {rd.n}")
            # a chunk is stored raw when compression would not make it smaller
            if size > raw or (size == 0 and raw > 0):
                raise rd.error(f"{what} holds {size} bytes for {raw} bytes of pixels")
            ratio = _DECODED_RATIO.get(part.comp)
            if ratio is not None and raw > ratio * size:
                raise rd.error(f"{what}: {size} bytes cannot hold {raw} bytes of "
                               f"{part.comp_name} data")
            if keep:
                chunks.append((part, i, data, size, raw))
            starts[k], ends[k] = off, data + size
            k += 1
    order = np.argsort(starts, kind="stable")
    s, e = starts[order], ends[order]
    clash = np.flatnonzero(s[1:] < e[:-1])
    if clash.size:
        j = int(clash[0])
        raise rd.error(f"chunks overlap (bytes {s[j]}..{e[j]} and {s[j + 1]}..)")
    return parts, multipart, chunks


def exr_header_check(path):
    """Validate an OpenEXR file's structure without decoding its pixels.

    Checks the magic number and version flags; every header attribute (name and type
    NUL-terminated within 255 bytes, size >= 0 and within the file, no duplicates, the types and
    sizes of the standard attributes); each part's channel list, compression, data/display
    window (non-empty, at most :data:`~hazy_gloss.constants.MAX_IMAGE_PIXELS` and at most
    :data:`~hazy_gloss.constants.MAX_EXR_TEXELS_PER_BYTE` per byte of the file), type, tile
    description and chunkCount; the offset table fits the file; every chunk's part number,
    scanline or tile coordinates and size match its header, lie within the file (so a cut-off
    last chunk is caught) and do not overlap.  Scanline and tiled parts with any codec are
    checked; deep data is refused (Blender does not load deep images).

    Returns a tuple of :class:`ExrPart`.  Raises :class:`ExrError` (a ``ValueError``, one
    line naming the file and the defect); ``OSError`` if the file cannot be opened.  Cost: the
    headers plus a few bytes per chunk (read, not memory-mapped: a mapped file cut short by
    another process meanwhile raises SIGBUS, which kills Blender; here it is "truncated")."""
    path = os.fspath(path)
    with open(path, "rb") as fh:
        if os.fstat(fh.fileno()).st_size == 0:
            err = ExrError(f"{path}: the file is empty")
            err.kind, err.detail = "truncated", "the file is empty"
            raise err
        rd = _Reader(FileBytes(fh), path)
        try:
            parts, _, _ = _parse(rd)
        except FileShrankError as exc:
            raise rd.cut(str(exc), sure=True) from None
    return tuple(ExrPart(name=p.name, type=p.type, compression=p.comp_name,
                         data_window=p.window, width=p.width, height=p.height,
                         channels=tuple((n, _PIXEL_TYPE_NAMES[t], xs, ys)
                                        for n, t, xs, ys in p.channels),
                         chunks=p.chunks) for p in parts)


def _predictor_deinterleave(raw):
    """Undo OpenEXR's ZIP/RLE preprocessing: byte delta predictor, then two-half interleave.
    uint8 arithmetic wraps modulo 256, which is the predictor's own arithmetic."""
    t = np.frombuffer(raw, dtype=np.uint8).copy()
    t[1:] -= np.uint8(128)
    t = np.cumsum(t, dtype=np.uint8)
    half = (t.size + 1) // 2
    out = np.empty(t.size, np.uint8)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out


def _rle_decode(raw, expected, rd, what):
    """OpenEXR RLE: a signed count byte c; c < 0: -c literal bytes follow; else one byte
    repeated c + 1 times.  The output may not exceed ``expected`` bytes."""
    out = bytearray()
    i, n = 0, len(raw)
    while i < n:
        count = raw[i] - 256 if raw[i] > 127 else raw[i]
        i += 1
        if count < 0:
            if i - count > n or len(out) - count > expected:
                raise rd.error(f"{what}: corrupt RLE data")
            out += raw[i:i - count]
            i -= count
        else:
            if i >= n or len(out) + count + 1 > expected:
                raise rd.error(f"{what}: corrupt RLE data")
            out += raw[i:i + 1] * (count + 1)
            i += 1
    if len(out) != expected:
        raise rd.error(f"{what}: RLE data decodes to {len(out)} bytes, expected {expected}")
    return bytes(out)


def _inflate(raw, expected, rd, what):
    d = zlib.decompressobj()
    try:
        out = d.decompress(raw, expected + 1)
    except zlib.error as exc:
        raise rd.error(f"{what}: corrupt zlib data ({exc})") from None
    if len(out) != expected or not d.eof:
        got = f"more than {expected}" if len(out) > expected else str(len(out))
        raise rd.error(f"{what}: zlib data decodes to {got} bytes, expected {expected}"
                       + ("" if d.eof or len(out) > expected else " (stream cut off)"))
    return out


def read_exr(path):
    """Every channel of a scanline OpenEXR file (single- or multi-part) as float32 arrays.

    Returns ``{channel name: (H, W) float32}`` with full names as Blender writes them, e.g.
    ``"HG Narrow Delta.Combined.R"`` or ``"HG Narrow Delta.hg_beta.X"``.  Row 0 is the BOTTOM
    row (Blender's pixel order, like ``Image.pixels``).  Compression NONE, RLE, ZIPS and ZIP
    (Blender's default) are supported; lossy codecs (PIZ, PXR24, B44, DWA), tiled parts and
    subsampled channels are not (and would break an exact recomposite anyway).

    Raises :class:`ExrError` (a ``ValueError``; one line naming the file and the defect) for
    any malformed, truncated or unsupported file — never another exception type, never a hang,
    and memory bounded by the file's size (see the module docstring); ``OSError`` if the file
    cannot be read."""
    path = os.fspath(path)
    with open(path, "rb") as fh:
        data = fh.read()
    rd = _Reader(data, path)
    parts, _, chunks = _parse(rd, keep=True)
    names = set()
    for part in parts:
        if part.type != "scanlineimage":
            raise rd.error(f"part {part.index} is {part.type}; only scanline EXR parts are "
                           "supported")
        if part.comp not in _DECODED_RATIO:
            raise rd.error(f"EXR compression {part.comp_name} is not supported (use ZIP or NONE)")
        for name, _, xs, ys in part.channels:
            if (xs, ys) != (1, 1):
                raise rd.error(f"EXR channel {name!r} is subsampled; not supported")
            if name in names:
                raise rd.error(f"channel {name!r} appears in two parts")
            names.add(name)
        part.row_bytes = part.line_bytes(part.window[1], part.window[1])
    total = sum(part.line_bytes(part.window[1], part.window[3]) for part in parts)
    if total > MAX_DECODED_BYTES:
        raise rd.error(f"{total} bytes of pixel data exceeds the limit of {MAX_DECODED_BYTES}")

    decoded = {part.index: np.empty(part.line_bytes(part.window[1], part.window[3]), np.uint8)
               for part in parts}
    for part, i, start, size, raw in chunks:
        block = data[start:start + size]
        what = f"chunk {i} of part {part.index}"
        if size < raw:  # stored raw when compression would not help (size == raw)
            if part.comp == 0:
                raise rd.error(f"{what} holds {size} bytes for {raw} bytes of pixels")
            if part.comp == 1:
                block = _predictor_deinterleave(_rle_decode(block, raw, rd, what))
            else:
                block = _predictor_deinterleave(_inflate(block, raw, rd, what))
        q = i * part.lines * part.row_bytes
        decoded[part.index][q:q + raw] = np.frombuffer(block, np.uint8)

    out = {}
    for part in parts:
        w, h = part.width, part.height
        rows = decoded.pop(part.index).reshape(h, -1)
        q = 0
        for name, t, _, _ in part.channels:
            dt = _PIXEL_TYPES[t]
            arr = rows[:, q:q + w * dt.itemsize].view(dt)
            out[name] = np.ascontiguousarray(arr[::-1], dtype=np.float32)  # file: top row first
            q += w * dt.itemsize
    return out
