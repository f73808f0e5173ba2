# SPDX-License-Identifier: GPL-3.0-or-later
"""Images in strips for the texture conversion (bpy-free): memory that does not grow with the
image, and writes verified without decoding them again.

- :class:`ExrStripWriter` (scanline OpenEXR, 32-bit float; NONE, ZIPS, ZIP) and
  :class:`PngStripWriter` (16-bit RGB PNG) encode strips of rows in numpy + zlib.  zlib and
  numpy release the GIL, so strips are encoded on several threads (:meth:`encode` is
  thread-safe, :meth:`append` takes the encoded strips in order).  Every byte written is
  hashed; :meth:`verify` reads the file back **as bytes** and compares the hashes, then checks
  its structure (hazy_gloss.imagecheck) — the proof that the file holds what was encoded,
  without decoding it;
- :class:`OiioStrips` reads rows of any image OpenImageIO reads (scanline and tiled EXR, PNG,
  JPEG, TIFF, ...), one strip at a time (OpenImageIO 3.0 / 3.1 decode PNG row by row);
  :class:`ArrayStrips` serves rows of an array already in memory;
- :func:`run_strips`: the strip pipeline (read in order, map and encode on a thread pool,
  append in order), a generator that yields after every strip so that a caller (the modal
  operator) can show progress and cancel between two strips.

Rows here are in **file order** (row 0 is the top row); Blender's ``Image.pixels`` and the
conversion's numpy inputs are bottom row first, which :class:`ArrayStrips` turns over.
"""
from __future__ import annotations

import hashlib
import os
import struct
import zlib
from collections import deque
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from . import constants as K

__all__ = ("ExrStripWriter", "PngStripWriter", "OiioStrips", "ArrayStrips", "StripError",
           "run_strips", "strip_rows", "worker_count", "EXR_CODECS", "ZIP_LEVEL", "PNG_LEVEL")

#: Codecs :class:`ExrStripWriter` writes (OpenEXR ids, scanlines per chunk); others go
#: through OpenImageIO.
EXR_CODECS = {"NONE": (0, 1), "ZIPS": (2, 1), "ZIP": (3, 16)}
ZIP_LEVEL = K.EXR_ZIP_LEVEL
PNG_LEVEL = K.PNG_ZIP_LEVEL
_READ_BLOCK = 8 << 20


class StripError(ValueError):
    """A file that cannot be read or written as strips; one line naming the file."""


def worker_count(limit=None):
    """Threads for the strip pool: the CPUs this process may run on (``os.sched_getaffinity``,
    so a process pinned to one core gets one), at most ``limit``."""
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    return max(1, min(n, limit or n))


