# SPDX-License-Identifier: GPL-3.0-or-later
"""Images in strips for the texture conversion (bpy-free), through OpenImageIO: memory that
does not grow with the image.

- :class:`OiioStrips` reads rows of any image OpenImageIO reads (scanline and tiled EXR, PNG,
  JPEG, TIFF, ...), one strip at a time (OpenImageIO 3.0 / 3.1 decode PNG row by row);
  :class:`ArrayStrips` serves rows of an array already in memory;
- :class:`OiioStripWriter` writes a 32-bit float OpenEXR (any codec OpenEXR has) or a 16-bit
  RGB PNG strip by strip; :meth:`~OiioStripWriter.verify` decodes the file once and compares
  what it reads with what was written (the proof that the file holds it);
- :func:`run_strips`: the strip pipeline (read in order, map and encode on a thread pool,
  append in order), a generator that yields after every strip so that a caller (the modal
  operator) can show progress and cancel between two strips.

Rows here are in **file order** (row 0 is the top row); Blender's ``Image.pixels`` and the
conversion's numpy inputs are bottom row first, which :class:`ArrayStrips` turns over.
"""
from __future__ import annotations

import hashlib
import os
from collections import deque
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import constants as K
from .oiio import error_text, held_stderr, open_input, read_rows

__all__ = ("OiioStripWriter", "OiioStrips", "ArrayStrips", "StripError", "run_strips",
           "strip_rows", "worker_count", "ZIP_LEVEL", "PNG_LEVEL")

ZIP_LEVEL = K.EXR_ZIP_LEVEL
PNG_LEVEL = K.PNG_ZIP_LEVEL


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
# Writing
# --------------------------------------------------------------------------------------------


class OiioStripWriter:
    """An image written strip by strip by OpenImageIO: ``file_format`` "OPEN_EXR" (32-bit float
    scanlines, ``codec`` any OpenEXR codec; ZIP at zlib level :data:`ZIP_LEVEL`) or "PNG" (16-bit,
    values in [0, 1] stored as floor(v * 65535 + 0.5), Blender's rounding; zlib level
    :data:`PNG_LEVEL`); ``channels`` 3 (RGB; a scalar strip is stored grey) or 1.

    :meth:`encode` (thread-safe, on the pool) turns a strip into what is written, :meth:`append`
    writes strips in order and hashes them, :meth:`close` completes the file.  :meth:`verify`
    decodes it once: lossless codecs (and PNG's codes) must read back to the same sha256, lossy
    ones to finite values; a file cut off or changed on its way to the disk fails there."""

    def __init__(self, oiio, path, width, height, file_format="OPEN_EXR", codec="ZIP",
                 channels=3):
        self.oiio, self.path = oiio, os.fspath(path)
        self.width, self.height, self.channels = int(width), int(height), int(channels)
        self.png = file_format == "PNG"
        self.codec = "PNG" if self.png else codec.upper()
        self.exact = self.png or self.codec in K.LOSSLESS_EXR_CODECS
        self.row = 0
        self.closed = False
        self._hash = hashlib.sha256()
        spec = oiio.ImageSpec(self.width, self.height, self.channels,
                              oiio.UINT16 if self.png else oiio.FLOAT)
        if self.png:
            spec.attribute("png:compressionLevel", PNG_LEVEL)
        else:
            spec.attribute("compression", f"zip:{ZIP_LEVEL}" if self.codec == "ZIP"
                           else self.codec.lower())
            spec.attribute("DateTime", "")  # none: a rerun writes the same bytes
        self.names = list(spec.channelnames)
        # by the format's name: a temporary's name may not end in .exr or .png
        self.out = oiio.ImageOutput.create("png" if self.png else "openexr")
        if self.out is None or not self.out.open(self.path, spec):
            why = error_text(self.out if self.out is not None else oiio)
            self.out = None
            raise StripError(f"{self.path}: cannot be written as "
                             f"{'PNG' if self.png else 'OpenEXR ' + self.codec} ({why})")

    def encode(self, y0, values):
        """Rows ``y0 ..`` (file order) of (rows, W) or (rows, W, 3) float32 values, as written."""
        v = np.asarray(values, np.float32)
        if v.ndim == 2:
            v = v[..., None]
        if v.shape[-1] != self.channels:
            v = np.broadcast_to(v[..., :1], v.shape[:2] + (self.channels,)) \
                if self.channels != 1 else v[..., :1]
        if self.png:
            v = np.floor(np.clip(v, 0, 1) * np.float32(65535) + np.float32(0.5)).astype(np.uint16)
        return y0, np.ascontiguousarray(v)

    def append(self, encoded):
        y0, v = encoded
        if not self.out.write_scanlines(y0, y0 + v.shape[0], 0, v):
            raise OSError(error_text(self.out) or f"{self.path}: a strip was not written")
        self._hash.update(v.tobytes())
        self.row += v.shape[0]

    def close(self):
        """Complete the file and close it."""
        if self.row != self.height:
            raise StripError(f"{self.path}: {self.row} of {self.height} rows written")
        out, self.out = self.out, None
        if out is not None and not out.close():
            raise OSError(error_text(out) or f"{self.path}: not completed")
        self.closed = True

    def abort(self):
        if self.out is not None:
            self.out.close()
            self.out = None

    def verify(self):
        """Decode the file once: its size and values must be those written (lossy codecs:
        finite).  Raises StripError naming what differs (the libraries' own messages on stderr
        dropped with it)."""
        with held_stderr() as keep:
            try:
                self._verify()
            except StripError:
                keep[0] = False
                raise

    def _verify(self):
        reader = OiioStrips(self.oiio, self.path)
        try:
            try:
                names = list(reader.spec.channelnames)
            except UnicodeDecodeError:
                names = ["(not UTF-8)"]
            if (reader.width, reader.height, names) != (self.width, self.height, self.names):
                raise StripError(f"{self.path} reads back as {reader.width}x{reader.height} "
                                 f"({', '.join(names)}), not {self.width}x{self.height} "
                                 f"({', '.join(self.names)})")
            h = hashlib.sha256()
            rows = strip_rows(self.width)
            for y0 in range(0, self.height, rows):
                v = reader.rows(y0, min(self.height, y0 + rows), native=self.png)
                if not self.exact and not np.isfinite(v).all():
                    raise StripError(f"{self.path} reads back with non-finite values")
                h.update(np.ascontiguousarray(v).tobytes())
        finally:
            reader.close()
        if self.exact and h.hexdigest() != self._hash.hexdigest():
            raise StripError(f"{self.path} reads back with other values than written")


