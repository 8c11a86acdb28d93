"""Renders a tiny two-view-layer scene with Cycles and writes what lensblur must read:
  OUT/render.exr     multilayer render: Front.Combined.RGBA + Front.Depth.Z, Back.*
  OUT/fileout_0001.exr  compositor File Output node (multilayer): Image.RGBA + Depth.V
  OUT/stack_0001.exr    one File Output node, both layers: fg.RGBA + fgDepth.V, bg_Image.RGBA + bg_Z.V
Usage: blender -b --factory-startup --python blender_render.py -- OUT
Front: a 2x2 plane 5 m from the camera; Back: a large plane 10 m away. Transparent film,
so the Front layer is empty (alpha 0, Z = 1e10) around its plane."""
import sys
import bpy

out = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.samples = 4
scene.cycles.use_denoising = False  # Debian builds Blender without OpenImageDenoise
scene.render.resolution_x, scene.render.resolution_y = 32, 24
scene.render.resolution_percentage = 100
scene.render.film_transparent = True
scene.frame_current = 1

cam_data = bpy.data.cameras.new("Camera")
cam = bpy.data.objects.new("Camera", cam_data)
scene.collection.objects.link(cam)
cam.location = (0.0, 0.0, 10.0)  # looking down -Z
scene.camera = cam


def plane(name, size, z, colour):
    mesh = bpy.data.meshes.new(name)
    h = size / 2
    mesh.from_pydata([(-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z)], [], [(0, 1, 2, 3)])
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes = mat.node_tree.nodes
    nodes.clear()
    emit = nodes.new("ShaderNodeEmission")
    emit.inputs["Color"].default_value = colour
    result = nodes.new("ShaderNodeOutputMaterial")
    mat.node_tree.links.new(emit.outputs["Emission"], result.inputs["Surface"])
    mesh.materials.append(mat)
    coll = bpy.data.collections.new(name)
    scene.collection.children.link(coll)
    obj = bpy.data.objects.new(name, mesh)
    coll.objects.link(obj)
    return coll


front = plane("FrontPlane", 2.0, 5.0, (1.0, 0.2, 0.1, 1.0))
back = plane("BackPlane", 40.0, 0.0, (0.1, 0.3, 0.8, 1.0))

first = scene.view_layers[0]
first.name = "Front"
second = scene.view_layers.new("Back")
for layer, hidden in ((first, back), (second, front)):
    layer.use_pass_z = True
    layer.cycles.denoising_store_passes = False
    layer.layer_collection.children[hidden.name].exclude = True

scene.use_nodes = True
tree = scene.node_tree
tree.nodes.clear()
rl = tree.nodes.new("CompositorNodeRLayers")
rl.layer = "Front"
comp = tree.nodes.new("CompositorNodeComposite")
tree.links.new(rl.outputs["Image"], comp.inputs["Image"])
fo = tree.nodes.new("CompositorNodeOutputFile")
fo.format.file_format = "OPEN_EXR_MULTILAYER"
fo.format.color_depth = "32"
fo.base_path = out + "/fileout_"
fo.file_slots.clear()
fo.file_slots.new("Image")
fo.file_slots.new("Depth")
tree.links.new(rl.outputs["Image"], fo.inputs["Image"])
tree.links.new(rl.outputs["Depth"], fo.inputs["Depth"])

# One File Output node writing the whole stack, per-layer slots named as users do:
# colour `fg` + depth `fgDepth`, colour `bg_Image` + depth `bg_Z`.
rl_back = tree.nodes.new("CompositorNodeRLayers")
rl_back.layer = "Back"
stack = tree.nodes.new("CompositorNodeOutputFile")
stack.format.file_format = "OPEN_EXR_MULTILAYER"
stack.format.color_depth = "32"
stack.base_path = out + "/stack_"
stack.file_slots.clear()
for slot, node, socket in (("fg", rl, "Image"), ("fgDepth", rl, "Depth"), ("bg_Image", rl_back, "Image"), ("bg_Z", rl_back, "Depth")):
    stack.file_slots.new(slot)
    tree.links.new(node.outputs[socket], stack.inputs[slot])

scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
scene.render.image_settings.color_depth = "16"
scene.render.filepath = out + "/render.exr"
bpy.ops.render.render(write_still=True)
print("LENSBLUR_RENDER_DONE")
