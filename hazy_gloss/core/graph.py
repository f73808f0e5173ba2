# SPDX-License-Identifier: GPL-3.0-or-later
"""Node math as data: a small expression graph with Blender's Math / Vector Math semantics.

The haze mapping's node form (:mod:`hazy_gloss.core.node_math`) is written once against
:class:`Graph`; the bpy emitters (``hazy_gloss.blender.nodes.emit``) turn a graph into shader
or compositor nodes, and :func:`evaluate` runs it in numpy with the semantics of Cycles' SVM
(``kernel/svm/math_util.h``, ``kernel/svm/mix.h``), so pure tests check the node math against
the numpy mapping without rendering.

- Values are float32; a vector is three lanes (Blender's Vector Math / colour sockets).
- DIVIDE is safe (x / 0 = 0), SQRT of a negative is 0, POWER of a negative base with a
  non-integer exponent is 0, ``clamp=True`` saturates the result (the Math node's Clamp).
- CLAMP(x, lo, hi): the Clamp node (Min Max), min(max(x, lo), hi) with the kernel's
  comparisons (max(a, b) = a > b ? a : b): x NaN gives lo.  SVM runs it cheaper than a Math
  node, and a Math node's Clamp option costs a second node (Cycles expands it into one).
- MIX(t, a, b) = (1-t) a + t b (the float Mix node): an exact select for t ∈ {0, 1} when both
  branches are finite.  VMIX: the vector Mix, per lane (a vector factor: Non-Uniform); with
  a = 0 it is the product t b (finite t), cheaper in SVM than Vector Math Multiply.
- SATURATE(v): each lane in [0, 1], NaN -> 0, ±inf to 1 / 0: a colour Mix node with Clamp
  Result (v as B at factor 1), one node where Vector Math needs two.
- RAMP(x): a Color Ramp node (linear, RGB) as a 1-D table of up to 32 stops, evaluated as
  Cycles does: Blender bakes the ramp into 256 entries (BKE_colorband_evaluate at i/255) and
  the kernel interpolates those linearly (kernel/svm/ramp.h rgb_ramp_lookup).
- TABLE(d): a lookup in a float table of the graph (:meth:`Graph.table`, H x W values, or
  H x W x 3 for a colour table): an Environment Texture (equirectangular, Linear) of a float
  Non-Color image, the table with one texel of edge padding, read in the direction ``d`` as
  Cycles does (kernel/svm/image.h svm_node_tex_environment, direction_to_equirectangular;
  interp_linear with the periodic wrap of its EXTENSION_REPEAT); a vector with the value in
  every lane (a colour table: its three channels).  Not an Image Texture: Blender lists every
  Image Texture inside a material's node groups as a Texture Paint slot.
- Building folds constants (in float32 with the same semantics, as Cycles' own constant folding
  does) and merges identical sub-expressions, so a graph fed constants emits only the nodes
  that depend on linked inputs, and never two nodes computing the same thing.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ("Expr", "Graph", "evaluate", "ramp_table", "SCALAR_OPS", "VECTOR_OPS")

#: Math node operations used here, with their arity.
SCALAR_OPS = {"ADD": 2, "SUBTRACT": 2, "MULTIPLY": 2, "DIVIDE": 2, "MULTIPLY_ADD": 3,
              "POWER": 2, "SQRT": 1, "MINIMUM": 2, "MAXIMUM": 2, "LESS_THAN": 2,
              "GREATER_THAN": 2, "COMPARE": 3, "ABSOLUTE": 1, "CLAMP": 3, "FLOOR": 1,
              "COSINE": 1, "SINE": 1, "EXPONENT": 1}
#: Vector Math node operations used here (SCALE: vector × scalar).
VECTOR_OPS = {"ADD": 2, "SUBTRACT": 2, "MULTIPLY": 2, "DIVIDE": 2, "MULTIPLY_ADD": 3,
              "POWER": 2, "MINIMUM": 2, "MAXIMUM": 2, "SCALE": 2, "ABSOLUTE": 1, "FLOOR": 1,
              "DOT_PRODUCT": 2}
#: Vector Math operations whose result is a scalar (the node's Value output).
VECTOR_TO_SCALAR = ("DOT_PRODUCT",)
#: Color Ramp: Blender's table size for the kernel (RAMP_TABLE_SIZE) and its stop limit.
RAMP_TABLE_SIZE = 256
RAMP_MAX_STOPS = 32

_F32 = np.float32
_F32_MAX = float(np.finfo(_F32).max)


class Expr:
    """One value of the graph.  ``op``: "input", "const", a Math operation (scalar), "V" + a
    Vector Math operation, "MIX", "SEPARATE" (one lane of a vector), "COMBINE" or "RAMP"
    (``value``: its stops, ((position, (r, g, b)), ...) in float32)."""

    __slots__ = ("op", "args", "vector", "clamp", "lane", "name", "value", "label", "index")

    def __init__(self, op, args=(), *, vector=False, clamp=False, lane=None, name=None,
                 value=None, label=None, index=-1):
        self.op = op
        self.args = tuple(args)
        self.vector = vector
        self.clamp = clamp
        self.lane = lane
        self.name = name
        self.value = value
        self.label = label
        self.index = index

    @property
    def is_const(self):
        return self.op == "const"

    def __repr__(self):
        if self.op == "const":
            return f"const({self.value})"
        if self.op == "input":
            return f"input({self.name})"
        return f"{self.op}#{self.index}"


def _const_key(value):
    return tuple(float(v) for v in np.ravel(value))


def _math_node(op, doc):
    """A :class:`Graph` method making the scalar Math node ``op`` of its operands (keywords as
    :meth:`Graph.math`)."""
    def method(self, *args, **kw):
        return self.math(op, *args, **kw)
    method.__doc__ = doc
    return method


class Graph:
    """Builds expressions, folding constants and merging duplicates (hash-consing)."""

    def __init__(self):
        self.nodes = []  # every non-constant Expr, in creation order (a topological order)
        self._memo = {}
        self.inputs = {}
        self.tables = {}  # name -> (H + 2, W + 2) float32, edge-padded (the images TABLE reads)
        self.sections = None  # [(title, first expression index)] when a caller names its parts

    def section(self, title):
        """Expressions made from here on belong to the part ``title`` (where sections are kept:
        a layer group draws each in a frame of its own)."""
        if self.sections is not None and title:
            self.sections.append((title, len(self.nodes)))

    # -- leaves --------------------------------------------------------------------------------
    def input(self, name, *, vector=False):
        if name in self.inputs:
            return self.inputs[name]
        e = self._add(Expr("input", vector=vector, name=name))
        self.inputs[name] = e
        return e

    def const(self, value):
        """A constant: a number, or three numbers (a vector)."""
        if isinstance(value, Expr):
            return value
        big = np.finfo(_F32).max  # as a float socket holds it (RNA clamps to ±FLT_MAX)
        arr = np.clip(np.asarray(value, dtype=np.float64), -big, big).astype(_F32)
        vector = arr.size == 3
        if arr.size not in (1, 3):
            raise ValueError(f"a constant is a number or three numbers, got {value!r}")
        key = ("const", _const_key(arr), vector)
        e = self._memo.get(key)
        if e is None:
            e = Expr("const", vector=vector, value=arr.reshape(3) if vector else _F32(arr.reshape(())))
            self._memo[key] = e
        return e

    def value(self, x):
        """``x`` as an Expr (numbers become constants)."""
        return x if isinstance(x, Expr) else self.const(x)

    def _add(self, e):
        e.index = len(self.nodes)
        self.nodes.append(e)
        return e

    def _make(self, op, args, *, vector, clamp=False, lane=None, label=None, stops=None):
        args = tuple(self.value(a) for a in args)
        if all(a.is_const for a in args) and op != "TABLE":
            return self.const(_apply(op, [a.value for a in args], [a.vector for a in args],
                                     clamp=clamp, lane=lane, stops=stops))
        key = (op, tuple(id(a) for a in args), clamp, lane, stops)
        e = self._memo.get(key)
        if e is None:
            e = self._add(Expr(op, args, vector=vector, clamp=clamp, lane=lane, label=label,
                               value=stops))
            self._memo[key] = e
        elif label and not e.label:
            e.label = label
        return e

    # -- scalar Math ---------------------------------------------------------------------------
    def math(self, op, *args, clamp=False, label=None):
        if op not in SCALAR_OPS or len(args) != SCALAR_OPS[op]:
            raise ValueError(f"Math {op} takes {SCALAR_OPS.get(op)} operands")
        args = [self.value(a) for a in args]
        if any(a.vector for a in args):
            raise TypeError(f"Math {op} on a vector operand")
        return self._make(op, args, vector=False, clamp=clamp, label=label)

    add = _math_node("ADD", "a + b.")
    sub = _math_node("SUBTRACT", "a - b.")
    mul = _math_node("MULTIPLY", "a * b.")
    div = _math_node("DIVIDE", "a / b.")
    madd = _math_node("MULTIPLY_ADD", "a * b + c.")
    sqrt = _math_node("SQRT", "sqrt(a).")
    minimum = _math_node("MINIMUM", "min(a, b).")
    maximum = _math_node("MAXIMUM", "max(a, b).")
    less = _math_node("LESS_THAN", "1 if a < b else 0.")
    clamp = _math_node("CLAMP", "min(max(a, lo), hi), NaN -> lo (one Clamp node; ``lo``, ``hi`` may "
                       "be expressions: lo <= hi is the caller's to keep).")

    def at_least(self, a, lo, **kw):
        """max(a, lo) for a known finite (not ±inf): a Clamp node, cheaper than Maximum."""
        return self.clamp(a, lo, _F32_MAX, **kw)

    def at_most(self, a, hi, **kw):
        """min(a, hi) for a known finite (a NaN gives -FLT_MAX, not hi)."""
        return self.clamp(a, -_F32_MAX, hi, **kw)

    def select(self, cond, if_true, if_false, **kw):
        """cond ∈ {0, 1}: the Mix node, (1 - cond) if_false + cond if_true."""
        c, a, b = self.value(cond), self.value(if_true), self.value(if_false)
        if a is b:
            return a
        if c.is_const:
            return a if float(c.value) >= 0.5 else b
        return self.mix(c, b, a, **kw)

    def mix(self, t, a, b, **kw):
        """(1 - t) a + t b, scalar ``t`` (the float or vector Mix node, factor not clamped)."""
        t, a, b = self.value(t), self.value(a), self.value(b)
        if t.vector:
            raise TypeError("mix() takes a scalar factor (vmix: a vector one)")
        if a.vector != b.vector:
            raise TypeError("mix of a vector and a scalar")
        return self._make("MIX", (t, a, b), vector=a.vector, **kw)

    def vmix(self, t, a, b, **kw):
        """(1 - t) a + t b per lane: the vector Mix node (Non-Uniform factor for a vector ``t``);
        scalar ``a``, ``b`` are broadcast."""
        return self._make("VMIX", (self.value(t), self.value(a), self.value(b)), vector=True, **kw)

    def vmul(self, a, b, **kw):
        """a b per lane (``a`` may be a scalar) for finite operands, as the vector Mix
        (1 - a) 0 + a b: SVM runs it faster than Vector Math Multiply or Scale (an infinite
        ``a`` would give NaN)."""
        return self.vmix(a, 0.0, b, **kw)

    # -- vectors -------------------------------------------------------------------------------
    def vmath(self, op, *args, label=None):
        """A Vector Math node.  Scalar operands are allowed: Blender turns a float linked into a
        vector input into (f, f, f).  SCALE's second operand is the scalar factor."""
        if op not in VECTOR_OPS or len(args) != VECTOR_OPS[op]:
            raise ValueError(f"Vector Math {op} takes {VECTOR_OPS.get(op)} operands")
        args = [self.value(a) for a in args]
        if op == "SCALE" and args[1].vector:
            raise TypeError("Vector Math SCALE takes a scalar factor")
        return self._make("V" + op, args, vector=op not in VECTOR_TO_SCALAR, label=label)

    def dot(self, a, b, **kw):
        """a · b (Vector Math DOT_PRODUCT: a scalar)."""
        return self.vmath("DOT_PRODUCT", a, b, **kw)

    def ramp(self, x, stops, **kw):
        """A Color Ramp node (linear interpolation, RGB) read at the scalar ``x``: a vector.
        ``stops``: up to 32 (position, (r, g, b)) with increasing positions in [0, 1]."""
        stops = tuple((float(np.float32(p)), tuple(float(np.float32(c)) for c in col))
                      for p, col in stops)
        if not 1 <= len(stops) <= RAMP_MAX_STOPS or any(len(c) != 3 for _, c in stops):
            raise ValueError(f"a ramp has 1 to {RAMP_MAX_STOPS} stops of three values")
        if any(b[0] < a[0] for a, b in zip(stops, stops[1:])) or not 0 <= stops[0][0] <= stops[-1][0] <= 1:
            raise ValueError("ramp stops need increasing positions in [0, 1]")
        x = self.value(x)
        if x.vector:
            raise TypeError("a ramp is read at a scalar")
        return self._make("RAMP", (x,), vector=True, stops=stops, **kw)

    def table(self, name, data, u, v, **kw):
        """A lookup in the float table ``data`` (H x W, or H x W x 3 for colours; registered as
        ``name``) at the texture coordinate (u, v) in [0, 1]²: texel (i, j) is centred at
        ((j + ½)/W, (i + ½)/H)."""
        data = np.ascontiguousarray(np.asarray(data, dtype=_F32))
        if data.ndim not in (2, 3) or min(data.shape[:2]) < 1 or data.shape[2:] not in ((), (3,)):
            raise ValueError("a table is an H x W or H x W x 3 array")
        padded = np.pad(data, ((1, 1), (1, 1)) + ((0, 0),) * (data.ndim - 2), mode="edge")
        have = self.tables.get(name)
        if have is not None and (have.shape != padded.shape or not np.array_equal(have, padded)):
            raise ValueError(f"table {name!r} is registered with other values")
        self.tables[name] = padded
        u, v = self.value(u), self.value(v)
        if u.vector or v.vector:
            raise TypeError("a table is read at two scalars")
        if u.is_const and v.is_const:
            with np.errstate(all="ignore"):
                return self.const(tuple(_table_rgb(data, u.value, v.value)))
        # clamped to the texel centres (EXTEND), then the padded image's coordinates, whose
        # direction is (sin θ cos φ, sin θ sin φ, cos θ), φ = π - 2π u, θ = π - π v (the inverse
        # of direction_to_equirectangular); the padding keeps the wrap off the far side
        h, w = data.shape[:2]
        pi = math.pi
        u = self.clamp(u, 0.5 / w, 1.0 - 0.5 / w)
        v = self.clamp(v, 0.5 / h, 1.0 - 0.5 / h)
        phi = self.madd(u, -2.0 * pi * w / (w + 2), pi - 2.0 * pi / (w + 2))
        theta = self.madd(v, -pi * h / (h + 2), pi - pi / (h + 2))
        sin_t = self.math("SINE", theta)
        d = self.combine(self.mul(sin_t, self.math("COSINE", phi)),
                         self.mul(sin_t, self.math("SINE", phi)), self.math("COSINE", theta))
        return self._make("TABLE", (d,), vector=True, stops=name, **kw)

    def vclamp01(self, v, **kw):
        """A vector clamped to [0, 1] per lane, NaN -> 0 (SATURATE: one colour Mix node); a
        scalar becomes (f, f, f) first, as when linked into a colour input."""
        return self._make("SATURATE", (self.value(v),), vector=True, **kw)

    def separate(self, v):
        """The three lanes of a vector (one Separate node)."""
        v = self.value(v)
        if not v.vector:
            raise TypeError("separate() of a scalar")
        return tuple(self._make("SEPARATE", (v,), vector=False, lane=i) for i in range(3))

    def combine(self, x, y, z, **kw):
        return self._make("COMBINE", (x, y, z), vector=True, **kw)

    def vsqrt(self, v, **kw):
        """√ per lane (< 0 gives 0) as Separate Color, three Math Square Roots, Combine Color:
        faster in SVM than Vector Math Power 0.5 (three powf calls)."""
        x, y, z = self.separate(v)
        return self.combine(self.sqrt(x), self.sqrt(y), self.sqrt(z), **kw)

    def channel_max(self, v, **kw):
        """The largest lane of a finite vector (e.g. a clamped colour): Clamp nodes."""
        r, g, b = self.separate(v)
        return self.at_least(self.at_least(r, g), b, **kw)

    # -- bookkeeping ---------------------------------------------------------------------------
    def used(self, outputs, stop=()):
        """The non-constant expressions ``outputs`` depend on, in topological order; the
        expressions whose index is in ``stop`` are included but not followed further."""
        seen = set()
        order = []
        stack = [e for e in _flatten(outputs) if not e.is_const]
        while stack:
            e = stack.pop()
            if e.index in seen:
                continue
            seen.add(e.index)
            if e.index not in stop:
                stack.extend(a for a in e.args if not a.is_const)
        for e in self.nodes:
            if e.index in seen:
                order.append(e)
        return order


