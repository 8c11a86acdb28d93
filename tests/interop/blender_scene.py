"""The test scene of the Blender add-on tests (blender_plugin.py, blender_animation.py):
three emissive, procedurally textured planes facing an 85 mm f/1 camera, one view layer each
(the others excluded), transparent film, Depth pass on, and a Reference view layer holding
every plane for Cycles' own depth of field:
  L_front  a checker bar 1.5 m away (CoC radius ~6.7 px at 160 px wide, focused at 4 m)
  L_mid    a wave-textured card 4 m away, in focus (via a focus object off the view axis)
  L_back   a checker wall 15 m away (CoC radius ~2.9 px)"""
import math
import time

import bpy
import addon_utils  # after bpy: importing PyPI's bpy module puts Blender's modules on the path

WIDTH, HEIGHT = 160, 120
PINHOLE_SAMPLES = 16  # emission only: the pinhole layers converge fast (anti-aliasing only)
DOF_SAMPLES = 1024  # the aperture integral is noisy; see the Rust tests for the thresholds


def setup_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.use_denoising = False  # Debian builds Blender without OpenImageDenoise
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 1
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.view_settings.view_transform = "Standard"
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)  # at the origin, looking down -Z
    scene.camera = cam
    cam.data.lens = 85.0
    cam.data.sensor_width = 36.0
    dof = cam.data.dof
    dof.aperture_fstop = 1.0
    dof.aperture_blades = 5
    dof.aperture_rotation = math.radians(10.0)
    target = bpy.data.objects.new("FocusTarget", None)
    scene.collection.objects.link(target)
    # Off the view axis: the focus distance is planar (4), not Euclidean (4.016).
    target.location = (0.3, 0.2, -4.0)
    dof.focus_object = target
    return scene


def emission_material(name, texture):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.clear()
    coords = nodes.new("ShaderNodeTexCoord")
    tex = texture(nodes)
    links.new(coords.outputs["Object"], tex.inputs["Vector"])
    emit = nodes.new("ShaderNodeEmission")
    links.new(tex.outputs["Color"], emit.inputs["Color"])
    result = nodes.new("ShaderNodeOutputMaterial")
    links.new(emit.outputs["Emission"], result.inputs["Surface"])
    return mat


def checker(size, c1, c2):
    def make(nodes):
        tex = nodes.new("ShaderNodeTexChecker")
        tex.inputs["Scale"].default_value = 1.0 / size
        tex.inputs["Color1"].default_value = c1
        tex.inputs["Color2"].default_value = c2
        return tex

    return make


def waves(nodes):
    tex = nodes.new("ShaderNodeTexWave")
    tex.inputs["Scale"].default_value = 4.0
    tex.inputs["Distortion"].default_value = 3.0
    return tex


def plane(scene, name, rect, z, material):
    (x0, y0), (x1, y1) = rect
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)], [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    coll = bpy.data.collections.new(name)
    scene.collection.children.link(coll)
    coll.objects.link(bpy.data.objects.new(name, mesh))
    return coll


def build_planes(scene):
    front = emission_material("front", checker(0.04, (0.9, 0.1, 0.05, 1), (0.9, 0.9, 0.85, 1)))
    mid = emission_material("mid", waves)
    back = emission_material("back", checker(0.4, (0.15, 0.3, 0.8, 1), (0.8, 0.65, 0.2, 1)))
    return {
        "L_front": plane(scene, "front", ((-0.22, -0.3), (-0.08, 0.3)), -1.5, front),
        "L_mid": plane(scene, "mid", ((-0.5, -0.45), (0.7, 0.35)), -4.0, mid),
        "L_back": plane(scene, "back", ((-6.0, -5.0), (6.0, 5.0)), -15.0, back),
    }


def build_view_layers(scene, collections):
    """One view layer per plane, the other planes' collections excluded; plus Reference
    (everything, off until the ground-truth render)."""
    names = list(collections)
    scene.view_layers[0].name = names[0]
    for name in names[1:]:
        scene.view_layers.new(name)
    for name in names:
        layer = scene.view_layers[name]
        layer.use_pass_z = True
        for other, coll in collections.items():
            layer.layer_collection.children[coll.name].exclude = other != name
    reference = scene.view_layers.new("Reference")
    reference.use = False
    return reference


def enable_addon(binary):
    """Enables the add-on; returns its version adapters (`lensblur.compat`), which the scripts
    use for what differs between Blender versions in their own setup too."""
    module = addon_utils.enable("lensblur", default_set=True, handle_error=None)
    assert module is not None, "the lensblur add-on is not installed in the addons folder"
    bpy.context.preferences.addons["lensblur"].preferences.binary_path = binary
    return module.compat


def render_truth(scene, path, use_dof, samples):
    """Renders the Reference view layer (every plane) alone to `path`, with or without
    Cycles' depth of field; returns the seconds it took."""
    for layer in scene.view_layers:
        layer.use = layer.name == "Reference"
    scene.render.use_compositing = False  # write the Reference layer itself, not a composite
    scene.camera.data.dof.use_dof = use_dof
    scene.cycles.samples = samples
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    settings.color_depth = "32"
    scene.render.filepath = path
    start = time.time()
    bpy.ops.render.render(write_still=True)
    return time.time() - start
