# SPDX-License-Identifier: GPL-3.0-or-later
"""Scene helpers for render tests (plain functions; import inside a bpy process, no pytest).

Typical use, in a test that has the ``clean_file`` fixture (an empty file)::

    import scenes
    scenes.setup_render(samples=1, resolution=(8, 8))
    mat = ...                                   # any bpy material
    info = scenes.flat_plane_scene(mat, light_dir=(30, 0))
    img = scenes.render_exr()                   # (H, W, 4) float32, row 0 = bottom row
    pixel = img[4, 4, :3]                       # = Strength * f_r(info["wi"], info["wo"]) * cos θi

Everything is set explicitly, because the defaults break exact tests (denoising, adaptive
sampling, a grey world, a sun of angle 0.00918 rad, indirect clamp 10, glossy blur 1, a 1.5 px
Blackman-Harris pixel filter, MULTI_GGX / F82 node defaults...; docs/blender-versions.md).
"""
from __future__ import annotations

import math
import os
import sys
import tempfile

import bpy
import numpy as np
from mathutils import Matrix, Vector

__all__ = (
    "eevee_engine_id",
    "new_material",
    "empty_material",
    "metallic_material",
    "setup_render",
    "black_world",
    "uniform_world",
    "flat_plane_scene",
    "plane_grid_scene",
    "furnace_sphere_scene",
    "render_exr",
    "centre",
    "eevee_setup",
    "spherical_direction",
)

VERSION = bpy.app.version


# ------------------------------------------------------------------------------------------------
# Version differences (as hazy_gloss/blender/compat.py meets them; the harness must not depend
# on the code under test)
# ------------------------------------------------------------------------------------------------


def eevee_engine_id():
    """``BLENDER_EEVEE`` in 5.0; ``BLENDER_EEVEE_NEXT`` in 4.2-4.5."""
    items = bpy.types.RenderSettings.bl_rna.properties["engine"].enum_items.keys()
    return "BLENDER_EEVEE_NEXT" if "BLENDER_EEVEE_NEXT" in items else "BLENDER_EEVEE"


def new_material(name="Material"):
    """A material with a node tree (``use_nodes`` is deprecated in 5.0, required in 4.x)."""
    mat = bpy.data.materials.new(name)
    if VERSION < (5, 0, 0):
        mat.use_nodes = True
    return mat


def _output_node(tree):
    for node in tree.nodes:
        if node.bl_idname == "ShaderNodeOutputMaterial":
            return node
    return tree.nodes.new("ShaderNodeOutputMaterial")


def empty_material(name="Material"):
    """A material whose tree holds only its Material Output: (material, output node)."""
    mat = new_material(name)
    tree = mat.node_tree
    for node in list(tree.nodes):
        if node.bl_idname != "ShaderNodeOutputMaterial":
            tree.nodes.remove(node)
    return mat, _output_node(tree)


def metallic_material(name="Metallic", *, roughness=0.3, ior=(0.2, 0.9, 1.1),
                      extinction=(3.9, 2.4, 2.2), distribution="GGX",
                      fresnel_type="PHYSICAL_CONDUCTOR", anisotropy=0.0, rotation=0.0):
    """A Metallic BSDF material with every result-changing setting explicit.

    The node defaults are MULTI_GGX and F82; this sets ``distribution`` and ``fresnel_type``.
    Anisotropic materials need an explicit tangent (an unlinked Tangent falls back to a radial
    tangent); link one yourself if ``anisotropy`` != 0."""
    mat, out = empty_material(name)
    tree = mat.node_tree
    bsdf = tree.nodes.new("ShaderNodeBsdfMetallic")
    bsdf.distribution = distribution
    bsdf.fresnel_type = fresnel_type
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["IOR"].default_value = ior
    bsdf.inputs["Extinction"].default_value = extinction
    bsdf.inputs["Anisotropy"].default_value = anisotropy
    bsdf.inputs["Rotation"].default_value = rotation
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


