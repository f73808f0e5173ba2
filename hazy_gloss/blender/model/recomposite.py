# SPDX-License-Identifier: GPL-3.0-or-later
"""The recomposite in Blender (paper §4.3): materials in recomposite mode, the four view layers,
multilayer EXR output and the compositor group.  The math is in ``hazy_gloss.recomposite``.

Hazy materials switch per view layer through an Attribute node (type VIEW_LAYER) reading the
custom property ``hg_recomposite`` on the layer (0 or missing = normal), gated by the Light
Path node's Is Camera Ray: secondary bounces always see the normal material, so every layer
gets the same incident light.  In recomposite mode a material renders Eq. 1 with two Metallic
F82 lobes at Edge Tint 1 (pure Schlick, F0 = r, linear in r as Eq. 11 needs).  Non-hazy objects
are linked to a collection held out in the four layers (Cycles holdout acts on camera rays
only: they still cast shadows and appear in reflections), so they are path traced once, in the
original layer.  AOVs on the first layer hold β, r, p, 1 - p, a hazy mask, β_h and r_c
(coverage-weighted; divided by the mask).
"""
import bpy
import numpy as np

from ... import constants as K
from ...core import node_math
from ...core.graph import Graph
from ...recomposite import (AOVS, GRAPH_INPUTS, GROUP_NAME, GROUP_VERSION, HOLDOUT_COLLECTION,
                            LAYERS, PROPERTY, compositor_graph, exr_layers)
from ...conversion.imagecheck import FORMAT_NAMES, check_image_file, read_exr
from .. import compat
from . import fallback, material, material_read
from . import stamp as _stamps
from ..nodes.builder import TreeBuilder
from ..nodes.emit import combine_compositor, emit
from ..nodes.lobes import build_lobes, tangent

__all__ = ("STAMP", "RC_PREFIX", "Unsupported", "convert_material", "restore_material",
           "setup_recomposite", "clear_recomposite", "ensure_compositor_group", "build_compositor")

STAMP = K.RECOMPOSITE_STAMP  # on materials and on the scene
RC_PREFIX = "HG RC"  # names of the nodes this module adds to material and compositor trees


class Unsupported(ValueError):
    """A hazy material that cannot render in recomposite mode (it is then left as it is and
    treated as non-hazy: it appears unchanged in the composite)."""


def _surface_link(tree, out):
    sock = out.inputs["Surface"]
    if not sock.is_linked:
        return None
    return sock.links[0].from_socket


def _schlick_distribution(dist):
    if dist == "ASHIKHMIN_SHIRLEY":
        raise Unsupported("Ashikhmin-Shirley lobes have no Metallic (Schlick) counterpart")
    # Multiscatter GGX scales each lobe by a factor that depends non-linearly on F0
    # (Cycles' microfacet_ggx_preserve_energy): Eq. 11 would not hold.  Single-scatter GGX.
    return "GGX" if dist == "MULTI_GGX" else dist


def _lobe_dicts(narrow, wide, anisotropic):
    n = dict(roughness=narrow["roughness"], anisotropy=None, rotation=None)
    w = dict(roughness=wide["roughness"], anisotropy=None, rotation=None)
    if anisotropic:
        n.update(anisotropy=narrow["anisotropy"], rotation=narrow["rotation"])
        w.update(anisotropy=wide["anisotropy"], rotation=wide["rotation"])
    return n, w


def _constant_values(p):
    """Lobe parameters and AOV values as Python constants (lean materials).  The lobes are
    Metallic BSDFs whatever the kind, so their anisotropy is in the Metallic convention (the
    dielectric description's)."""
    d = material.lobes_for(dict(p, kind="DIELECTRIC", distribution="GGX"))
    m = d.mapping
    wide = d.wide if d.wide is not None else d.narrow
    f = lambda x: float(np.asarray(x))  # noqa: E731
    narrow, wide = _lobe_dicts(vars(d.narrow), vars(wide), d.anisotropic)
    return dict(narrow=narrow, wide=wide, anisotropic=d.anisotropic,
                beta=f(m.beta), reflectivity=tuple(float(x) for x in m.reflectivity),
                peak_ratio=f(m.peak_ratio), peak_complement=f(m.peak_complement),
                haziness=f(m.haziness),
                core_reflectivity=tuple(float(x) for x in m.core_reflectivity))


