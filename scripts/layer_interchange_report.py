# SPDX-License-Identifier: GPL-3.0-or-later
"""Measure how MaterialX's OpenPBR 1.1.1 draws the haze layers of the looks, against Cycles'
Principled BSDF (docs/interchange.md §5), bpy-free:

    .venv/bin/python scripts/layer_interchange_report.py          # rewrites the marked block
    .venv/bin/python scripts/layer_interchange_report.py --print  # prints it instead

For every part of every look (hazy_gloss/utils/looks.py: the dielectric or metal base, the coat)
the layer's constants as blender/model/layer.py maps them (tests/pure/openpbr_measure.layer_part), then:

- the Fresnel gap: where the exact dielectric Fresnel of the raised η dips below F0, Cycles'
  Principled keeps F0 (max(F_η, F0)) and MaterialX's dielectric_bsdf does not;
- the specular error of that alone (both lobes, β, single scattering; brdf.compare: max = worst
  |Δ| over the view's maximum, mean = relative L1, 13 views);
- the peak drift in MaterialX's reference shaders: they compensate every GGX lobe's energy by
  1 + F (1-E)/E, the layer keeps the peak for Cycles (no compensation under GGX, Cycles' own under
  Multiscatter GGX); hazy / haze-free peak - 1;
- the base darkening OpenPBR would apply under the coat with coat_darkening 1 (the export
  writes 0: Cycles darkens the base by the coat's albedo only).
"""
import argparse
import os
import platform
import re
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "tests", "pure"))  # openpbr_measure (not shipped)

import openpbr_measure as measure  # noqa: E402
from hazy_gloss.utils.looks import LOOKS  # noqa: E402

DOC = os.path.join(ROOT, "docs", "interchange.md")
MARK = "layer-differences"
#: stronger dielectric haze than the looks' (the paper keeps dielectrics at 0-0.1)
EXTRA = (("Plastic, haziness 0.3", dict(ior=1.5, roughness=0.3, haziness=0.3, haze_extent=5.0)),
         ("Plastic, haziness 0.6", dict(ior=1.5, roughness=0.3, haziness=0.6, haze_extent=5.0)))


def _f0(eta):
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def _eta(f0):
    s = np.sqrt(f0)
    return (1.0 + s) / (1.0 - s)


def rows(distribution):
    out = []
    for look in LOOKS.values():
        p = look.principled
        h = dict(look.haze)
        rough = float(p.get("Roughness", 0.5))
        extent = h.get("haze_extent", 5.0)
        ext = float(extent[0]) if hasattr(extent, "__len__") else float(extent)
        if h.get("haziness", 0.0) > 0.0:
            if p.get("Metallic", 0.0) >= 1.0:
                base = p.get("Base Color", (0.8, 0.8, 0.8, 1.0))[:3]
                tint = p.get("Specular Tint", (1.0, 1.0, 1.0, 1.0))[:3]
                part = measure.layer_part(base, rough, h["haziness"], ext, distribution, lobe="F82_TINT",
                                    tint=tint)
                out.append((look.name, "metal (F82-tint: the same model)", f"r = {max(part['r']):.3f}",
                            "—", "0 / 0", measure.materialx_peak_drift(part), "—"))
            else:
                part = measure.hazy_dielectric(float(p.get("IOR", 1.5)), roughness=rough,
                                         haziness=h["haziness"], haze_extent=ext, distribution=distribution)
                e = measure.specular_error(part)
                out.append((look.name, "dielectric", f"η' = {part['eta']:.3f}",
                            f"{measure.fresnel_gap(part['eta']):.3f}", f"{e['max']:.3f} / {e['mean']:.4f}",
                            measure.materialx_peak_drift(part), "—"))
        if h.get("coat_haziness", 0.0) > 0.0 and p.get("Coat Weight", 0.0) > 0.0:
            ci = float(p.get("Coat IOR", 1.5))
            cext = float(h.get("coat_haze_extent", 5.0))
            part = measure.layer_part(_f0(ci), float(p.get("Coat Roughness", 0.03)), h["coat_haziness"],
                                cext, "MULTI_GGX", lobe="COAT")  # the coat is always compensated
            eta_c = float(_eta(max(part["r"])))
            albedo = np.asarray(p.get("Base Color", (0.8, 0.8, 0.8, 1.0))[:3], float)
            dark = measure.coat_darkening_factor(albedo, eta_c)
            out.append((look.name, "coat", f"η_c' = {eta_c:.3f} (user {ci:g})",
                        "— (exact in both)", "0 / 0", measure.materialx_peak_drift(part),
                        ", ".join(f"{x:.3f}" for x in dark)))
    for name, kw in EXTRA:
        part = measure.hazy_dielectric(distribution=distribution, **kw)
        e = measure.specular_error(part)
        out.append((name, "dielectric", f"η' = {part['eta']:.3f}", f"{measure.fresnel_gap(part['eta']):.3f}",
                    f"{e['max']:.3f} / {e['mean']:.4f}", measure.materialx_peak_drift(part), "—"))
    return out


def block():
    t0 = time.time()
    lines = ["| look | part | written | Fresnel gap | specular error (Fresnel) max / mean | "
             "MaterialX peak drift, Multiscatter GGX (GGX) | OpenPBR coat darkening if on |",
             "|---|---|---|---:|---:|---:|---:|"]
    ms, gx = rows("MULTI_GGX"), rows("GGX")
    for a, b in zip(ms, gx):
        lines.append(f"| {a[0]} | {a[1]} | {a[2]} | {a[3]} | {a[4]} | {a[5]:+.4f} ({b[5]:+.4f}) | {a[6]} |")
    lines.append("")
    lines.append(f"_Measured by `scripts/layer_interchange_report.py` in {time.time() - t0:.0f} s on "
                 f"{platform.machine()} / Python {platform.python_version()} / numpy {np.__version__}._")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--print", action="store_true", help="print instead of rewriting the docs")
    args = ap.parse_args(argv)
    text = block()
    if args.print:
        print(text)
        return 0
    doc = open(DOC, encoding="utf-8").read()
    rx = re.compile(rf"(<!-- {MARK} -->\n).*?(\n<!-- /{MARK} -->)", re.S)
    if not rx.search(doc):
        raise SystemExit(f"docs/interchange.md has no <!-- {MARK} --> block")
    doc = rx.sub(lambda m: m.group(1) + text + m.group(2), doc)
    with open(DOC, "w", encoding="utf-8") as f:
        f.write(doc)
    print(f"rewrote the {MARK} block of {DOC}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
