# SPDX-License-Identifier: GPL-3.0-or-later
"""Blender materials from interchange.surfaces.SurfaceSpec (what the MaterialX importer reads
from a library surface or a layered document): the BSDF node with its values, the node
network feeding it (Image Texture, Math, Vector Math, Mix, Mapping, UV Map, Normal Map,
Tangent), and the haze layer through the public API (api.make_hazy).  Only built-in nodes."""
import os

import bpy

from ...conversion.imagecheck import ImageFileError, check_image_file
from ...interchange import materialx_import, surfaces
from .. import compat

__all__ = ("build",)

_OUTPUT = "ShaderNodeOutputMaterial"
#: sockets a Blender version may lack; a non-default value there is noted
_DEFAULT_OF_OPTIONAL = {"Thin Wall": 0.0, "Transmission Dispersion Scale": 0.0,
                        "Transmission Dispersion Abbe Number": 20.0, "Diffuse Roughness": 0.0,
                        "Thin Film Thickness": 0.0, "Thin Film IOR": 1.33}


def _socket(sockets, key):
    for s in sockets:
        if s.identifier == key:
            return s
    for s in sockets:
        if s.name == key and getattr(s, "enabled", True):
            return s
    return sockets.get(key) if hasattr(sockets, "get") else None


def _set_value(sock, value):
    dv = sock.default_value
    if hasattr(dv, "__len__"):
        vals = list(value) if isinstance(value, (tuple, list)) else [float(value)] * 3
        n = len(dv)
        vals = (vals + [1.0] * n)[:n] if n == 4 else (vals + [0.0] * n)[:n]
        sock.default_value = vals
    elif isinstance(dv, bool):
        sock.default_value = bool(value >= 0.5 if isinstance(value, float) else value)
    else:
        v = value if not isinstance(value, (tuple, list)) else sum(value[:3]) / 3.0
        sock.default_value = type(dv)(v)


def _damage(path):
    """Why Blender must not load ``path`` (conversion.imagecheck: damaged, not an image), or
    None when it passes the check; a missing file is None too (the caller tells)."""
    try:
        check_image_file(path)
    except FileNotFoundError:
        return None
    except (ImageFileError, OSError) as exc:
        return str(exc)
    return None


def _placeholder(name, path):
    """An image that points at ``path`` without loading it (it loads when a good file is there)."""
    img = bpy.data.images.new(name, 1, 1)
    img.source = "FILE"
    img.filepath = path
    return img


def _image(info, notes):
    """The Image datablock of a file (loaded once per file and colour space); a missing file,
    or one the image check refuses (Blender's loaders are not safe on damaged files), gets an
    image that points at the path (it loads when a good file appears), and a note."""
    path = info["path"]
    cs = info.get("colorspace") or "sRGB"
    for img in bpy.data.images:
        if img.get("hazy_gloss_import_path") == path and img.colorspace_settings.name == cs:
            return img
    udim = bool(info.get("udim"))
    name = os.path.basename(path)
    damage = None if udim or not os.path.isfile(path) else _damage(path)
    if udim:
        img = _udim_image(path, name, notes)
    elif not os.path.isfile(path):
        img = _placeholder(name, path)
        notes.append(f"texture {path} not found: the Image Texture points at it")
    elif damage is not None:
        img = _placeholder(name, path)
        notes.append(f"texture not loaded: {damage}: the Image Texture points at it")
    else:
        img = bpy.data.images.load(path, check_existing=False)
    img["hazy_gloss_import_path"] = path
    try:
        img.colorspace_settings.name = cs
    except TypeError:
        notes.append(f"colour space {cs!r} is not in this Blender's configuration: {img.colorspace_settings.name}")
    return img


