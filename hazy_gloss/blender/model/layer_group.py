# SPDX-License-Identifier: GPL-3.0-or-later
"""The haze layer's node group: one per configuration (BSDF type, distribution, subsurface
method or Fresnel type, haze curve, Blender version), shared by every material that has it.

Its interface is the wrapped BSDF's own inputs — names, types, limits, defaults and panels as
Blender declares them (core.tables.bsdf_interfaces, read through Make Group) — and a Haze panel
(schema.HAZE_SOCKETS).  Its inside is core.layer_graph emitted as built-in nodes: the haze
mapping in frames, then the BSDF slots (copies of the wrapped node type whose inputs are the
group's own, except those the mapping computes) and their Mix Shaders.  Two outputs: "BSDF"
(the layer) and "EEVEE" (each layer's lobes folded into one, for the EEVEE-only output).
"""
from __future__ import annotations

import hashlib
import re
import sys

import bpy

from ... import constants as K
from ...core import (body_colour, graph, layer_graph, multiscatter, node_body_colour, node_fresnel,
                     node_math, node_multiscatter, node_thin_film, thin_film)
from ...core.multiscatter import cycles_version
from ...core import tables
from ...core.tables import bsdf_interfaces, cycles_albedo_tables
from ... import schema
from . import groups, stamp
from ..nodes import builder
from ..nodes import emit as emit_module
from ..nodes.builder import TreeBuilder, socket_value
from ..nodes.emit import emit
from .groups import rebuild_interface

#: Bumped when what a group holds changes: older groups are rebuilt in place on first use.
GROUP_VERSION = 3  # 2: films and glass keep the IOR (the tint raises F0); 3: Environment tables

BSDF_NODES = {"PRINCIPLED": "ShaderNodeBsdfPrincipled", "METALLIC": "ShaderNodeBsdfMetallic",
              "GLOSSY": "ShaderNodeBsdfGlossy"}
#: Node settings a configuration fixes (the group node has no enum properties).
NODE_SETTINGS = {"PRINCIPLED": ("distribution", "subsurface_method"),
                 "METALLIC": ("distribution", "fresnel_type"), "GLOSSY": ("distribution",)}
_LABEL = {"PRINCIPLED": "Hazy Principled BSDF", "METALLIC": "Hazy Metallic BSDF",
          "GLOSSY": "Hazy Glossy BSDF"}
_SETTING_LABEL = {"RANDOM_WALK": "", "RANDOM_WALK_SKIN": "Skin", "BURLEY": "Christensen-Burley",
                  "F82": "F82", "PHYSICAL_CONDUCTOR": "Physical"}


def version_tag(version=None):
    v = cycles_version(version)
    return f"{v[0]}.{v[1]}"


def settings_of(node):
    """{setting: value} of a BSDF node (what a configuration fixes)."""
    kind = kind_of(node)
    settings = {p: getattr(node, p) for p in NODE_SETTINGS[kind]}
    unknown = [p for p, v in settings.items() if not v]  # (an enum a newer Blender saved)
    if unknown:
        prop = node.bl_rna.properties[unknown[0]].name
        raise ValueError(f"the {prop} of “{node.name}” is one this Blender does not know (the "
                         f"file was saved by a newer Blender): pick one in the node, then try "
                         f"again")
    return settings


def kind_of(node):
    for kind, idname in BSDF_NODES.items():
        if node.bl_idname == idname or (kind == "GLOSSY" and node.bl_idname == "ShaderNodeBsdfAnisotropic"):
            return kind
    return None


def config_for(kind, settings, *, smooth=False, baked=False, body=False):
    """The layer_graph.Config of a BSDF kind and its node settings."""
    return layer_graph.Config(kind, settings.get("distribution", "GGX"),
                              fresnel=settings.get("fresnel_type", ""), smooth=bool(smooth),
                              version=cycles_version(None), baked=bool(baked), body=bool(body))


def group_name(kind, settings, smooth=False, baked=False, body=False):
    """E.g. "Hazy Principled BSDF (Multiscatter GGX, Skin, Smooth, 5.3)" (< 64 bytes; the
    version inside the brackets: Blender reads a trailing ".3" as a copy's number)."""
    parts = [K.label(K.DISTRIBUTION_TERMS, settings.get("distribution", ""))]
    for key in ("subsurface_method", "fresnel_type"):
        label = _SETTING_LABEL.get(settings.get(key), "")
        if label:
            parts.append(label)
    if smooth:
        parts.append("Smooth")
    if baked:
        parts.append("Converted")
    if body:
        parts.append("Body")
    name = f"{_LABEL[kind]} ({', '.join(parts + [version_tag()])})"
    for long, short in _SHORTER:  # Blender's ID names hold 63 bytes
        if len(name.encode()) <= 63:
            break
        name = name.replace(long, short)
    return name


