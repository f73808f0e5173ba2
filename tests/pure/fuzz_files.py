# SPDX-License-Identifier: GPL-3.0-or-later
"""Test helpers for the file readers: a pure-python OpenEXR / PNG writer and a deterministic
mutation fuzzer for the add-on's image files (tests/pure/test_fuzz_readers.py;
tests/blender/test_imagecheck.py checks that Blender loads what the writer writes, and what
the check passes of these files).

``python tests/pure/fuzz_files.py [old_reader.py]`` prints the attack -> count -> outcome table
for ``hazy_gloss.conversion.imagecheck.read_exr``, or for the ``read_exr`` of an older module given as a
file (each case in a time limit; run it under ``ulimit -v`` for an old reader, which can try to
allocate 14 GiB).
"""
from __future__ import annotations

import random
import signal
import struct
import time
import tracemalloc
import zlib
from collections import Counter

import numpy as np

_COMP = {"NONE": 0, "RLE": 1, "ZIPS": 2, "ZIP": 3}
_LINES = {0: 1, 1: 1, 2: 1, 3: 16}
_PTYPE = {np.dtype("<u4"): 0, np.dtype("<f2"): 1, np.dtype("<f4"): 2}


# ============================================================================================
# Writers
# ============================================================================================


def _preprocess(raw):
    """OpenEXR's ZIP/RLE preprocessing: split even/odd bytes, then a byte delta predictor."""
    b = np.frombuffer(raw, np.uint8)
    t = np.concatenate([b[0::2], b[1::2]])
    p = t.copy()
    p[1:] = t[1:] - t[:-1] + np.uint8(128)
    return p.tobytes()


def rle_encode(data):
    """OpenEXR RLE: runs of >= 3 equal bytes as (count - 1, byte), up to 128; literal runs as
    (-length, bytes...), up to 127."""
    out, i, n = bytearray(), 0, len(data)
    while i < n:
        j = i + 1
        while j < n and j - i < 128 and data[j] == data[i]:
            j += 1
        if j - i >= 3:
            out += bytes((j - i - 1, data[i]))
            i = j
            continue
        j = i
        while j < n and j - i < 127 and not (j + 2 < n and data[j] == data[j + 1] == data[j + 2]):
            j += 1
        j = max(j, i + 1)
        out.append(256 - (j - i))
        out += data[i:j]
        i = j
    return bytes(out)


def _compress(raw, comp):
    if comp == 0:
        return raw
    pre = _preprocess(raw)
    packed = rle_encode(pre) if comp == 1 else zlib.compress(pre, 6)
    return packed if len(packed) < len(raw) else raw


def _attr(name, typ, value):
    return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(value)) + value


def _chlist(channels):
    out = b""
    for name in sorted(channels):
        out += name.encode() + b"\0" + struct.pack("<iB3xii", _PTYPE[channels[name].dtype], 0, 1, 1)
    return out + b"\0"


def _box(part):
    h, w = next(iter(part["channels"].values())).shape
    x0, y0 = part.get("origin", (0, 0))
    return struct.pack("<iiii", x0, y0, x0 + w - 1, y0 + h - 1)


