# SPDX-License-Identifier: GPL-3.0-or-later
"""A hazy material's node-editor edits: the values of the add-on's nodes the user changed since
the add-on wrote them (:func:`node_edits`, compared with the stamp's record,
blender.model.material.WRITTEN), and reading them back into the stamped parameters
(:func:`adopt_edits`; :func:`adopt_node_edits` for the depsgraph handler): the group inputs of
an in-shader material are the perceptual parameters, a lean tree reads back through the inverse
haze mapping."""
from typing import NamedTuple

import numpy as np

from ... import constants as K
from ...core import inverse_haze_mapping
from ...core.conventions import lobe_alphas, metallic_anisotropy
from ...core.parameters import normalise
from . import layer, stamp
from .material import WRITTEN, current_value, lobes_for, record_writes, write_stamp, writes
from .material_read import is_hazy, read_parameters
from ..nodes.builder import socket_value
from ..nodes.lobes import ANISO_INPUTS
from ..nodes.ownership import ours


def _differs(now, was):
    if isinstance(now, str) or isinstance(was, str):
        return now != was
    a = np.atleast_1d(np.asarray(now, dtype=np.float64))
    b = np.atleast_1d(np.asarray(was, dtype=np.float64))
    if a.shape != b.shape:
        n = min(a.size, b.size)  # an RGBA socket against an RGB value: alpha is not ours
        a, b = a[:n], b[:n]
    return bool(np.any(np.abs(a - b) > 1e-6 + 1e-5 * np.abs(b)))


def _readable(was, attr):
    """Whether a value of the stamp's record reads as what the add-on wrote: a setting's name,
    or a number or list of numbers (anyone can edit the stamp: the rest is not compared)."""
    if attr:
        return isinstance(was, str)
    number = lambda x: isinstance(x, (int, float)) and not isinstance(x, bool)  # noqa: E731
    return number(was) or (isinstance(was, list) and 0 < len(was) <= 4 and all(map(number, was)))


class Edit(NamedTuple):
    """A value the user changed in the node editor: the add-on wrote ``was``, the node holds
    ``now``."""

    role: str
    node: str  # the node's name now
    name: str
    now: object
    was: object
    attr: bool

    def __str__(self):
        return f"{self.node}: {self.name}"


def node_edits(mat, p=None):
    """[Edit] of the add-on's values the user changed in the node editor (socket values and
    node settings of a lean or in-shader tree of the stamped structure).  Compared with what
    the add-on last wrote (the stamp's record); for a material stamped before the record
    existed, with what the stamped parameters map to now."""
    if not is_hazy(mat) or mat.node_tree is None or layer.is_layered(mat):
        return []
    try:
        p = p or read_parameters(mat)
        d = lobes_for(p)
    except (ValueError, TypeError):
        return []
    ws = writes(mat, p, d)
    if ws is None:  # not the stamped structure: the next change rebuilds
        return []
    rec = (stamp.group(mat, K.STAMP) or {}).get(WRITTEN)
    mine = ours(mat.node_tree)
    out = []
    for w in ws:
        node = mine.get(w.role)
        if node is None:
            continue
        now = current_value(node, w)
        if now is None:
            continue
        key = ("@" if w.attr else "") + w.name
        if isinstance(rec, dict):
            entry = rec.get(w.role)
            was = entry.get(key) if isinstance(entry, dict) else None
            if not _readable(was, w.attr):
                continue  # not recorded (or a damaged record): nothing to compare with
        else:
            was = w.value if w.attr else socket_value(node.inputs[w.name], w.value)
        if _differs(now, was):
            out.append(Edit(w.role, node.name, w.name, now, was, w.attr))
    return out


#: Group inputs -> the perceptual parameter they are (in-shader mapping).
_GROUP_KEYS = {"Core Reflectivity": "core_reflectivity", "Edge Tint": "edge_tint",
               "Roughness": "roughness", "Anisotropy": "anisotropy", "Rotation": "rotation",
               "Haziness": "haziness", "Smoothness": "smoothness", "Base Color": "base_color",
               "Transmission": "transmission"}


def _adopt_group(p, edits):
    """p with the group inputs the user edited (they are the perceptual parameters)."""
    q = dict(p)
    ex, ey = q["haze_extent"]
    for e in edits:
        v = e.now
        if e.role == "Tangent":
            continue
        if e.name == "Haze Extent":
            ex = ey = v
        elif e.name == "Haze Extent X":
            ex = v
        elif e.name == "Haze Extent Y":
            ey = v
        elif e.name in _GROUP_KEYS:
            q[_GROUP_KEYS[e.name]] = tuple(v[:3]) if isinstance(v, tuple) else v
    q["haze_extent"] = (ex, ey)
    return q


def _tangent_of(mat, p):
    t = ours(mat.node_tree).get("Tangent")
    if t is None or t.bl_idname != "ShaderNodeTangent":
        return p["tangent"]
    return "UV_MAP" if t.direction_type == "UV_MAP" else f"RADIAL_{t.axis}"