_GROUP_INPUTS = {"core_reflectivity": "Core Reflectivity", "edge_tint": "Edge Tint",
                 "roughness": "Roughness", "haziness": "Haziness", "anisotropy": "Anisotropy",
                 "rotation": "Rotation", "smoothness": "Smoothness"}


def _socket_values(tree, p, tb):
    """Lobe parameters from the inputs of an in-shader group node: the mapping's node math
    (core.node_math), emitted with the group's unlinked inputs as constants, so only what
    depends on a texture becomes nodes."""
    node = material.ours(tree).get(material.GROUP_ROLE)
    if node is None or node.bl_idname != "ShaderNodeGroup":
        return None
    aniso = "Anisotropy" in node.inputs
    smooth = "Smoothness" in node.inputs

    def src(name):
        sock = node.inputs.get(name)
        if sock is None:
            return None
        if sock.is_linked:
            return sock.links[0].from_socket
        v = sock.default_value
        return tuple(v)[:3] if hasattr(v, "__len__") else float(v)

    s = {key: src(name) for key, name in _GROUP_INPUTS.items()}
    s["haze_extent_x"] = src("Haze Extent X" if aniso else "Haze Extent")
    s["haze_extent_y"] = src("Haze Extent Y") if aniso else s["haze_extent_x"]
    g = Graph()
    exprs = {k: (g.input(k, vector=node_math.INPUTS[k]) if hasattr(v, "node") else g.const(v))
             for k, v in s.items() if v is not None}
    # kind DIELECTRIC: the anisotropy outputs use the Metallic convention (our lobes are Metallic)
    m = node_math.mapping(g, exprs, kind="DIELECTRIC", anisotropic=aniso, smooth=smooth,
                          distribution=p["distribution"])
    wanted = {k: m[k] for k in ("roughness", "roughness_wide", "beta", "reflectivity",
                                "peak_ratio", "peak_complement")}
    if aniso:
        wanted.update(anisotropy_wide=m["anisotropy_wide"], rotation_wide=m["rotation_wide"])
    wanted["haziness"] = g.clamp(exprs["haziness"], 0.0, K.MAX_HAZINESS)
    v = emit(tb, g, wanted, {k: x for k, x in s.items() if hasattr(x, "node")})
    narrow = dict(roughness=v["roughness"], anisotropy=s.get("anisotropy"), rotation=s.get("rotation"))
    wide = dict(roughness=v["roughness_wide"], anisotropy=v.get("anisotropy_wide"),
                rotation=v.get("rotation_wide"))
    narrow, wide = _lobe_dicts(narrow, wide, aniso)
    tangent_in = node.inputs.get("Tangent")
    normal_in = node.inputs["Normal"]
    return dict(narrow=narrow, wide=wide, anisotropic=aniso, beta=v["beta"],
                reflectivity=v["reflectivity"], peak_ratio=v["peak_ratio"],
                peak_complement=v["peak_complement"], haziness=v["haziness"],
                core_reflectivity=s["core_reflectivity"],
                tangent=tangent_in.links[0].from_socket if aniso and tangent_in.is_linked else None,
                normal=normal_in.links[0].from_socket if normal_in.is_linked else None,
                base_color=src("Base Color") if "Base Color" in node.inputs else None)


