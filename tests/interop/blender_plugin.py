"""Drives the lensblur add-on in headless Blender the way a user would, and renders the
ground truth it is compared with.
Usage: blender -b --factory-startup --python blender_plugin.py -- OUT LENSBLUR_BINARY
The add-on must be installed (the test symlinks it into $BLENDER_USER_SCRIPTS/addons).

Scene: blender_scene.py (three textured planes, one view layer each).
Writes to OUT:
  result.exr     the add-on's result (save_path), also the image datablock lensblur_result
  reference.exr  the same scene in one view layer rendered by Cycles with depth of field
  pinhole.exr    the same scene without depth of field (what no blur at all would give)
Prints LENSBLUR_PLUGIN_REPORT <json> (the tool's report, as stored on the image),
LENSBLUR_PLUGIN_CHECKS <json> and finally LENSBLUR_PLUGIN_DONE."""
import json
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import (  # noqa: E402 (found through the path above)
    DOF_SAMPLES, PINHOLE_SAMPLES, build_planes, build_view_layers, enable_addon, render_truth, setup_scene,
)

out, binary = sys.argv[sys.argv.index("--") + 1:][:2]
checks = {}


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
    node = compat.compositor_tree(scene).nodes.get("lensblur_result")
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

    # The panel's method menu (LENSBLUR_MT_methods draws these), and each item picked through
    # the menu's operator lands in the scene's setting.
    addon = sys.modules["lensblur"]
    checks["methods"] = [item[0] for item in addon.settings.method_items(bpy.context)]
    for name in checks["methods"]:
        bpy.ops.lensblur.set_method(name=name)
        assert scene.lensblur.method == name, (name, scene.lensblur.method)
    bpy.ops.lensblur.set_method(name=checks["methods"][0])
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
    with compat.multilayer_exr(scene.render.image_settings):
        bpy.data.images["Render Result"].save_render(stack_path, scene=scene)
    bpy.ops.lensblur.defocus(filepath=stack_path, layers="L_*", exclude="L_front")
    report = json.loads(bpy.data.images["lensblur_result"]["lensblur_report"])
    checks["file_layers"] = [l["name"] for l in report["layers"]]


scene = setup_scene()
collections = build_planes(scene)
build_view_layers(scene, collections)
compat = enable_addon(binary)
run_addon(scene)
checks["pinhole.exr_s"] = render_truth(scene, os.path.join(out, "pinhole.exr"), False, PINHOLE_SAMPLES)
checks["reference.exr_s"] = render_truth(scene, os.path.join(out, "reference.exr"), True, DOF_SAMPLES)
print("LENSBLUR_PLUGIN_CHECKS " + json.dumps(checks))
print("LENSBLUR_PLUGIN_DONE")