# ------------------------------------------------------------------------------------------------
# Render settings and worlds
# ------------------------------------------------------------------------------------------------


def _world(name, color, strength):
    world = bpy.data.worlds.new(name)
    if VERSION < (5, 0, 0):
        world.use_nodes = True
    tree = world.node_tree
    bg = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeBackground"), None)
    if bg is None:
        bg = tree.nodes.new("ShaderNodeBackground")
        out = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"), None)
        if out is None:
            out = tree.nodes.new("ShaderNodeOutputWorld")
        tree.links.new(bg.outputs[0], out.inputs["Surface"])
    bg.inputs["Color"].default_value = (*color, 1.0)
    bg.inputs["Strength"].default_value = strength
    world.color = color
    bpy.context.scene.world = world
    return world


def black_world():
    """A world that emits nothing (colour 0, strength 0)."""
    return _world("HG Test Black World", (0.0, 0.0, 0.0), 0.0)


def uniform_world(strength=1.0, color=(1.0, 1.0, 1.0)):
    """A constant environment of radiance ``strength * color`` (a furnace)."""
    return _world("HG Test Uniform World", tuple(color), float(strength))


def _cpu_count():
    """Cores this process may use (respects CPU affinity / container limits where visible)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:
        return os.cpu_count() or 1


def setup_render(engine="CYCLES", samples=1, resolution=(64, 64), *, bounces=4, threads=None,
                 seed=0):
    """Configure the current scene for exact, noise-free analytic tests and return it.

    Cycles on the CPU; ``samples`` fixed (adaptive sampling and denoising off); a Gaussian pixel
    filter of the minimum width 0.01 px (each pixel is the value at its centre; BOX would
    ignore the width and average over the whole pixel); no clamping,
    no glossy blur, light threshold 0, path guiding off; film exposure 1 and the Standard view
    transform (EXR output is scene-linear anyway); a black world; seed fixed; all cores.
    ``bounces`` sets every bounce limit (a plane lit by a delta sun needs 0 bounces, a convex
    object in a furnace 1; use more for concave or layered set-ups).
    """
    scene = bpy.context.scene
    render = scene.render
    render.engine = engine
    render.resolution_x, render.resolution_y = resolution
    render.resolution_percentage = 100
    render.pixel_aspect_x = render.pixel_aspect_y = 1.0
    render.film_transparent = False
    render.use_border = False
    render.threads_mode = "FIXED"
    render.threads = threads or _cpu_count()
    if hasattr(render, "use_persistent_data"):
        render.use_persistent_data = False

    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = samples
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    if hasattr(cy, "use_preview_denoising"):
        cy.use_preview_denoising = False
    # Cycles' BOX filter is always 1 px wide (it ignores filter_width; the UI hides it), so
    # samples spread over the whole pixel.  A Gaussian of the minimum width 0.01 px puts every
    # sample within 0.005 px of the pixel centre: each pixel is the value at its centre.
    cy.pixel_filter_type = "GAUSSIAN"
    cy.filter_width = 0.01
    cy.seed = seed
    cy.use_animated_seed = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.blur_glossy = 0.0
    cy.light_sampling_threshold = 0.0
    cy.use_guiding = False
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    cy.film_exposure = 1.0
    cy.max_bounces = bounces
    cy.diffuse_bounces = bounces
    cy.glossy_bounces = bounces
    cy.transmission_bounces = bounces
    cy.volume_bounces = bounces
    cy.transparent_max_bounces = max(bounces, 8)
    cy.min_light_bounces = 0
    cy.min_transparent_bounces = 0
    if hasattr(cy, "use_auto_tile"):
        cy.use_auto_tile = False
    if hasattr(cy, "use_fast_gi"):
        cy.use_fast_gi = False

    vs = scene.view_settings
    vs.view_transform = "Standard"
    vs.look = "None"
    vs.exposure = 0.0
    vs.gamma = 1.0
    vs.use_curve_mapping = False
    scene.display_settings.display_device = "sRGB"

    if hasattr(render, "use_compositing"):
        render.use_compositing = False
    if hasattr(render, "use_sequencer"):
        render.use_sequencer = False

    black_world()
    return scene


def eevee_setup(samples=1, resolution=(64, 64)):
    """Configure the current scene for EEVEE (engine id per version), black world, Standard view.

    EEVEE is not exact (LTC lights, split-sum, approximated conductor Fresnel, no anisotropy) and
    its first render compiles shaders (~30 s headless).  Returns the scene."""
    scene = setup_render(samples=samples, resolution=resolution)
    scene.render.engine = eevee_engine_id()
    ee = scene.eevee
    ee.taa_render_samples = samples
    if hasattr(ee, "use_shadows"):
        ee.use_shadows = True
    if hasattr(ee, "use_raytracing"):
        ee.use_raytracing = False
    if "filter_size" in scene.render.bl_rna.properties:  # EEVEE's pixel filter (px)
        prop = scene.render.bl_rna.properties["filter_size"]
        scene.render.filter_size = prop.hard_min
    return scene


# ------------------------------------------------------------------------------------------------
# Scenes
# ------------------------------------------------------------------------------------------------


def spherical_direction(theta_deg, phi_deg=0.0):
    """Unit vector at polar angle θ from +Z and azimuth φ from +X (world = plane-local frame)."""
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return Vector((math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)))


def _direction64(theta_deg, phi_deg=0.0):
    """spherical_direction in float64 numpy (mathutils vectors are float32)."""
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def _plane_mesh(name, size):
    """A square in the XY plane facing +Z, UV-mapped with U along +X (tangent = +X)."""
    h = size / 2.0
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, co in zip(uv.data, [(0, 0), (1, 0), (1, 1), (0, 1)]):
        loop.uv = co
    mesh.update()
    return mesh


def _link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _camera_basis(view_dir):
    """Rotation whose local +Z is ``view_dir`` (the camera looks along -Z), with image right
    (local +X) horizontal, along +Y x view_dir, and image up (local +Y) = view_dir x right.
    Looking straight down, right = +X and up = +Y; tilted about X, up leans towards +Z.
    (``Vector.to_track_quat`` is avoided: it flips the up axis for some directions.)"""
    z = view_dir.normalized()
    ref = Vector((0.0, 1.0, 0.0)) if abs(z.y) < 0.999 else Vector((0.0, 0.0, 1.0))
    x = ref.cross(z).normalized()
    y = z.cross(x)
    return Matrix((x, y, z)).transposed()


def _ortho_camera(name, view_dir, ortho_scale, distance=10.0):
    cam_data = bpy.data.cameras.new(name)
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = ortho_scale
    cam_data.clip_start = 0.01
    cam_data.clip_end = 4.0 * distance
    cam = _link(bpy.data.objects.new(name, cam_data))
    cam.location = view_dir * distance
    cam.rotation_euler = _camera_basis(view_dir).to_euler()
    bpy.context.scene.camera = cam
    return cam


def _sun(light_dir, strength):
    sun_data = bpy.data.lights.new("HG Test Sun", type="SUN")
    sun_data.energy = strength
    sun_data.angle = 0.0
    sun_data.color = (1.0, 1.0, 1.0)
    if hasattr(sun_data, "use_shadow"):
        sun_data.use_shadow = True
    sun = _link(bpy.data.objects.new("HG Test Sun", sun_data))
    # A sun emits along its local -Z: point local +Z at the light (towards wi).
    sun.rotation_euler = light_dir.to_track_quat("Z", "Y").to_euler()
    sun.location = light_dir * 5.0
    return sun


def flat_plane_scene(material, *, tilt_deg=0.0, view_dir=None, light_dir=(30.0, 0.0),
                     strength=1.0, ortho_scale=1.0):
    """A plane facing +Z at the origin, an orthographic camera, a delta sun.  Returns a dict.

    The world frame is the plane's shading frame: normal +Z, tangent +X (the UV U axis).
    ``light_dir=(θ, φ)`` in degrees: the sun sits at polar angle θ from the normal and azimuth φ
    from +X (so wi = spherical_direction(θ, φ)); angle 0, so it is a delta light and the
    irradiance on the plane is ``strength * cos θ``.
    The camera looks at the origin from ``view_dir=(θ_v, φ_v)`` (default (0, 0): straight down
    -Z, view direction = normal).  ``tilt_deg=t`` is the shorthand for a camera tilted about the
    X axis, i.e. ``view_dir=(t, -90)`` (the camera sits on the -Y side).
    The plane is sized so it fills the frame at any view angle < 85°.
    Every pixel then reads  strength * f_r(wi, wo) * cos θi  (no other light, black world).

    Returned keys: plane, camera, sun (objects), wi, wo (numpy unit vectors, local = world frame),
    size (the plane's edge length).
    """
    if view_dir is None:
        view_dir = (float(tilt_deg), -90.0) if tilt_deg else (0.0, 0.0)
    wi = spherical_direction(*light_dir)
    wo = spherical_direction(*view_dir)
    cos_v = max(wo.z, math.cos(math.radians(85.0)))
    size = 4.0 * ortho_scale / cos_v

    plane = _link(bpy.data.objects.new("HG Test Plane", _plane_mesh("HG Test Plane", size)))
    plane.data.materials.append(material)
    cam = _ortho_camera("HG Test Camera", wo, ortho_scale)
    sun = _sun(wi, strength)
    return {
        "plane": plane,
        "camera": cam,
        "sun": sun,
        "wi": _direction64(*light_dir),
        "wo": _direction64(*view_dir),
        "size": size,
    }


def render_plane(material, *, engine="CYCLES", samples=1, resolution=(8, 8), light_dir=(30.0, 0.0),
                 view_dir=(0.0, 0.0), strength=1.0):
    """``material`` on flat_plane_scene in a scene of its own (every object removed first):
    Cycles with 1 sample and no bounces (every pixel f_r(wi, wo) cos θi · strength), or EEVEE
    with ``samples``.  Returns the float64 RGB image."""
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    if engine == "EEVEE":
        eevee_setup(samples=samples, resolution=resolution)
    else:
        setup_render("CYCLES", samples=1, resolution=resolution, bounces=0)
    flat_plane_scene(material, light_dir=light_dir, view_dir=view_dir, strength=strength)
    return render_exr()[..., :3].astype(np.float64)


def centre(img):
    """The mean RGB of the 2x2 pixels at the centre of ``img`` (a plane's f_r cos θi there)."""
    h, w = img.shape[:2]
    return img[h // 2 - 1:h // 2 + 1, w // 2 - 1:w // 2 + 1, :3].reshape(-1, 3).mean(axis=0)


def _feed(tree, sock, v):
    if isinstance(v, bpy.types.NodeSocket):
        tree.links.new(v, sock)
    elif v is not None:
        sock.default_value = v


def math_node(tree, op, *operands):
    """A Math node ``op`` on ``operands`` (sockets are linked, numbers typed in); its output."""
    n = tree.nodes.new("ShaderNodeMath")
    n.operation = op
    for sock, v in zip(n.inputs, operands):
        _feed(tree, sock, v)
    return n.outputs[0]


def combine_xyz(tree, *lanes):
    """A Combine XYZ node of three lanes (sockets or numbers); its output."""
    n = tree.nodes.new("ShaderNodeCombineXYZ")
    for sock, v in zip(n.inputs, lanes):
        _feed(tree, sock, v)
    return n.outputs[0]


def plane_grid_scene(materials, *, strength=1.0):
    """One unit plane per material, tiled in a square grid facing +Z, seen straight down by an
    orthographic camera, lit by a delta sun along the normal: one render measures them all.

    Call :func:`setup_render` with ``resolution=(info["side"],) * 2`` (one pixel per plane) and
    ``bounces=0``.  Pixel [row, col] of :func:`render_exr` (row 0 = bottom) shows
    ``materials[info["index"][row, col]]`` (-1: no plane) and reads
    ``strength * f_r(n, n)`` (cos θi = 1).  Returns a dict: side, index (side x side ints)."""
    side = max(4, math.ceil(math.sqrt(len(materials))))  # Blender renders at least 4 x 4 px
    index = np.full((side, side), -1, dtype=np.int64)
    for i, mat in enumerate(materials):
        row, col = divmod(i, side)
        mesh = _plane_mesh(f"HG Grid {i}", 1.0)
        obj = _link(bpy.data.objects.new(f"HG Grid {i}", mesh))
        obj.location = (col - (side - 1) / 2.0, row - (side - 1) / 2.0, 0.0)
        obj.data.materials.append(mat)
        index[row, col] = i
    _ortho_camera("HG Test Camera", Vector((0.0, 0.0, 1.0)), float(side))
    _sun(Vector((0.0, 0.0, 1.0)), strength)
    return {"side": side, "index": index}


def _points_sphere_group(material, radius):
    tree = bpy.data.node_groups.new("HG Test Points Sphere", "GeometryNodeTree")
    tree.interface.new_socket(name="Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    out = tree.nodes.new("NodeGroupOutput")
    pts = tree.nodes.new("GeometryNodePoints")
    pts.inputs["Count"].default_value = 1
    pts.inputs["Position"].default_value = (0.0, 0.0, 0.0)
    pts.inputs["Radius"].default_value = radius
    setmat = tree.nodes.new("GeometryNodeSetMaterial")
    setmat.inputs["Material"].default_value = material
    tree.links.new(pts.outputs["Points"], setmat.inputs["Geometry"])
    tree.links.new(setmat.outputs["Geometry"], out.inputs[0])
    return tree


def analytic_sphere(name, location, material, radius=0.5):
    """A sphere Cycles renders exactly (a geometry-nodes point of ``radius``) at ``location``."""
    obj = _link(bpy.data.objects.new(name, bpy.data.meshes.new(name)))
    obj.location = location
    obj.modifiers.new("points", "NODES").node_group = _points_sphere_group(material, radius)
    obj.data.materials.append(material)
    return obj


def furnace_sphere_scene(material, world_strength=1.0, *, radius=1.0, view_dir=(0.0, 0.0),
                         ortho_scale=None):
    """An exact sphere (a geometry-nodes point of radius ``radius``, which Cycles renders as an
    analytic sphere) with ``material``, in a uniform white world of radiance ``world_strength``,
    seen by an orthographic camera from ``view_dir=(θ, φ)`` (degrees, default straight down).

    The film is transparent so that sphere pixels have alpha 1 and background pixels alpha 0:
    use ``img[..., 3] > 0.999`` as the sphere mask.  Default framing: the sphere spans 80% of the
    frame.  Call :func:`setup_render` first (with ``bounces`` >= 1, more for non-convex set-ups);
    this replaces its black world.  Returns a dict: sphere, camera, world, radius."""
    world = uniform_world(world_strength)
    bpy.context.scene.render.film_transparent = True
    obj = _link(bpy.data.objects.new("HG Test Sphere", bpy.data.meshes.new("HG Test Sphere")))
    mod = obj.modifiers.new("HG Points Sphere", "NODES")
    mod.node_group = _points_sphere_group(material, radius)
    obj.data.materials.append(material)
    cam = _ortho_camera("HG Test Camera", spherical_direction(*view_dir),
                        ortho_scale or 2.5 * radius)
    return {"sphere": obj, "camera": cam, "world": world, "radius": radius}


# ------------------------------------------------------------------------------------------------
# Rendering
# ------------------------------------------------------------------------------------------------


#: What Cycles logs when a material needs more closures than the kernel holds (it then drops
#: lobes): every test render fails on it.  Logged (scene/scene.cpp get_max_closure_count) with
#: Blender's debug flag on in 5.x; 4.5's glog keeps it at a verbose level the module cannot set.
CLOSURE_WARNING = "Maximum number of closures exceeded"


class ClosureLimitExceeded(AssertionError):
    pass


def render_still():
    """bpy.ops.render.render(write_still=True), failing when Cycles reports that a material
    exceeds its closure limit (stdout and stderr are read around the render)."""
    fds = (1, 2)
    sys.stdout.flush()
    sys.stderr.flush()
    log = tempfile.TemporaryFile(mode="w+b")
    saved = [os.dup(f) for f in fds]
    debug = bpy.app.debug
    try:
        for f in fds:
            os.dup2(log.fileno(), f)
        bpy.app.debug = True
        bpy.ops.render.render(write_still=True)
    finally:
        bpy.app.debug = debug
        sys.stdout.flush()
        sys.stderr.flush()
        for f, fd in zip(fds, saved):
            os.dup2(fd, f)
            os.close(fd)
    log.seek(0)
    text = log.read().decode("utf-8", "replace")
    log.close()
    kept = [ln for ln in text.splitlines() if "Saved:" in ln or "WARNING" in ln or "Error" in ln]
    if kept:
        print("\n".join(kept))
    bad = [ln for ln in text.splitlines() if CLOSURE_WARNING in ln]
    if bad:
        raise ClosureLimitExceeded(bad[0].strip())


def render_exr(path=None, *, codec="ZIP"):
    """Render the current scene and return its pixels as float32 (H, W, 4), RGBA, scene-linear.

    Row 0 is the BOTTOM row of the image (Blender's pixel order); column 0 is the left column.
    Route: 32-bit float OpenEXR (lossless ``codec`` ZIP or NONE) written by ``write_still``,
    loaded with ``bpy.data.images.load`` and read with ``foreach_get`` (a background-mode Render
    Result has no readable pixels).  The image datablock is removed; the file is deleted unless
    ``path`` was given."""
    scene = bpy.context.scene
    render = scene.render
    settings = render.image_settings
    if hasattr(settings, "media_type"):  # 5.0
        settings.media_type = "IMAGE"
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    settings.color_depth = "32"
    settings.exr_codec = codec
    if hasattr(settings, "color_management"):
        settings.color_management = "FOLLOW_SCENE"
    render.use_file_extension = True

    keep = path is not None
    if not keep:
        fd, path = tempfile.mkstemp(suffix=".exr", prefix="hg_render_")
        os.close(fd)
    path = os.path.abspath(path)
    old_path = render.filepath
    render.filepath = path
    try:
        render_still()
    finally:
        render.filepath = old_path
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        raise RuntimeError(f"render did not write {path}")

    img = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = img.size
        channels = img.channels
        buf = np.empty(w * h * channels, dtype=np.float32)
        img.pixels.foreach_get(buf)
    finally:
        bpy.data.images.remove(img)
        if not keep:
            os.remove(path)
    arr = buf.reshape(h, w, channels)
    if channels == 3:
        arr = np.concatenate([arr, np.ones((h, w, 1), np.float32)], axis=-1)
    return arr


def render_aovs(read_exr, tree, sockets):
    """Cycles' values of ``sockets`` ({name: socket of ``tree``}) per pixel, written by Value
    AOV outputs added to ``tree``: {name: (H, W) float64}, row 0 the bottom.  A colour socket
    reads as Blender's Color -> Float conversion (its luminance), as it does into a float
    input.  ``read_exr`` as for :func:`render_passes`."""
    vl = bpy.context.view_layer
    for name, sock in sockets.items():
        if name not in vl.aovs:
            aov = vl.aovs.add()
            aov.name, aov.type = name, "VALUE"
        out = tree.nodes.new("ShaderNodeOutputAOV")
        out.aov_name = name
        tree.links.new(sock, out.inputs["Value"])
    scene = bpy.context.scene
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    fd, path = tempfile.mkstemp(suffix=".exr", prefix="hg_aov_")
    os.close(fd)
    old = scene.render.filepath
    scene.render.filepath = path
    try:
        render_still()
        ch = read_exr(path)
    finally:
        scene.render.filepath = old
        if os.path.exists(path):
            os.remove(path)
    return {n: np.asarray(next(v for k, v in ch.items() if k.split(".")[-2] == n), np.float64)
            for n in sockets}


#: Render passes by the names :func:`render_passes` takes -> (view-layer property, EXR pass
#: names: 5.x writes "Glossy Direct", 4.5 "GlossDir").
PASSES = {
    "combined": (None, ("Combined",)),
    "glossy_direct": ("use_pass_glossy_direct", ("Glossy Direct", "GlossDir")),
    "glossy_color": ("use_pass_glossy_color", ("Glossy Color", "GlossCol")),
    "diffuse_direct": ("use_pass_diffuse_direct", ("Diffuse Direct", "DiffDir")),
    "diffuse_color": ("use_pass_diffuse_color", ("Diffuse Color", "DiffCol")),
    "emission": ("use_pass_emit", ("Emission", "Emit")),
    "glossy_indirect": ("use_pass_glossy_indirect", ("Glossy Indirect", "GlossInd")),
    "diffuse_indirect": ("use_pass_diffuse_indirect", ("Diffuse Indirect", "DiffInd")),
    "transmission_direct": ("use_pass_transmission_direct", ("Transmission Direct", "TransDir")),
    "transmission_indirect": ("use_pass_transmission_indirect",
                              ("Transmission Indirect", "TransInd")),
    "transmission_color": ("use_pass_transmission_color", ("Transmission Color", "TransCol")),
    "normal": ("use_pass_normal", ("Normal",)),
}


def render_passes(read_exr, names=("combined",), *, path=None):
    """Render the current scene to a multilayer EXR and return {name: (H, W, 3) float64} for the
    pass ``names`` (keys of :data:`PASSES`; "normal" is the world-space shading normal) plus
    "alpha" (H, W).  Cycles' direct passes hold
    the light without the BSDF's colour: "glossy" (glossy direct x glossy colour) and "diffuse"
    are what the combined pass adds up.  ``read_exr`` is an EXR reader
    ``path -> {channel: (H, W)}`` (hazy_gloss.conversion.imagecheck.read_exr; the harness does not import it)."""
    scene = bpy.context.scene
    vl = bpy.context.view_layer
    wanted = list(names)
    for light in ("glossy", "diffuse"):
        if light in wanted:
            wanted.remove(light)
            wanted += [f"{light}_direct", f"{light}_color"]
    for name in wanted:
        prop = PASSES[name][0]
        if prop:
            setattr(vl, prop, True)
    settings = scene.render.image_settings
    if hasattr(settings, "media_type"):
        settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    keep = path is not None
    if not keep:
        fd, path = tempfile.mkstemp(suffix=".exr", prefix="hg_passes_")
        os.close(fd)
    old = scene.render.filepath
    scene.render.filepath = path
    try:
        render_still()
        ch = read_exr(path)
    finally:
        scene.render.filepath = old
        if not keep and os.path.exists(path):
            os.remove(path)
    out = {}
    for name in wanted:
        exr = PASSES[name][1]
        keys = [k for k in ch if k.split(".")[-2] in exr]
        by = {k.split(".")[-1]: ch[k] for k in keys}
        xyz = ("X", "Y", "Z") if "X" in by else ("R", "G", "B")  # vector passes: X, Y, Z
        out[name] = np.stack([by[c] for c in xyz], axis=-1).astype(np.float64)
    for light in ("glossy", "diffuse"):
        if light in names:
            out[light] = out[f"{light}_direct"] * out[f"{light}_color"]
    alpha = [k for k in ch if k.endswith("Combined.A")]
    out["alpha"] = ch[alpha[0]].astype(np.float64) if alpha else None
    return out
