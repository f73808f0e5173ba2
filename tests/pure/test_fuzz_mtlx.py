# SPDX-License-Identifier: GPL-3.0-or-later
"""Fuzz of the add-on's MaterialX reader (interchange.materialx.read, behind api.import_materialx
and the File > Import operator): mutations of one of our own documents.

Outcomes allowed: the materials (each recognised, or not with its reasons; every returned
parameter finite), or one ValueError line naming the file.  Never another exception, never more
than CASE_WORK operations (work_bound.Counter: Python calls and loop iterations, the same on
every machine; the seconds are benchmarks/time_limits.py's).  Counts go to
out/measurements/fuzz_mtlx.json (docs/verification.md)."""
import collections
import json
import math
import random
import re
from pathlib import Path

import pytest

from hazy_gloss.interchange import materialx as M
from test_interchange import _sources
from work_bound import Counter, WorkLimit

OUT = Path(__file__).resolve().parents[2] / "out" / "measurements"
#: operations one document may take: the most any case takes is about 7600 (a damaged value,
#: read to the end of the file); 25 times that is a reader gone quadratic or round in circles
CASE_WORK = 200_000
VALUES = ("nan", "inf", "-inf", "1e999", "-1", "", "a", "1,2", "0,0,0,0,0", "1e-45", "-0",
          "1e38,1e38,1e38", "x" * 5000)
TYPES = ("float", "color3", "vector3", "BSDF", "string", "integer", "bogus")
BILLION_LAUGHS = ('<?xml version="1.0"?><!DOCTYPE l [<!ENTITY a "lol">'
                  + "".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">'
                            for i in range(8))
                  + ']><materialx version="1.39">&i;</materialx>')