def _flatten(outputs):
    if isinstance(outputs, Expr):
        return [outputs]
    if isinstance(outputs, dict):
        outputs = list(outputs.values())
    out = []
    for o in outputs:
        out.extend(_flatten(o) if isinstance(o, (dict, list, tuple)) else [o])
    return [o for o in out if isinstance(o, Expr)]


# ------------------------------------------------------------------------------------------------
# Semantics (Cycles SVM, float32)
# ------------------------------------------------------------------------------------------------


# (the operations run under np.errstate(all="ignore"): _apply's, or evaluate's for a whole graph)
def _safe_divide(a, b):
    return np.where(b != 0, a / np.where(b != 0, b, _F32(1)), _F32(0)).astype(_F32)


def _safe_pow(a, b):
    bad = (a < 0) & (b != np.trunc(b))
    return np.where(bad, _F32(0), np.power(np.where(bad, _F32(1), a), b)).astype(_F32)


def _clamp(x, lo, hi):  # kernel max/min: a > b ? a : b, a < b ? a : b
    m = np.where(x > lo, x, lo)
    return np.where(m < hi, m, hi).astype(_F32)


def _fmin(a, b):  # fminf: NaN loses
    return np.fmin(a, b).astype(_F32)


def _fmax(a, b):
    return np.fmax(a, b).astype(_F32)


