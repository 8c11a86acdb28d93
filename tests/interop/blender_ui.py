"""Drives the add-on's operators the way the UI does (INVOKE_DEFAULT: modal, timer-polled), in
Blender with a window (under Xvfb) and simulated events (--enable-event-simulate).
Usage: xvfb-run blender --factory-startup --enable-event-simulate --python blender_ui.py -- OUT LENSBLUR_BINARY
Checks, printed as LENSBLUR_UI_CHECKS <json> before LENSBLUR_UI_DONE:
  - defocus from the panel runs in the background: Blender's own timers keep firing while
    lensblur runs (the interface is responsive), the result and the tool's stderr warnings
    arrive when it ends;
  - Esc while lensblur runs cancels it: no result, no temporary folder left;
  - Esc while the animation renders its layers (after the first frame) cancels it: the frames
    written are whole, lensblur never runs, the scene is back on its frame."""
import json
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blender_scene import PINHOLE_SAMPLES, build_planes, build_view_layers, enable_addon, setup_scene  # noqa: E402

out, binary = sys.argv[sys.argv.index("--") + 1:][:2]
checks = {"ticks_while_running": 0}


def slow_binary(delay, warning):
    """A lensblur that first sleeps `delay` s and prints a warning on stderr (what the CPU
    fallback does), so there is time to see the UI run and to press Esc."""
    path = os.path.join(out, f"slow-lensblur-{delay}")
    with open(path, "w") as f:
        f.write(f'#!/bin/sh\necho "lensblur: warning: {warning}" >&2\nsleep {delay}\nexec "{binary}" "$@"\n')
    os.chmod(path, 0o755)
    return path


def use_binary(path):
    bpy.context.preferences.addons["lensblur"].preferences.binary_path = path


def window_override():
    window = bpy.context.window_manager.windows[0]
    area = next(a for a in window.screen.areas if a.type == "PROPERTIES")
    return bpy.context.temp_override(window=window, area=area, screen=window.screen)


def setup():
    scene = setup_scene()
    build_view_layers(scene, build_planes(scene))
    enable_addon(binary)
    scene.render.use_single_layer = False
    scene.camera.data.dof.use_dof = False
    scene.cycles.samples = PINHOLE_SAMPLES
    scene.frame_start, scene.frame_end = 1, 3
    bpy.ops.render.render()
    checks["tmp_before"] = sorted(n for n in os.listdir(os.environ["TMPDIR"]) if n.startswith("lensblur"))


def start_defocus():
    use_binary(slow_binary(2, "slow test binary"))
    with window_override():
        checks["invoke"] = list(bpy.ops.lensblur.defocus("INVOKE_DEFAULT", save_path=os.path.join(out, "ui.exr")))
    checks["started"] = time.time()


def defocus_done():
    image = bpy.data.images.get("lensblur_result")
    if image is None:
        checks["ticks_while_running"] += 1
        return False
    checks["defocus_seconds"] = time.time() - checks["started"]
    checks["defocus_warnings"] = json.loads(image["lensblur_warnings"])
    checks["defocus_size"] = list(image.size)
    bpy.data.images.remove(image)
    return True


def start_and_cancel_defocus():
    use_binary(slow_binary(5, "slow test binary"))
    with window_override():
        bpy.ops.lensblur.defocus("INVOKE_DEFAULT")
    bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="PRESS")
    checks["cancel_started"] = time.time()


def defocus_cancelled():
    # The slow binary would have finished 5 s after the start: wait past that.
    if time.time() - checks["cancel_started"] < 6.0:
        return False
    checks["cancelled_result"] = bpy.data.images.get("lensblur_result") is not None
    checks["tmp_after_cancel"] = sorted(n for n in os.listdir(os.environ["TMPDIR"]) if n.startswith("lensblur"))
    return True


def start_animation():
    use_binary(binary)
    bpy.context.scene.frame_set(2)
    with window_override():
        bpy.ops.lensblur.defocus_animation("INVOKE_DEFAULT", directory=os.path.join(out, "anim"))


def cancel_after_first_frame():
    """Esc once the first frame's layers are written (the operator renders one per tick)."""
    folder = os.path.join(out, "anim")
    if "anim_cancel_started" not in checks:
        if not os.path.isfile(os.path.join(folder, "layers.0001.exr")):
            return False
        bpy.context.window_manager.windows[0].event_simulate(type="ESC", value="PRESS")
        checks["anim_cancel_started"] = time.time()
    if time.time() - checks["anim_cancel_started"] < 2.0:
        return False
    checks["anim_files"] = sorted(os.listdir(folder))
    checks["anim_sequence"] = bpy.data.images.get("lensblur_sequence") is not None
    checks["anim_frame"] = bpy.context.scene.frame_current
    return True


STEPS = [
    (setup, None),
    (start_defocus, defocus_done),
    (start_and_cancel_defocus, defocus_cancelled),
    (start_animation, cancel_after_first_frame),
]
state = {"step": 0, "waiting": None, "deadline": time.time() + 120}


def tick():
    try:
        if state["waiting"] is not None:
            if not state["waiting"]():
                if time.time() > state["deadline"]:
                    raise TimeoutError(f"step {state['step']} did not finish")
                return 0.05
            state["waiting"] = None
            state["step"] += 1
        if state["step"] == len(STEPS):
            print("LENSBLUR_UI_CHECKS " + json.dumps(checks), flush=True)
            print("LENSBLUR_UI_DONE", flush=True)
            bpy.ops.wm.quit_blender()
            return None
        start, wait = STEPS[state["step"]]
        print(f"lensblur ui step {state['step']}: {start.__name__}", flush=True)
        start()
        if wait is None:
            state["step"] += 1
        else:
            state["waiting"] = wait
        return 0.05
    except Exception:
        import traceback

        traceback.print_exc()
        sys.stdout.flush()
        os._exit(1)


# Persistent: setup_scene() loads factory settings, which drops ordinary timers.
bpy.app.timers.register(tick, first_interval=0.5, persistent=True)