def _build_schlick(tree, p, v, tb):
    """The recomposite-mode hazy material: Eq. 1 with two Metallic F82 lobes (Schlick, F0 = r),
    switched per view layer for camera rays, and the AOVs."""
    att = tb.node("ShaderNodeAttribute", name="Mode", label=f"View layer [{PROPERTY}]", depth=0,
                  attribute_type="VIEW_LAYER", attribute_name=PROPERTY)
    lp = tb.node("ShaderNodeLightPath", name="Light Path", depth=0)
    g = Graph()
    mode = g.mul(g.input("layer"), g.input("camera"), label="mode (camera rays)")
    normal = g.less(mode, 0.5, label="normal")
    wide = g.math("GREATER_THAN", mode, 2.5, label="wide lobe only")
    one = g.add(g.math("COMPARE", mode, 2.0, 0.5), g.math("COMPARE", mode, 4.0, 0.5), label="F = 1")
    beta = g.input("beta") if hasattr(v["beta"], "node") else g.const(v["beta"])
    refl = g.input("reflectivity", vector=True) if hasattr(v["reflectivity"], "node") \
        else g.const(v["reflectivity"])
    out = emit(tb, g, dict(fac=g.madd(normal, beta, wide, label="mix factor"),
                           f0=g.vmath("MULTIPLY_ADD", refl, normal, one, label="F0")),
               dict(layer=att.outputs["Fac"], camera=lp.outputs["Is Camera Ray"], beta=v["beta"],
                    reflectivity=v["reflectivity"]))
    depth = 2 + tb.max_depth
    shared = dict(tangent=v.get("tangent"), normal=v.get("normal"))
    bsdf = build_lobes(tb, "CONDUCTOR", _schlick_distribution(p["distribution"]), beta=out["fac"],
                       narrow=v["narrow"], wide=v["wide"], fresnel=dict(schlick_f0=out["f0"]),
                       shared=shared, depth=depth, always_wide=True)
    base = v.get("base_color")
    if base is not None and (hasattr(base, "node") or max(base) > 0.0):
        diff = tb.node("ShaderNodeBsdfDiffuse", name="Base", label="Base (diffuse)", depth=depth)
        tb.feed(diff.inputs["Color"], base)
        if v.get("normal") is not None:
            tb.link(v["normal"], diff.inputs["Normal"])
        add = tb.node("ShaderNodeAddShader", name="Base add", depth=depth + 2)
        tb.link(diff.outputs[0], add.inputs[0])
        tb.link(bsdf, add.inputs[1])
        bsdf = add.outputs[0]

    values = {"beta": v["beta"], "reflectivity": v["reflectivity"], "peak_ratio": v["peak_ratio"],
              "peak_complement": v["peak_complement"], "mask": 1.0, "haziness": v["haziness"],
              "core_reflectivity": v["core_reflectivity"]}
    for aov, typ, key in AOVS:
        n = tb.node("ShaderNodeOutputAOV", name=f"AOV {aov}", depth=depth + 3)
        n.aov_name = aov
        tb.feed(n.inputs["Value" if typ == "VALUE" else "Color"], values[key])
    return bsdf


def convert_material(mat):
    """Switch one hazy material to recomposite mode (idempotent).  Raises Unsupported."""
    try:
        p = material_read.read_parameters(mat)
    except ValueError as exc:  # a damaged stamp: skipped, with the reason
        raise Unsupported(str(exc)) from None
    if p is None:
        raise Unsupported(f"{mat.name!r} is not a hazy material")
    if mat.library is not None:
        raise Unsupported(f"{mat.name!r} is linked from a library")
    if p.get("layered"):
        raise Unsupported("a haze layer on the material's own BSDF (Make Hazy) has no "
                          "recomposite passes yet")
    _schlick_distribution(p["distribution"])
    restore_material(mat)
    notes = []
    if fallback.remove_export_fallback(mat):  # its outputs would hide the recomposite tree from Cycles
        notes.append("the glTF/USD export fallback was removed (add it again after leaving "
                     "recomposite mode)")
    tree = mat.node_tree
    out = material.output_node(tree)
    original = _surface_link(tree, out)
    tb = TreeBuilder(tree, prefix=RC_PREFIX, x0=600.0, y0=-900.0, roles=False)
    if p["kind"] == "DIELECTRIC" and p["transmission"] > 0.0:
        notes.append("transmission is not handled in recomposite mode (rendered opaque)")
    if p["distribution"] == "MULTI_GGX":
        notes.append("multiscatter GGX rendered as single-scatter GGX (Eq. 11 needs linearity in F0)")
    try:
        v = _socket_values(tree, p, tb) if p["shader_mapping"] else None
        if v is None:
            v = _constant_values(p)
            v["base_color"] = p["base_color"] if p["kind"] == "DIELECTRIC" else None
            if v["anisotropic"]:  # the lean tree's explicit tangent
                t = material.ours(tree).get("Tangent")
                v["tangent"] = t.outputs[0] if t is not None else tangent(tb, p["tangent"], 0)
        bsdf = _build_schlick(tree, p, v, tb)
    except Exception:
        for n in tb.created:
            tree.nodes.remove(n)
        raise
    # every node we add carries the RC prefix: restore_material removes exactly those (they
    # have no role, so the material's own updates leave them alone)
    for n in tb.created:
        if not n.name.startswith(RC_PREFIX + " "):
            n.name = f"{RC_PREFIX} {n.name}"
    tree.links.new(bsdf, out.inputs["Surface"])
    mat[STAMP] = {"version": GROUP_VERSION,
                  "surface_node": original.node.name if original is not None else "",
                  "surface_socket": original.identifier if original is not None else ""}
    return notes


