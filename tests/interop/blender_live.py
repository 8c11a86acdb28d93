"""The add-on's Live mode, headless: blender_scene.py's planes rendered pinhole, then a live
session (one `lensblur serve` per session, the stack loaded once) follows three focus distances,
an f-stop and a near-blur change; after each, the live image must equal the one-shot
`bpy.ops.lensblur.defocus` of the same settings. The modal operator only calls
LiveSession.update from a timer; background Blender runs no modal operators, so the session is
driven here as the timer would (`settle`: update until the image shows the settings).
Usage: blender -b --factory-startup --python blender_live.py -- OUT LENSBLUR_BINARY
(with the add-on installed, as for blender_plugin.py)
Prints LENSBLUR_LIVE_CHECKS <json>, then LENSBLUR_LIVE_DONE."""
import json
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import PINHOLE_SAMPLES, build_planes, build_view_layers, enable_addon, setup_scene  # noqa: E402

out, binary = sys.argv[sys.argv.index("--") + 1:][:2]
checks = {"blender": bpy.app.version_string, "steps": []}

scene = setup_scene()
build_view_layers(scene, build_planes(scene))
# LENSBLUR_LIVE_SIDE=256 renders a square frame of that side (for measuring; the test keeps the scene's).
if os.environ.get("LENSBLUR_LIVE_SIDE"):
    scene.render.resolution_x = scene.render.resolution_y = int(os.environ["LENSBLUR_LIVE_SIDE"])
enable_addon(binary)
live = sys.modules["lensblur"].live
scene.render.use_single_layer = False
scene.camera.data.dof.use_dof = False
scene.cycles.samples = PINHOLE_SAMPLES
bpy.ops.render.render()
scene.lensblur.layers = "L_*"
dof = scene.camera.data.dof
dof.focus_object = None


def pixels():
    return list(bpy.data.images["lensblur_result"].pixels[:])


session = live.LiveSession(bpy.context)
try:
    steps = [("focus_distance", 2.0), ("focus_distance", 3.25), ("focus_distance", 6.0), ("aperture_fstop", 2.8), ("near_blur", 2.0)]
    for setting, value in steps:
        if setting == "near_blur":
            scene.lensblur.near_blur = value
        else:
            setattr(dof, setting, value)
        start = time.perf_counter()
        session.settle(bpy.context)
        latency_ms = (time.perf_counter() - start) * 1e3
        live_pixels = pixels()
        total_ms, render_ms = session.last
        bpy.ops.lensblur.defocus(layers="L_*", near_blur=scene.lensblur.near_blur, far_blur=scene.lensblur.far_blur)
        one_shot = pixels()
        difference = max(abs(a - b) for a, b in zip(live_pixels, one_shot))
        checks["steps"].append({
            "setting": setting, "value": value, "max_difference": difference,
            "same_size": len(live_pixels) == len(one_shot), "latency_ms": latency_ms,
            "request_ms": total_ms, "render_ms": render_ms,
            "mean": sum(live_pixels) / len(live_pixels),
        })
    # A focus behind the camera is refused by the add-on; the session keeps the message and
    # renders the next good value.
    dof.focus_distance = -1.0
    session.update(bpy.context)
    checks["bad_value_error"] = session.error
    dof.focus_distance = 3.0
    session.settle(bpy.context)
    checks["after_bad_value"] = session.error
    checks["tmp"] = session.tmp
finally:
    session.close()
checks["tmp_removed"] = not os.path.exists(checks["tmp"])
print("LENSBLUR_LIVE_CHECKS " + json.dumps(checks))
print("LENSBLUR_LIVE_DONE")
# Leave without the interpreter's exit handlers: bpy 4.5's own (its delayed file-close thread's
# GlobalState destructor) once deadlocked at exit in CI after every check had passed, and a
# process that never exits hangs the test. Everything is written and flushed by now.
sys.stdout.flush()
sys.stderr.flush()
os._exit(0)
