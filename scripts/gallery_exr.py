# SPDX-License-Identifier: GPL-3.0-or-later
"""Render the gallery's first three rows (the paper's Figure 3 and Table 3 materials) of a
checkout as float EXR, noise fixed (16 samples, seed 0, no denoising), to compare two versions
of the code pixel for pixel:

    .venv/bin/python scripts/gallery_exr.py <checkout> out/a.exr
    .venv/bin/python scripts/gallery_exr.py <other checkout> out/b.exr
"""
import os
import sys


def main(repo, out):
    sys.path.insert(0, repo)
    sys.path.insert(0, os.path.join(repo, "scripts"))
    import bpy
    import gallery
    import hazy_gloss
    hazy_gloss.register()
    from hazy_gloss import api
    bpy.ops.wm.read_homefile(use_empty=True)
    scene = bpy.context.scene
    gallery.studio(scene)
    gallery.sphere_rows(scene, gallery.gallery_rows(api)[:3])
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.use_denoising = False
    scene.cycles.seed = 0
    scene.render.resolution_x, scene.render.resolution_y = 260, 170
    s = scene.render.image_settings
    if hasattr(s, "media_type"):
        s.media_type = "IMAGE"
    s.file_format, s.color_depth, s.exr_codec = "OPEN_EXR", "32", "ZIP"
    scene.render.filepath = os.path.abspath(out)
    bpy.ops.render.render(write_still=True)


if __name__ == "__main__":
    main(os.path.abspath(sys.argv[1]), sys.argv[2])
