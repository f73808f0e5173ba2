# SPDX-License-Identifier: GPL-3.0-or-later
"""What a haze layer cannot do for its node's values, in plain words, with the setting that fixes
it: haze that cannot show (no room above the core's reflectivity), a peak the Specular Tint cannot
hold, what Keep Body Colour cannot keep, how far a thin film moves a metal's peak, a haze input
holding a value out of its range (typed by a script, or from a key or driver).
blender.model.layer.notes gathers these (with what only the material can tell: a bypassed layer
node, maps converted for other inputs) for the panel, the operator and the API."""
from __future__ import annotations

import numpy as np

from ... import constants as K
from ...core import body_colour, thin_film
from ...core.parameters import RANGES
from ...schema import HAZE_SOCKETS
from . import layer_values

__all__ = ("out_of_range_notes", "mirror_core_notes", "outputs_for_notes", "SUGGESTED_CAP",
           "FAINT_HALO", "FAINT_CAP", "room_notes", "coat_note", "film_peak_change", "body_note")


def out_of_range_notes(node, animated=()):
    """A line for each unlinked haze input whose value is out of its parameter's range: what it
    renders as (the group clamps it, NaN to the lower end; ``animated``: inputs whose keys or
    drivers set it)."""
    out = []
    for key, (name, *_rest) in HAZE_SOCKETS.items():
        sock = node.inputs.get(name)
        if sock is None or sock.is_linked or not hasattr(sock, "default_value"):
            continue
        lo, hi = RANGES[key[:-2] if key.endswith(("_x", "_y")) else key]
        v = float(sock.default_value)
        source = " (from its keys or driver)" if name in animated else ""
        if np.isnan(v):  # (the group reads it through a Maximum or Clamp node: NaN -> lo)
            out.append(f"{name} is NaN{source}: it renders as {lo:g}; give it a number")
        elif v < lo or (hi is not None and v > hi):
            rng = f"[{lo:g}, {hi:g}]" if hi is not None and np.isfinite(hi) else f">= {lo:g}"
            shown = max(v, lo) if hi is None else min(max(v, lo), hi)
            out.append(f"{name} is {v:g}{source}, outside {rng}: it renders as {shown:g}")
    return out



def mirror_core_notes(node):
    """A line for a core (or coat) roughness below the smallest the haze mapping takes, where
    it has haze: the lobe stays the mirror it is, and the halo is sized as for that smallest
    roughness (the group clamps the mapping's input, not the narrow lobe's own)."""
    lo = K.min_roughness(layer_values.group_config(node).get("settings", {}).get("distribution"))
    out = []
    for rough, haze in (("Roughness", "Haziness"), ("Coat Roughness", "Coat Haziness")):
        r, h = node.inputs.get(rough), node.inputs.get(haze)
        if r is None or h is None or r.is_linked or not (h.is_linked or h.default_value > 0):
            continue
        v = float(r.default_value)
        if v < lo:  # (NaN compares False: the out-of-range and NaN notes are the BSDF's own)
            out.append(f"{rough} {v:.4g} is below {lo:g}: that lobe stays a mirror and its halo "
                       f"is sized as for {rough} {lo:g} (the haze mapping's smallest)")
    return out

def outputs_for_notes(node):
    """The shown values the notes read for this node (evaluating all of them costs ~10 ms: the
    film and glass math is skipped where the node has neither)."""
    shown = layer_values.graph_of(node).shown
    keys = {"beta dielectric", "beta metal", "beta", "reflectivity metal", "reflectivity"}
    inp = node.inputs
    tr, film = inp.get("Transmission Weight"), inp.get("Thin Film Thickness")
    if (tr is not None and (tr.is_linked or tr.default_value > 0.0)) or \
            (film is not None and (film.is_linked or film.default_value > 0.1)):
        keys.add("tint narrow")
    if layer_values.group_config(node).get("body"):
        keys |= {"roughness wide", "IOR dielectric"}
    coat = inp.get("Coat Haziness")
    if coat is not None and (coat.is_linked or coat.default_value > 0.0):
        keys.add("coat IOR")
    return {k: shown[k] for k in keys if k in shown}


#: The Reflectivity Cap a note proposes where a colour at 1 leaves no room for haze.
SUGGESTED_CAP = 0.98