_SCALAR = {
    "ADD": lambda a, b: a + b,
    "SUBTRACT": lambda a, b: a - b,
    "MULTIPLY": lambda a, b: a * b,
    "DIVIDE": _safe_divide,
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "POWER": _safe_pow,
    "SQRT": lambda a: np.sqrt(np.maximum(a, _F32(0))),
    "MINIMUM": _fmin,
    "MAXIMUM": _fmax,
    "LESS_THAN": lambda a, b: (a < b).astype(_F32),
    "GREATER_THAN": lambda a, b: (a > b).astype(_F32),
    "COMPARE": lambda a, b, c: ((a == b) | (np.abs(a - b) <= np.maximum(c, np.finfo(_F32).eps))
                                ).astype(_F32),
    "ABSOLUTE": np.abs,
    "FLOOR": np.floor,
    "CLAMP": _clamp,
    "COSINE": np.cos,
    "SINE": np.sin,
    "EXPONENT": np.exp,
}


def _saturate(x):
    return np.minimum(np.maximum(np.nan_to_num(x, nan=0.0), _F32(0)), _F32(1)).astype(_F32)


def ramp_table(stops):
    """The RAMP_TABLE_SIZE x 3 float32 table Blender hands Cycles for a linear RGB Color Ramp:
    BKE_colorband_evaluate at (float)i / (size - 1) — constant before the first and after the
    last stop, else mfac·right + fac·left with fac = (in - right.pos)/(left.pos - right.pos)."""
    pos = np.array([p for p, _ in stops], _F32)
    col = np.array([c for _, c in stops], _F32)
    out = np.empty((RAMP_TABLE_SIZE, 3), _F32)
    for i in range(RAMP_TABLE_SIZE):
        t = _F32(i) / _F32(RAMP_TABLE_SIZE - 1)
        if len(pos) == 1 or t <= pos[0]:
            out[i] = col[0]
            continue
        a = int(np.searchsorted(pos, t, side="right"))  # first stop with pos > t
        if a == len(pos):
            out[i] = col[-1]
            continue
        right, left = a, a - 1
        if pos[left] != pos[right]:
            fac = (t - pos[right]) / (pos[left] - pos[right])
        else:
            fac = _F32(0)
        out[i] = (_F32(1) - fac) * col[right] + fac * col[left]
    return out


