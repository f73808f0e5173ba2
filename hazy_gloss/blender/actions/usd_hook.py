# SPDX-License-Identifier: GPL-3.0-or-later
"""What the add-on's USDHook does in Blender's own File > Export / Import > USD.

Export: Blender writes each material's UsdPreviewSurface (for a hazy material: the user's BSDF
at haziness 0, which the layer keeps beside it) and, with *MaterialX Network* on, a MaterialX
translation of the tree, in which the layer's group is node math and the haze is lost.
:func:`export_material` then puts the material's exact network on it (the one Export Hazy
Gloss USD writes: the user's BSDF copies mixed by β, interchange/layered.py) with its haze
values, in place of that translation.  It does so whether MaterialX Network is on or off: a
MaterialX network is the only place USD can hold the haze.

Import: :func:`wants` claims the Materials that hold a haze layer's network, and
:func:`import_material` builds each as the Principled BSDF (or Metallic, Glossy) with its haze
layer, as Import Hazy Gloss MaterialX does; Blender's importer reads every other material.

Blender may run the export callbacks on its export job's thread: they only read Blender data.
"""
import os

from ... import constants as K
from ...interchange import materialx_import, usd
from ..model import material_read, surface_build
from . import interchange, make_hazy

__all__ = ("export_material", "wants", "import_material")


def export_material(stage, material, usd_material, export_texture=None):
    """Put ``material``'s haze on the ``usd_material`` Blender exported.  ``export_texture``:
    the hook context's (a Blender image -> the asset path Blender writes for it).  Returns
    the notes of what the network does not hold, or None when the material is not hazy;
    ValueError (one line) when its haze cannot be written."""
    mat = getattr(material, "original", None) or material  # (the hook gets the evaluated copy)
    if not (material_read.is_hazy(mat) or K.MAPS_STAMP in mat):
        return None
    src, why = interchange.source_of(mat)
    if src is None:
        raise ValueError(why)
    path = stage.GetRootLayer().realPath
    directory = os.path.dirname(path)
    if export_texture is not None and src.layer is not None:
        _point_at_exported(src.layer, export_texture, directory)
    interchange.write_tables([src], path)
    return usd.author(stage, usd_material.GetPath(), src, directory)


def _point_at_exported(snapshot, export_texture, directory):
    """The snapshot's images with a file read from where Blender's export put them (Export
    Textures on: its textures folder), so that the network and the preview share them."""
    import bpy
    for b in snapshot.nodes.values():
        img = getattr(b, "image", None)
        if not img or not img.get("path"):
            continue
        image = bpy.data.images.get(str(img.get("name", "")))
        if image is None:
            continue
        try:
            asset = export_texture(image)
        except (RuntimeError, ValueError, TypeError):
            continue
        if asset:
            file = os.path.normpath(os.path.join(directory, asset))
            if os.path.isfile(file):
                img["path"] = file


def wants(usd_material):
    """True for a Material that holds a haze layer's network."""
    return usd.is_layered(usd_material)


def import_material(stage, material, usd_material):
    """Build the Blender ``material`` Blender's importer made for ``usd_material`` (empty) as
    its BSDF with the haze layer.  Returns the notes; ValueError (one line) when it cannot."""
    doc, _ = usd.read_document(stage, only=usd_material.GetPath())
    found = materialx_import.recognise(doc)
    if not found or found[0].surface is None:
        raise ValueError(f"{usd_material.GetPath()} holds no surface this add-on can build")
    im = found[0]
    named = usd_material.GetPrim().GetAttribute("userProperties:blender:data_name")
    name = (named.Get() if named else None) or im.name  # (as Blender's own reader names it)
    if name and material.name != name:
        material.name = name
    surface_build.build(im, apply_haze=make_hazy.apply_imported_haze, into=material)
    material[interchange.IMPORT_STAMP] = {
        "file": stage.GetRootLayer().realPath, "exact": int(bool(im.exact)),
        "source": im.source, "notes": "\n".join(im.notes)}
    return im.notes