def strip_rows(width, texels=K.STRIP_TEXELS, multiple=16):
    """Rows per strip: about ``texels`` texels, a multiple of ``multiple`` (the EXR ZIP chunk)."""
    rows = max(1, int(texels) // max(int(width), 1))
    return max(multiple, rows // multiple * multiple)


# --------------------------------------------------------------------------------------------
# Writers
# --------------------------------------------------------------------------------------------


class _HashedFile:
    """A file written front to back (or patched once, see ExrStripWriter) whose bytes are
    hashed per region as they are written."""

    def __init__(self, path):
        self.path = path
        self.fh = open(path, "wb")
        self.size = 0

    def write(self, data, digest):
        self.fh.write(data)
        digest.update(data)
        self.size += len(data)

    def close(self):
        if self.fh is not None:
            try:
                self.fh.close()
            finally:
                self.fh = None


def _hash_file(path, regions):
    """sha256 of each (start, end) byte region of ``path`` (read as bytes, in blocks)."""
    out = []
    with open(path, "rb") as fh:
        for start, end in regions:
            fh.seek(start)
            h, left = hashlib.sha256(), end - start
            while left > 0:
                block = fh.read(min(_READ_BLOCK, left))
                if not block:
                    break
                h.update(block)
                left -= len(block)
            out.append(h.hexdigest() if left == 0 else None)
    return out


class _StripWriter:
    """Shared by the two formats: the file, the region hashes and the read-back proof."""

    def __init__(self, path, width, height):
        self.path, self.width, self.height = os.fspath(path), int(width), int(height)
        self._file = None
        self._regions = []  # [(start, end, sha256 object)]
        self.closed = False

    def verify(self, check=None):
        """Read the file back as bytes: its size and the sha256 of every region must be those
        of the bytes encoded; then ``check(path)`` (a structure check) must pass.  Raises
        StripError naming what differs."""
        size = os.path.getsize(self.path)
        want = self._regions[-1][1]
        if size != want:
            raise StripError(f"{self.path} has {size} bytes, {want} were written")
        got = _hash_file(self.path, [(a, b) for a, b, _ in self._regions])
        for (a, b, h), g in zip(self._regions, got):
            if g != h.hexdigest():
                raise StripError(f"bytes {a}..{b} of {self.path} read back differently from "
                                 "what was written")
        if check is not None:
            check(self.path)

    def abort(self):
        if self._file is not None:
            self._file.close()


class ExrStripWriter(_StripWriter):
    """A scanline OpenEXR file of 32-bit float channels (B, G, R; or one named channel),
    written strip by strip.  ``codec``: NONE, ZIPS or ZIP (OpenEXR's ZIP: 16 scanlines per
    chunk, byte interleave, delta predictor, zlib; a chunk that does not shrink is stored
    raw, as OpenEXR does).  Files are byte-identical for identical pixels (no date)."""

    def __init__(self, path, width, height, channels=3, codec="ZIP", level=ZIP_LEVEL):
        super().__init__(path, width, height)
        if codec not in EXR_CODECS:
            raise StripError(f"{path}: EXR codec {codec} is not written here")
        self.comp, self.lines = EXR_CODECS[codec]
        self.channels = int(channels)
        self.level = level
        self.names = ("B", "G", "R") if self.channels == 3 else ("Y",)
        self.chunks = -(-self.height // self.lines)
        self.offsets = []
        self._header = self._make_header()
        self._table_at = len(self._header)
        self._chunks_at = self._table_at + 8 * self.chunks
        self._chunk_hash = hashlib.sha256()
        self._file = _HashedFile(self.path)
        self._file.fh.seek(self._chunks_at)  # header and offset table: written last
        self._file.size = self._chunks_at
        self.row = 0

    def _make_header(self):
        def attr(name, typ, data):
            return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(data)) + data

        chlist = b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1)
                          for n in self.names) + b"\0"
        box = struct.pack("<4i", 0, 0, self.width - 1, self.height - 1)
        return (struct.pack("<ii", K.EXR_MAGIC, 2)
                + attr("channels", "chlist", chlist)
                + attr("compression", "compression", bytes([self.comp]))
                + attr("dataWindow", "box2i", box) + attr("displayWindow", "box2i", box)
                + attr("lineOrder", "lineOrder", b"\0")
                + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
                + attr("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0))
                + attr("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")

    def encode(self, y0, values):
        """The chunks of rows ``y0 ..`` (file order; ``y0`` a multiple of the chunk height):
        ``values`` (rows, W) or (rows, W, 3) float32 (RGB, or a scalar stored grey).
        Thread-safe; returns the bytes for :meth:`append`."""
        v = np.asarray(values, np.float32)
        if v.ndim == 2 and self.channels == 3:
            v = np.broadcast_to(v[..., None], v.shape + (3,))
        elif v.ndim == 3 and self.channels == 1:
            v = v[..., 0]
        rows = v.shape[0]
        if v.ndim == 3:  # per scanline: B, G, R planes of W values
            planes = np.ascontiguousarray(v[..., ::-1].transpose(0, 2, 1), "<f4")
        else:
            planes = np.ascontiguousarray(v, "<f4")
        line_bytes = self.width * 4 * self.channels
        raw = planes.view(np.uint8).reshape(rows, line_bytes)
        out = []
        for r in range(0, rows, self.lines):
            block = raw[r:r + self.lines].reshape(-1)
            data = block.tobytes()
            if self.comp != 0:
                t = np.empty_like(block)
                half = (block.size + 1) // 2
                t[:half], t[half:] = block[0::2], block[1::2]
                d = np.empty_like(t)
                d[0] = t[0]
                np.subtract(t[1:], t[:-1], out=d[1:])
                d[1:] += np.uint8(128)
                z = zlib.compress(d.tobytes(), self.level)
                if len(z) < len(data):
                    data = z
            out.append(struct.pack("<ii", y0 + r, len(data)) + data)
        return rows, out

    def append(self, encoded):
        rows, chunks = encoded
        for c in chunks:
            self.offsets.append(self._file.size)
            self._file.write(c, self._chunk_hash)
        self.row += rows

    def close(self):
        """Write the header and offset table (the file is complete) and close it."""
        if self.row != self.height or len(self.offsets) != self.chunks:
            raise StripError(f"{self.path}: {self.row} of {self.height} rows written")
        end = self._file.size
        head = self._header + struct.pack(f"<{self.chunks}Q", *self.offsets)
        self._file.fh.seek(0)
        self._file.fh.write(head)
        self._file.close()
        self._regions = [(0, len(head), hashlib.sha256(head)), (len(head), end, self._chunk_hash)]
        self.closed = True


def _adler32_combine(a1, a2, len2):
    """zlib's adler32_combine: the Adler-32 of A + B from those of A and B and len(B)."""
    base = 65521
    rem = len2 % base
    s1 = a1 & 0xFFFF
    s2 = (rem * s1) % base
    s1 += (a2 & 0xFFFF) + base - 1
    s2 += (a1 >> 16) + (a2 >> 16) + base - rem
    s1 %= base
    s2 %= base
    return (s2 << 16) | s1


def _paeth_filter(x, prev):
    """PNG filter 4 (Paeth) of the rows ``x`` (uint8, (n, row bytes)) above which is ``prev``,
    for 6-byte pixels.  Encoding is vectorised: it uses the original bytes."""
    bpp = 6
    a = np.zeros_like(x, dtype=np.int16)
    a[:, bpp:] = x[:, :-bpp]
    b = prev.astype(np.int16)
    c = np.zeros_like(a)
    c[:, bpp:] = prev[:, :-bpp]
    pa = np.abs(b - c)
    pb = np.abs(a - c)
    pc = np.abs(a + b - 2 * c)
    pred = np.where((pa <= pb) & (pa <= pc), a, np.where(pb <= pc, b, c))
    return (x.astype(np.int16) - pred).astype(np.uint8)


class PngStripWriter(_StripWriter):
    """A 16-bit RGB PNG written strip by strip.  Values in [0, 1] are stored as
    floor(v * 65535 + 0.5) (Blender's rounding).  Each strip is filtered (Sub for its first
    row, Paeth below) and deflated on its own, ending on a byte boundary (Z_SYNC_FLUSH) — the
    pigz way: strips compress in parallel into one valid zlib stream."""

    def __init__(self, path, width, height, level=PNG_LEVEL):
        super().__init__(path, width, height)
        self.level = level
        self._hash = hashlib.sha256()
        self._file = _HashedFile(self.path)
        self._adler = 1
        ihdr = struct.pack(">IIBBBBB", self.width, self.height, 16, 2, 0, 0, 0)
        self._file.write(b"\x89PNG\r\n\x1a\n" + self._chunk(b"IHDR", ihdr), self._hash)
        self._first = True
        self.row = 0

    @staticmethod
    def _chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    def encode(self, y0, values):
        v = np.asarray(values, np.float32)
        if v.ndim == 2:
            v = np.broadcast_to(v[..., None], v.shape + (3,))
        rows = v.shape[0]
        code = np.floor(np.clip(v, 0, 1) * np.float32(65535) + np.float32(0.5))
        x = code.astype(">u2").view(np.uint8).reshape(rows, self.width * 6)
        filt = np.empty((rows, 1 + x.shape[1]), np.uint8)
        filt[0, 0] = 1  # Sub: needs nothing above (strips are encoded independently)
        filt[0, 1:7] = x[0, :6]
        filt[0, 7:] = x[0, 6:] - x[0, :-6]
        if rows > 1:
            filt[1:, 0] = 4
            filt[1:, 1:] = _paeth_filter(x[1:], x[:-1])
        raw = filt.tobytes()
        last = y0 + rows == self.height
        c = zlib.compressobj(self.level, zlib.DEFLATED, -15)
        data = c.compress(raw) + c.flush(zlib.Z_FINISH if last else zlib.Z_SYNC_FLUSH)
        return rows, data, zlib.adler32(raw), len(raw)

    def append(self, encoded):
        rows, data, adler, n = encoded
        self._adler = _adler32_combine(self._adler, adler, n)
        if self._first:  # the zlib header (CMF 0x78: deflate, 32K window; FLEVEL 1)
            data = b"\x78\x5e" + data
            self._first = False
        self.row += rows
        if self.row == self.height:
            data += struct.pack(">I", self._adler)
        for i in range(0, len(data), 1 << 30):
            self._file.write(self._chunk(b"IDAT", data[i:i + (1 << 30)]), self._hash)

    def close(self):
        if self.row != self.height:
            raise StripError(f"{self.path}: {self.row} of {self.height} rows written")
        self._file.write(self._chunk(b"IEND", b""), self._hash)
        end = self._file.size
        self._file.close()
        self._regions = [(0, end, self._hash)]
        self.closed = True


# --------------------------------------------------------------------------------------------
# Readers
# --------------------------------------------------------------------------------------------

#: 8-bit code -> Blender's float (k x float32(1/255), what Image.pixels holds).
_BYTE_FLOATS = np.arange(256, dtype=np.float32) * np.float32(1 / 255)


class OiioStrips:
    """Rows of an image file through an OpenImageIO module ``oiio`` (passed in: it is found
    through Blender).  ``rows(y0, y1)`` -> float32 (n, W, C) raw file values in file order:
    8-bit files as k x float32(1/255), others as OpenImageIO's float conversion (16-bit:
    k x float32(1/65535); both bit-identical to Blender's ``Image.pixels``, tested).
    Rows must be asked in increasing order for sequential formats (PNG, JPEG)."""

    def __init__(self, oiio, path, label=None):
        self.oiio, self.path = oiio, os.fspath(path)
        self.label = label or self.path
        inp = oiio.ImageInput.open(self.path)
        if inp is None:
            raise StripError(f"{self.path}: cannot be read ({_one_line(oiio.geterror())})")
        self.inp = inp
        spec = inp.spec()
        self.width, self.height, self.channels = spec.width, spec.height, spec.nchannels
        self.y = spec.y
        self.x = spec.x
        base = spec.format.basetype
        self.byte = base == oiio.UINT8
        self.is_float = base in (oiio.HALF, oiio.FLOAT, oiio.DOUBLE)
        self.format_name = inp.format_name()
        if self.width < 1 or self.height < 1 or self.channels < 1:
            self.close()
            raise StripError(f"{self.path}: no pixels ({self.width}x{self.height}, "
                             f"{self.channels} channels)")

    def rows(self, y0, y1, nch=None):
        nch = min(self.channels, nch or self.channels)
        fmt = self.oiio.UINT8 if self.byte else self.oiio.FLOAT
        a = self.inp.read_scanlines(0, 0, self.y + y0, self.y + y1, 0, 0, nch, fmt)
        if a is None or not hasattr(a, "shape"):
            raise StripError(f"{self.path}: rows {y0}..{y1} cannot be read "
                             f"({_one_line(self.inp.geterror())})")
        a = np.asarray(a).reshape(y1 - y0, self.width, nch)
        return np.take(_BYTE_FLOATS, a) if self.byte else a.astype(np.float32, copy=False)

    def close(self):
        if self.inp is not None:
            self.inp.close()
            self.inp = None


class ArrayStrips:
    """Rows of an (H, W[, C]) array in Blender's order (row 0 at the bottom), served in file
    order (views, no copy of the whole)."""

    def __init__(self, array, label=""):
        self.array = array
        self.height, self.width = array.shape[:2]
        self.channels = array.shape[2] if array.ndim == 3 else 1
        self.label = label
        self.is_float = True
        self.byte = False

    def rows(self, y0, y1, nch=None):
        h = self.height
        a = self.array[h - y1:h - y0][::-1]
        return a if a.ndim == 3 else a[..., None]

    def close(self):
        pass


def _one_line(text):
    return "; ".join(p.strip() for p in str(text).splitlines() if p.strip()) or "no reason given"


# --------------------------------------------------------------------------------------------
# The pipeline
# --------------------------------------------------------------------------------------------


def run_strips(height, rows, read, compute, write, *, workers=None, pool=None):
    """Strips of ``rows`` rows over ``height``: ``read(y0, y1)`` in order on this thread,
    ``compute(y0, y1, data)`` on ``workers`` threads (or ``pool``), ``write(y0, y1, result)``
    in order on this thread.  At most ``workers + 1`` strips are in flight (memory: that many
    strips).  A generator: yields (rows done, height) after each strip is written; an
    exception from any stage (or thrown in) cancels the strips in flight."""
    starts = list(range(0, height, rows))
    own = pool is None
    n = worker_count(workers)
    if own and n > 1:
        pool = ThreadPoolExecutor(max_workers=n)
    try:
        if pool is None:
            for y0 in starts:
                y1 = min(height, y0 + rows)
                write(y0, y1, compute(y0, y1, read(y0, y1)))
                yield y1, height
            return
        pending = deque()
        it = iter(starts)
        for y0 in it:
            y1 = min(height, y0 + rows)
            pending.append((y0, y1, pool.submit(compute, y0, y1, read(y0, y1))))
            if len(pending) > n:
                a, b, fut = pending.popleft()
                write(a, b, fut.result())
                yield b, height
        while pending:
            a, b, fut = pending.popleft()
            write(a, b, fut.result())
            yield b, height
    finally:
        if own and pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