def _ramp_lookup(table, f):
    """kernel/svm/ramp.h rgb_ramp_lookup without extrapolation: f saturated (NaN -> 0)."""
    n = len(table)
    f = _saturate(f) * _F32(n - 1)
    i = np.clip(f.astype(np.int64), 0, n - 1)
    t = (f - i.astype(_F32)).astype(_F32)
    a = table[i]
    b = table[np.minimum(i + 1, n - 1)]
    return np.where((t > 0)[..., None], (_F32(1) - t)[..., None] * a + t[..., None] * b, a).astype(_F32)


_RAMP_CACHE = {}


def _table_rgb(data, u, v, wrap=False):
    """_table_lookup of a grey (H, W) table in every lane, or of each channel of an (H, W, 3)
    one: (..., 3)."""
    if data.ndim == 2:
        return np.repeat(_table_lookup(data, u, v, wrap)[..., None], 3, axis=-1)
    return np.stack([_table_lookup(data[..., c], u, v, wrap) for c in range(3)], axis=-1)


def _environment_rgb(data, d):
    """An Environment Texture (equirectangular, Linear) of ``data`` in the directions ``d``
    (..., 3), as Cycles reads it: safe_normalize, direction_to_equirectangular, interp_linear
    with EXTENSION_REPEAT (indices wrapped); (..., 3)."""
    d = np.asarray(d, _F32)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    length = np.sqrt(x * x + y * y + z * z).astype(_F32)
    zn = np.where(length > 0, z / np.where(length > 0, length, _F32(1)), z).astype(_F32)
    zero = length == 0  # (direction_to_equirectangular of the zero vector: (0, 0))
    u = np.where(zero, _F32(0), (np.arctan2(y, x).astype(_F32) - _F32(math.pi)) / _F32(-2.0 * math.pi))
    v = np.where(zero, _F32(0), (np.arccos(np.clip(zn, -1, 1)).astype(_F32) - _F32(math.pi))
                 / _F32(-math.pi))
    return _table_rgb(data, np.asarray(u, _F32), np.asarray(v, _F32), wrap=True)


