# SPDX-License-Identifier: GPL-3.0-or-later
"""A haze layer on transmissive and filmed dielectrics, as node math
(core.layer_graph evaluated in numpy with Blender's node semantics), against derivations written
here: the peak equation of the closures the group builds, the film's F(0) against
core.thin_film.  Their energy is rendered (tests/blender/test_real_materials.py: a white furnace,
reflection and transmission passes apart)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from hazy_gloss.core import layer_graph, node_thin_film, thin_film
from hazy_gloss.core.tables import bsdf_interfaces
from hazy_gloss.core.graph import Graph, evaluate
from hazy_gloss.schema import HAZE_SOCKETS

VERSIONS = ((4, 5), (5, 2), (5, 3))


def _inputs(lay, version, **values):
    """Every graph input of ``lay``: the Principled's declared defaults, the haze defaults,
    ``values`` by socket / haze name."""
    decl = bsdf_interfaces.TABLES[f"{version[0]}.{version[1]}"]["PRINCIPLED"]["sockets"]
    haze = {key: socket[1] for key, socket in HAZE_SOCKETS.items()}
    out = {}
    for name, e in lay.graph.inputs.items():
        kind, _, key = name.partition(":")
        if kind == "in":
            v = values.get(key, decl[key]["default"] if key in decl else 0.0)
        elif kind == "haze":
            v = values.get(key, haze[key])
        else:  # the view cosine of Keep Body Colour: face-on
            v = 0.0
        v = np.asarray(v, np.float32)
        out[name] = (np.broadcast_to(v.ravel()[:3], (3,)) if e.vector else v.reshape(-1)[0])
    return out


def _slots(lay, ins):
    outs = {}
    for s in layer_graph.slots_of(lay.cycles):
        for k, e in s.writes.items():
            outs[(s.role, k)] = e
    mixes = {}

    def walk(t):
        if isinstance(t, layer_graph.Mix):
            if not t.add:
                mixes[t.role] = t.factor
            walk(t.a)
            walk(t.b)
    walk(lay.cycles)
    vals = evaluate({**{f"{r}|{k}": e for (r, k), e in outs.items()}, **mixes}, ins, lay.graph.tables)
    slot = {}
    for key, v in vals.items():
        if "|" in key:
            r, k = key.split("|")
            slot.setdefault(r, {})[k] = np.asarray(v, np.float64)
    return slot, {k: float(vals[k]) for k in mixes}


def _f0(eta):
    return ((eta - 1.0) / (eta + 1.0)) ** 2


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("ior", [1.31, 1.333, 1.5, 1.77, 2.42])
@pytest.mark.parametrize("haziness", [0.3, 0.6, 0.9])
def test_glass_keeps_its_ior_its_peak_and_its_energy(version, ior, haziness):
    lay = layer_graph.build(layer_graph.Config("PRINCIPLED", "GGX", version=version))
    rough = 0.2
    ins = _inputs(lay, version, **{"Transmission Weight": 1.0, "IOR": ior, "Roughness": rough,
                                   "Base Color": (1.0, 1.0, 1.0), "haziness": haziness})
    slot, mix = _slots(lay, ins)
    narrow, wide = slot["A narrow"], slot["A wide"]
    f = mix["Mix A"]
    # refraction: the narrow lobe carries it with the user's IOR and roughness
    assert narrow["IOR"] == np.float32(ior)
    assert "Roughness" not in narrow
    # the halo: a white mirror (Metallic 1, F0 = 1, no film) that transmits nothing
    assert wide["Metallic"] == 1.0 and np.all(wide["Base Color"] == 1.0)
    assert np.all(wide["Specular Tint"] == 1.0) and wide["Thin Film Thickness"] == 0.0
    # GGX peaks D(0) = 1/(π α_x α_y), α = R²: the peak equation, independently
    a_n = rough ** 2
    a_w = float(wide["Roughness"]) ** 2
    p = a_n ** 2 / a_w ** 2
    f0 = _f0(ior)
    f0_n = f0 * float(narrow["Specular Tint"][0])
    peak = (1.0 - f) * f0_n + f * p
    assert peak == pytest.approx(f0, rel=2e-6)
    assert f > 0.0  # haze is there
    # the energy (T drops by what R gains) is measured by Cycles in a white furnace, the
    # reflection and transmission passes apart: tests/blender/test_real_materials.py


@pytest.mark.parametrize("level", [0.2, 0.5, 0.8])
@pytest.mark.parametrize("weight", [0.25, 0.5, 1.0])
def test_partly_transmissive_peak(level, weight):
    """Transmission lobe F0 = F0(η) tint, specular F0 = F0(η) 2 Level tint: the peak is their
    mix by the Transmission Weight, and one tint scales both."""
    version = (5, 3)
    lay = layer_graph.build(layer_graph.Config("PRINCIPLED", "GGX", version=version))
    ior, rough = 1.5, 0.25
    ins = _inputs(lay, version, **{"Transmission Weight": weight, "IOR": ior, "Roughness": rough,
                                   "Specular IOR Level": level, "haziness": 0.5})
    slot, mix = _slots(lay, ins)
    f = mix["Mix A"]
    p = rough ** 4 / float(slot["A wide"]["Roughness"]) ** 4
    base = _f0(ior) * ((1.0 - weight) * 2.0 * level + weight)
    tint = float(slot["A narrow"]["Specular Tint"][0])
    assert (1.0 - f) * base * tint + f * p == pytest.approx(base, rel=2e-6)


def test_opaque_dielectric_still_raises_its_ior():
    """No transmission, no film: the IOR raise of before (Eq. 1's exact dielectric Fresnel)."""
    version = (5, 3)
    lay = layer_graph.build(layer_graph.Config("PRINCIPLED", "GGX", version=version))
    ins = _inputs(lay, version, **{"IOR": 1.5, "Roughness": 0.2, "haziness": 0.5})
    slot, mix = _slots(lay, ins)
    assert slot["A narrow"]["IOR"] > 1.5 and np.all(slot["A narrow"]["Specular Tint"] == 1.0)
    assert slot["A wide"]["Metallic"] == 0.0 and mix["Mix A"] > 0.0


@pytest.mark.parametrize("version", VERSIONS)
def test_haziness_zero_gives_the_users_values(version):
    lay = layer_graph.build(layer_graph.Config("PRINCIPLED", "MULTI_GGX", version=version))
    vals = {"Transmission Weight": 1.0, "IOR": 1.45, "Roughness": 0.3,
            "Specular Tint": (0.9, 0.8, 0.7), "Thin Film Thickness": 350.0}
    slot, mix = _slots(lay, _inputs(lay, version, **vals))
    assert mix["Mix A"] == 0.0
    assert slot["A narrow"]["IOR"] == np.float32(1.45)
    assert np.array_equal(slot["A narrow"]["Specular Tint"], np.float32((0.9, 0.8, 0.7)))


# --------------------------------------------------------------------------------------------
# Thin films: F(0) as node math, and the tint that keeps the peak
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("version", [(4, 5), (5, 3)])
def test_node_film_is_core_thin_film(version):
    g = Graph()
    f = node_thin_film.dielectric_film(g, g.input("d"), g.input("nf"), g.input("eta"),
                                       version=version)
    rng = np.random.default_rng(7)
    worst = 0.0
    for d in np.concatenate([rng.uniform(0.11, 2.0, 40), rng.uniform(2.0, 40.0, 40),
                             rng.uniform(40.0, 1500.0, 120)]):
        nf, eta = rng.uniform(1.0, 2.6), rng.uniform(1.01, 3.0)
        got = evaluate(f, {"d": np.float32(d), "nf": np.float32(nf), "eta": np.float32(eta)},
                       g.tables)
        ref = thin_film.dielectric_reflectance(eta, 0.5, 1.0, d, nf, version=version)
        worst = max(worst, float(np.abs(np.asarray(got, np.float64) - ref).max()))
    # 4.5: its Gaussian fit read from a table, linear between entries 0.034 rad of the fastest
    # cosine apart: (0.034)²/8 of the sensitivity, times Σ 2|C_m| <= 0.1
    assert worst <= (2e-5 if version < (5, 0) else 2e-6), worst


@pytest.mark.parametrize("version", [(4, 5), (5, 3)])
@pytest.mark.parametrize("transmission", [0.0, 1.0])
def test_filmed_dielectric_keeps_its_peak(version, transmission):
    """The narrow lobe's Specular Tint gives the peak Eq. 5 asks, through Cycles' film
    scaling F (1 + s (tint - 1)) (core.thin_film's model, evaluated here on the slot's values)."""
    lay = layer_graph.build(layer_graph.Config("PRINCIPLED", "GGX", version=version))
    film = dict(thickness=420.0, film_ior=1.38)
    ior, rough = 1.52, 0.25
    ins = _inputs(lay, version, **{"Transmission Weight": transmission, "IOR": ior,
                                   "Roughness": rough, "Thin Film Thickness": film["thickness"],
                                   "Thin Film IOR": film["film_ior"], "haziness": 0.3,
                                   "Base Color": (0.05, 0.05, 0.05)})
    slot, mix = _slots(lay, ins)
    f = mix["Mix A"]
    narrow, wide = slot["A narrow"], slot["A wide"]
    assert narrow["IOR"] == np.float32(ior)  # the film and the refraction see the user's IOR
    before = thin_film.dielectric_reflectance(ior, 0.5, 1.0, version=version, **film)
    n_peak = thin_film.dielectric_reflectance(ior, 0.5, narrow["Specular Tint"],
                                              version=version, **film)
    p = rough ** 4 / float(wide["Roughness"]) ** 4
    if transmission:  # the mirror: F0 = its colour
        w_peak = wide["Base Color"]
    else:
        w_peak = thin_film.dielectric_reflectance(ior, 0.5, wide["Specular Tint"],
                                                  version=version, **film)
    after = (1.0 - f) * n_peak + f * p * w_peak
    # (4.5: the film's F from the table, test_node_film_is_core_thin_film)
    rtol = 5e-5 if version < (5, 0) else 5e-6
    assert np.allclose(after, before, rtol=rtol, atol=1e-8), (after, before)


def test_colour_tables_and_new_math():
    g = Graph()
    data = np.arange(2 * 5 * 3, dtype=np.float32).reshape(2, 5, 3) / 7.0
    u, v = g.input("u"), g.input("v")
    t = g.table("rgb", data, u, v)
    for uu, vv in ((0.1, 0.25), (0.5, 0.75), (0.93, 0.6)):
        got = evaluate(t, {"u": np.float32(uu), "v": np.float32(vv)}, g.tables)
        x, y = uu * 5 - 0.5, vv * 2 - 0.5  # interp_linear, indices clamped
        i, j = int(math.floor(x)), int(math.floor(y))
        tx, ty = x - i, y - j
        ci = [min(max(k, 0), 4) for k in (i, i + 1)]
        cj = [min(max(k, 0), 1) for k in (j, j + 1)]
        ref = ((1 - ty) * ((1 - tx) * data[cj[0], ci[0]] + tx * data[cj[0], ci[1]])
               + ty * ((1 - tx) * data[cj[1], ci[0]] + tx * data[cj[1], ci[1]]))
        assert np.allclose(got, ref, atol=1e-6)
    c, e = g.math("COSINE", u), g.math("EXPONENT", v)
    got = evaluate({"c": c, "e": e}, {"u": np.float32(0.3), "v": np.float32(-2.0)})
    assert got["c"] == pytest.approx(math.cos(0.3), abs=1e-7)
    assert got["e"] == pytest.approx(math.exp(-2.0), rel=1e-6)
    with pytest.raises(ValueError):
        g.table("bad", np.zeros((2, 2, 2)), u, v)


def test_reflectivity_cap_makes_room():
    """A colour at 1 has no room for a halo; under the cap it has, and the peak is the cap's."""
    version = (5, 3)
    lay = layer_graph.build(layer_graph.Config("PRINCIPLED", "GGX", version=version))
    gold = {"Metallic": 1.0, "Base Color": (1.06, 0.77, 0.31), "Roughness": 0.3, "haziness": 0.6}
    slot, mix = _slots(lay, _inputs(lay, version, **gold))
    assert mix["Mix A"] == 0.0  # β = 0: no haze at all
    slot, mix = _slots(lay, _inputs(lay, version, reflectivity_cap=0.98, **gold))
    beta = mix["Mix A"]
    assert beta > 0.0
    p = 0.3 ** 4 / float(slot["A wide"]["Roughness"]) ** 4
    raised = slot["A narrow"]["Base Color"]
    peak = (1.0 - beta) * raised + beta * p * raised
    assert peak == pytest.approx(np.minimum((1.06, 0.77, 0.31), 0.98), rel=2e-6)
