"""The same Cycles render saved as Blender 5's default multilayer EXR (multi-part: one part per
pass, `Front.Combined`, `Front.Depth`, ...) and as the interleaved single-part layout that older
Blenders write; the test reads both with lensblur and expects the same stack.
Usage: python blender_multipart.py -- OUT   (PyPI's bpy 5.x, whose image settings have
`use_exr_interleave`)
Scene: blender_scene.py's three planes, one view layer each, pinhole, 64x48 at 4 samples.
Writes OUT/parts.exr and OUT/interleaved.exr, then prints LENSBLUR_MULTIPART_DONE."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import build_planes, build_view_layers, setup_scene  # noqa: E402

out = sys.argv[sys.argv.index("--") + 1]
scene = setup_scene()
build_view_layers(scene, build_planes(scene))
scene.render.resolution_x, scene.render.resolution_y = 64, 48
scene.cycles.samples = 4
scene.camera.data.dof.use_dof = False
bpy.ops.render.render()

settings = scene.render.image_settings
assert hasattr(settings, "use_exr_interleave"), f"Blender {bpy.app.version_string} has no EXR interleave option"
settings.media_type = "MULTI_LAYER_IMAGE"
settings.file_format = "OPEN_EXR_MULTILAYER"
settings.color_depth = "32"
result = bpy.data.images["Render Result"]
# Blender's default first, as a user's own render output writes it.
assert not settings.use_exr_interleave, "multi-part is no longer the default"
result.save_render(os.path.join(out, "parts.exr"), scene=scene)
settings.use_exr_interleave = True
result.save_render(os.path.join(out, "interleaved.exr"), scene=scene)
print("LENSBLUR_MULTIPART_DONE")