def _f0(ior):
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def _parts(node, linked):
    """(the name of its β among the shown values, the core reflectivity the user set (largest
    channel), what it is) of each part the node renders, from its unlinked values (a linked
    reflectivity: None, not judged)."""
    inp = node.inputs
    cfg = layer_values.group_config(node)
    kind = cfg.get("bsdf")

    def colour(name):
        return None if name in linked else float(max(inp[name].default_value[:3]))
    out = []
    if kind == "PRINCIPLED":
        m = None if "Metallic" in linked else float(inp["Metallic"].default_value)
        if m is None or m > 0.0:
            out.append(("beta metal", colour("Base Color"), "Base Color"))
        if (m is None or m < 1.0) and not {"IOR", "Specular IOR Level", "Specular Tint"} & set(linked):
            tint = float(max(inp["Specular Tint"].default_value[:3]))
            level = 2.0 * max(float(inp["Specular IOR Level"].default_value), 0.0)
            if float(inp["Transmission Weight"].default_value) > 1e-5:
                level = 1.0
            out.append(("beta dielectric",
                        _f0(float(inp["IOR"].default_value)) * level * tint, "the specular F0"))
    elif kind == "METALLIC" and cfg.get("settings", {}).get("fresnel_type") == "PHYSICAL_CONDUCTOR":
        rc = None
        if not {"IOR", "Extinction"} & set(linked):
            n = np.asarray(inp["IOR"].default_value[:3], float)
            k = np.asarray(inp["Extinction"].default_value[:3], float)
            rc = float((((n - 1) ** 2 + k * k) / ((n + 1) ** 2 + k * k)).max())
        out.append(("beta", rc, "the F0 of its IOR and Extinction"))
    elif kind == "METALLIC":
        out.append(("beta", colour("Base Color"), "Base Color"))
    else:
        out.append(("beta", colour("Color"), "Color"))
    return out


#: A halo carrying less than this share of β_h in β hardly shows (a colour near 1 leaves the
#: energy bound of Eq. 6 little room): the notes say how little and what the cap would give.
FAINT_HALO = 0.05
#: The Reflectivity Cap proposed for a faint halo (a bright metal's F(0)).
FAINT_CAP = 0.9


def room_notes(node, vals, linked, haze):
    """Haze that cannot show, or hardly shows, or the peak it cannot keep, with the setting
    that fixes it."""
    out = []
    cap = float(haze.get("reflectivity_cap", 1.0))
    bh = haze.get("haziness")
    for key, rc, what in _parts(node, linked):
        if rc is None:  # (a linked reflectivity: not judged, its β not evaluated)
            continue
        beta = vals.get(key, 0.0)
        if isinstance(bh, (int, float)) and 0.0 < beta < FAINT_HALO * bh \
                and FAINT_CAP < rc < min(cap, 1.0) - 1e-6 and "Reflectivity Cap" not in linked:
            shown = layer_values.graph_of(node).shown
            capped = layer_values.evaluate(node, {key: shown[key]},
                                           overrides={"haze:reflectivity_cap": FAINT_CAP})[0][key]
            out.append(f"little haze shows: {what} at {rc:.3g} leaves the halo "
                       f"{100 * beta:.1f}% of the reflection at haziness {bh:g} (the energy "
                       f"bound, Eq. 6); Reflectivity Cap {FAINT_CAP:g} gives it "
                       f"{100 * capped:.0f}% (the peak then drops by "
                       f"{100 * (1 - FAINT_CAP / rc):.1f}%)")
        if beta > 0.0:
            continue
        if rc >= min(cap, 1.0) - 1e-6 and cap > SUGGESTED_CAP:
            loss = 1.0 - SUGGESTED_CAP / min(rc, 1.0)
            out.append(f"no haze shows: {what} reaches {rc:.3g}, which leaves no room for a halo; "
                       f"set Reflectivity Cap to {SUGGESTED_CAP} to allow haze (the peak then drops "
                       f"by {100 * loss:.1f}%)")
        elif rc <= 1e-6:
            out.append(f"no haze shows: {what} is 0, so there is no reflection to put a halo "
                       f"around")
        elif rc >= min(cap, 1.0) - 1e-6:
            out.append(f"no haze shows: {what} ({rc:.3g}) leaves no room for a halo at this "
                       f"Reflectivity Cap ({cap:g}): lower the cap")
    tint = None if {"Specular Tint", "IOR"} & set(linked) else vals.get("tint narrow")
    if tint is not None and vals.get("beta dielectric", 0.0) > 0.0:
        f0 = _f0(float(node.inputs["IOR"].default_value)) * max(tint)
        if f0 > 1.0:
            out.append(f"the peak cannot hold: keeping it would need an F0 of {f0:.3g} (above 1) "
                       f"through the Specular Tint; lower Haziness")
    return out