def restore_material(mat):
    """Leave recomposite mode: remove the RC nodes and relink the original surface."""
    tree = mat.node_tree
    if tree is None:
        return False
    ours = [n for n in tree.nodes if n.name.startswith(RC_PREFIX + " ")]
    present = STAMP in mat
    if not present and not ours:
        return False
    for n in ours:
        tree.nodes.remove(n)
    if present:  # a stamp that is not a group, or names no node: only the relink is skipped
        stamp = _stamps.group(mat, STAMP) or {}
        name = stamp.get("surface_node", "")
        node = tree.nodes.get(name) if isinstance(name, str) else None
        if node is not None:
            sock = next((s for s in node.outputs if s.identifier == stamp.get("surface_socket")), None)
            outs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
            out = next((n for n in outs if n.is_active_output), outs[0] if outs else None)
            if sock is not None and out is not None:
                tree.links.new(sock, out.inputs["Surface"])
        del mat[STAMP]
    return True


def _scene_state(scene):
    """The scene's recomposite stamp as a dict whose values have the types setup wrote (what
    does not is left out: a damaged stamp only loses what it cannot say)."""
    state = _stamps.group(scene, STAMP) or {}
    types = {"template": str, "file_format": str, "color_depth": str, "exr_codec": str,
             "media_type": str, "use_single_layer": (bool, int), "template_use": (bool, int)}
    return {k: v for k, v in state.items() if k in types and isinstance(v, types[k])}


# ============================================================================================
# bpy glue: view layers and output
# ============================================================================================

_LAYER_ATTRS = ("samples", "use_solid", "use_sky", "use_ao", "use_strand", "use_volumes",
                "use_motion_blur", "pass_alpha_threshold", "material_override", "world_override")


def _copy_layer_collections(src, dst):
    for attr in ("exclude", "holdout", "indirect_only"):
        if hasattr(src, attr):
            setattr(dst, attr, getattr(src, attr))
    by_name = {c.name: c for c in dst.children}
    for child in src.children:
        if child.name in by_name:
            _copy_layer_collections(child, by_name[child.name])


def _layer_collection(layer, name):
    stack = [layer.layer_collection]
    while stack:
        lc = stack.pop()
        if lc.name == name:
            return lc
        stack.extend(lc.children)
    return None


def _new_layer(scene, template, name, mode, aovs):
    layer = scene.view_layers.get(name) or scene.view_layers.new(name)
    for attr in _LAYER_ATTRS:
        if hasattr(template, attr):
            try:
                setattr(layer, attr, getattr(template, attr))
            except (AttributeError, TypeError):
                pass
    _copy_layer_collections(template.layer_collection, layer.layer_collection)
    layer.use = True
    layer.use_pass_combined = True
    layer.use_freestyle = False
    if hasattr(layer, "cycles") and hasattr(layer.cycles, "use_denoising"):
        layer.cycles.use_denoising = False  # the buffers must stay linear in the radiance
    layer[PROPERTY] = float(mode)
    existing = {a.name for a in layer.aovs}
    if aovs:
        for aov, typ, _ in AOVS:
            if aov not in existing:
                a = layer.aovs.add()
                a.name = aov
                a.type = typ
    return layer


def _set_multilayer_exr(scene, codec="ZIP"):
    s = scene.render.image_settings
    if hasattr(s, "media_type"):  # 5.0
        s.media_type = "MULTI_LAYER_IMAGE"
    s.file_format = "OPEN_EXR_MULTILAYER"
    s.color_depth = "32"
    s.exr_codec = codec


_GEOMETRY_TYPES = {"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"}


