# SPDX-License-Identifier: GPL-3.0-or-later
"""The demo gallery: the paper's Figure 3 layout (a dielectric row and a conductor row of spheres
with increasing haziness, α_n = 0.01, λ_h = 7), the Table 3 materials and the looks (Principled
materials without and with their haze layer), rendered with Cycles.

    .venv/bin/python scripts/gallery.py [--out out/gallery.png] [--samples 48] [--scale 1.0]
    .venv/bin/python scripts/gallery.py --rows haziness --out docs/img/sweep_haziness.png
    .venv/bin/python scripts/gallery.py --rows extent --out docs/img/sweep_extent.png
    .venv/bin/python scripts/gallery.py --rows looks --out docs/img/looks.png
    .venv/bin/python scripts/gallery.py --rows layer --out docs/img/layer.png

Runs on the bpy module; loads the add-on the way scripts do (repo root on sys.path).
"""
import argparse
import math
import os
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)

import bpy  # noqa: E402

import hazy_gloss  # noqa: E402

R_01 = math.sqrt(0.01)  # the paper's α_n = 0.01 is Blender roughness R = √α = 0.1

# Figure 3: dielectric row (r_c typical of a dielectric, greenish Lambertian) and conductor row
FIG3_HAZINESS_DIELECTRIC = (0.0, 0.025, 0.05, 0.1, 0.2)
FIG3_HAZINESS_CONDUCTOR = (0.0, 0.25, 0.5, 0.75, 0.99)

# Table 3 (α_n given as α; converted to R = √α)
TABLE3 = {
    "Probe A": dict(kind="DIELECTRIC", core_reflectivity=0.02, roughness=math.sqrt(0.01),
                    haziness=0.1, haze_extent=5.0, base_color=(0.02, 0.02, 0.025)),
    "Probe B": dict(kind="CONDUCTOR", core_reflectivity=0.5, edge_tint=1.0,
                    roughness=math.sqrt(0.01), haziness=0.99, haze_extent=5.0),
    "Fertility": dict(kind="CONDUCTOR", core_reflectivity=(0.5, 0.28, 0.1), edge_tint=(0.8, 0.06, 0.03),
                      roughness=math.sqrt(0.03), haziness=0.99, haze_extent=5.0),
    "Vase": dict(kind="DIELECTRIC", core_reflectivity=0.05, roughness=math.sqrt(0.01), haziness=0.15,
                 haze_extent=7.0, base_color=(0.01, 0.05, 0.02)),
    "Teapot": dict(kind="CONDUCTOR", core_reflectivity=(0.5, 0.12, 0.12), edge_tint=(0.0, 0.85, 1.0),
                   roughness=math.sqrt(0.01), haziness=0.99, haze_extent=(10.0, 1.0), tangent="RADIAL_Z"),
}


def analytic_sphere(name, location, material, radius=0.5):
    """An analytic sphere: a geometry-nodes point, which Cycles renders as an exact sphere."""
    obj = bpy.data.objects.new(name, bpy.data.meshes.new(name))
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    mod = obj.modifiers.new("points", "NODES")
    ng = bpy.data.node_groups.new(name, "GeometryNodeTree")
    ng.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    pts = ng.nodes.new("GeometryNodePoints")
    pts.inputs["Count"].default_value = 1
    pts.inputs["Radius"].default_value = radius
    setm = ng.nodes.new("GeometryNodeSetMaterial")
    setm.inputs["Material"].default_value = material
    out = ng.nodes.new("NodeGroupOutput")
    ng.links.new(pts.outputs[0], setm.inputs["Geometry"])
    ng.links.new(setm.outputs[0], out.inputs[0])
    mod.node_group = ng
    obj.data.materials.append(material)  # so material-slot lookups find it
    obj.visible_glossy = False  # each sphere reflects the studio only, not its neighbours
    return obj