def _table_lookup(data, u, v, wrap=False):
    """kernel/util/image.h interp_linear with EXTENSION_EXTEND (``wrap``: REPEAT) on a float
    image, one channel."""
    h, w = data.shape
    u, v = np.asarray(u, _F32), np.asarray(v, _F32)
    x = (u * _F32(w) - _F32(0.5)).astype(_F32)
    y = (v * _F32(h) - _F32(0.5)).astype(_F32)
    ix = np.where(np.isfinite(x), np.floor(x), 0.0).astype(np.int64)
    iy = np.where(np.isfinite(y), np.floor(y), 0.0).astype(np.int64)
    tx = np.where(np.isfinite(x), x - ix.astype(_F32), _F32(0)).astype(_F32)
    ty = np.where(np.isfinite(y), y - iy.astype(_F32), _F32(0)).astype(_F32)
    if wrap:  # EXTENSION_REPEAT: wrap_periodic
        nix, niy = (ix + 1) % w, (iy + 1) % h
        ix, iy = ix % w, iy % h
    else:
        nix, niy = np.clip(ix + 1, 0, w - 1), np.clip(iy + 1, 0, h - 1)
        ix, iy = np.clip(ix, 0, w - 1), np.clip(iy, 0, h - 1)
    one = _F32(1)
    out = ((one - ty) * (one - tx) * data[iy, ix] + (one - ty) * tx * data[iy, nix]
           + ty * (one - tx) * data[niy, ix] + ty * tx * data[niy, nix])
    return np.asarray(out, _F32)