def _scan(scene):
    """(hazy materials, names of objects that show a hazy material — directly, through geometry
    nodes, or through what they instance) from the evaluated depsgraph of the context's view
    layer when ``scene`` is the context scene, else from the objects' own materials."""
    depsgraph = bpy.context.evaluated_depsgraph_get() if bpy.context.scene == scene else None
    mats, objects = set(), set()

    def materials(ob):
        out = [slot.material for slot in getattr(ob, "material_slots", ())]
        out += list(getattr(getattr(ob, "data", None), "materials", ()) or ())
        return [m.original for m in out if m is not None]

    if depsgraph is not None:
        for inst in depsgraph.object_instances:
            hazy = [m for m in materials(inst.object) if material_read.is_hazy(m)]
            if hazy:
                mats.update(hazy)
                objects.add(inst.object.original.name)
                if inst.is_instance and inst.parent is not None:
                    objects.add(inst.parent.original.name)
    for ob in scene.objects:  # unevaluated fallback (and objects hidden from the depsgraph)
        hazy = [m for m in materials(ob) if material_read.is_hazy(m)]
        if hazy:
            mats.update(hazy)
            objects.add(ob.name)
    return sorted(mats, key=lambda m: m.name), objects


def _holdout_collection(scene, hazy_objects):
    """A collection of the scene's non-hazy objects (linked, not moved), created anew."""
    coll = bpy.data.collections.get(HOLDOUT_COLLECTION)
    if coll is None:
        coll = bpy.data.collections.new(HOLDOUT_COLLECTION)
    for ob in list(coll.objects):
        coll.objects.unlink(ob)
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    for ob in scene.objects:
        if ob.type in _GEOMETRY_TYPES and ob.name not in hazy_objects \
                and ob.instance_type in ("NONE", "VERTS", "FACES") and not ob.particle_systems \
                and ob.name not in coll.objects:
            if ob.instance_type != "NONE" and ob.children:
                continue  # instances children: they may be hazy
            coll.objects.link(ob)
    return coll


def setup_recomposite(scene, *, template=None, compositor=True, holdout=True, exr_codec="ZIP"):
    """Set ``scene`` up so one render yields everything the recomposite needs.

    - every hazy material of the scene switches to recomposite mode (Schlick lobes, AOVs);
    - ``template`` (default: the first enabled view layer) stays the ordinary render, V0;
    - four view layers ``LAYERS`` are created from it, the first one with the AOVs;
    - ``holdout``: non-hazy objects are linked to the collection ``HOLDOUT_COLLECTION``, held
      out in the four layers (camera rays only), so only hazy surfaces cost render time there.
      Anything left visible (e.g. non-hazy slots of a hazy object) cancels exactly anyway;
    - output: multilayer OpenEXR, 32-bit float, lossless ``exr_codec``;
    - ``compositor``: the scene compositor gets the "Hazy Gloss Recomposite" group fed by Render
      Layers nodes (edit its inputs after the render; the output is the recomposite).
    Returns a report dict: converted, skipped ({name: reason}), notes, layers, template, held_out."""
    if scene.render.engine != "CYCLES":
        raise ValueError("the recomposite passes need Cycles (the per-layer switch relies on "
                         "Cycles' view-layer attributes and holdout semantics)")
    state = _scene_state(scene)
    if template is None:
        name = state.get("template")
        template = scene.view_layers.get(name) if name else None
    if template is None:
        template = next((vl for vl in scene.view_layers if vl.use and vl.name not in LAYERS), None) \
            or next(vl for vl in scene.view_layers if vl.name not in LAYERS)
    if template.name in LAYERS:
        raise ValueError(f"the original layer cannot be one of {LAYERS}")
    s = scene.render.image_settings
    if not state:
        state = {"file_format": s.file_format, "color_depth": s.color_depth,
                 "exr_codec": s.exr_codec, "use_single_layer": bool(scene.render.use_single_layer),
                 "media_type": getattr(s, "media_type", ""), "template_use": bool(template.use)}
    state["template"] = template.name

    mats, hazy_objects = _scan(scene)
    report = {"converted": [], "skipped": {}, "notes": {}, "layers": list(LAYERS),
              "template": template.name, "held_out": []}
    for mat in mats:
        try:
            notes = convert_material(mat)
        except Unsupported as exc:
            report["skipped"][mat.name] = str(exc)
            continue
        report["converted"].append(mat.name)
        if notes:
            report["notes"][mat.name] = notes

    coll = _holdout_collection(scene, hazy_objects) if holdout else None
    for vl in scene.view_layers:  # the holdout acts in our four layers only
        lc = _layer_collection(vl, HOLDOUT_COLLECTION)
        if lc is not None:
            lc.holdout = False
    for i, (layer_name, mode) in enumerate(zip(LAYERS, (1, 2, 3, 4))):
        layer = _new_layer(scene, template, layer_name, mode, aovs=(i == 0))
        lc = _layer_collection(layer, HOLDOUT_COLLECTION)
        if lc is not None:
            lc.exclude = False
            lc.holdout = coll is not None
    if coll is not None:
        report["held_out"] = sorted(ob.name for ob in coll.objects)
    template.use = True
    scene.render.use_single_layer = False
    _set_multilayer_exr(scene, exr_codec)
    scene[STAMP] = state
    if compositor:
        build_compositor(scene)
    return report