# --------------------------------------------------------------------------------------------
# Readers
# --------------------------------------------------------------------------------------------

#: 8-bit code -> Blender's float (k x float32(1/255), what Image.pixels holds).
_BYTE_FLOATS = np.arange(256, dtype=np.float32) * np.float32(1 / 255)


class OiioStrips:
    """Rows of an image file through an OpenImageIO module ``oiio`` (passed in: it is found
    through Blender, :mod:`.oiio`).  ``rows(y0, y1)`` -> float32 (n, W, C) raw file
    values in file order: 8-bit files as k x float32(1/255), others as OpenImageIO's float
    conversion (16-bit: k x float32(1/65535); both bit-identical to Blender's ``Image.pixels``,
    tested).  Rows must be asked in increasing order for sequential formats (PNG, JPEG).  A
    strip that does not decode cleanly (a cut-off or corrupt file) raises StripError."""

    def __init__(self, oiio, path, label=None):
        self.oiio, self.path = oiio, os.fspath(path)
        self.label = label or self.path
        inp, why = open_input(oiio, self.path)
        if inp is None:
            raise StripError(f"{self.path}: cannot be read ({why})")
        self.inp = inp
        self.spec = spec = inp.spec()
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

    def rows(self, y0, y1, nch=None, native=False):
        """Rows y0..y1; ``native``: in the file's own type (no conversion)."""
        nch = min(self.channels, nch or self.channels)
        fmt = self.oiio.UNKNOWN if native else self.oiio.UINT8 if self.byte else self.oiio.FLOAT
        with held_stderr() as keep:
            a = read_rows(self.inp, self.spec, 0, 0, self.y + y0, self.y + y1, range(nch), fmt)
            why = error_text(self.inp)
            if why or a is None or not hasattr(a, "shape"):
                keep[0] = False
                raise StripError(f"{self.path}: rows {y0}..{y1} cannot be read "
                                 f"({why or 'no reason given'})")
        a = np.asarray(a).reshape(y1 - y0, self.width, nch)
        if native:
            return a
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