def _label(text, location, size=0.11):
    curve = bpy.data.curves.new(text, "FONT")
    curve.body = text
    curve.size = size
    curve.align_x = "CENTER"
    obj = bpy.data.objects.new(text, curve)
    bpy.context.scene.collection.objects.link(obj)
    obj.location = location
    obj.rotation_euler = (math.pi / 2, 0.0, 0.0)  # face the camera (which looks along +Y)
    obj.visible_glossy = False
    mat = bpy.data.materials.get("HG label") or bpy.data.materials.new("HG label")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 0.8
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(em.outputs[0], out.inputs[0])
    curve.materials.append(mat)


def band_world(scene, name, stops):
    """A world whose colour is a constant-interpolated ramp over the direction's height:
    ``stops`` = [(position in [0, 1] from straight down to straight up, RGBA), ...]."""
    world = bpy.data.worlds.new(name)
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    coord = nt.nodes.new("ShaderNodeTexCoord")
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    mapz = nt.nodes.new("ShaderNodeMapRange")
    mapz.inputs[1].default_value = -1.0
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    cr = ramp.color_ramp
    cr.interpolation = "CONSTANT"
    for i, (pos, colour) in enumerate(stops):
        e = cr.elements[i] if i < len(cr.elements) else cr.elements.new(pos)
        e.position = pos
        e.color = colour
    bg = nt.nodes.new("ShaderNodeBackground")
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(coord.outputs["Generated"], sep.inputs[0])
    nt.links.new(sep.outputs["Z"], mapz.inputs[0])
    nt.links.new(mapz.outputs[0], ramp.inputs[0])
    nt.links.new(ramp.outputs[0], bg.inputs[0])
    nt.links.new(bg.outputs[0], out.inputs[0])
    return world


def studio(scene):
    """Dark environment with a bright horizon band (reflections show a sharp edge and its halo)
    and two small, strong area lights (sharp highlights with visible halos)."""
    band_world(scene, "HG gallery", [(0.0, (0.002, 0.002, 0.003, 1)), (0.52, (0.6, 0.62, 0.7, 1)),
                                     (0.62, (0.01, 0.012, 0.02, 1))])
    for loc, energy in (((3.0, -4.0, 5.0), 600.0), ((-4.0, -2.0, 2.0), 250.0)):
        light = bpy.data.lights.new("HG key", "AREA")
        light.size = 0.15
        light.energy = energy
        obj = bpy.data.objects.new("HG key", light)
        scene.collection.objects.link(obj)
        obj.location = loc
        direction = -obj.location.normalized()
        obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def sphere_rows(scene, rows, *, ortho_scale=5.2):
    """rows: [(labels, materials)], laid out top to bottom and centred, an orthographic camera
    ``ortho_scale`` units wide framing them."""
    for r, (labels, mats) in enumerate(rows):
        z = 1.1 * ((len(rows) - 1) / 2 - r)
        for c, (label, mat) in enumerate(zip(labels, mats)):
            x = 1.0 * (c - (len(mats) - 1) / 2)
            analytic_sphere(mat.name, (x, 0.0, z), mat, radius=0.42)
            _label(label, (x, 0.45, z - 0.53), size=0.09)  # behind: not reflected
    cam = bpy.data.cameras.new("HG camera")
    cam.type = "ORTHO"
    cam.sensor_fit = "HORIZONTAL"  # ortho_scale is the width (AUTO takes the longer side)
    cam.ortho_scale = ortho_scale
    cam_obj = bpy.data.objects.new("HG camera", cam)
    scene.collection.objects.link(cam_obj)
    cam_obj.location = (0.0, -10.0, 0.0)
    cam_obj.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.camera = cam_obj