def clear_recomposite(scene):
    """Undo :func:`setup_recomposite`: materials, view layers, holdout collection, output
    settings, compositor nodes."""
    for mat in bpy.data.materials:
        restore_material(mat)
    state = _scene_state(scene)
    for name in LAYERS:
        layer = scene.view_layers.get(name)
        if layer is not None and len(scene.view_layers) > 1:
            scene.view_layers.remove(layer)
    coll = bpy.data.collections.get(HOLDOUT_COLLECTION)
    if coll is not None:
        bpy.data.collections.remove(coll)
    template = scene.view_layers.get(state.get("template", ""))
    if template is not None:
        template.use = bool(state.get("template_use", True))
    s = scene.render.image_settings
    if state:
        if state.get("media_type") and hasattr(s, "media_type"):
            try:
                s.media_type = state["media_type"]
            except (TypeError, ValueError, AttributeError):
                pass
        for attr in ("file_format", "color_depth", "exr_codec"):
            try:
                setattr(s, attr, state[attr])
            except (KeyError, TypeError, ValueError, AttributeError):
                pass
        scene.render.use_single_layer = bool(state.get("use_single_layer", False))
    if STAMP in scene:
        del scene[STAMP]
    tree = compat.compositor_tree(scene, create=False)
    if tree is not None:
        for n in [n for n in tree.nodes if n.name.startswith(RC_PREFIX + " ")]:
            tree.nodes.remove(n)


# ============================================================================================
# Compositor (the version differences are in compat.py)
# ============================================================================================


