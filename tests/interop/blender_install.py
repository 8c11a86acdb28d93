"""Installs the add-on from its package as a user would, then runs it: on Blender 4.2+ the
Extension zip through Install from Disk's operator (`extensions.package_install_files` into the
user repository), on older Blenders the legacy zip through Add-ons > Install
(`preferences.addon_install`). Then blender_scene.py's planes, rendered pinhole, are defocused by
`bpy.ops.lensblur.defocus`, the result shown in the compositor.
Usage: blender -b --factory-startup --python blender_install.py -- OUT LENSBLUR_BINARY
with OUT/lensblur.zip (Extension zip on 4.2+, legacy zip before; build_extension.py makes both).
Prints LENSBLUR_INSTALL_CHECKS <json>, then LENSBLUR_INSTALL_DONE."""
import json
import os
import sys

import bpy
import addon_utils  # after bpy: importing PyPI's bpy module puts Blender's modules on the path

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import PINHOLE_SAMPLES, build_planes, build_view_layers, setup_scene  # noqa: E402

out, binary = sys.argv[sys.argv.index("--") + 1:][:2]
package = os.path.join(out, "lensblur.zip")
checks = {"blender": bpy.app.version_string}

scene = setup_scene()
build_view_layers(scene, build_planes(scene))
if bpy.app.version >= (4, 2, 0):
    result = bpy.ops.extensions.package_install_files(filepath=package, repo="user_default", enable_on_install=True)
    module_name = "bl_ext.user_default.lensblur"
else:
    result = bpy.ops.preferences.addon_install(filepath=package)
    module_name = "lensblur"
    addon_utils.enable(module_name, default_set=True, handle_error=None)
checks["install"] = sorted(result)
checks["enabled"] = module_name in bpy.context.preferences.addons
checks["installed_in"] = os.path.dirname(sys.modules[module_name].__file__)
bpy.context.preferences.addons[module_name].preferences.binary_path = binary

scene.render.use_single_layer = False
scene.cycles.samples = PINHOLE_SAMPLES
bpy.ops.render.render()
bpy.ops.lensblur.defocus(layers="L_*", use_node=True)
image = bpy.data.images["lensblur_result"]
checks["image_size"] = list(image.size)
checks["layers"] = [layer["name"] for layer in json.loads(image["lensblur_report"])["layers"]]
tree = sys.modules[module_name].compat.compositor_tree(scene)
checks["node_image"] = tree.nodes["lensblur_result"].image.name
print("LENSBLUR_INSTALL_CHECKS " + json.dumps(checks))
print("LENSBLUR_INSTALL_DONE")