def _udim_image(path, name, notes):
    """A tiled image of the files a ``<UDIM>`` path names (each existing tile added, as
    Blender's USD importer does; a tile the image check refuses is left out, with a note)."""
    import re
    folder, pattern = os.path.split(path)
    rx = re.compile("^" + re.escape(pattern).replace(re.escape("<UDIM>"), r"(1\d{3})") + "$")
    found = sorted(int(m.group(1)) for f in (os.listdir(folder) if os.path.isdir(folder) else ())
                   for m in [rx.match(f)] if m)
    tiles = []
    for t in found:
        damage = _damage(path.replace("<UDIM>", str(t)))
        if damage is None:
            tiles.append(t)
        else:
            notes.append(f"tile {t} not loaded: {damage}")
    if not tiles:
        notes.append(f"no {'readable ' if found else ''}tile of {path} found: the Image "
                     "Texture points at it")
    first = tiles[0] if tiles else 1001
    img = bpy.data.images.load(path.replace("<UDIM>", str(first)), check_existing=False) if tiles \
        else bpy.data.images.new(name, 1, 1)
    img.source = "TILED"
    img.filepath = path
    if tiles and img.tiles:
        img.tiles[0].number = first
    for t in tiles[1:]:
        img.tiles.new(tile_number=t)
    if tiles:
        img.reload()
        for tile in [t for t in img.tiles if t.number not in tiles]:  # Blender finds them too
            img.tiles.remove(tile)
    return img


def build(im, notes=None, apply_haze=None, into=None):
    """A new material from ``im.surface`` (or the empty material ``into``: Blender's USD
    importer makes it); returns it.  Notes (what this Blender cannot hold) go to ``im.notes``.
    ``apply_haze(material, bsdf node, keywords)`` makes its haze layer (the public
    api.make_hazy, passed in by api.import_materialx: this module does not import the API,
    which imports it)."""
    spec = im.surface
    notes = im.notes if notes is None else notes
    haze = materialx_import.resolve_haze(spec)  # first: it sets the user's F(0) the layer raises
    mat = compat.new_material(im.name) if into is None else into
    if mat.node_tree is None:  # (4.5 hands the USD hook a material without one)
        mat.use_nodes = True
    tree = mat.node_tree
    for n in list(tree.nodes):
        tree.nodes.remove(n)
    out = tree.nodes.new(_OUTPUT)
    out.location = (400, 300)
    bsdf = tree.nodes.new(spec.bsdf)
    bsdf.location = (100, 300)
    for key, value in spec.props.items():
        if hasattr(bsdf, key):
            try:
                setattr(bsdf, key, value)
            except TypeError:
                notes.append(f"{key} {value!r} is not available in Blender {bpy.app.version_string}")
    made = {}
    for i, (key, tn) in enumerate(spec.nodes.items()):
        n = tree.nodes.new(tn.bl_idname)
        n.location = (-300 - 220 * (i % 4), 300 - 260 * (i // 4))
        if tn.label:
            n.label = tn.label
        for prop, value in tn.props.items():
            try:
                setattr(n, prop, value)
            except (AttributeError, TypeError):
                pass
        if tn.image is not None:
            n.image = _image(tn.image, notes)
        made[key] = n
    for key, tn in spec.nodes.items():
        _connect(tree, made[key], tn.inputs, made, notes)
    _connect(tree, bsdf, spec.inputs, made, notes, optional=True)
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    out.is_active_output = True
    if haze and (float(haze.get("haziness", 0.0)) > 0.0 or float(haze.get("coat_haziness", 0.0)) > 0.0):
        if apply_haze is None:
            notes.append(f"the haze layer ({haze}) was not made: import through api.import_materialx")
        else:
            try:
                apply_haze(mat, bsdf, haze)
            except ValueError as exc:
                notes.append(f"the haze layer was not made: {exc}")
    return mat


def _connect(tree, node, inputs, made, notes, optional=False):
    for key, value in inputs.items():
        sock = _socket(node.inputs, key)
        if sock is None:
            if optional and not isinstance(value, surfaces.Link) and value == _DEFAULT_OF_OPTIONAL.get(key, value):
                continue
            notes.append(f"{key}: this Blender's {node.bl_label} has no such input (not imported)")
            continue
        if isinstance(value, surfaces.Link):
            src = made.get(value.node)
            out = _socket(src.outputs, value.output) if src is not None else None
            if out is not None:
                tree.links.new(out, sock)
            continue
        try:
            _set_value(sock, value)
        except (TypeError, ValueError, AttributeError) as exc:
            notes.append(f"{key}: {exc}")