_SHORTER = (("Christensen-Burley", "Burley"),
            (K.label(K.DISTRIBUTION_TERMS, "MULTI_GGX"), "MS GGX"),
            (K.label(K.DISTRIBUTION_TERMS, "ASHIKHMIN_SHIRLEY"), "AS"), (" BSDF (", " ("))


def _stamp_of(kind, settings, smooth, baked=False, body=False):
    d = {"kind": "layer", "version": GROUP_VERSION, "bsdf": kind, "settings": dict(settings),
         "smooth": int(bool(smooth)), "blender": version_tag()}
    if baked:
        d["baked"] = 1
    if body:
        d["body"] = 1
    return d


def fits(ng, kind, settings, smooth, baked=False, body=False, linked_ok=False):
    """Whether ``ng`` is this Blender's and add-on's group of the configuration (a linked group
    is read-only here, so it does not fit a local layer unless ``linked_ok``)."""
    if ng is None or (ng.library is not None and not linked_ok):
        return False
    return (stamp.group(ng, K.GROUP_STAMP) or {}) == _stamp_of(kind, settings, smooth, baked, body)


def is_layer_group(ng):
    return ng is not None and (stamp.group(ng, K.GROUP_STAMP) or {}).get("kind") == "layer"


def ensure_group(kind, settings, smooth=False, baked=False, body=False):
    """The group of this configuration: found by its stamp (a renamed group is taken), else
    appended from the groups the extension ships or the per-user cache, else built (and
    cached); an outdated group of the same name is rebuilt in place (its users keep their links
    and values)."""
    config = (kind, settings, smooth, baked, body)
    name = group_name(*config)
    ng = bpy.data.node_groups.get(name)
    if fits(ng, *config):
        return ng
    found = next((g for g in bpy.data.node_groups if fits(g, *config)), None)
    if found is not None:
        return found
    stale = ng is not None and ng.library is None and is_layer_group(ng)
    if not stale:
        cached = _from_cache(name, config)
        if cached is not None:
            return _unedited(cached)
    if not stale:
        ng = bpy.data.node_groups.new(name, "ShaderNodeTree")
    before = set(bpy.data.node_groups), set(bpy.data.images)
    try:
        build(ng, *config)
    except Exception as exc:  # (nothing half-built stays in the file)
        bpy.data.batch_remove([i for c, old in zip((bpy.data.node_groups, bpy.data.images), before)
                               for i in c if i not in old] + ([] if stale else [ng]))
        raise ValueError(f"building the layer group “{name}” failed: {exc}") from exc
    ng[K.GROUP_STAMP] = _stamp_of(*config)
    _keep_one_copy(ng, *before)
    _to_cache(ng)
    return _unedited(ng)


# --------------------------------------------------------------------------------------------
# The per-user cache: building a group takes seconds (every node edit in Blender updates the
# whole tree), appending it from a .blend tens of milliseconds
# --------------------------------------------------------------------------------------------

#: The modules whose code builds the groups: their files are hashed (a module object, not a path,
#: so a moved or renamed module cannot drop out of the hash unnoticed), and so are the data
#: tables they read (core/tables/*.json).
_SOURCES = (sys.modules[__name__], emit_module, builder, groups, layer_graph, node_math,
            node_fresnel, node_multiscatter, node_body_colour, body_colour, node_thin_film,
            thin_film, cycles_albedo_tables, graph, bsdf_interfaces, multiscatter, K, schema)
_digest = []

#: Where the built extension keeps the layer groups it ships, under the package (beside
#: assets/, not in it: the asset library holds assets only).
SHIPPED_DIR = ("layer_groups",)
#: The configurations shipped (built by each Blender scripts/build.py finds): each BSDF's
#: default settings and the other distribution an artist picks most.
SHIPPED = (
    ("PRINCIPLED", {"distribution": "MULTI_GGX", "subsurface_method": "RANDOM_WALK"}),
    ("PRINCIPLED", {"distribution": "GGX", "subsurface_method": "RANDOM_WALK"}),
    ("METALLIC", {"distribution": "MULTI_GGX", "fresnel_type": "F82"}),
    ("METALLIC", {"distribution": "GGX", "fresnel_type": "F82"}),
    ("METALLIC", {"distribution": "MULTI_GGX", "fresnel_type": "PHYSICAL_CONDUCTOR"}),
    ("METALLIC", {"distribution": "GGX", "fresnel_type": "PHYSICAL_CONDUCTOR"}),
    ("GLOSSY", {"distribution": "MULTI_GGX"}),
    ("GLOSSY", {"distribution": "GGX"}),
)


