# SPDX-License-Identifier: GPL-3.0-or-later
"""The panel's plots (haze intensity, BRDF slice) as previews and as float images.

Drawn with numpy (``utils.plots``) into previews of a ``bpy.utils.previews`` collection and
shown with ``layout.template_icon``.  Measured in 4.5 and 5.x (background mode): a collection
preview takes exact pixels through ``image_pixels_float`` (stored 8-bit), also from ``draw()``
since it is not ID data; an image data-block's ``preview`` is generated asynchronously by the UI
(size 0 in background mode, not settable) and writing an image in ``draw()`` is forbidden, so it
is not used for the panel.  ``hazy_gloss.plot_to_image`` writes full-resolution float copies into
hidden image data-blocks (zero users: not saved).  Plots are recomputed only when the parameters
or the plot settings change.
"""
from collections import OrderedDict

import bpy
import bpy.utils.previews
import numpy as np

from ...utils import plots as plotlib
from ..model import material
from . import properties

__all__ = ("PLOT_SIZE", "IMAGE_NAMES", "compute_plots", "plot_icon", "plot_image", "open_previews",
           "close_previews")

_previews = {"collection": None}
_plot_cache = OrderedDict()  # (which, material) -> (key, preview name)
_PLOT_CACHE_SIZE = 16
PLOT_SIZE = 160

IMAGE_NAMES = {"haze": ".Hazy Gloss · haze intensity", "brdf": ".Hazy Gloss · BRDF slice"}


# --------------------------------------------------------------------------------------------
# Plots
# --------------------------------------------------------------------------------------------


def _plot_key(p, prefs, size):
    return (repr(sorted(p.items())), bool(prefs.plot_log_scale), float(prefs.plot_incidence), size)


def compute_plots(mat, prefs, size=PLOT_SIZE, which=("haze", "brdf")):
    """{"haze": rgba, "brdf": rgba} for the material's stamped parameters (display values)."""
    p = properties.parameters(mat)
    m = material.map_parameters(p)
    out = {}
    if "haze" in which:
        out["haze"] = plotlib.haze_plot(float(np.max(p["core_reflectivity"])), float(m.peak_ratio),
                                        p["haziness"], p["smoothness"], size=(size, size))
    if "brdf" in which:
        out["brdf"] = plotlib.brdf_plot(m, p["kind"], theta_i=float(prefs.plot_incidence),
                                        size=(size, size), log=bool(prefs.plot_log_scale))
    return out


def plot_icon(mat, which, prefs, size=PLOT_SIZE):
    """icon_id of an up-to-date preview of plot ``which`` ("haze" / "brdf") for ``mat``."""
    pcoll = _previews["collection"]
    if pcoll is None:
        return 0
    p = properties.parameters(mat)
    key = _plot_key(p, prefs, size)
    slot = (which, mat.name_full)
    cached = _plot_cache.get(slot)
    if cached is not None and cached[0] == key and cached[1] in pcoll:
        _plot_cache.move_to_end(slot)
        return pcoll[cached[1]].icon_id
    name = f"{which}:{mat.name_full}"
    preview = pcoll[name] if name in pcoll else pcoll.new(name)
    try:
        rgba = compute_plots(mat, prefs, size, which=(which,))[which]
    except ValueError:
        return 0
    preview.image_size = (size, size)
    preview.image_pixels_float.foreach_set(np.ascontiguousarray(rgba, dtype=np.float32).ravel())
    _plot_cache[slot] = (key, name)
    _plot_cache.move_to_end(slot)
    while len(_plot_cache) > _PLOT_CACHE_SIZE:
        _, (_, old) = _plot_cache.popitem(last=False)
        if old in pcoll:
            del pcoll[old]
    return preview.icon_id


def plot_image(which, rgba):
    """Write ``rgba`` (display values) into the hidden float image for ``which``; zero users,
    no fake user, so it is never saved."""
    name = IMAGE_NAMES[which]
    h, w = rgba.shape[:2]
    img = bpy.data.images.get(name)
    if img is not None and (tuple(img.size) != (w, h) or img.library is not None):
        bpy.data.images.remove(img)
        img = None
    if img is None:
        img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
    img.use_fake_user = False
    linear = plotlib.srgb_to_linear(rgba)
    img.pixels.foreach_set(np.ascontiguousarray(linear, dtype=np.float32).ravel())
    img.update()
    return img


def open_previews():
    _previews["collection"] = bpy.utils.previews.new()
    _plot_cache.clear()


def close_previews():
    pcoll = _previews["collection"]
    _previews["collection"] = None
    _plot_cache.clear()
    if pcoll is not None:
        bpy.utils.previews.remove(pcoll)
