"""Loads an EXR written by lensblur the way a Blender user would (bpy.data.images.load and a
compositor Image node), reports what Blender sees, and re-renders one pass through the
compositor into a plain RGBA float EXR so the test can compare pixel values.
Usage: blender -b --factory-startup --python blender_load.py -- INPUT OUTPUT [LAYER]
Prints one line: LENSBLUR_LOAD <json> with the node's layer list probe and output sockets."""
import json
import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
src, dst = args[0], args[1]
layer = args[2] if len(args) > 2 else ""

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
img = bpy.data.images.load(src)
scene.use_nodes = True
tree = scene.node_tree
tree.nodes.clear()
node = tree.nodes.new("CompositorNodeImage")
node.image = img
report = {"type": img.type, "layers": []}
try:
    node.layer = "\x01no-such-layer"
except TypeError as e:
    # Blender lists the layers it found in the enum error: "... not found in ('a', 'b')".
    report["layers"] = [s.strip(" '") for s in str(e).split("not found in (")[-1].rstrip(")").split(",") if s.strip(" '")]
if layer:
    node.layer = layer
report["outputs"] = [o.name for o in node.outputs]
print("LENSBLUR_LOAD " + json.dumps(report))

cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam)
scene.camera = cam
scene.render.engine = "CYCLES"
scene.cycles.samples = 1
scene.cycles.use_denoising = False
first = node.outputs[0]
width, height = (img.size[0], img.size[1]) if img.size[0] else (0, 0)
if not width:
    # Multilayer images have no flat buffer; the size comes from the node's render result.
    width, height = int(args[3]), int(args[4])
scene.render.resolution_x, scene.render.resolution_y = width, height
scene.render.resolution_percentage = 100
scene.render.film_transparent = True
scene.view_settings.view_transform = "Standard"
comp = tree.nodes.new("CompositorNodeComposite")
comp.use_alpha = True
tree.links.new(first, comp.inputs["Image"])
tree.links.new(node.outputs["Alpha"], comp.inputs["Alpha"])
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_mode = "RGBA"
scene.render.image_settings.color_depth = "32"
scene.render.filepath = dst
bpy.ops.render.render(write_still=True)
print("LENSBLUR_LOAD_DONE")