def _apply(op, vals, vector_args, *, clamp=False, lane=None, stops=None):
    """One operation on float32 values; ``vector_args`` says which operands are vectors
    (S + (3,)) — scalar operands of a vector operation are broadcast over the lanes."""
    with np.errstate(all="ignore"):
        return _apply_arrays(op, [np.asarray(v, dtype=_F32) for v in vals], vector_args,
                             clamp, lane, stops)


def _apply_arrays(op, vals, vector_args, clamp, lane, stops):
    """_apply on float32 arrays, under the caller's np.errstate(all="ignore")."""
    if op == "RAMP":
        table = _RAMP_CACHE.get(stops)
        if table is None:
            table = _RAMP_CACHE.setdefault(stops, ramp_table(stops))
        return _ramp_lookup(table, vals[0])
    if op == "TABLE":  # (stops: the padded table itself, handed in by evaluate)
        return _environment_rgb(stops, vals[0])
    if op == "VDOT_PRODUCT":
        a, b = np.broadcast_arrays(*(v if is_vec else np.repeat(v[..., None], 3, -1)
                                     for v, is_vec in zip(vals, vector_args)))
        return np.asarray(a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2], _F32)
    if op == "SATURATE":
        v = vals[0] if vector_args[0] else np.repeat(vals[0][..., None], 3, -1)
        return _saturate(v)
    if op == "SEPARATE":
        out = vals[0][..., lane]
    elif op == "COMBINE":
        out = np.stack(np.broadcast_arrays(*vals), axis=-1)
    else:
        if op.startswith("V") or (op == "MIX" and any(vector_args)):
            vals = [v if is_vec else v[..., None] for v, is_vec in zip(vals, vector_args)]
        if op in ("MIX", "VMIX"):
            t, a, b = vals
            out = (_F32(1) - t) * a + t * b
        elif op == "VSCALE":
            out = vals[0] * vals[1]
        else:
            out = _SCALAR[op[1:] if op.startswith("V") else op](*vals)
        if op.startswith("V") and out.shape[-1:] != (3,):  # scalar operands only: (f, f, f)
            out = np.broadcast_to(out, out.shape[:-1] + (3,))
    out = np.asarray(out, dtype=_F32)
    return _saturate(out) if clamp else out


