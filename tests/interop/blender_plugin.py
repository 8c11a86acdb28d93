"""Drives the lensblur add-on in headless Blender the way a user would, and renders the
ground truth it is compared with.
Usage: blender -b --factory-startup --python blender_plugin.py -- OUT LENSBLUR_BINARY
The add-on must be installed (the test symlinks it into $BLENDER_USER_SCRIPTS/addons).

Scene: three emissive, procedurally textured planes facing an 85 mm f/1 camera, one view
layer each (the others excluded), transparent film, Depth pass on:
  L_front  a checker bar 1.5 m away (CoC radius ~6.7 px at 160 px wide)
  L_mid    a wave-textured card 4 m away, in focus (via a focus object off the view axis)
  L_back   a checker wall 15 m away (CoC radius ~2.9 px)
Writes to OUT:
  result.exr     the add-on's result (save_path), also the image datablock lensblur_result
  reference.exr  the same scene in one view layer rendered by Cycles with depth of field
  pinhole.exr    the same scene without depth of field (what no blur at all would give)
Prints LENSBLUR_PLUGIN_REPORT <json> (the tool's report, as stored on the image),
LENSBLUR_PLUGIN_CHECKS <json> and finally LENSBLUR_PLUGIN_DONE."""
import json
import math
import os
import sys
import time

import addon_utils
import bpy

out, binary = sys.argv[sys.argv.index("--") + 1:][:2]
WIDTH, HEIGHT = 160, 120
PINHOLE_SAMPLES = 16  # emission only: the pinhole layers converge fast (anti-aliasing only)
DOF_SAMPLES = 1024  # the aperture integral is noisy; see the Rust test for the threshold
checks = {}


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


def enable_addon():
    module = addon_utils.enable("lensblur", default_set=True, handle_error=None)
    assert module is not None, "the lensblur add-on is not installed in the addons folder"
    bpy.context.preferences.addons["lensblur"].preferences.binary_path = binary


def expect_error(fragment, **kwargs):
    """Operator errors are Blender reports; in background mode bpy.ops raises them."""
    try:
        bpy.ops.lensblur.defocus(**kwargs)
    except RuntimeError as e:
        assert fragment in str(e), f"expected '{fragment}' in: {e}"
        return str(e)
    raise AssertionError(f"lensblur.defocus({kwargs}) did not fail")


def run_addon(scene):
    scene.render.use_single_layer = False
    scene.camera.data.dof.use_dof = False
    scene.cycles.samples = PINHOLE_SAMPLES
    bpy.ops.render.render()
    start = time.time()
    bpy.ops.lensblur.defocus(save_path=os.path.join(out, "result.exr"), use_node=True)
    checks["operator_s"] = time.time() - start
    image = bpy.data.images["lensblur_result"]
    checks["image_size"] = list(image.size)
    checks["image_packed"] = image.packed_file is not None
    # Pixels come from the saved file; the temporary one is gone by now.
    px = image.pixels[:]
    checks["image_mean_alpha"] = sum(px[3::4]) / (len(px) / 4)
    node = scene.node_tree.nodes.get("lensblur_result")
    checks["node_image"] = node.image.name if node else None
    print("LENSBLUR_PLUGIN_REPORT " + image["lensblur_report"])

    # Again without a save path: the result is packed, and replaces the first datablock
    # (the compositor node follows it).
    bpy.ops.lensblur.defocus(layers="L_mid,L_b*", use_node=False)
    image = bpy.data.images["lensblur_result"]
    checks["rerun_packed"] = image.packed_file is not None
    checks["rerun_layers"] = [l["name"] for l in json.loads(image["lensblur_report"])["layers"]]
    checks["rerun_node_image"] = node.image.name
    checks["images"] = sorted(i.name for i in bpy.data.images)

    # A plain focus distance, no focus object: the distance setting is the focus.
    dof = scene.camera.data.dof
    target, dof.focus_object, dof.focus_distance = dof.focus_object, None, 3.25
    bpy.ops.lensblur.defocus(layers="L_mid,L_back")
    report = json.loads(bpy.data.images["lensblur_result"]["lensblur_report"])
    checks["plain_focus_distance"] = report["camera"]["focus_distance"]
    dof.focus_object = target

    rna = bpy.ops.lensblur.defocus.get_rna_type()
    checks["methods"] = [item.identifier for item in rna.properties["method"].enum_items]
    # `lensblur render` itself fails (after the stack was written): a device name that
    # matches nothing. Its message comes back as the report.
    os.environ["LENSBLUR_DEVICE"] = "no-such-gpu"
    try:
        checks["render_error"] = expect_error("lensblur failed", layers="L_mid")
    finally:
        del os.environ["LENSBLUR_DEVICE"]
    checks["glob_error"] = expect_error("no view layer matches 'L_side*'", layers="L_side*")
    checks["exclude_error"] = expect_error("no view layer left", exclude="L_*")
    not_exr = os.path.join(out, "not-an.exr")
    with open(not_exr, "w") as f:
        f.write("not an EXR")
    checks["tool_error"] = expect_error("lensblur info", filepath=not_exr)

    # A multilayer EXR path instead of the Render Result, with an exclusion.
    stack_path = os.path.join(out, "stack.exr")
    scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    bpy.data.images["Render Result"].save_render(stack_path, scene=scene)
    bpy.ops.lensblur.defocus(filepath=stack_path, layers="L_*", exclude="L_front")
    report = json.loads(bpy.data.images["lensblur_result"]["lensblur_report"])
    checks["file_layers"] = [l["name"] for l in report["layers"]]


def render_truth(scene, name, use_dof, samples):
    for layer in scene.view_layers:
        layer.use = layer.name == "Reference"
    scene.use_nodes = False  # write the Reference layer itself, not a composite
    scene.camera.data.dof.use_dof = use_dof
    scene.cycles.samples = samples
    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_mode = "RGBA"
    settings.color_depth = "32"
    scene.render.filepath = os.path.join(out, name)
    start = time.time()
    bpy.ops.render.render(write_still=True)
    checks[f"{name}_s"] = time.time() - start


scene = setup_scene()
collections = build_planes(scene)
build_view_layers(scene, collections)
enable_addon()
run_addon(scene)
render_truth(scene, "pinhole.exr", False, PINHOLE_SAMPLES)
render_truth(scene, "reference.exr", True, DOF_SAMPLES)
print("LENSBLUR_PLUGIN_CHECKS " + json.dumps(checks))
print("LENSBLUR_PLUGIN_DONE")
