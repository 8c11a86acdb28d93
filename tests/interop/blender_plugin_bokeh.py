"""Bokeh orientation of the lensblur add-on against Cycles: one small emissive square far
behind focus, a 5-blade aperture turned 20 degrees (odd blade counts show a mirror).
Usage: blender -b --factory-startup --python blender_plugin_bokeh.py -- OUT LENSBLUR_BINARY
(with the add-on installed, as for blender_plugin.py). Writes to OUT: stack.exr (the pinhole
Render Result), addon.exr (the add-on's result), reference.exr (Cycles DOF); prints
LENSBLUR_BOKEH_DONE."""
import math
import os
import sys

import bpy
import addon_utils  # after bpy: importing PyPI's bpy module puts Blender's modules on the path

out, binary = sys.argv[sys.argv.index("--") + 1:][:2]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.use_denoising = False
scene.cycles.seed = 1
scene.render.resolution_x = scene.render.resolution_y = 96
scene.render.resolution_percentage = 100
scene.render.film_transparent = True
cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
scene.collection.objects.link(cam)
scene.camera = cam
cam.data.lens = 50.0
dof = cam.data.dof
# CoC radius 16.7 px for the square at 15 m; the pentagon is far larger than the square.
dof.aperture_fstop, dof.focus_distance = 0.5, 0.4
dof.aperture_blades, dof.aperture_rotation = 5, math.radians(20.0)

mesh = bpy.data.meshes.new("square")
h = 0.2
mesh.from_pydata([(-h, -h, -15), (h, -h, -15), (h, h, -15), (-h, h, -15)], [], [(0, 1, 2, 3)])
mat = bpy.data.materials.new("light")
mat.use_nodes = True
nodes = mat.node_tree.nodes
nodes.clear()
emit = nodes.new("ShaderNodeEmission")
emit.inputs["Strength"].default_value = 5.0
surface = nodes.new("ShaderNodeOutputMaterial")
mat.node_tree.links.new(emit.outputs["Emission"], surface.inputs["Surface"])
mesh.materials.append(mat)
scene.collection.objects.link(bpy.data.objects.new("square", mesh))
scene.view_layers[0].name = "L_square"
scene.view_layers[0].use_pass_z = True

addon = addon_utils.enable("lensblur", default_set=True, handle_error=None)
assert addon is not None
bpy.context.preferences.addons["lensblur"].preferences.binary_path = binary
scene.cycles.samples = 16
bpy.ops.render.render()
bpy.ops.lensblur.defocus(save_path=os.path.join(out, "addon.exr"))
settings = scene.render.image_settings
with addon.compat.multilayer_exr(settings):
    bpy.data.images["Render Result"].save_render(os.path.join(out, "stack.exr"), scene=scene)

dof.use_dof = True
scene.cycles.samples = 1024
settings.file_format = "OPEN_EXR"
settings.color_mode = "RGBA"
settings.color_depth = "32"
scene.render.filepath = os.path.join(out, "reference.exr")
bpy.ops.render.render(write_still=True)
print("LENSBLUR_BOKEH_DONE")