def _code_digest():
    """A hash of the code that builds groups (a cached group from other code is not taken)."""
    if not _digest:
        h = hashlib.sha256()
        for path in [module.__file__ for module in _SOURCES] + tables.files():
            with open(path, "rb") as fh:
                h.update(fh.read())
        _digest.append(h.hexdigest()[:16])
    return _digest[0]


def _file_name(name):
    """The .blend of a group in the per-user cache and in the extension's shipped groups."""
    import re
    slug = re.sub(r"[^A-Za-z0-9.]+", "_", name).strip("_")
    return f"{_code_digest()}-{GROUP_VERSION}-{slug}.blend"


def _shipped_path(name):
    """Where the built extension ships this group (scripts/build.py: write_shipped)."""
    import os
    package_dir = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    return os.path.join(package_dir, *SHIPPED_DIR, _file_name(name))


def _cache_path(name):
    import os
    import re
    try:
        base = bpy.utils.extension_path_user(__package__.rpartition(".blender")[0],
                                             path="layer_groups", create=True)
    except (ValueError, TypeError, AttributeError, RuntimeError):
        # registered by a script (import hazy_gloss; register()): a per-user temporary folder
        import getpass
        import tempfile
        try:
            user = re.sub(r"[^A-Za-z0-9]+", "_", getpass.getuser())
        except (KeyError, OSError):
            user = "user"
        base = os.path.join(tempfile.gettempdir(), f"hazy_gloss_{user}", "layer_groups")
        try:
            os.makedirs(base, exist_ok=True)
        except OSError:
            return None
    return os.path.join(base, _file_name(name))


def _from_cache(name, config):
    """The group appended from the extension's shipped groups, else from the per-user cache;
    None when neither has it (or holds a group that does not fit)."""
    for path in (_shipped_path(name), _cache_path(name)):
        ng = _append(path, name, config)
        if ng is not None:
            return ng
    return None


def _drop_library(path):
    """The Library entry an append leaves behind (it holds nothing once the data is local)."""
    import os
    for lib in [lib for lib in bpy.data.libraries
                if os.path.normcase(os.path.abspath(bpy.path.abspath(lib.filepath)))
                == os.path.normcase(os.path.abspath(path))]:
        if not any(i.library == lib for c in (bpy.data.node_groups, bpy.data.images) for i in c):
            bpy.data.libraries.remove(lib)


def _append(path, name, config):
    import os
    if path is None or not os.path.isfile(path):
        return None
    before = set(bpy.data.node_groups), set(bpy.data.images)
    try:
        with bpy.data.libraries.load(path, link=False) as (src, dst):
            if name not in src.node_groups:
                return None
            dst.node_groups = [name]
    except (OSError, RuntimeError):
        return None
    finally:
        _drop_library(path)
    new = [g for g in bpy.data.node_groups if g not in before[0]]
    for i in new + [i for i in bpy.data.images if i not in before[1]]:
        i.use_fake_user = False  # (as built ones: dropped on save once nothing uses them)
    ng = next((g for g in new if fits(g, *config)), None)
    _keep_one_copy(ng, *before)
    return ng


def _keep_one_copy(ng, groups_before, images_before):
    """After ``ng`` was appended or built: the node groups and images that came with it give
    way to the file's where those are the same (_share_parts), and what nothing of ``ng``
    uses is removed, in one pass over the file (everything new, when ``ng`` is None)."""
    groups_before, images_before = _alive(groups_before), _alive(images_before)
    new_groups = [g for g in bpy.data.node_groups if g not in groups_before]
    new_images = [i for i in bpy.data.images if i not in images_before]
    drop = new_groups + new_images if ng is None else _share_parts(
        ng, groups_before, images_before, new_groups, new_images)
    if drop:
        bpy.data.batch_remove([i for i in drop if i is not ng])