def header_attributes(part, multipart, chunk_count, display=None):
    """The attribute list [(name, type, value bytes)] the writer emits for a part; a multi-part
    file's parts share ``display`` (OpenEXR requires the display window to be the same)."""
    ch = part["channels"]
    box = _box(part)
    attrs = [("channels", "chlist", _chlist(ch)),
             ("compression", "compression", bytes((_COMP[part.get("compression", "ZIP")],))),
             ("dataWindow", "box2i", box), ("displayWindow", "box2i", display or box),
             ("lineOrder", "lineOrder", b"\0"), ("pixelAspectRatio", "float", struct.pack("<f", 1)),
             ("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0)),
             ("screenWindowWidth", "float", struct.pack("<f", 1))]
    if multipart:
        attrs += [("name", "string", part.get("name", "part").encode()),
                  ("type", "string", b"scanlineimage"),
                  ("chunkCount", "int", struct.pack("<i", chunk_count))]
    return attrs + list(part.get("extra", ()))


def encode_exr(parts, *, multipart=None, header_hook=None):
    """A scanline OpenEXR file as bytes, and its layout (for targeted mutations).

    ``parts``: list of {"channels": {name: (H, W) array of float16/float32/uint32, row 0 =
    bottom}, "compression": "NONE"|"RLE"|"ZIPS"|"ZIP", "origin": (x0, y0), "name": str,
    "extra": [(name, type, bytes)]}.  ``header_hook(part index, attrs) -> attrs`` edits the
    attribute list before it is written (offsets stay consistent with the edited header).

    Layout: {"attrs": [(name, start, size field, value start, end, part)], "table": (start, count),
    "chunks": [(offset, size field position, data start, data size)], "header_end": int}."""
    multipart = len(parts) > 1 if multipart is None else multipart
    blocks, counts = [], []
    for part in parts:
        comp = _COMP[part.get("compression", "ZIP")]
        lines = _LINES[comp]
        ch = part["channels"]
        names = sorted(ch)
        h = next(iter(ch.values())).shape[0]
        x0, y0 = part.get("origin", (0, 0))
        chunks = []
        for c, top in enumerate(range(0, h, lines)):
            raw = b"".join(np.ascontiguousarray(ch[n][h - 1 - j]).tobytes()
                           for j in range(top, min(top + lines, h)) for n in names)
            chunks.append((y0 + top, _compress(raw, comp)))
        blocks.append(chunks)
        counts.append(len(chunks))
    long_names = any(len(n) > 31 for p in parts for n in p["channels"])
    version = 2 | (0x1000 if multipart else 0) | (0x400 if long_names or multipart else 0)
    out = bytearray(struct.pack("<ii", 20000630, version))
    layout = {"attrs": [], "chunks": []}
    for i, part in enumerate(parts):
        attrs = header_attributes(part, multipart, counts[i], _box(parts[0]) if multipart else None)
        if header_hook is not None:
            attrs = header_hook(i, attrs)
        for name, typ, value in attrs:
            start = len(out)
            rec = _attr(name, typ, value)
            size_pos = start + len(name.encode()) + len(typ.encode()) + 2
            layout["attrs"].append((name, start, size_pos, size_pos + 4, start + len(rec), i))
            out += rec
        out += b"\0"
    if multipart:
        out += b"\0"
    layout["header_end"] = len(out)
    table = len(out)
    total = sum(counts)
    layout["table"] = (table, total)
    out += b"\0" * (8 * total)
    k = 0
    for i, chunks in enumerate(blocks):
        for y, payload in chunks:
            off = len(out)
            struct.pack_into("<Q", out, table + 8 * k, off)
            head = struct.pack("<i", i) if multipart else b""
            out += head + struct.pack("<ii", y, len(payload))
            layout["chunks"].append((off, off + len(head) + 4, off + len(head) + 8, len(payload)))
            out += payload
            k += 1
    return bytes(out), layout


def encode_tiled_exr(channels, tile=(4, 4), levels="ONE"):
    """A single-part uncompressed tiled EXR (for the image check and Blender): ``levels``
    "ONE", "MIPMAP" or "RIPMAP" (rounding down; lower levels hold every 2^l-th pixel)."""
    h, w = next(iter(channels.values())).shape
    tx, ty = tile
    mode = {"ONE": 0, "MIPMAP": 1, "RIPMAP": 2}[levels]
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    attrs = [("channels", "chlist", _chlist(channels)), ("compression", "compression", b"\0"),
             ("dataWindow", "box2i", box), ("displayWindow", "box2i", box),
             ("lineOrder", "lineOrder", b"\0"), ("pixelAspectRatio", "float", struct.pack("<f", 1)),
             ("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0)),
             ("screenWindowWidth", "float", struct.pack("<f", 1)),
             ("tiles", "tiledesc", struct.pack("<IIB", tx, ty, mode))]
    out = bytearray(struct.pack("<ii", 20000630, 2 | 0x200))
    for a in attrs:
        out += _attr(*a)
    out += b"\0"
    nlx = nly = 1
    if mode == 1:
        nlx = nly = max(w, h).bit_length()
    elif mode == 2:
        nlx, nly = w.bit_length(), h.bit_length()
    order = [(lx, lx) for lx in range(nlx)] if mode != 2 else \
        [(lx, ly) for ly in range(nly) for lx in range(nlx)]
    names = sorted(channels)
    tiles = []
    for lx, ly in order:
        img = {n: channels[n][::-1][::2 ** ly, ::2 ** lx] for n in names}  # top row first
        lh, lw = max(h >> ly, 1), max(w >> lx, 1)
        img = {n: a[:lh, :lw] for n, a in img.items()}
        for j in range(-(-lh // ty)):
            for i in range(-(-lw // tx)):
                raw = b"".join(np.ascontiguousarray(img[n][r, i * tx:(i + 1) * tx]).tobytes()
                               for r in range(j * ty, min((j + 1) * ty, lh)) for n in names)
                tiles.append(struct.pack("<iiiii", i, j, lx, ly, len(raw)) + raw)
    table = len(out)
    out += b"\0" * (8 * len(tiles))
    for k, t in enumerate(tiles):
        struct.pack_into("<Q", out, table + 8 * k, len(out))
        out += t
    return bytes(out)


def encode_png(pixels, *, bit_depth=8, idat_parts=1):
    """A PNG (grey, grey+alpha, RGB or RGBA from an (H, W, C) uint8/uint16 array, row 0 = top),
    the image data split into ``idat_parts`` IDAT chunks."""
    h, w, c = pixels.shape
    colour = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    dt = ">u2" if bit_depth == 16 else "u1"
    rows = b"".join(b"\0" + pixels[r].astype(dt).tobytes() for r in range(h))
    data = zlib.compress(rows, 6)

    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d))

    out = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bit_depth, colour, 0, 0, 0))
    out += chunk(b"tEXt", b"Software\0hazy_gloss tests")
    step = -(-len(data) // idat_parts)
    for i in range(0, len(data), step):
        out += chunk(b"IDAT", data[i:i + step])
    return out + chunk(b"IEND", b"")


# ============================================================================================
# Valid files to mutate
# ============================================================================================


def _rng_channels(rng, names, shape, dtype, quantize=True):
    """Random channels; ``quantize`` rounds to 1/16 so that RLE and ZIP find something to
    compress (a chunk that does not compress is stored raw, skipping the decoder)."""
    out = {}
    for n in names:
        if np.dtype(dtype) == np.dtype("<u4"):
            out[n] = rng.integers(0, 1 << 20, shape).astype("<u4")
        else:
            a = rng.random(shape, dtype=np.float32) * 4
            if quantize:
                a = np.round(a * 16) / 16
            a[0, :] = 0.0  # runs for RLE
            out[n] = a.astype(dtype)
    return out


def recomposite_parts(rng, shape=(6, 5), multipart=True, compression="ZIP"):
    """The channels of a recomposite render (what hazy_gloss.recomposite.passes_from_exr reads)."""
    from hazy_gloss.recomposite import AOVS, LAYERS
    layers = ("ViewLayer",) + LAYERS
    groups = {f"{layer}.Combined": [f"{layer}.Combined.{c}" for c in "RGBA"] for layer in layers}
    for aov, typ, _ in AOVS:
        groups[f"{LAYERS[0]}.{aov}"] = ([f"{LAYERS[0]}.{aov}.X"] if typ == "VALUE"
                                        else [f"{LAYERS[0]}.{aov}.{c}" for c in "RGBA"])
    if multipart:
        return [{"name": g, "compression": compression,
                 "channels": _rng_channels(rng, names, shape, "<f4")} for g, names in groups.items()]
    names = [n for ns in groups.values() for n in ns]
    return [{"compression": compression, "channels": _rng_channels(rng, names, shape, "<f4")}]


def base_files(seed=0):
    """(label, bytes, layout, expected channels, is recomposite) valid files: every codec,
    single and multi part, HALF / FLOAT / UINT channels, odd sizes, a non-zero data window."""
    rng = np.random.default_rng(seed)
    out = []
    for comp in ("NONE", "RLE", "ZIPS", "ZIP"):
        ch = _rng_channels(rng, ["R", "G", "B", "A"], (19, 7), "<f4")
        ch.update(_rng_channels(rng, ["Z"], (19, 7), "<f2"))
        ch["A"][:] = 0.0  # runs (RLE stores a chunk raw when it does not get shorter)
        ch["Z"][:] = ch["Z"][:, :1]
        part = {"channels": ch, "compression": comp}
        data, layout = encode_exr([part])
        out.append((f"single {comp}", data, layout, ch, False))
    parts = [{"name": "a", "compression": "ZIP",
              "channels": _rng_channels(rng, ["a.R", "a.G"], (17, 3), "<f4")},
             {"name": "b", "compression": "RLE", "origin": (-2, 5),
              "channels": _rng_channels(rng, ["b.V"], (17, 3), "<f2")},
             {"name": "c", "compression": "NONE",
              "channels": _rng_channels(rng, ["c.id"], (2, 4), "<u4")},
             {"name": "d", "compression": "ZIPS",
              "channels": _rng_channels(rng, ["d.X"], (3, 2), "<f4")}]
    data, layout = encode_exr(parts)
    out.append(("multi-part mixed", data, layout,
                {k: v for p in parts for k, v in p["channels"].items()}, False))
    for mp in (True, False):
        parts = recomposite_parts(rng, multipart=mp)
        data, layout = encode_exr(parts, multipart=mp)
        out.append((f"recomposite {'multi' if mp else 'single'}-part", data, layout,
                    {k: v for p in parts for k, v in p["channels"].items()}, True))
    return out


# ============================================================================================
# Mutations (deterministic)
# ============================================================================================

INT32_EDGES = (0, 1, -1, -2, -4, 2, 255, 256, 65535, 1 << 24, (1 << 31) - 1, -(1 << 31),
               (1 << 30), -(1 << 30))
WINDOW_EDGES = (0, 1, -1, 65535, (1 << 31) - 1, -(1 << 31), 1 << 30)
UINT64_EDGES = (0, 1, 7, 8, (1 << 63), (1 << 64) - 1, (1 << 32), (1 << 31) - 1)


def _set(data, pos, fmt, value):
    b = bytearray(data)
    if pos + struct.calcsize(fmt) > len(b):
        return None
    struct.pack_into(fmt, b, pos, value)
    return bytes(b)


def _boundaries(layout, n, attrs, chunks):
    marks = {0, 1, 4, 7, 8, 9, n - 1, n - 2, layout["header_end"] - 1, layout["header_end"]}
    for _, start, size_pos, value, end, _ in attrs:
        marks.update((start, start + 1, size_pos - 1, size_pos, size_pos + 2, value, value + 1,
                      end - 1, end))
    t, count = layout["table"]
    marks.update((t - 1, t, t + 4, t + 8 * count - 1, t + 8 * count))
    for off, size_pos, data, size in chunks:
        marks.update((off, off + 2, size_pos, size_pos + 4, data, data + 1, data + size // 2,
                      data + size - 1))
    return sorted(m for m in marks if 0 <= m < n)


def zlib_bomb(size=64 << 20):
    """A valid zlib stream that inflates to ``size`` zero bytes (64 MiB -> ~64 KB)."""
    c = zlib.compressobj(9)
    chunk = bytes(1 << 20)
    out = b"".join(c.compress(chunk) for _ in range(size >> 20))
    return out + c.flush()


def _replace_chunk(data, layout, k, payload):
    """Replace chunk k's data (and size field) by ``payload`` and re-point the later offsets."""
    off, size_pos, start, size = layout["chunks"][k]
    delta = len(payload) - size
    b = bytearray(data[:start] + payload + data[start + size:])
    struct.pack_into("<i", b, size_pos, len(payload))
    t, count = layout["table"]
    for i in range(count):
        (o,) = struct.unpack_from("<Q", b, t + 8 * i)
        if o > off:
            struct.pack_into("<Q", b, t + 8 * i, o + delta)
    return bytes(b)


def mutations(label, data, layout, seed):
    """Yield (attack, bytes) for one valid file."""
    rng = random.Random(f"{seed}:{label}")
    n = len(data)
    # field attacks on the first two parts and the last one (the others are alike)
    last = layout["attrs"][-1][5]
    attrs = [a for a in layout["attrs"] if a[5] in (0, 1, last)]
    # truncation: every structural boundary +-1 and a stride through the data
    t, count = layout["table"]
    picked = sorted({0, 1, count // 2, count - 1} & set(range(count)))
    chunks = [layout["chunks"][i] for i in picked]
    lengths = set(_boundaries(layout, n, attrs, chunks)) | set(range(0, n, max(7, n // 128))) \
        | set(range(16))
    for m in sorted(lengths):
        if m < n:
            yield "truncate", data[:m]
    # single-byte flips (half of them in the header, where they matter most)
    for i in range(160):
        pos = rng.randrange(layout["header_end"] if i % 2 else n)
        b = bytearray(data)
        b[pos] ^= rng.randrange(1, 256)
        yield "byte flip", bytes(b)
    for _ in range(40):
        b = bytearray(data)
        for _ in range(8):
            b[rng.randrange(n)] = rng.randrange(256)
        yield "8 random bytes", bytes(b)
    # attribute sizes: negative, huge, random
    for _, start, size_pos, _, _, _ in attrs:
        # -(record length so far) points the parser back at the same attribute (a loop)
        for v in (-1, -4, -(1 << 31), start - size_pos - 4):
            yield "negative attribute size", _set(data, size_pos, "<i", v)
        for v in ((1 << 31) - 1, n, n - size_pos):
            yield "huge attribute size", _set(data, size_pos, "<i", v)
        yield "random attribute size", _set(data, size_pos, "<i", rng.randrange(-(1 << 31), 1 << 31))
    # value fields: data windows, channel list fields, compression, chunkCount, flags
    for name, _, _, value, end, _ in attrs:
        if name in ("dataWindow", "displayWindow"):
            for k in range(4):
                for v in WINDOW_EDGES:
                    yield "data window", _set(data, value + 4 * k, "<i", v)
        elif name == "compression":
            for v in (4, 5, 9, 10, 11, 12, 100, 255):
                yield "compression id", _set(data, value, "<B", v)
        elif name == "chunkCount":
            for v in INT32_EDGES:
                yield "chunkCount", _set(data, value, "<i", v)
        elif name == "channels":
            nul = data.index(b"\0", value)
            for v in (3, -1, 7, 1 << 30):
                yield "channel pixel type", _set(data, nul + 1, "<i", v)
            for v in (0, -1, 2, 1 << 30):
                yield "channel sampling", _set(data, nul + 9 + 4 * rng.randrange(2), "<i", v)
    for v in (0x202, 0x802, 0x1002, 0x1202, 0x402, 0x2002, 0x80000002, 1, 3, 0xFFFFFFFF):
        yield "version flags", _set(data, 4, "<I", v)
    yield "version flags", _set(data, 4, "<i", struct.unpack_from("<i", data, 4)[0] ^ 0x1000)
    # offset table entries
    offs = [c[0] for c in layout["chunks"]]
    for i in picked:
        for v in UINT64_EDGES + (n, n - 4, offs[i] + 1, offs[i] - 1, offs[(i + 1) % count], t):
            yield "offset table", _set(data, t + 8 * i, "<Q", v)
        yield "offset table", _set(data, t + 8 * i, "<Q", rng.randrange(1 << 64))
    # chunk headers: y, size, part number
    for off, size_pos, start, size in chunks:
        for v in INT32_EDGES + (size - 1, size + 1, n):
            yield "chunk size", _set(data, size_pos, "<i", v)
        for v in (-1, 1, (1 << 31) - 1, -(1 << 31)):
            (y,) = struct.unpack_from("<i", data, size_pos - 4)
            yield "chunk y", _set(data, size_pos - 4, "<i", y + v if abs(v) == 1 else v)
        if size_pos - 8 >= off:
            for v in (-1, 1, 99):
                yield "chunk part number", _set(data, off, "<i", v)
    # chunk payloads: a zlib bomb, an RLE bomb, garbage, cut-off / over-long zlib streams
    k = len(layout["chunks"]) // 2
    yield "zlib bomb (64 MiB)", _replace_chunk(data, layout, k, BOMB)
    yield "RLE bomb", _replace_chunk(data, layout, k, bytes((127, 0)) * 4096)
    yield "RLE bomb", _replace_chunk(data, layout, k, bytes((0x80,)) + bytes(3))
    for _ in range(4):
        yield "garbage chunk data", _replace_chunk(
            data, layout, rng.randrange(len(layout["chunks"])),
            bytes(rng.randrange(256) for _ in range(rng.randrange(1, 64))))
    _, _, start, size = layout["chunks"][k]
    payload = data[start:start + size]
    try:
        raw = zlib.decompress(payload)
    except zlib.error:
        raw = None
    if raw is not None:
        yield "zlib bomb (within size)", _replace_chunk(data, layout, k,
                                                        zlib.compress(bytes(len(raw) * 100), 9))
        yield "zlib short/long", _replace_chunk(data, layout, k, zlib.compress(raw[:-1]))
        yield "zlib short/long", _replace_chunk(data, layout, k, zlib.compress(raw + b"\0"))
        yield "zlib short/long", _replace_chunk(data, layout, k, payload[:-3])


def header_mutations(label, parts, seed, multipart=None):
    """Rebuild a valid file with its attribute lists edited: reordered, duplicated, deleted,
    retyped, renamed, oversized and foreign attributes, odd channel lists."""
    rng = random.Random(f"hdr:{seed}:{label}")

    def build(hook):
        return encode_exr(parts, multipart=multipart, header_hook=hook)[0]

    yield "reordered attributes", build(lambda i, a: rng.sample(a, len(a)))
    yield "reordered attributes", build(lambda i, a: a[::-1])
    names = [a[0] for a in header_attributes(parts[0], len(parts) > 1, 1)]
    for k in range(len(names)):
        yield "duplicated attribute", build(lambda i, a, k=k: a[:k + 1] + [a[k]] + a[k + 1:])
        yield "deleted attribute", build(lambda i, a, k=k: a[:k] + a[k + 1:])
        yield "retyped attribute", build(
            lambda i, a, k=k: a[:k] + [(a[k][0], "float", a[k][2])] + a[k + 1:])
        yield "resized attribute value", build(
            lambda i, a, k=k: a[:k] + [(a[k][0], a[k][1], a[k][2] + b"\0\0\0")] + a[k + 1:])
        yield "resized attribute value", build(
            lambda i, a, k=k: a[:k] + [(a[k][0], a[k][1], a[k][2][:-1])] + a[k + 1:])
    yield "foreign attributes", build(lambda i, a: a + [("x" * 300, "string", b"long name")])
    yield "foreign attributes", build(lambda i, a: a + [("note", "y" * 300, b"long type")])
    yield "foreign attributes", build(lambda i, a: a + [("note", "", b"empty type")])
    yield "foreign attributes", build(lambda i, a: a + [("preview", "preview", bytes(5000))])
    yield "foreign attributes", build(
        lambda i, a: a + [(f"a{j}", "int", b"\0\0\0\0") for j in range(5000)])
    yield "duplicated part", encode_exr(parts + parts[:1], multipart=True)[0]

    def chl(raw):
        return lambda i, a: [(n, t, raw if n == "channels" else v) for n, t, v in a]

    good = dict((n, v) for n, _, v in header_attributes(parts[0], False, 1))["channels"]
    yield "channel list", build(chl(b"\0"))
    yield "channel list", build(chl(b""))
    yield "channel list", build(chl(good[:-1]))
    yield "channel list", build(chl(good + b"extra"))
    yield "channel list", build(chl(good[:good.index(b"\0") + 1] + good))
    yield "channel list", build(chl(b"R\0" + struct.pack("<iB3xii", 2, 0, 1, 1) * 2 + b"\0"))
    yield "channel list", build(chl(b"".join(f"c{j}\0".encode() + struct.pack("<iB3xii", 2, 0, 1, 1)
                                             for j in range(5000)) + b"\0"))
    yield "channel list", build(chl(b"R" * 400 + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) + b"\0"))
    yield "channel list", build(chl(b"\xff\xfe\0" + struct.pack("<iB3xii", 2, 0, 1, 1) + b"\0"))
    for box in ((0, 0, (1 << 31) - 1, 0), (0, 0, 0, (1 << 31) - 1), (-(1 << 31), -(1 << 31),
                (1 << 31) - 1, (1 << 31) - 1), (0, 0, 1 << 20, 1 << 20), (5, 5, 4, 4)):
        yield "huge/inverted data window", build(
            lambda i, a, box=box: [(n, t, struct.pack("<iiii", *box) if n == "dataWindow" else v)
                                   for n, t, v in a])


BOMB = zlib_bomb()


def png_bases(seed=0):
    rng = np.random.default_rng(seed)
    return [("png RGBA 8", encode_png(rng.integers(0, 256, (9, 7, 4)), idat_parts=3)),
            ("png grey 16", encode_png(rng.integers(0, 65536, (5, 11, 1)), bit_depth=16)),
            ("png RGB 8", encode_png(np.zeros((64, 64, 3), np.uint8), idat_parts=2))]


def _png_chunks(data):
    pos, out = 8, []
    while pos + 8 <= len(data):
        (length,) = struct.unpack_from(">I", data, pos)
        out.append((pos, length, data[pos + 4:pos + 8]))
        pos += 12 + length
    return out


def png_mutations(label, data, seed):
    """Yield (attack, bytes) for one valid PNG."""
    rng = random.Random(f"png:{seed}:{label}")
    n = len(data)
    chunks = _png_chunks(data)
    marks = {0, 1, 7, 8, 9, n - 1, n - 4, n - 12}
    for pos, length, _ in chunks:
        marks.update((pos, pos + 4, pos + 8, pos + 8 + length // 2, pos + 8 + length,
                      pos + 11 + length))
    for m in sorted(marks | set(range(0, n, max(5, n // 128)))):
        if 0 <= m < n:
            yield "png truncate", data[:m]
    for _ in range(120):
        b = bytearray(data)
        b[rng.randrange(n)] ^= rng.randrange(1, 256)
        yield "png byte flip", bytes(b)
    for pos, length, _ in chunks:
        for v in (0, 1, length - 1, length + 1, 0x7FFFFFFF, 0x80000000, 0xFFFFFFFF, n):
            yield "png chunk length", _set(data, pos, ">I", v & 0xFFFFFFFF)
        yield "png chunk type", _set(data, pos + 4, "4s", b"a\x00b ")
        yield "png chunk crc", _set(data, pos + 8 + length, ">I", 0x12345678)

    def fix(b, pos, length):  # a correct CRC after editing a chunk's data
        return _set(b, pos + 8 + length, ">I", zlib.crc32(b[pos + 4:pos + 8 + length]))

    ihdr = chunks[0][0]
    for field, fmt, values in ((0, ">I", (0, 1 << 31, 0xFFFFFFFF, 1 << 16)),
                               (4, ">I", (0, 1 << 31, 0xFFFFFFFF, 1 << 16)),
                               (8, ">B", (0, 3, 7, 32)), (9, ">B", (1, 3, 5, 7)),
                               (10, ">B", (1,)), (11, ">B", (1,)), (12, ">B", (2,))):
        for v in values:
            yield "png IHDR field", fix(_set(data, ihdr + 8 + field, fmt, v), ihdr, 13)
    body = [c for c in chunks if c[2] not in (b"IHDR", b"IEND")]
    head, tail = data[:chunks[1][0]], data[chunks[-1][0]:]

    def piece(c):
        return data[c[0]:c[0] + 12 + c[1]]

    yield "png chunk order", head + b"".join(piece(c) for c in body[::-1]) + tail
    yield "png chunk order", (data[:8] + b"".join(piece(c) for c in chunks[1:-1])
                              + piece(chunks[0]) + tail)
    yield "png chunk order", data + data[8:]
    yield "png chunk order", data[:-12]
    yield "png chunk order", head + tail
    idats = [c for c in body if c[2] == b"IDAT"]
    if len(idats) > 1:
        text = [c for c in body if c[2] != b"IDAT"]
        yield "png chunk order", head + piece(idats[0]) + b"".join(piece(c) for c in text) \
            + b"".join(piece(c) for c in idats[1:]) + tail


# ============================================================================================
# Running readers under limits
# ============================================================================================


class Timeout(BaseException):
    pass


def _alarm(signum, frame):
    raise Timeout()


def run_case(fn, path, expected_types, *, time_limit=None, trace=True):
    """Run ``fn(path)``: returns (outcome, detail, seconds, peak bytes) with outcome one of
    "accepted", "rejected" (an expected exception type), "other exception", "hang" (only with
    a ``time_limit`` in seconds: the command line's table; the tests bound no time).

    ``trace``: measure the peak with tracemalloc (started and stopped around the call, as it
    slows Python code down ~9x); else the peak is reported as 0."""
    old = signal.signal(signal.SIGALRM, _alarm)
    if trace:
        tracemalloc.start()
    t0 = time.perf_counter()
    if time_limit:
        signal.setitimer(signal.ITIMER_REAL, time_limit)
    try:
        result = fn(path)
        outcome, detail = "accepted", result
    except Timeout:
        outcome, detail = "hang", None
    except expected_types as exc:
        outcome, detail = "rejected", exc
    except BaseException as exc:  # noqa: BLE001 - the point is to classify everything
        outcome, detail = "other exception", exc
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    seconds = time.perf_counter() - t0
    peak = 0
    if trace:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return outcome, detail, seconds, peak


def all_cases(seed=0):
    """Yield (attack, base label, bytes, is recomposite) for every EXR case."""
    for label, data, layout, _, recomp in base_files(seed):
        yield "valid", label, data, recomp
        for attack, mutated in mutations(label, data, layout, seed):
            if mutated is not None:
                yield attack, label, mutated, recomp
    # a chunk of 256 KiB of zeros whose data inflates to 64 MiB (within the chunk's size)
    zeros = {"R": np.zeros((16, 4096), np.float32)}
    data, layout = encode_exr([{"channels": zeros, "compression": "ZIP"}])
    yield "valid", "zeros 4096x16 ZIP", data, False
    yield "zlib bomb (within size)", "zeros 4096x16 ZIP", _replace_chunk(data, layout, 0, BOMB), False
    rng = np.random.default_rng(seed)
    single = [{"channels": _rng_channels(rng, ["R", "G", "B"], (9, 5), "<f4"), "compression": "ZIP"}]
    multi = recomposite_parts(rng, shape=(3, 2))
    for label, parts, mp, recomp in (("single ZIP", single, False, False),
                                     ("recomposite multi-part", multi, True, True)):
        for attack, mutated in header_mutations(label, parts, seed, mp):
            yield attack, label, mutated, recomp


def _main(argv):
    import importlib.util
    import os
    import sys
    import tempfile
    here = os.path.dirname(os.path.abspath(__file__))
    sys.path.insert(0, os.path.dirname(os.path.dirname(here)))
    if len(argv) > 1:
        spec = importlib.util.spec_from_file_location("old_exr", argv[1])
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
        expected = (ValueError,)
    else:
        from hazy_gloss.conversion import imagecheck as mod
        expected = (mod.ImageFileError,)
    table = Counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "case.exr")
        for attack, _, data, _ in all_cases():
            with open(path, "wb") as fh:
                fh.write(data)
            outcome, detail, _, peak = run_case(mod.read_exr, path, expected, time_limit=2.0)
            if outcome in ("other exception", "rejected"):
                t = type(detail)
                name = t.__name__ if t.__module__ == "builtins" else f"{t.__module__}.{t.__name__}"
                if outcome == "rejected":
                    name = t.__name__
                outcome = f"{'uncaught' if outcome != 'rejected' else 'raised'} {name}"
            if peak > 64 << 20:
                outcome += " (> 64 MB)"
            table[(attack, outcome)] += 1
    width = max(len(a) for a, _ in table)
    for (attack, outcome), count in sorted(table.items()):
        print(f"{attack:<{width}}  {count:6d}  {outcome}")
    print("total", sum(table.values()))


if __name__ == "__main__":
    import sys
    _main(sys.argv)
