"""Drives the add-on's shot operators in headless Blender: a 5-frame focus pull (focus
distance and f-stop animated) of blender_scene.py's three planes, one view layer each.
Usage: blender -b --factory-startup --python blender_animation.py -- OUT LENSBLUR_BINARY
Writes to OUT:
  shot/           bpy.ops.lensblur.defocus_animation: layers.000N.exr (Blender's renders),
                  camera.json (the animated camera), defocus.000N.exr (lensblur)
  farm/           bpy.ops.lensblur.farm_bundle over frames 2-3: layers, camera.json and
                  farm-bundle/ (template.yaml, parameter_values.json)
  reference.000N.exr  Cycles' own depth of field of each frame
Prints LENSBLUR_ANIMATION_CHECKS <json>, then LENSBLUR_ANIMATION_DONE."""
import json
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import (  # noqa: E402 (found through the path above)
    DOF_SAMPLES, PINHOLE_SAMPLES, build_planes, build_view_layers, enable_addon, render_truth, setup_scene,
)

out, binary = sys.argv[sys.argv.index("--") + 1:][:2]
# The pull: focus from in front of the card (2 m) to the back wall (15 m), stopping down.
FOCUS = {1: 2.0, 2: 3.0, 3: 4.0, 4: 8.0, 5: 15.0}
FSTOP = {1: 1.0, 5: 2.0}
checks = {}


def animate_camera(scene):
    dof = scene.camera.data.dof
    dof.focus_object = None
    for frame, distance in FOCUS.items():
        dof.focus_distance = distance
        dof.keyframe_insert("focus_distance", frame=frame)
    for frame, fstop in FSTOP.items():
        dof.aperture_fstop = fstop
        dof.keyframe_insert("aperture_fstop", frame=frame)
    scene.frame_start, scene.frame_end = 1, 5


def warnings_of(image_name):
    return json.loads(bpy.data.images[image_name]["lensblur_warnings"])


def bad_setup_warnings(scene):
    """One frame with Film > Transparent off and the camera's DoF on: both are warned about."""
    scene.render.film_transparent = False
    scene.camera.data.dof.use_dof = True
    bpy.ops.lensblur.defocus_animation(directory=os.path.join(out, "bad"), frame_start=1, frame_end=1, use_node=False)
    checks["bad_setup_warnings"] = warnings_of("lensblur_sequence")
    scene.render.film_transparent = True
    scene.camera.data.dof.use_dof = False


def focus_pull(scene):
    bpy.ops.lensblur.defocus_animation(directory=os.path.join(out, "shot"))
    image = bpy.data.images["lensblur_sequence"]
    node = compat.compositor_tree(scene).nodes["lensblur_sequence"]
    report = json.loads(image["lensblur_report"])
    checks["sequence"] = {
        "source": image.source,
        "node_image": node.image.name,
        "node_frames": [node.frame_start, node.frame_offset, node.frame_duration],
        "rendered": report["rendered"],
        "warnings": warnings_of("lensblur_sequence"),
        "current_frame": scene.frame_current,
    }
    # The node shows the frame the scene is on.
    scene.frame_set(4)
    image.update()
    checks["sequence"]["size_at_frame_4"] = list(image.size)
    with open(os.path.join(out, "shot", "camera.json")) as f:
        checks["camera_file"] = json.load(f)


def stale_render(scene):
    """The Render Result of frame 3, defocused with the scene at frame 4: 'render again'."""
    scene.frame_set(3)
    bpy.ops.render.render()
    scene.frame_set(4)
    bpy.ops.lensblur.defocus(layers="L_*")
    checks["stale_warnings"] = warnings_of("lensblur_result")
    scene.frame_set(3)
    bpy.ops.lensblur.defocus(layers="L_*")
    checks["fresh_warnings"] = warnings_of("lensblur_result")


def farm(scene):
    bpy.ops.lensblur.farm_bundle(directory=os.path.join(out, "farm"), frame_start=2, frame_end=3, chunk_size=1)


scene = setup_scene()
build_view_layers(scene, build_planes(scene))
compat = enable_addon(binary)
animate_camera(scene)
scene.render.use_single_layer = False
scene.camera.data.dof.use_dof = False
scene.cycles.samples = PINHOLE_SAMPLES
bad_setup_warnings(scene)
focus_pull(scene)
stale_render(scene)
farm(scene)
for frame in FOCUS:
    scene.frame_set(frame)
    render_truth(scene, os.path.join(out, f"reference.{frame:04d}.exr"), True, DOF_SAMPLES)
print("LENSBLUR_ANIMATION_CHECKS " + json.dumps(checks))
print("LENSBLUR_ANIMATION_DONE")