def gallery_rows(api):
    dielectric = [api.create_material(f"Fig3 dielectric {h}", kind="DIELECTRIC", core_reflectivity=0.04,
                                      roughness=R_01, haziness=h, haze_extent=7.0,
                                      base_color=(0.03, 0.12, 0.05))
                  for h in FIG3_HAZINESS_DIELECTRIC]
    conductor = [api.create_material(f"Fig3 conductor {h}", kind="CONDUCTOR", core_reflectivity=0.5,
                                     edge_tint=1.0, roughness=R_01, haziness=h, haze_extent=7.0)
                 for h in FIG3_HAZINESS_CONDUCTOR]
    table = [api.create_material(name, **params) for name, params in TABLE3.items()]
    return [([f"haziness {h:g}" for h in FIG3_HAZINESS_DIELECTRIC], dielectric),
            ([f"haziness {h:g}" for h in FIG3_HAZINESS_CONDUCTOR], conductor),
            (list(TABLE3), table)] + looks_rows(api)


def looks_rows(api):
    """The looks (utils.looks): Principled materials as an artist builds them, without haze
    (top) and with the haze layer Make Hazy puts on them (bottom)."""
    from hazy_gloss.utils.looks import LOOKS
    plain = [api.create_look(k, f"{look.name} (no haze)", haziness=0.0, coat_haziness=0.0)
             for k, look in LOOKS.items()]
    hazy = [api.create_look(k) for k in LOOKS]
    return [([f"{look.name}, no haze" for look in LOOKS.values()], plain),
            ([f"{look.name}, hazy" for look in LOOKS.values()], hazy)]


def layer_rows(api):
    """Haze as a layer on Principled materials (docs/user-guide.md): the coat's haziness on car
    paint, and Keep Body Colour on a red plastic."""
    coats = (0.0, 0.2, 0.4, 0.6, 0.8)
    paint = [api.create_look("CAR_PAINT", f"Car paint coat {h}", haziness=0.0, coat_haziness=h)
             for h in coats]
    body = [("0", 0.0, False), ("0.1", 0.1, False), ("0.1, body kept", 0.1, True),
            ("0.3", 0.3, False), ("0.3, body kept", 0.3, True)]
    plastic = [api.create_look("GLOSSY_PLASTIC", f"Plastic {label}", haziness=h,
                               keep_body_colour=keep) for label, h, keep in body]
    return [([f"coat haziness {h:g}" for h in coats], paint),
            ([f"haziness {label}" for label, _, _ in body], plastic)]


def glass_rows(api):
    """Haze on transmissive Principled materials (docs/user-guide.md): refraction keeps the
    artist's IOR, the reflection gains its halo and the transmitted light loses what it gains."""
    import bpy as _bpy

    def glass(name, ior, tint, roughness, h):
        mat = _bpy.data.materials.new(name)
        if _bpy.app.version < (5, 0, 0):
            mat.use_nodes = True
        b = mat.node_tree.nodes["Principled BSDF"]
        for key, v in (("Transmission Weight", 1.0), ("IOR", ior), ("Roughness", roughness),
                       ("Base Color", tint + (1.0,))):
            b.inputs[key].default_value = v
        api.make_hazy(mat, haziness=h, haze_extent=6.0)
        return mat
    hs = (0.0, 0.1, 0.3, 0.6, 0.9)
    clear = [glass(f"Glass {h}", 1.52, (1.0, 1.0, 1.0), 0.03, h) for h in hs]
    honey = [glass(f"Honey {h}", 1.504, (0.83, 0.57, 0.04), 0.08, h) for h in hs]
    return [([f"glass, haziness {h:g}" for h in hs], clear),
            ([f"honey, haziness {h:g}" for h in hs], honey)]