#: evaluation plans by their output expressions (a layer's panel values, its slots: a handful)
_PLANS = {}
_PLANS_MAX = 256


def _plan(exprs):
    """What evaluating ``exprs`` runs, in order: (expr, args, vector args) with every constant
    argument converted once (args: (True, array, scalar) or (False, index)); cached per output
    tuple."""
    key = tuple(exprs)
    plan = _PLANS.get(key)
    if plan is None:
        if len(_PLANS) >= _PLANS_MAX:
            _PLANS.clear()
        steps = []
        for e in _topo(exprs):
            args = []
            for a in e.args:
                if a.is_const:
                    arr = np.asarray(a.value, dtype=_F32)
                    args.append((True, arr, arr[()] if arr.ndim == 0 else arr))
                else:
                    args.append((False, a.index))
            fast = None if any(a.vector for a in e.args) else _FAST.get(e.op)
            steps.append((e, tuple(args), [a.vector for a in e.args], fast))
        plan = _PLANS[key] = steps
    return plan


def _fmin_scalar(a, b):  # fminf: NaN loses
    return b if a != a else a if (b != b or a < b) else b


def _fmax_scalar(a, b):
    return b if a != a else a if (b != b or a > b) else b


_ONE, _ZERO = _F32(1), _F32(0)
#: Scalar operations on np.float32 scalars (ten times quicker than on 0-d arrays), the same
#: float32 results as _SCALAR's: one rounding per operation, NaN where the array form has it.
_FAST = {
    "ADD": lambda a, b: a + b,
    "SUBTRACT": lambda a, b: a - b,
    "MULTIPLY": lambda a, b: a * b,
    "MULTIPLY_ADD": lambda a, b, c: a * b + c,
    "DIVIDE": lambda a, b: a / b if b != 0 else _ZERO,
    "MINIMUM": _fmin_scalar,
    "MAXIMUM": _fmax_scalar,
    "CLAMP": lambda x, lo, hi: (lambda m: m if m < hi else hi)(x if x > lo else lo),
    "SQRT": lambda a: _F32(math.sqrt(a)) if a > 0 else (a if a != a else _ZERO),
    "GREATER_THAN": lambda a, b: _ONE if a > b else _ZERO,
    "LESS_THAN": lambda a, b: _ONE if a < b else _ZERO,
    "ABSOLUTE": abs,
    "MIX": lambda t, a, b: (_ONE - t) * a + t * b,
}