def _lobe_alpha(value, lobe, kind, anisotropic, rotation):
    """(α_x, α_y, rotation) of one lean lobe in its node's convention, long axis along x
    (``value(role, input)`` reads the lobe's inputs; an isotropic one keeps ``rotation``)."""
    if not anisotropic:
        a = float(np.clip(value(lobe, "Roughness"), 0.0, 1.0)) ** 2
        return a, a, rotation
    a_name, r_name = ANISO_INPUTS[kind]
    return lobe_alphas(value(lobe, "Roughness"), float(value(lobe, a_name)),
                       float(value(lobe, r_name)), glossy=kind == "LEGACY")


def _other_lobe(lobe):
    return "Wide lobe" if lobe == "Narrow lobe" else "Narrow lobe"


def _adopt_lean(mat, p, d, edits, pending=()):
    """p with a lean tree's values read back through the inverse haze mapping
    (core.inverse_haze_mapping), or None when they are not a hazy material's (the lobes no
    longer share one Fresnel term, a Glossy colour pair has no single β, ...).  A value shared
    by both lobes (the Fresnel inputs, a dielectric's base, the distribution) that the user
    changed on one lobe is taken as the new shared value.  ``pending``: edits not tried here,
    read as the add-on wrote them."""
    kind = p["kind"]
    mine = ours(mat.node_tree)
    narrow, wide = mine["Narrow lobe"], mine.get("Wide lobe")
    edited = {(e.role, e.name): e.now for e in edits}
    held = {(e.role, e.name): e.was for e in pending}

    def value(node_role, name):
        if (node_role, name) in edited:
            return edited[(node_role, name)]
        if name in _SHARED[kind] and (_other_lobe(node_role), name) in edited:
            return edited[(_other_lobe(node_role), name)]
        if (node_role, name) in held:
            v = held[(node_role, name)]
            return tuple(float(x) for x in v)[:3] if isinstance(v, (list, tuple)) else float(v)
        v = mine[node_role].inputs[name].default_value
        return tuple(float(x) for x in v)[:3] if hasattr(v, "__len__") else float(v)

    dist = edited.get(("Narrow lobe", "distribution")) or \
        edited.get(("Wide lobe", "distribution")) or p["distribution"]
    if dist not in K.NODE_DISTRIBUTIONS[kind] or dist == "MULTI_GGX":
        return None  # Multiscatter GGX: Cycles' energy factor is not inverted here
    aniso = bool(d.anisotropic)
    ax, ay, rot = _lobe_alpha(value, "Narrow lobe", kind, aniso, p["rotation"])
    rough = (ax * ay) ** 0.25
    anisotropy = float(metallic_anisotropy(ay / ax)) if aniso and ax > 0 else 0.0
    if wide is not None:
        wx, wy, wrot = _lobe_alpha(value, "Wide lobe", kind, aniso, p["rotation"])
        turn = (wrot - rot) % 0.5
        if aniso and abs(turn - 0.25) < 1e-4:
            wx, wy = wy, wx
        elif aniso and min(turn, 0.5 - turn) > 1e-4:
            return None  # the halo is rotated against the core
    else:
        wx, wy = (float(a) for a in d.mapping.alpha_wide)
    kw = {}
    if kind == "CONDUCTOR":
        if narrow.fresnel_type != "PHYSICAL_CONDUCTOR":
            return None
        kw = dict(ior=value("Narrow lobe", "IOR"), extinction=value("Narrow lobe", "Extinction"))
        beta = float(value("Lobe mix", "Fac")) if wide is not None else 0.0
    elif kind == "DIELECTRIC":
        ior = float(value("Narrow lobe", "IOR"))
        f0 = ((ior - 1.0) / (ior + 1.0)) ** 2 if ior != -1.0 else 1.0
        tint = np.asarray(value("Narrow lobe", "Specular Tint"), float)[:3]
        kw = dict(reflectivity=np.clip(f0 * tint, 0.0, 1.0))
        beta = float(value("Lobe mix", "Fac")) if wide is not None else 0.0
    else:
        k_n = np.asarray(value("Narrow lobe", "Color"), float)[:3]
        k_w = np.asarray(value("Wide lobe", "Color"), float)[:3] if wide is not None else 0 * k_n
        r = k_n + k_w
        ch = int(np.argmax(r))
        beta = float(k_w[ch] / r[ch]) if r[ch] > 0 else 0.0
        kw = dict(reflectivity=np.clip(r, 0.0, 1.0))
    try:
        inv = inverse_haze_mapping(beta, (ax, ay), (max(wx, ax), max(wy, ay)), distribution=dist,
                                   smoothness=p["smoothness"], alpha_max=K.ALPHA_MAX, **kw)
    except ValueError:
        return None
    q = dict(p, distribution=dist, roughness=rough, anisotropy=anisotropy, rotation=rot % 1.0,
             core_reflectivity=tuple(float(x) for x in np.clip(inv.core_reflectivity, 0, 1)),
             haziness=float(np.clip(inv.haziness, 0.0, K.MAX_HAZINESS)),
             haze_extent=tuple(float(x) for x in inv.haze_extent))
    if not aniso:
        q["rotation"] = p["rotation"]
    if kind == "CONDUCTOR":
        q["edge_tint"] = tuple(float(x) for x in np.clip(inv.edge_tint, 0, 1))
    if kind == "DIELECTRIC":
        q["base_color"] = tuple(value("Narrow lobe", "Base Color"))[:3]
        q["transmission"] = float(value("Narrow lobe", "Transmission Weight"))
    if wide is None:  # no halo: the haze values stay (they do not show)
        q["haziness"], q["haze_extent"] = p["haziness"], p["haze_extent"]
    return q