def sweep_rows(api, which):
    """Parameter sweeps for the docs (paper Figures 4 and 8)."""
    from hazy_gloss.blender.nodes.builder import TreeBuilder
    from hazy_gloss.blender.model import material
    from hazy_gloss.blender.nodes.lobes import build_lobes
    base = dict(kind="CONDUCTOR", core_reflectivity=(0.9, 0.62, 0.35), edge_tint=(1.0, 0.85, 0.6),
                roughness=R_01)
    if which == "haziness":  # Figure 8: β_h (ours) vs the physical mix weight β of Eq. 1
        hs = (0.0, 0.25, 0.5, 0.75, 0.95)
        ours = [api.create_material(f"βh {h}", haziness=h, haze_extent=7.0, **base) for h in hs]
        m = api.map_parameters(api.normalise_parameters(dict(base, haziness=0.95, haze_extent=7.0)))
        top = float(m.beta)
        betas = [top * h / hs[-1] for h in hs]
        physical = []
        for b in betas:  # a hand-built mix: same lobes and Fresnel as β_h = 0, β moved by hand
            mat = api.create_material(f"β {b:.2f}", haziness=0.0, haze_extent=7.0, **base)
            tree = mat.node_tree
            material.remove_ours(tree)
            core = api.map_parameters(api.normalise_parameters(dict(base, haziness=0.0)))
            tb = TreeBuilder(tree, roles=True)
            bsdf = build_lobes(tb, "CONDUCTOR", "GGX", beta=b,
                               narrow=dict(roughness=R_01, anisotropy=None, rotation=None),
                               wide=dict(roughness=R_01 * math.sqrt(8.0), anisotropy=None, rotation=None),
                               fresnel=dict(ior=tuple(map(float, core.ior)),
                                            extinction=tuple(map(float, core.extinction))),
                               shared={}, depth=1)
            tree.links.new(bsdf, material.output_node(tree).inputs["Surface"])
            physical.append(mat)
        return [([f"haziness {h:g}" for h in hs], ours),
                ([f"mix weight {b:.2f}" for b in betas], physical)]
    if which == "extent":  # Figure 4: haze extent, isotropic and anisotropic
        ext = (1.0, 3.0, 7.0, 15.0, 30.0)
        iso = [api.create_material(f"λ {e}", haziness=0.8, haze_extent=e, **base) for e in ext]
        aniso_ext = ((1.0, 1.0), (10.0, 1.0), (1.0, 10.0), (20.0, 3.0), (3.0, 20.0))
        aniso = [api.create_material(f"λ {e}", haziness=0.8, haze_extent=e, tangent="RADIAL_Z", **base)
                 for e in aniso_ext]
        return [([f"extent {e:g}" for e in ext], iso),
                ([f"extent x {x:g}, y {y:g}" for x, y in aniso_ext], aniso)]
    raise ValueError(which)


def render(out_path, samples=48, scale=1.0, rows="gallery"):
    hazy_gloss.register()
    from hazy_gloss import api
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    studio(scene)
    spheres = (gallery_rows(api) if rows == "gallery" else looks_rows(api) if rows == "looks"
               else layer_rows(api) if rows == "layer" else glass_rows(api) if rows == "glass"
               else sweep_rows(api, rows))
    width = max(5.2, max(len(mats) for _, mats in spheres) + 0.2)  # scene units, 1 per sphere
    sphere_rows(scene, spheres, ortho_scale=width)
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = True
    try:
        scene.cycles.denoiser = "OPENIMAGEDENOISE"
    except TypeError:
        scene.cycles.use_denoising = False
    scene.render.resolution_x = int(round(200 * width * scale))  # 200 px per unit
    scene.render.resolution_y = int((140 + 230 * len(spheres)) * scale)
    scene.view_settings.view_transform = "AgX" if "AgX" in [
        i.identifier for i in scene.view_settings.bl_rna.properties["view_transform"].enum_items] else "Filmic"
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.abspath(out_path)
    os.makedirs(os.path.dirname(os.path.abspath(out_path)), exist_ok=True)
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(REPO, "out", "gallery.png"))
    ap.add_argument("--samples", type=int, default=48)
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--rows", choices=("gallery", "looks", "layer", "glass", "haziness", "extent"),
                    default="gallery",
                    help="the gallery, or a parameter sweep for the docs")
    args = ap.parse_args(argv)
    seconds = render(args.out, args.samples, args.scale, args.rows)
    print(f"hazy_gloss gallery: wrote {os.path.abspath(args.out)} ({seconds:.0f} s render, "
          f"{args.samples} samples)")


if __name__ == "__main__":
    main()