def evaluate(outputs, inputs, tables=None, *, lazy=False):
    """Values of ``outputs`` (an Expr, a list or a dict of them) for ``inputs`` (name ->
    float32 array, vectors shaped (..., 3)), with Blender's node semantics in float32.
    ``tables``: the graph's (Graph.tables), for TABLE lookups.  ``lazy`` (one shading point
    only): a select whose factor is exactly 0 or 1 skips the side it drops — the same values
    wherever that side is finite (a NaN there makes Blender's Mix node NaN; lazy does not see
    it), for advice that need not pay for branches a point does not take."""
    exprs = _flatten(outputs)
    cache = {}
    tables = tables or {}
    plan = _plan(exprs)
    # one shading point (scalars 0-d, vectors (3,)): np.float32 scalars and the _FAST forms
    point = True
    for e, _args, _v, _f in plan:
        if e.op == "input":
            if e.name not in inputs:
                raise KeyError(f"no value for input {e.name!r}")
            v = np.asarray(inputs[e.name], dtype=_F32)
            if v.shape != ((3,) if e.vector else ()):
                point = False
            cache[e.index] = v
    if point:
        for k, v in cache.items():
            if v.ndim == 0:
                cache[k] = v[()]
        if lazy:
            with np.errstate(all="ignore"):
                _evaluate_point(exprs, plan, cache, tables)
            return _outputs(outputs, cache)
    with np.errstate(all="ignore"):
        for e, args, vector_args, fast in plan:
            if e.op == "input":
                continue
            if point:
                vals = [a[2] if a[0] else cache[a[1]] for a in args]
                if fast is not None:
                    out = fast(*vals)
                    cache[e.index] = _saturate(out)[()] if e.clamp else out
                    continue
            else:
                vals = [a[1] if a[0] else cache[a[1]] for a in args]
            if e.op == "TABLE" and e.value not in tables:
                raise KeyError(f"no table {e.value!r} (evaluate(..., tables=graph.tables))")
            out = _apply_arrays(
                e.op, vals, vector_args, e.clamp, e.lane,
                e.value if e.op == "RAMP" else tables[e.value] if e.op == "TABLE" else None)
            cache[e.index] = out[()] if point and out.ndim == 0 else out
    return _outputs(outputs, cache)


def _outputs(outputs, cache):
    def out(o):
        if isinstance(o, dict):
            return {k: out(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return type(o)(out(v) for v in o)
        if isinstance(o, Expr):
            return np.asarray(o.value, dtype=_F32) if o.is_const else np.asarray(cache[o.index])
        return o
    return out(outputs)


def _step(e, args, vector_args, fast, cache, tables):
    """One plan step at one shading point (values in ``cache``)."""
    vals = [a[2] if a[0] else cache[a[1]] for a in args]
    if fast is not None:
        out = fast(*vals)
        return _saturate(out)[()] if e.clamp else out
    if e.op == "TABLE" and e.value not in tables:
        raise KeyError(f"no table {e.value!r} (evaluate(..., tables=graph.tables))")
    out = _apply_arrays(e.op, vals, vector_args, e.clamp, e.lane,
                        e.value if e.op == "RAMP" else tables[e.value] if e.op == "TABLE" else None)
    return out[()] if out.ndim == 0 else out


def _evaluate_point(exprs, plan, cache, tables):
    """evaluate(lazy=True) at one shading point: demand-driven, a scalar select (MIX) whose
    factor is exactly 0 or 1 evaluates only the side it keeps ((1 - t) a + t b is a, or b,
    where the other side is finite), without the work of the side not taken (a layer's film,
    glass and Multiscatter branches)."""
    steps = {e.index: (e, args, v, f) for e, args, v, f in plan}
    stack = [e.index for e in exprs if not e.is_const]
    while stack:
        i = stack[-1]
        if i in cache:
            stack.pop()
            continue
        e, args, vector_args, fast = steps[i]
        need = [a[1] for a in args if not a[0]]
        if e.op == "MIX" and not vector_args[0] and not args[0][0]:
            t = args[0][1]
            if t not in cache:
                stack.append(t)
                continue
            tv = cache[t]
            keep = [a for a in args[1:] if not a[0]]
            if tv == 0.0 or tv == 1.0:
                side = args[1] if tv == 0.0 else args[2]
                if side[0]:
                    cache[i] = side[2]
                    stack.pop()
                    continue
                if side[1] not in cache:
                    stack.append(side[1])
                    continue
                cache[i] = cache[side[1]]
                stack.pop()
                continue
            need = [a[1] for a in keep]
        missing = [j for j in need if j not in cache]
        if missing:
            stack.extend(missing)
            continue
        cache[i] = _step(e, args, vector_args, fast, cache, tables)
        stack.pop()


def _topo(exprs):
    seen = {}
    stack = [e for e in exprs if not e.is_const]
    while stack:
        e = stack.pop()
        if e.index in seen:
            continue
        seen[e.index] = e
        stack.extend(a for a in e.args if not a.is_const)
    return [seen[i] for i in sorted(seen)]
