"""Blender's Defocus compositor node on one RGB+Z frame, timed inside Blender.

Usage: blender -b --factory-startup --python-exit-code 1 --python blender_defocus.py --
       RGBZ.exr OUT.png PARAMS_JSON REPEATS
RGBZ.exr is a Blender multilayer EXR (ViewLayer.Combined.RGBA + ViewLayer.Depth.Z, planar Z).
PARAMS_JSON: lens_mm, sensor_mm, f_stop, focus_distance, blur_max, width, height, bokeh (the mapping
from lensblur's camera is worked out in src/bench/blender.rs). The scene has no Render Layers
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
camera.dof.focus_distance = params["focus_distance"]
camera_object = bpy.data.objects.new("Camera", camera)
scene.collection.objects.link(camera_object)
scene.camera = camera_object

scene.use_nodes = True
tree = scene.node_tree
tree.nodes.clear()
image = tree.nodes.new("CompositorNodeImage")
image.image = bpy.data.images.load(src)
defocus = tree.nodes.new("CompositorNodeDefocus")
defocus.bokeh = params.get("bokeh", "CIRCLE")
defocus.use_zbuffer = True
defocus.use_preview = False
defocus.use_gamma_correction = False
defocus.f_stop = params["f_stop"]
defocus.blur_max = params["blur_max"]
composite = tree.nodes.new("CompositorNodeComposite")
# A multilayer EXR's Image node has one output per pass: Combined (colour) and Depth.
colour = image.outputs.get("Combined") or image.outputs.get("Image")
depth = image.outputs.get("Depth") or image.outputs.get("Z")
if colour is None or depth is None:
    raise RuntimeError("no colour or depth output on the Image node: " + ", ".join(o.name for o in image.outputs))
tree.links.new(colour, defocus.inputs["Image"])
tree.links.new(depth, defocus.inputs["Z"])
tree.links.new(defocus.outputs["Image"], composite.inputs["Image"])

seconds = []
for _ in range(repeats):
    start = time.perf_counter()
    bpy.ops.render.render()
    seconds.append(time.perf_counter() - start)

scene.render.image_settings.file_format = "PNG"
scene.render.image_settings.color_mode = "RGB"
scene.render.image_settings.color_depth = "8"
bpy.data.images["Render Result"].save_render(dst)
report = {
    "seconds": seconds,
    "version": bpy.app.version_string,
    "execution_mode": getattr(tree, "execution_mode", "n/a"),
    "threads": scene.render.threads,
    "outputs": [o.name for o in image.outputs],
}
print("LENSBLUR_BLENDER " + json.dumps(report))
