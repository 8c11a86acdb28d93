"""The add-on on a scene at Unit Scale 0.01 (one Blender unit is a centimetre): blender_scene.py's
planes, focus object and camera clipping scaled 100 times about the camera, so the scene is the
same in metres and every distance, the Z pass and the focus distance are 100 times as many
Blender units; the lens stays 85 mm f/1. The reference is Cycles' depth of field of the scene
as built in metres at Unit Scale 1: Cycles itself ignores the Unit Scale (it reads the lens'
millimetres as 1e-3 Blender units whatever a unit is), so at 0.01 its blur is 100 times too
small, and the physical truth of the scene is its render at scale 1.
Usage: blender -b --factory-startup --python blender_unit_scale.py -- OUT LENSBLUR_BINARY
(with the add-on installed, as for blender_plugin.py). Writes to OUT: result.exr (the add-on's
result at 0.01), reference.exr (Cycles' depth of field at scale 1); prints
LENSBLUR_UNITS_REPORT <json> (the tool's report) and LENSBLUR_UNITS_DONE."""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import (  # noqa: E402 (found through the path above)
    DOF_SAMPLES, PINHOLE_SAMPLES, build_planes, build_view_layers, enable_addon, render_truth, setup_scene,
)

UNITS_PER_METRE = 100.0
out, binary = sys.argv[sys.argv.index("--") + 1:][:2]



def build_in_units(scene, collections, units_per_metre):
    """The scene in units of 1 / `units_per_metre` metres. The planes' vertices are in metres
    around the camera at the origin: scaling the objects scales the scene about the camera and
    keeps their textures (object coordinates) as they were."""
    scene.unit_settings.scale_length = 1.0 / units_per_metre
    for collection in collections.values():
        for obj in collection.objects:
            obj.scale = (units_per_metre,) * 3
    cam = scene.camera.data
    cam.dof.focus_object.location = BUILT_FOCUS * units_per_metre
    cam.clip_start, cam.clip_end = BUILT_CLIP[0] * units_per_metre, BUILT_CLIP[1] * units_per_metre


scene = setup_scene()
collections = build_planes(scene)
build_view_layers(scene, collections)
cam = scene.camera.data
BUILT_FOCUS, BUILT_CLIP = cam.dof.focus_object.location.copy(), (cam.clip_start, cam.clip_end)
build_in_units(scene, collections, UNITS_PER_METRE)

enable_addon(binary)
scene.render.use_single_layer = False
cam.dof.use_dof = False
scene.cycles.samples = PINHOLE_SAMPLES
bpy.ops.render.render()
bpy.ops.lensblur.defocus(save_path=os.path.join(out, "result.exr"))
print("LENSBLUR_UNITS_REPORT " + bpy.data.images["lensblur_result"]["lensblur_report"])
build_in_units(scene, collections, 1.0)
render_truth(scene, os.path.join(out, "reference.exr"), True, DOF_SAMPLES)
print("LENSBLUR_UNITS_DONE")
