# SPDX-License-Identifier: GPL-3.0-or-later
"""A bpy-free reader of the scanline OpenEXR files Blender writes (single- or multi-part,
uncompressed, RLE, ZIPS and ZIP), for the recomposite passes and for checking a file before it
is handed to Blender (a truncated EXR can crash Blender's own loader)."""
from __future__ import annotations

import struct
import zlib

import numpy as np

__all__ = ("read_exr",)

_EXR_MAGIC = 20000630
_LINES_PER_CHUNK = {0: 1, 1: 1, 2: 1, 3: 16}  # NONE, RLE, ZIPS, ZIP
_PIXEL_TYPES = {0: np.dtype("<u4"), 1: np.dtype("<f2"), 2: np.dtype("<f4")}


def _exr_header(data, pos):
    attrs = {}
    while True:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode("latin-1")
        pos = end + 1
        if not name:
            return attrs, pos
        end = data.index(b"\0", pos)
        typ = data[pos:end].decode("latin-1")
        pos = end + 1
        (size,) = struct.unpack_from("<i", data, pos)
        pos += 4
        attrs[name] = (typ, data[pos:pos + size])
        pos += size


def _exr_channels(raw):
    out, p = [], 0
    while raw[p] != 0:
        end = raw.index(b"\0", p)
        name = raw[p:end].decode("utf-8")
        (ptype,) = struct.unpack_from("<i", raw, end + 1)
        xs, ys = struct.unpack_from("<ii", raw, end + 9)
        if (xs, ys) != (1, 1):
            raise ValueError(f"EXR channel {name!r} is subsampled; not supported")
        out.append((name, ptype))
        p = end + 17
    return out


def _predictor_deinterleave(raw):
    """Undo OpenEXR's ZIP/RLE preprocessing: byte delta predictor, then two-half interleave."""
    t = np.frombuffer(raw, dtype=np.uint8).astype(np.int64)
    t[1:] -= 128
    t = (np.cumsum(t) & 0xFF).astype(np.uint8)
    half = (t.size + 1) // 2
    out = np.empty(t.size, np.uint8)
    out[0::2] = t[:half]
    out[1::2] = t[half:]
    return out.tobytes()


def _rle_decode(raw):
    out = bytearray()
    i, n = 0, len(raw)
    while i < n:
        count = struct.unpack_from("<b", raw, i)[0]
        i += 1
        if count < 0:
            out += raw[i:i - count]
            i -= count
        else:
            out += raw[i:i + 1] * (count + 1)
            i += 1
    return bytes(out)


def read_exr(path):
    """Every channel of a scanline OpenEXR file (single- or multi-part) as float32 arrays.

    Returns ``{channel name: (H, W) float32}`` with full names as Blender writes them, e.g.
    ``"HG Narrow Delta.Combined.R"`` or ``"HG Narrow Delta.hg_beta.X"``.  Row 0 is the BOTTOM
    row (Blender's pixel order, like ``Image.pixels``).  Compression NONE, RLE, ZIPS and ZIP
    (Blender's default) are supported; lossy codecs (PIZ, PXR24, B44, DWA) are not — and would
    break an exact recomposite anyway."""
    with open(path, "rb") as fh:
        data = fh.read()
    magic, version = struct.unpack_from("<ii", data, 0)
    if magic != _EXR_MAGIC:
        raise ValueError(f"{path}: not an OpenEXR file")
    if version & 0x200 or version & 0x800 and not version & 0x1000:
        raise ValueError(f"{path}: tiled or deep EXR files are not supported")
    multipart = bool(version & 0x1000)
    pos = 8
    headers = []
    while True:
        attrs, pos = _exr_header(data, pos)
        headers.append(attrs)
        if not multipart:
            break
        if data[pos] == 0:
            pos += 1
            break
    tables = []
    for attrs in headers:
        comp = attrs["compression"][1][0]
        if comp not in _LINES_PER_CHUNK:
            raise ValueError(f"{path}: EXR compression {comp} not supported (use ZIP or NONE)")
        if attrs.get("type", ("", b"scanlineimage"))[1].rstrip(b"\0") != b"scanlineimage":
            raise ValueError(f"{path}: only scanline EXR parts are supported")
        y0, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])[1::2]
        n = (y1 - y0 + _LINES_PER_CHUNK[comp]) // _LINES_PER_CHUNK[comp]
        tables.append(struct.unpack_from(f"<{n}Q", data, pos))
        pos += 8 * n

    out = {}
    for attrs, offsets in zip(headers, tables):
        channels = _exr_channels(attrs["channels"][1])
        comp = attrs["compression"][1][0]
        x0, y0, x1, y1 = struct.unpack("<iiii", attrs["dataWindow"][1])
        w, h = x1 - x0 + 1, y1 - y0 + 1
        lines = _LINES_PER_CHUNK[comp]
        row_bytes = sum(_PIXEL_TYPES[t].itemsize for _, t in channels) * w
        res = {name: np.empty((h, w), np.float32) for name, _ in channels}
        for off in offsets:
            if multipart:
                off += 4  # part number
            y, size = struct.unpack_from("<ii", data, off)
            block = data[off + 8:off + 8 + size]
            n = min(lines, y1 - y + 1)
            if size < row_bytes * n:  # stored uncompressed when compression would not help
                if comp in (2, 3):
                    block = _predictor_deinterleave(zlib.decompress(block))
                elif comp == 1:
                    block = _predictor_deinterleave(_rle_decode(block))
            q = 0
            for row in range(n):
                for name, t in channels:
                    dt = _PIXEL_TYPES[t]
                    res[name][y - y0 + row] = np.frombuffer(block, dt, w, q)
                    q += dt.itemsize * w
        for name, arr in res.items():
            out[name] = arr[::-1].copy()  # file order is top row first
    return out