def _alive(ids):
    """``ids`` without those removed since (a stale group's rebuild removes its old sections)."""
    out = set()
    for i in ids:
        try:
            i.name
        except ReferenceError:
            continue
        out.add(i)
    return out


def _uses(ng, out):
    """``ng`` and the node groups and images it reads, nested ones included."""
    out.add(ng)
    for node in ng.nodes:
        if node.bl_idname == "ShaderNodeGroup" and node.node_tree is not None and \
                node.node_tree not in out:
            _uses(node.node_tree, out)
        elif node.bl_idname in K.IMAGE_NODES and node.image is not None:
            out.add(node.image)
    return out


#: What Blender adds to the name of a data-block appended beside one of the same name.
COPY_SUFFIX = re.compile(r"\.\d{3,}$")


def _share_parts(ng, groups_before, images_before, new_groups, new_images):
    """Point the just appended ``ng`` at the section groups and tables the file has already
    (the same name and code, the same values) instead of the copies the append brought;
    returns the copies, now unused."""

    def originals(new, before):
        names = {i.name: i for i in before if i.library is None}  # (never a linked one)
        out = {}
        for i in new:
            base = COPY_SUFFIX.sub("", i.name)
            if base != i.name and base in names:
                out[i] = names[base]
        return out

    groups, images = originals(new_groups, groups_before), originals(new_images, images_before)
    if not groups and not images:  # (the first configuration in a file: nothing to share)
        return []
    for node in ng.nodes:
        sub = node.node_tree if node.bl_idname == "ShaderNodeGroup" else None
        if sub in groups and _same_part(sub, groups[sub]):
            node.node_tree = groups[sub]
        elif sub in new_groups and images:
            for inner in sub.nodes:
                old = images.get(inner.image) if inner.bl_idname in K.IMAGE_NODES else None
                if old is not None and _same_table(inner.image, old):
                    inner.image = old
    used = _uses(ng, set())
    return [i for i in new_groups + new_images if i not in used]


def _same_table(new, old):
    """The same table: the same hash of its values, the same packed bytes."""
    digest = new.get("hazy_gloss_table")
    return digest is not None and old.get("hazy_gloss_table") == digest and \
        new.packed_file is not None and old.packed_file is not None and \
        old.packed_file.data == new.packed_file.data


def _to_cache(ng):
    import os
    path = _cache_path(ng.name)
    if path is None:
        return
    tmp = path + f".{os.getpid()}.tmp"
    try:
        bpy.data.libraries.write(tmp, {ng}, fake_user=True, compress=True)
        os.replace(tmp, path)
    except (OSError, RuntimeError):
        try:
            os.remove(tmp)
        except OSError:
            pass


def write_shipped(out_dir, configs=None):
    """Build the ``configs`` (default SHIPPED) with this Blender and write each into
    ``out_dir`` as the cache names it (scripts/build.py puts them in the extension, so the first
    Make Hazy on a machine appends instead of building).  Returns the files written."""
    import os
    os.makedirs(out_dir, exist_ok=True)
    written = []
    for kind, settings in configs or SHIPPED:
        config = (kind, dict(settings), False, False, False)
        name = group_name(*config)
        if bpy.data.node_groups.get((name, None)) is not None:
            raise RuntimeError(f"write_shipped runs in an empty file; {name!r} is in this one")
        ng = bpy.data.node_groups.new(name, "ShaderNodeTree")
        build(ng, *config)
        ng[K.GROUP_STAMP] = _stamp_of(*config)
        path = os.path.join(out_dir, _file_name(name))
        bpy.data.libraries.write(path, {ng}, fake_user=True, compress=True)
        written.append(path)
    return written


# --------------------------------------------------------------------------------------------
# Interface
# --------------------------------------------------------------------------------------------


def _declarations(kind):
    tables = bsdf_interfaces.TABLES
    tag = version_tag()
    if tag not in tables:  # a newer Blender: its sockets, with the newest known declarations
        tag = max(tables, key=lambda t: tuple(int(x) for x in t.split(".")))
    return tables[tag][kind]


def bsdf_inputs(node):
    """The enabled inputs of a BSDF node, in order (what the group's interface mirrors)."""
    return [s for s in node.inputs if s.enabled]