def _build_group(ng):
    for n in list(ng.nodes):
        ng.nodes.remove(n)
    ng.interface.clear()
    for key, (vector, name, desc) in GRAPH_INPUTS.items():
        if name is None:
            continue
        s = ng.interface.new_socket(name=name, in_out="INPUT",
                                    socket_type="NodeSocketColor" if vector else "NodeSocketFloat")
        s.description = desc
        if name.endswith("Factor"):
            s.min_value, s.max_value = 0.0, 1.0
        if key == "new_haziness":
            s.default_value = 0.5
        elif key == "new_core_reflectivity":
            s.default_value = (0.5, 0.5, 0.5, 1.0)
        elif key == "peak_ratio":
            s.default_value = 1.0
    ng.interface.new_socket(name="Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    gin = ng.nodes.new("NodeGroupInput")
    gin.location = (-400, 0)
    gout = ng.nodes.new("NodeGroupOutput")
    tb = TreeBuilder(ng, prefix="", roles=False)
    g = Graph()
    i = {k: g.input(k, vector=v[0]) for k, v in GRAPH_INPUTS.items()}
    sources = {k: gin.outputs[v[1]] for k, v in GRAPH_INPUTS.items() if v[1] is not None}
    # the original's alpha passes through: split it off the Original input
    sep = tb.node("CompositorNodeSeparateColor", depth=1)
    tb.link(gin.outputs["Original"], sep.inputs[0])
    sources["original_alpha"] = sep.outputs[3]
    out = emit(tb, g, compositor_graph(g, i)["image"], sources, backend="COMPOSITOR")
    image = combine_compositor(tb, out, sources["original_alpha"])
    gout.location = (180.0 * (tb.max_depth + 2), 0)
    ng.links.new(image, gout.inputs["Image"])
    return ng


def ensure_compositor_group():
    """The compositor node group "Hazy Gloss Recomposite" (built from code, rebuilt if stale)."""
    ng = bpy.data.node_groups.get(GROUP_NAME)
    if ng is not None and ng.bl_idname == "CompositorNodeTree" \
            and (_stamps.group(ng, K.GROUP_STAMP) or {}).get("version") == GROUP_VERSION:
        return ng
    if ng is None or ng.bl_idname != "CompositorNodeTree":
        ng = bpy.data.node_groups.new(GROUP_NAME, "CompositorNodeTree")
    _build_group(ng)
    ng[K.GROUP_STAMP] = {"version": GROUP_VERSION}
    ng.use_fake_user = True
    return ng


def build_compositor(scene, source=None, *, original=None, haziness=None, core_reflectivity=None):
    """Wire the scene compositor: passes -> "Hazy Gloss Recomposite" -> output.

    ``source`` None: Render Layers nodes of the original layer and the four layers (live after
    a render); a path: a multilayer EXR written by a recomposite render, loaded in Image nodes
    (re-compositing a saved render costs no rendering: a compositor with no Render Layers node
    does not render).  ``original``: the original layer's name (default: from the setup, or the
    one layer of the file that is not ours).
    ``haziness`` / ``core_reflectivity``: new values (factors set to 1); None keeps.
    Returns the group node.  A damaged ``source`` raises ImageFileError (a ValueError,
    hazy_gloss.conversion.imagecheck) before Blender loads it."""
    tree = compat.compositor_tree(scene)
    for n in [n for n in tree.nodes if n.name.startswith(RC_PREFIX + " ")]:
        tree.nodes.remove(n)
    out_socket = compat.compositor_output(tree, f"{RC_PREFIX} Output")
    group = tree.nodes.new("CompositorNodeGroup")
    group.node_tree = ensure_compositor_group()
    group.name = f"{RC_PREFIX} Recomposite"
    group.label = GROUP_NAME
    group.location = (500, 0)
    group.width = 260

    image = None
    if source is not None:
        info = check_image_file(bpy.path.abspath(str(source)))  # a damaged EXR can crash Blender's loader
        if info.format != "OPEN_EXR":
            raise ValueError(f"{source} is a {FORMAT_NAMES[info.format]} file: the recomposite "
                             "source must be the multilayer OpenEXR of a render")
        image = bpy.data.images.load(bpy.path.abspath(str(source)), check_existing=True)
        image.reload()
        if original is None:
            others = [n for n in exr_layers(read_exr(bpy.path.abspath(str(source))))
                      if n not in LAYERS and n != "Composite"]
            if len(others) != 1:
                raise ValueError(f"cannot tell the original layer among {others}; pass original=")
            original = others[0]
    elif original is None:
        original = _scene_state(scene).get("template")
        if original is None or scene.view_layers.get(original) is None:
            raise ValueError("run setup_recomposite first (or pass original=<view layer>)")
    names = (original,) + LAYERS
    layer_sockets = [GRAPH_INPUTS[k][1] for k in ("original",) + tuple(
        ("narrow_delta", "narrow_one", "wide_delta", "wide_one"))]
    for k, (layer_name, sock_name) in enumerate(zip(names, layer_sockets)):
        if image is None:
            n = tree.nodes.new("CompositorNodeRLayers")
            n.scene = scene
            n.layer = layer_name
        else:
            n = tree.nodes.new("CompositorNodeImage")
            n.image = image
            n.layer = layer_name
        n.name = f"{RC_PREFIX} {layer_name}"
        n.label = layer_name
        n.location = (0, 600 - 320 * k)
        tree.links.new(n.outputs["Image" if "Image" in n.outputs else "Combined"],
                       group.inputs[sock_name])
        if k == 1:
            for aov, _, key in AOVS:
                if aov in n.outputs:  # renders before hg_peak_complement existed lack it
                    tree.links.new(n.outputs[aov], group.inputs[GRAPH_INPUTS[key][1]])
    if haziness is not None:
        group.inputs["New Haziness"].default_value = float(haziness)
        group.inputs["Haziness Factor"].default_value = 1.0
    if core_reflectivity is not None:
        rc = np.broadcast_to(np.asarray(core_reflectivity, dtype=float), (3,))
        group.inputs["New Core Reflectivity"].default_value = (*map(float, rc), 1.0)
        group.inputs["Core Reflectivity Factor"].default_value = 1.0
    tree.links.new(group.outputs["Image"], out_socket)
    scene.render.use_compositing = True
    return group
