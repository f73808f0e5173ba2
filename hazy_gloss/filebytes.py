# SPDX-License-Identifier: GPL-3.0-or-later
"""Bounded reads of an open file for the image checkers (bpy-free): :class:`FileBytes`.

The checkers once memory-mapped the file: when another process cuts the file short while it
is mapped, the next touch of a page past the new end raises SIGBUS, which kills Blender.  Every
read here is a seek and read on the open file, and a read the file can no longer serve raises
:class:`FileShrankError` (a ``ValueError``) for the checker to name.
"""
from __future__ import annotations

import io
import operator
import os
import struct
import zlib

__all__ = ("FileBytes", "FileShrankError")

#: Bytes read ahead when a header walk goes on past the cached window (one window is kept).
WINDOW = 64 << 10
#: Bytes read after a jump (an EXR chunk header): a whole window each would be slower than the
#: memory map was.
JUMP = 512
#: Bytes read at once, into one reused buffer, when scanning or checksumming a long range.
PIECE = 1 << 20


class FileShrankError(ValueError):
    """The file ended before the length it had when it was opened (cut off meanwhile)."""


class FileBytes:
    """Read-only bytes-like access to a binary file object, of the length it had when wrapped:
    ``len(fb)``, ``fb[i]`` (an int), ``fb[a:b]`` (bytes), :meth:`unpack_from`, :meth:`find`
    and :meth:`crc32`.  Ranges are clipped to that length as for ``bytes``; a range the file
    no longer holds raises :class:`FileShrankError`, never returns short data."""

    def __init__(self, fh):
        self._fh = fh
        self._n = fh.seek(0, io.SEEK_END)
        self._at, self._win = 0, b""
        try:  # one pread per read where there is one (no seek, no copy through a buffer)
            self._fd = fh.fileno() if hasattr(os, "pread") else None
        except (AttributeError, io.UnsupportedOperation):
            self._fd = None

    def __len__(self):
        return self._n

    def _read(self, start, size, need):
        if self._fd is not None:
            data = os.pread(self._fd, size, start)
        else:
            self._fh.seek(start)
            data = self._fh.read(size)
        while len(data) < size:  # a read may return less than asked before the end
            more = os.pread(self._fd, size - len(data), start + len(data)) \
                if self._fd is not None else self._fh.read(size - len(data))
            if not more:
                break
            data += more
        if len(data) < need:
            raise self._shrank(start, start + need)
        return data

    def _shrank(self, start, stop):
        return FileShrankError(f"the file was cut off while it was read: bytes {start}..{stop} "
                               f"are gone, it had {self._n}")

    def _range(self, start, stop):
        """Bytes ``start..stop`` (0 <= start <= stop <= len)."""
        at, win = self._at, self._win
        if at <= start and stop <= at + len(win):
            return win[start - at:stop - at]
        if stop - start > WINDOW:
            return self._read(start, stop - start, stop - start)
        ahead = WINDOW if at <= start <= at + len(win) else JUMP  # walking on, or a jump
        self._win = self._read(start, max(stop - start, min(ahead, self._n - start)),
                               stop - start)
        self._at = start
        return self._win[:stop - start]

    def _pieces(self, start, stop):
        """``start..stop`` as (buffer, size) pieces: the window for a short range, else
        :data:`PIECE` bytes at a time read into one reused buffer (allocating a fresh buffer per
        piece cost more than the read itself)."""
        if stop - start <= WINDOW:
            data = self._range(start, stop)
            yield data, len(data)
            return
        buf = bytearray(PIECE)
        with memoryview(buf) as view:
            self._fh.seek(start)
            pos = start
            while pos < stop:
                want, got = min(PIECE, stop - pos), 0
                while got < want:
                    k = self._fh.readinto(view[got:want])
                    if not k:
                        raise self._shrank(pos + got, stop)
                    got += k
                yield buf, want
                pos += want

    def __getitem__(self, key):
        if isinstance(key, slice):
            start, stop = key.start, key.stop
            if type(start) is int and type(stop) is int and key.step is None \
                    and 0 <= start <= stop <= self._n:  # the parsers' slices, quickly
                return self._range(start, stop)
            start, stop, step = key.indices(self._n)
            if step != 1:
                raise ValueError("FileBytes slices have no step")
            return self._range(start, max(start, stop))
        i = operator.index(key)
        if not 0 <= i < self._n:
            raise IndexError("FileBytes index out of range")
        return self._range(i, i + 1)[0]

    def unpack_from(self, fmt, offset=0):
        """``struct.unpack_from(fmt, self, offset)`` (``struct.error`` past the end)."""
        stop = offset + struct.calcsize(fmt)
        if 0 <= offset and stop <= self._n:
            return struct.unpack_from(fmt, self._range(offset, stop))
        return struct.unpack_from(fmt, self[offset:stop])

    def find(self, sub, start=0, end=None):
        """``bytes.find`` for a non-empty ``sub``, read in pieces."""
        start, end, _ = slice(start, end).indices(self._n)
        if not sub:
            raise ValueError("FileBytes.find needs a non-empty sub")
        at, win = self._at, self._win
        if at <= start <= end <= at + len(win):  # within the window (a header's strings)
            i = win.find(sub, start - at, end - at)
            return i + at if i >= 0 else -1
        pos, tail = start, b""  # tail: the last len(sub) - 1 bytes, for a match across pieces
        for data, size in self._pieces(start, max(start, end)):
            i = (tail + bytes(data[:min(size, len(sub) - 1)])).find(sub) if tail else -1
            if i >= 0:
                return pos - len(tail) + i
            i = data.find(sub, 0, size)
            if i >= 0:
                return pos + i
            tail = bytes(data[max(0, size - len(sub) + 1):size])
            pos += size
        return -1

    def crc32(self, start, stop):
        """``zlib.crc32(self[start:stop])``, read in pieces."""
        start, stop, _ = slice(start, stop).indices(self._n)
        crc = 0
        for data, size in self._pieces(start, max(start, stop)):
            with memoryview(data) as view:
                crc = zlib.crc32(view[:size], crc)
        return crc