def _new_socket(iface, name, decl, parent):
    stype = decl.get("type", "NodeSocketFloat")
    s = iface.new_socket(name=name, in_out="INPUT", socket_type=stype, parent=parent)
    if decl.get("subtype") and hasattr(s, "subtype"):
        try:
            s.subtype = decl["subtype"]
        except (TypeError, ValueError):
            pass
    for attr, key in (("min_value", "min_value"), ("max_value", "max_value"),
                      ("default_value", "default")):
        if key in decl and hasattr(s, attr):
            try:
                setattr(s, attr, decl[key])
            except (TypeError, ValueError):
                pass
    s.hide_value = bool(decl.get("hide_value", False))
    return s


def _interface(ng, kind, template, smooth, baked=False):
    """The wrapped BSDF's inputs (``template``: a node of that kind and configuration) in its
    panels, then the Haze panel (or, converted, the Converted Maps); outputs BSDF and EEVEE."""
    iface = ng.interface
    iface.new_socket(name="BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
    eevee = iface.new_socket(name="EEVEE", in_out="OUTPUT", socket_type="NodeSocketShader")
    eevee.description = ("Each layer's narrow and wide lobes folded into one with the same peak: "
                         "for the EEVEE-only output (Hazy Gloss panel, EEVEE setting)")
    decl = _declarations(kind)
    panels = {}
    for sock in bsdf_inputs(template):
        d = dict(decl["sockets"].get(sock.name, {}))
        if not d:  # not declared in the table: the socket's own type
            d = {"type": {"VALUE": "NodeSocketFloat", "RGBA": "NodeSocketColor",
                          "VECTOR": "NodeSocketVector", "BOOLEAN": "NodeSocketBool",
                          "INT": "NodeSocketInt"}.get(sock.type, "NodeSocketFloat"),
                 "hide_value": sock.hide_value}
        title = d.get("panel", "")
        parent = None
        if title:
            parent = panels.get(title)
            if parent is None:
                parent = panels[title] = iface.new_panel(
                    title, default_closed=decl["panels"].get(title, True))
        _new_socket(iface, sock.name, d, parent)
    if baked:
        maps = iface.new_panel("Converted Maps", default_closed=False)
        for key, (name, colour) in layer_graph.BAKED.items():
            s = iface.new_socket(name=name, in_out="INPUT", parent=maps,
                                 socket_type="NodeSocketColor" if colour else "NodeSocketFloat")
            s.description = "Written by texture conversion (the haze mapping per texel)"
        return
    haze = iface.new_panel(K.HAZE_PANEL, default_closed=False)
    for param in haze_params(kind, smooth):
        name, default, lo, hi, desc = schema.HAZE_SOCKETS[param]
        s = iface.new_socket(name=name, in_out="INPUT", socket_type="NodeSocketFloat", parent=haze)
        if _SOCKET_PARAMETER[param].factor and hasattr(s, "subtype"):
            s.subtype = "FACTOR"
        s.default_value, s.min_value, s.max_value, s.description = default, lo, hi, desc


_SOCKET_PARAMETER = {k: p for p in schema.SCHEMA for k in schema.socket_keys(p)}


def haze_params(kind, smooth):
    """The haze sockets (schema.HAZE_SOCKETS keys) a group of ``kind`` has, in panel order."""
    return schema.layer_sockets(kind, smooth)


# --------------------------------------------------------------------------------------------
# Inside
# --------------------------------------------------------------------------------------------

_COLUMN = 180.0
_ROW = 160.0


def _frame(ng, title, nodes, x0, y0, at=None):
    """Put ``nodes`` (laid out from (0, 0) down: where they are, or ``at``: name -> (x, y)) in
    a labelled frame at (x0, y0)."""
    frame = ng.nodes.new("NodeFrame")
    frame.label = title
    frame.label_size = 16
    frame.shrink = True
    frame.location = (x0, y0)
    for n in nodes:
        x, y = at[n.name] if at is not None else tuple(n.location)
        n.parent = frame
        n.location = (x0 + x, y0 + y)
    return frame


def build(ng, kind, settings, smooth, baked=False, body=False):
    """(Re)build ``ng`` for this configuration.  An existing interface is kept when it is the
    same (the group nodes' links and values stay)."""
    ng.nodes.clear()
    template = ng.nodes.new(BSDF_NODES[kind])
    for p, v in settings.items():
        setattr(template, p, v)
    rebuild_interface(ng, lambda tree: _interface(tree, kind, template, smooth, baked),
                      update_sockets=False)
    ng.nodes.remove(template)
    cfg = config_for(kind, settings, smooth=smooth, baked=baked, body=body)
    lay = layer_graph.build(cfg)

    gin = ng.nodes.new("NodeGroupInput")
    gin.label = "Inputs (the BSDF's and the haze's)"
    sources = {}
    for sock in gin.outputs:
        if sock.name:
            sources[layer_graph.input_name(sock.name)] = sock
    if baked:
        for key, (name, _) in layer_graph.BAKED.items():
            sources[layer_graph.baked_name(key)] = gin.outputs[name]
    else:
        for param in haze_params(kind, smooth):
            sources[layer_graph.haze_name(param)] = gin.outputs[schema.HAZE_SOCKETS[param][0]]
    if body:  # the view cosine Keep Body Colour reads, on the BSDF's normal
        lw = ng.nodes.new("ShaderNodeLayerWeight")
        lw.label = "View cosine (Keep Body Colour)"
        lw.inputs["Blend"].default_value = 0.5
        ng.links.new(gin.outputs["Normal"], lw.inputs["Normal"])
        lw.location = (-1.5 * _COLUMN, 300.0)
        sources[node_body_colour.FACING] = lw.outputs["Facing"]

    # -- the math: one node group per section (readable, and far quicker to build: every
    #    node edit in Blender updates the whole tree it is in) ------------------------------
    outs, part_nodes = _emit_sections(ng, lay, sources)
    ys = [0.0, 0.0]  # two columns, each part in the shorter one
    for n in part_nodes:
        col = 0 if ys[0] >= ys[1] else 1
        n.location = (col * 1.6 * _COLUMN, ys[col])
        ys[col] -= 60.0 + 22.0 * (len(n.inputs) + len(n.outputs))
    width = 3.2 * _COLUMN
    _frame(ng, "Haze mapping (Eqs. 3-8, corrections): a group per part, Tab to open",
           part_nodes, 0.0, 0.0)
    gin.location = (-3.0 * _COLUMN, 0.0)

    # -- the BSDF slots and their mixes ---------------------------------------------------
    x_lobes = width + 3.0 * _COLUMN
    gin2 = ng.nodes.new("NodeGroupInput")
    gin2.label = "Inputs (passed to every BSDF)"
    gin2.location = (x_lobes - 2.0 * _COLUMN, 0.0)
    lobe_nodes = []
    results = {}
    for tree_name, tree in (("BSDF", lay.cycles), ("EEVEE", lay.eevee)):
        results[tree_name] = _closures(ng, tree, kind, settings, outs, gin2, x_lobes, lobe_nodes)
    gout = ng.nodes.new("NodeGroupOutput")
    gout.location = (x_lobes + 7.0 * _COLUMN, 0.0)
    for name, sock in results.items():
        ng.links.new(sock, gout.inputs[name])
    _frame(ng, "Lobes: copies of the BSDF with the haze's values, mixed by β", lobe_nodes, 0.0, 0.0)
    for s in gin.outputs:  # each Group Input shows the sockets it feeds
        s.hide = bool(s.name) and not s.is_linked
    for s in gin2.outputs:
        s.hide = bool(s.name) and not s.is_linked
    ng[K.GROUP_PRINT] = _fingerprint(ng)
    return lay


_edited_seen = {}  # (group session_uid, sizes) -> edited_parts (forget_edits clears it)


def forget_edits():
    """Node groups changed: what edited_parts(cached=True) remembered is stale."""
    _edited_seen.clear()


def _edits_key(ng):
    parts = [ng] + [n.node_tree for n in ng.nodes if getattr(n, "node_tree", None)]
    return (ng.session_uid,) + tuple((len(g.nodes), len(g.links)) for g in parts)


def _unedited(ng):
    """``ng`` as this code just built or appended it: no edit to look for."""
    _edited_seen[_edits_key(ng)] = []
    return ng


def edited_parts(ng, cached=False):
    """Names of the layer group ``ng`` and of its parts edited since they were built (their
    fingerprints differ; none for a group from before fingerprints, or another Blender's: it
    hashes otherwise, and its note says Upgrade).  ``cached``: as last found until
    forget_edits or a node or link more or less (hashing ~1000 nodes takes ~7 ms)."""
    if cached:  # (keyed also by node and link counts: a script's edit shows at once)
        key = _edits_key(ng)
        if key not in _edited_seen:
            _edited_seen[key] = edited_parts(ng)
        return _edited_seen[key]
    if (stamp.group(ng, K.GROUP_STAMP) or {}).get("blender") != version_tag():
        return []
    out = [ng.name] if isinstance(ng.get(K.GROUP_PRINT), str) and \
        ng[K.GROUP_PRINT] != _fingerprint(ng) else []
    for n in ng.nodes:
        sub = getattr(n, "node_tree", None)
        made = (sub.get(K.GROUP_STAMP) if sub is not None else None)
        if hasattr(made, "get") and isinstance(made.get("print"), str) and \
                made["print"] != _fingerprint(sub) and sub.name not in out:
            out.append(sub.name)
    return out


def _emit_sections(ng, lay, sources):
    """Emit ``lay``'s graph into ``ng`` with each section (core.layer_graph's frames) in a node
    group of its own: its inputs are the values it reads from the group's inputs and earlier
    sections, its outputs what later sections and the BSDF slots read.  Returns (the slots'
    and mixes' values: sockets of ``ng`` or constants, the section nodes)."""
    g = lay.graph
    wanted = lay.outputs()
    order = g.used(wanted)
    section = {e.index: lay.section_of(e) for e in order if e.op != "input"}
    final = {e.index for e in _exprs(wanted) if not e.is_const}
    readers = {}
    for e in order:
        for a in e.args:
            if not a.is_const:
                readers.setdefault(a.index, set()).add(section.get(e.index))
    sockets = {e.index: sources[e.name] for e in order if e.op == "input"}
    nodes = []
    tag = _short_tag(lay.config)
    for n_sec, (title, _) in enumerate(lay.sections):
        members = [e for e in order if section.get(e.index) == title]
        if not members:
            continue
        inside = {e.index for e in members}
        ext = []
        for e in members:
            for a in e.args:
                if not a.is_const and a.index not in inside and a not in ext:
                    ext.append(a)
        exported = [e for e in members if e.index in final or (readers.get(e.index, set()) - {title})]
        short = title.split(":")[0].split(" (")[0]  # (names stay far below 63 bytes)
        sub = _section_group(f".HG {tag} {n_sec} {short}", title, g, ext, exported)
        node = ng.nodes.new("ShaderNodeGroup")
        node.node_tree = sub
        node.label = title.split(":")[0]
        node.width = 220.0
        for i, a in enumerate(ext):
            ng.links.new(sockets[a.index], node.inputs[i])
        for i, e in enumerate(exported):
            sockets[e.index] = node.outputs[i]
        nodes.append(node)
    values = {k: (sockets[e.index] if not e.is_const else
                  (tuple(float(x) for x in e.value) if e.vector else float(e.value)))
              for k, e in wanted.items() if e is not None}
    return values, nodes


def _exprs(outputs):
    return [e for e in outputs.values() if e is not None]


def _short_tag(cfg):
    return hashlib.sha1(repr((cfg.key(), GROUP_VERSION)).encode()).hexdigest()[:6]


def _socket_name(e):
    return (e.label or e.name or f"value {e.index}")[:60]


def _part_stamp():
    """A section group's stamp: the code that built it (its name holds the configuration); the
    group adds ``print``, its _fingerprint when built."""
    return {"kind": "layer part", "version": GROUP_VERSION, "code": _code_digest()}


def _fingerprint(ng):
    """What a section group holds: its nodes (name, type, operation, unlinked input values)
    and how many links (so a part the artist edited is told from ours)."""
    h = hashlib.sha1(str(len(ng.links)).encode())
    for n in ng.nodes:
        h.update(f"{n.name}|{n.bl_idname}|{getattr(n, 'operation', '')}".encode())
        for sock in n.inputs:
            if not sock.is_linked and hasattr(sock, "default_value"):
                v = sock.default_value
                h.update(repr(tuple(v) if hasattr(v, "__len__") else v).encode())
    return h.hexdigest()


def _same_part(new, old):
    """Whether the file's section group ``old`` computes what the just made ``new`` does: both
    from this code, and ``old`` as ``new`` was when it was built (not edited since)."""
    stamps = [g.get(K.GROUP_STAMP) for g in (new, old)]
    if not all(hasattr(d, "to_dict") for d in stamps):
        return False
    a, b = (d.to_dict() for d in stamps)
    base = _part_stamp()
    if any(a.get(k) != v or b.get(k) != v for k, v in base.items()) or "print" not in a:
        return False
    return _fingerprint(old) == a["print"]


def _section_group(name, title, g, ext, exported):
    """One section of the layer's math as a node group (inputs ``ext``, outputs ``exported``).
    Where the file has one of that name in use, Blender names this one "<name>.001" and
    ensure_group gives the group the file's when the two are the same (_share_parts)."""
    old = bpy.data.node_groups.get((name, None))  # (a local one: never a linked group)
    if old is not None and old.users == 0:
        bpy.data.node_groups.remove(old)
    sub = bpy.data.node_groups.new(name, "ShaderNodeTree")
    iface = sub.interface
    for a in ext:
        iface.new_socket(name=_socket_name(a), in_out="INPUT",
                         socket_type="NodeSocketVector" if a.vector else "NodeSocketFloat")
    for e in exported:
        iface.new_socket(name=_socket_name(e), in_out="OUTPUT",
                         socket_type="NodeSocketVector" if e.vector else "NodeSocketFloat")
    gin = sub.nodes.new("NodeGroupInput")
    gout = sub.nodes.new("NodeGroupOutput")
    known = {a.index: gin.outputs[i] for i, a in enumerate(ext)}
    tb = TreeBuilder(sub, prefix="")
    tb.set_locations = False  # (laid out once, below)
    made = {}
    out = emit(tb, g, exported, {}, known=known, nodes_by_expr=made)
    for i, v in enumerate(out):
        sub.links.new(v, gout.inputs[i])
    nodes, seen = [], set()
    for _, n in sorted(made.items()):
        if n.name not in seen:
            seen.add(n.name)
            nodes.append(n)
    if nodes:
        _frame(sub, title, nodes, 0.0, 0.0, _relayout(nodes, tb.grid))
        right = max(n.location.x for n in nodes)
        gout.location = (right + 2.0 * _COLUMN, 0.0)
    gin.location = (-2.0 * _COLUMN, 0.0)
    sub[K.GROUP_STAMP] = {**_part_stamp(), "print": _fingerprint(sub)}
    return sub


def _relayout(nodes, grid):
    """Where ``nodes`` go in their frame: columns by the order of dependency (TreeBuilder's
    ``grid``: global depth and row), x from the smallest depth used, rows packed per column.
    Returns {node name: (x, y)}."""
    col = {d: i for i, d in enumerate(sorted({grid[n.name][0] for n in nodes}))}
    rows, at = {}, {}
    for n in sorted(nodes, key=lambda n: grid[n.name]):
        c = col[grid[n.name][0]]
        r = rows.get(c, 0)
        rows[c] = r + 1
        at[n.name] = (_COLUMN * c, -_ROW * r)
    return at


def _closures(ng, tree, kind, settings, outs, gin, x0, made):
    """Nodes of a layer_graph closure tree, below the BSDFs already ``made``; returns the
    output socket of its root."""
    count = [sum(n.bl_idname not in ("ShaderNodeMixShader", "ShaderNodeAddShader") for n in made)]

    def visit(node, depth):
        if isinstance(node, layer_graph.Slot):
            bsdf = ng.nodes.new(BSDF_NODES[kind])
            for p, v in settings.items():
                setattr(bsdf, p, v)
            bsdf.name = bsdf.label = node.role
            bsdf.hide = False
            bsdf.location = (x0, -count[0] * 700.0)
            count[0] += 1
            for sock in bsdf_inputs(bsdf):
                key = (node.role, sock.name)
                if sock.name in node.writes:
                    value = outs[key]
                    if hasattr(value, "node"):
                        ng.links.new(value, sock)
                    elif value is not None and hasattr(sock, "default_value"):
                        sock.default_value = socket_value(sock, value)
                elif sock.name in gin.outputs:
                    ng.links.new(gin.outputs[sock.name], sock)
            made.append(bsdf)
            return bsdf.outputs[0]
        a, b = visit(node.a, depth + 1), visit(node.b, depth + 1)
        mix = ng.nodes.new("ShaderNodeAddShader" if node.add else "ShaderNodeMixShader")
        mix.name = mix.label = node.role
        first = 0 if node.add else 1
        if not node.add:
            fac = outs[(node.role, "factor")]
            if hasattr(fac, "node"):
                ng.links.new(fac, mix.inputs[0])
            else:
                mix.inputs[0].default_value = float(fac)
        ng.links.new(a, mix.inputs[first])
        ng.links.new(b, mix.inputs[first + 1])
        mix.location = (x0 + (6 - depth) * _COLUMN, -(count[0] - 1) * 350.0)
        made.append(mix)
        return mix.outputs[0]

    return visit(tree, 0)