def coat_note(node, vals, linked):
    """The coat's raised F(0) (Eq. 2 keeps the coat's peak: a hazier coat reflects more), and
    what it leaves of the light through it at normal incidence (1 - F(0)): the base and its
    emission under the coat render that much darker.  None where small or unknown."""
    ior, weight = node.inputs.get("Coat IOR"), node.inputs.get("Coat Weight")
    if ior is None or weight is None or "Coat IOR" in linked or "Coat Haziness" in linked or \
            (not weight.is_linked and weight.default_value <= 0.0) or "coat IOR" not in vals:
        return None
    was, now = _f0(float(ior.default_value)), _f0(float(vals["coat IOR"]))
    passes = (1.0 - now) / max(1.0 - was, 1e-6)
    if passes > 0.99:
        return None
    return (f"Coat Haziness raises the coat's F(0) from {was:.3f} to {now:.3f} (to keep its peak): "
            f"face-on it lets {100 * passes:.0f}% of the light through that it did, so the base "
            f"and its emission under the coat render darker (a rougher coat needs less)")


def film_peak_change(node, vals=None, linked=None):
    """How much a thin film moves the layer's peak on a metal part (hazy / haze-free - 1, the
    channel that moves most), for the node's unlinked values, or None without a film on a hazy
    metal: the layer raises the metal's F0 (Base Color) as without a film (Eq. 5), and the
    film's interference on a conductor is not linear in F0 (core.thin_film: Cycles'
    normal-incidence reflectance).  A dielectric's film is in the layer's node math (exact)."""
    if vals is None:
        vals, linked = layer_values.values(node)
    inp = node.inputs
    d = inp.get("Thin Film Thickness")
    if d is None or d.is_linked or not thin_film.film_active(d.default_value):
        return None
    film = (float(d.default_value), float(inp["Thin Film IOR"].default_value))
    cfg = layer_values.group_config(node)
    changes = []
    if cfg.get("bsdf") == "PRINCIPLED":  # (the dielectric part's film is node math: exact)
        tint = np.asarray(inp["Specular Tint"].default_value, float)[:3]
        m = float(inp["Metallic"].default_value)
        if m > 0.0 and vals.get("beta metal", 0.0) > 0.0:
            base = np.clip(np.asarray(inp["Base Color"].default_value, float)[:3], 1e-9, 1.0)
            raised = np.clip(np.asarray(vals["reflectivity metal"], float), 1e-9, 1.0)
            a = thin_film.metal_reflectance(base, tint, *film)
            b = thin_film.metal_reflectance(raised, tint, *film)
            changes.append(np.asarray(b) / np.maximum(a, 1e-9) * base / raised - 1.0)
    elif cfg.get("bsdf") == "METALLIC" and vals.get("beta", 0.0) > 0.0 and \
            cfg.get("settings", {}).get("fresnel_type") == "F82":
        tint = np.asarray(inp["Edge Tint"].default_value, float)[:3]
        base = np.clip(np.asarray(inp["Base Color"].default_value, float)[:3], 1e-9, 1.0)
        raised = np.clip(np.asarray(vals["reflectivity"], float), 1e-9, 1.0)
        a = thin_film.metal_reflectance(base, tint, *film)
        b = thin_film.metal_reflectance(raised, tint, *film)
        changes.append(np.asarray(b) / np.maximum(a, 1e-9) * base / raised - 1.0)
    if not changes:
        return None
    worst = np.concatenate([np.ravel(c) for c in changes])
    return float(worst[np.argmax(np.abs(worst))])


def body_note(node, vals, linked):
    """What Keep Body Colour cannot keep for the node's values (a base that would need a
    colour above 1): core.body_colour's measure of it, for the panel (the shader computes the
    compensation itself)."""
    if {"Base Color", "Roughness", "IOR", "Specular Tint", "Specular IOR Level"} & set(linked):
        return None
    inp = node.inputs
    r = float(inp["Roughness"].default_value)
    rw = float(vals["roughness wide"])
    try:
        bc = body_colour.compensation(
            r * r, float(inp["IOR"].default_value), float(vals["IOR dielectric"]),
            float(vals["beta dielectric"]), rw * rw,
            base_color=tuple(inp["Base Color"].default_value)[:3],
            tint=tuple(inp["Specular Tint"].default_value)[:3],
            level=float(inp["Specular IOR Level"].default_value),
            distribution=layer_values.group_config(node).get("settings", {}).get("distribution", "GGX"))
    except (ValueError, FloatingPointError):
        return None
    warning = bc.warning()
    if warning is None:
        return None
    most = 1.0 / max(float(np.max(bc.c_face_on)), 1.0)
    return (f"{warning}: lower Haziness, or a Base Color of at most {most:.2f} keeps the body "
            f"colour")
