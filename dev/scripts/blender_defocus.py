"""Blender's Defocus compositor node on one RGB+Z frame, timed inside Blender.

Usage: blender -b --factory-startup --python-exit-code 1 --python blender_defocus.py --
       RGBZ.exr OUT.png PARAMS_JSON REPEATS
   or: BPY_VENV/bin/python blender_defocus.py -- RGBZ.exr OUT.png PARAMS_JSON REPEATS
(Blender 3.4's Defocus node, or 4.2+'s rewritten one through PyPI's bpy module).
OUT is a PNG (8-bit, display encoded, for looking at) or an EXR (RGBA, linear float, for
measuring). RGBZ.exr is a Blender multilayer EXR (ViewLayer.Combined.RGBA + ViewLayer.Depth.Z, planar Z).
PARAMS_JSON: lens_mm, sensor_mm, f_stop, focus_distance, blur_max, width, height, bokeh (the mapping
from lensblur's camera is worked out in dev/src/bench/blender.rs). The scene has no Render Layers
node, so bpy.ops.render.render() renders nothing but the compositor (the engine is the cheap
Workbench anyway). Each render is timed with time.perf_counter around the call; the PNG is
saved afterwards, outside the timing. Prints LENSBLUR_BLENDER <json>."""
import json
import sys
import time

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
src, dst, params, repeats = args[0], args[1], json.loads(args[2]), int(args[3])

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.engine = "BLENDER_WORKBENCH"
scene.render.resolution_x, scene.render.resolution_y = params["width"], params["height"]
scene.render.resolution_percentage = 100
scene.render.use_compositing = True
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"

# Defocus with use_zbuffer reads the lens, sensor and focus distance of scene.camera.
camera = bpy.data.cameras.new("Camera")
camera.lens = params["lens_mm"]
camera.sensor_fit = "AUTO"
camera.sensor_width = params["sensor_mm"]
# The frame is square: the sensor spans it whichever side Blender fits. Blender 5.0's node took
# its pixels per metre from the sensor height (24 mm by default) on this square frame: with only
# the width set it blurred 1.5 times (36 / 24) as much as 3.4 and lensblur, whose results it
# matches once both sides are set (measured on the bench's 256^2 frame).
camera.sensor_height = params["sensor_mm"]
camera.dof.focus_distance = params["focus_distance"]
camera_object = bpy.data.objects.new("Camera", camera)
scene.collection.objects.link(camera_object)
scene.camera = camera_object

if hasattr(scene, "compositing_node_group"):
    # Blender 5.0: the compositor is a node group of the scene, its result a Group Output node.
    tree = bpy.data.node_groups.new("Defocus", "CompositorNodeTree")
    tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    scene.compositing_node_group = tree
    composite = tree.nodes.new("NodeGroupOutput")
else:
    scene.use_nodes = True
    tree = scene.node_tree
    tree.nodes.clear()
    composite = tree.nodes.new("CompositorNodeComposite")
image = tree.nodes.new("CompositorNodeImage")
image.image = bpy.data.images.load(src)
defocus = tree.nodes.new("CompositorNodeDefocus")
defocus.bokeh = params.get("bokeh", "CIRCLE")
defocus.use_zbuffer = True
# 3.4 only: 4.2's rewrite dropped the preview (quality) switch and the gamma correction.
for legacy_setting in ("use_preview", "use_gamma_correction"):
    if hasattr(defocus, legacy_setting):
        setattr(defocus, legacy_setting, False)
defocus.f_stop = params["f_stop"]
defocus.blur_max = params["blur_max"]
# A multilayer EXR's Image node has one output per pass: Combined (colour) and Depth.
colour = image.outputs.get("Combined") or image.outputs.get("Image")
depth = image.outputs.get("Depth") or image.outputs.get("Z")
if colour is None or depth is None:
    raise RuntimeError("no colour or depth output on the Image node: " + ", ".join(o.name for o in image.outputs))
tree.links.new(colour, defocus.inputs["Image"])
tree.links.new(depth, defocus.inputs["Z"])
tree.links.new(defocus.outputs["Image"], composite.inputs[0])

seconds = []
for _ in range(repeats):
    start = time.perf_counter()
    bpy.ops.render.render()
    seconds.append(time.perf_counter() - start)

output = scene.render.image_settings
if dst.lower().endswith(".exr"):
    output.file_format, output.color_mode, output.color_depth = "OPEN_EXR", "RGBA", "32"
else:
    output.file_format, output.color_mode, output.color_depth = "PNG", "RGB", "8"
bpy.data.images["Render Result"].save_render(dst)
report = {
    "seconds": seconds,
    "version": bpy.app.version_string,
    "execution_mode": getattr(tree, "execution_mode", "n/a"),
    "threads": scene.render.threads,
    "outputs": [o.name for o in image.outputs],
}
print("LENSBLUR_BLENDER " + json.dumps(report))