def mutations(text, seed=1):
    """(attack, document text), deterministic."""
    rng = random.Random(seed)
    n = len(text)
    for cut in range(0, n, max(1, n // 300)):
        yield "truncation", text[:cut]
    for m in re.finditer(r'value="([^"]*)"', text):
        for v in VALUES:
            yield "input values (NaN, inf, overflow, wrong count, garbage)", \
                text[:m.start(1)] + v + text[m.end(1):]
    for m in re.finditer(r'(nodename|output|interfacename|nodegraph)="([^"]*)"', text):
        for v in ("", "nope", m.group(2)):
            yield "connections (dangling, empty)", text[:m.start(2)] + v + text[m.end(2):]
    for m in re.finditer(r'type="([^"]*)"', text):
        for v in TYPES:
            yield "types", text[:m.start(1)] + v + text[m.end(1):]
    lines = text.splitlines(True)
    for i in range(len(lines)):
        yield "a line deleted", "".join(lines[:i] + lines[i + 1:])
        yield "a line doubled", "".join(lines[:i] + [lines[i]] + lines[i:])
    for m in re.finditer(r'<\w+ name="([^"]+)" type="[^"]*"', text):
        yield "cycles (nodes reading themselves)", \
            re.sub(r'nodename="[^"]*"', f'nodename="{m.group(1)}"', text, count=3)
    data = text.encode()
    for _ in range(400):
        b = bytearray(data)
        for _ in range(8):
            b[rng.randrange(len(b))] = rng.randrange(256)
        yield "byte flips", b.decode("utf-8", "replace")
    yield "entity expansion (billion laughs)", BILLION_LAUGHS


def _finite(im):
    for v in (im.parameters or {}).values():
        for x in (v if isinstance(v, (tuple, list)) else (v,)):
            if isinstance(x, float) and not math.isfinite(x):
                return False
    return True


def _run(cases, path, finite):
    """Read every (attack, document) under the per-case work bound: (Counter of (attack,
    outcome), failures, the most operations a case took).  Outcomes allowed: "read" (every
    returned value ``finite``), "read, a damaged material said", "ValueError" (one line naming
    the file)."""
    counts, failures, most = collections.Counter(), [], 0
    with Counter() as work:
        for attack, doc in cases:
            Path(path).write_text(doc)
            try:
                got = work.run(M.read, path, limit=CASE_WORK)
                outcome = "read" if all(finite(im) for im in got) else "non-finite values"
                if outcome == "read" and any(any(n.startswith("damaged") for n in im.notes)
                                             for im in got):
                    outcome = "read, a damaged material said"
            except ValueError as exc:
                outcome = "ValueError"
                if "\n" in str(exc) or path not in str(exc):
                    failures.append(f"{attack}: not one line naming the file: {str(exc)[:200]!r}")
            except WorkLimit:
                outcome = "hang"
            except Exception as exc:  # noqa: BLE001  (what the fuzz looks for)
                outcome = type(exc).__name__
            most = max(most, work.count)
            counts[(attack, outcome)] += 1
            if outcome not in ("read", "read, a damaged material said", "ValueError"):
                failures.append(f"{attack}: {outcome}")
    return counts, failures, most


def test_the_work_bound_stops_a_reader_that_never_ends(tmp_path, monkeypatch):
    """The bound can fail: a reader that loops (calling Python code in its loop, or not) is a
    "hang"."""
    def loops(path):
        i = 0
        while i >= 0:
            i += 1

    def step(i):
        return i + 1

    def loops_calling(path):
        i = 0
        while i >= 0:
            i = step(i)

    import sys
    for reader in (loops, loops_calling) if sys.version_info >= (3, 12) else (loops_calling,):
        monkeypatch.setattr(M, "read", reader)
        counts, failures, most = _run([("a reader that never ends", "<materialx/>")],
                                      str(tmp_path / "case.mtlx"), _finite)
        assert failures == ["a reader that never ends: hang"], failures
        assert most == CASE_WORK + 1


def test_fuzz_materialx_reader(tmp_path):
    base = M.write(_sources(), tmp_path / "base.mtlx", validate_with_package=False).path
    text = Path(base).read_text()
    path = str(tmp_path / "case.mtlx")
    counts, failures, most = _run(mutations(text), path, _finite)
    table = {}
    for (attack, outcome), k in sorted(counts.items()):
        table.setdefault(attack, {})[outcome] = k
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "fuzz_mtlx.json").write_text(json.dumps(
        {"cases": sum(counts.values()), "most_work": most, "work_unit": Counter().unit,
         "by_attack": table}, indent=1))
    assert not failures, failures[:10]
    assert sum(counts.values()) > 4000
    assert counts[("truncation", "ValueError")] >= 290  # every cut but the whole file


@pytest.mark.parametrize("doc, words", [
    ("<materialx", "not a well-formed XML file"),
    ("<notmaterialx/>", "not a MaterialX document"),
    ('<materialx><surfacematerial name="m" type="material"><input name="surfaceshader" '
     'type="surfaceshader" value="1,2"/></surfacematerial></materialx>', None),
])
def test_bad_documents_get_one_line(tmp_path, doc, words):
    path = tmp_path / "bad.mtlx"
    path.write_text(doc)
    if words is None:  # a material whose surface is no shader: read, and said
        (im,) = M.read(path)
        assert im.parameters is None and im.notes
        return
    with pytest.raises(ValueError, match=words) as info:
        M.read(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)


def test_a_damaged_value_is_said_and_the_rest_read(tmp_path):
    """A value MaterialX refuses (a colour with two numbers) no longer aborts the file (it did:
    one ValueError for the whole document): the input takes its nodedef default, the material
    says so, the next material is read."""
    path = tmp_path / "bad.mtlx"
    path.write_text(
        '<materialx version="1.39"><open_pbr_surface name="s" type="surfaceshader">'
        '<input name="base_color" type="color3" value="1, 2"/></open_pbr_surface>'
        '<surfacematerial name="m" type="material"><input name="surfaceshader" type="surfaceshader" '
        'nodename="s"/></surfacematerial><open_pbr_surface name="t" type="surfaceshader"/>'
        '<surfacematerial name="n" type="material"><input name="surfaceshader" type="surfaceshader" '
        'nodename="t"/></surfacematerial></materialx>')
    m, n = M.read(path)
    assert m.surface.inputs["Base Color"] == (0.8, 0.8, 0.8) and "is not 3 numbers" in " ".join(m.notes)
    assert n.ok and n.exact


def _surface_finite(im):
    s = im.surface
    if s is None:
        return True
    vals = list(s.inputs.values()) + [v for n in s.nodes.values() for v in n.inputs.values()]
    for v in vals:
        for x in (v if isinstance(v, tuple) else (v,)):
            if isinstance(x, float) and not (math.isfinite(x) and abs(x) <= 3.4028234663852886e38):
                return False
    return True


def test_fuzz_library_surfaces(tmp_path):
    """The same mutations of documents of library surfaces (textures, node graphs, 1.38
    swizzles, UsdPreviewSurface readers): read (every value a float32 socket holds) or one
    ValueError line, never another exception or a hang.  Every other mutation of two fixtures,
    to keep it short."""
    fixtures = Path(__file__).resolve().parent / "mtlx_fixtures"
    path = str(tmp_path / "case.mtlx")
    cases = [(attack, doc) for name in ("gltf_orm_138.mtlx", "usd_preview_138.mtlx")
             for attack, doc in mutations((fixtures / name).read_text(), seed=3)]
    counts, failures, _ = _run(cases[::2], path, _surface_finite)
    assert not failures, failures[:10]
    assert sum(counts.values()) > 1000
    assert counts[("input values (NaN, inf, overflow, wrong count, garbage)", "read")] > 100