#: Inputs both lean lobes share (Eq. 1 has one Fresnel term).
_SHARED = {"CONDUCTOR": ("IOR", "Extinction"),
           "DIELECTRIC": ("IOR", "Specular Tint", "Base Color", "Transmission Weight"),
           "LEGACY": ()}


def _matches(mat, q, edits, pending=()):
    """``q`` normalised when it writes back what the nodes hold (the edited values where the
    user set them, shared values following the lobe the user edited; the ``pending`` edits,
    not tried here, are not compared), else None."""
    try:
        q = normalise(q, explicit=())
        dq = lobes_for(q)
    except (ValueError, TypeError):
        return None
    ws = writes(mat, q, dq)
    if ws is None:
        return None
    mine = ours(mat.node_tree)
    edited = {(e.role, e.name): e.now for e in edits}
    skipped = {(e.role, e.name) for e in pending}
    lean = not q["shader_mapping"]
    for w in ws:
        if (w.role, w.name) in skipped:
            continue
        node = mine.get(w.role)
        now = current_value(node, w) if node is not None else None
        if (w.role, w.name) in edited:
            now = edited[(w.role, w.name)]
        elif lean and (w.name in _SHARED.get(q["kind"], ()) or (w.attr and w.name == "distribution")):
            now = edited.get((_other_lobe(w.role), w.name), now)
        if now is None:
            continue
        want = w.value if w.attr else socket_value(node.inputs[w.name], w.value)
        if _differs(now, want):
            return None
    return q


def adopt_edits(mat, p=None, edits=None):
    """(parameters, replaced): the stamped parameters with the user's node-editor edits read
    back (in-shader: the group inputs are the perceptual parameters; lean: the inverse haze
    mapping), each kept only when the result writes back what the nodes hold, and the edits
    that could not be read back (they are replaced by the next change), as [Edit].  When not
    all of them read together, one at a time: an edit that does not read does not take the
    others with it."""
    p = p or read_parameters(mat)
    edits = node_edits(mat, p) if edits is None else edits
    if not edits:
        return p, []
    d = lobes_for(p)
    base = dict(p, tangent=_tangent_of(mat, p))  # a Tangent node's settings are the tangent

    def read(trial, pending):
        if p["shader_mapping"]:
            q = _adopt_group(base, trial)
        else:
            q = _adopt_lean(mat, base, d, trial, pending)
        return _matches(mat, q, trial, pending) if q is not None else None

    q = read(edits, [])
    if q is not None:
        return q, []
    kept = []
    for e in edits:
        if read(kept + [e], [x for x in edits if x not in kept and x is not e]) is not None:
            kept.append(e)
    replaced = [e for e in edits if e not in kept]
    q = read(kept, replaced) if kept else None
    return (q, replaced) if q is not None else (p, edits)


def adopt_node_edits(mat):
    """Read the user's node-editor edits of a lean / in-shader material into its stamp (the
    nodes are not touched: they already hold the values).  Returns (adopted, replaced) lists
    of Edit; called by the depsgraph handler (blender.actions.sync) after the user edits a node."""
    if mat is None or mat.library is not None or not is_hazy(mat) or layer.is_layered(mat):
        return [], []
    try:
        p = read_parameters(mat)
        edits = node_edits(mat, p)
        if not edits:
            return [], []
        q, replaced = adopt_edits(mat, p, edits)
    except (ValueError, TypeError):
        return [], []
    adopted = [e for e in edits if e not in replaced]
    if adopted:
        if q != p:
            old = stamp.group(mat, K.STAMP) or {}
            write_stamp(mat, q)
            if isinstance(old.get("structure"), str):
                mat[K.STAMP]["structure"] = old["structure"]
        record_writes(mat, q, lobes_for(q))
        if replaced:  # keep the record of what could not be read back: still an edit
            rec = mat[K.STAMP][WRITTEN]
            for e in replaced:
                key = ("@" if e.attr else "") + e.name
                if e.role in rec:
                    rec[e.role][key] = list(e.was) if isinstance(e.was, tuple) else e.was
    return adopted, replaced


__all__ = ("node_edits", "adopt_edits", "adopt_node_edits")
