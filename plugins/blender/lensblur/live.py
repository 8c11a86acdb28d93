"""Live mode: focus pulled in the panel re-renders at once through `lensblur serve`.

The stack (the Render Result's view layers, or the panel's EXR) is written and loaded once
into a resident `lensblur serve` process; each change of the focus distance, f-stop, aperture,
the blur sliders, or a click on the result (focus on that pixel) sends one render request. The
result comes back as raw float32 RGBA in a file the server renames into place (under /dev/shm
where it exists), which goes straight into the `lensblur_result` image's pixels: no EXR is
encoded or decoded per update. Only the latest value renders: while a render runs, changes
only update what to send next, and the server drops a queued render when a newer one arrives.

Why a server and not the Python package in-process: the add-on supports Blender 3.4 (legacy
add-ons, no bundled wheels) to 5.x, and a native module inside Blender shares its process
(a crash would take the user's scene with it). The server is the same `lensblur` binary the
add-on already runs, and a protocol round trip costs well under a millisecond."""
import json
import os
import shutil
import subprocess
import tempfile
import threading
import time

import bpy

from . import camera, preferences, result, stack
from .errors import LensblurError
from .operator import begin_polling, end_polling, report_failure

# How often the modal operator looks for changed settings and finished renders.
POLL_SECONDS = 0.02


class Server:
    """A `lensblur serve` process: requests written as JSON lines, answers read by a thread
    and kept by id. No bpy here."""

    def __init__(self, binary):
        try:
            self.proc = subprocess.Popen(
                [binary, "serve"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                stderr=subprocess.PIPE, text=True, bufsize=1,
            )
        except OSError as e:
            raise LensblurError(f"cannot run {binary}: {e}") from e
        self._answers, self._stderr, self._next_id = {}, [], 0
        self._changed = threading.Condition()
        self.greeting = None
        threading.Thread(target=self._read_answers, daemon=True).start()
        threading.Thread(target=self._read_stderr, daemon=True).start()
        with self._changed:
            self._changed.wait_for(lambda: self.greeting is not None or self.proc.poll() is not None, timeout=30)
        if self.greeting is None:
            raise LensblurError(f"lensblur serve did not start: {' '.join(self._stderr[-4:])}")

    def _read_answers(self):
        for line in self.proc.stdout:
            answer = json.loads(line)
            with self._changed:
                if answer.get("event") == "ready":
                    self.greeting = answer
                else:
                    self._answers[answer.get("id")] = answer
                self._changed.notify_all()
        with self._changed:
            self._changed.notify_all()

    def _read_stderr(self):
        for line in self.proc.stderr:
            self._stderr.append(line.rstrip("\n"))

    def send(self, op, **fields):
        """Sends a request; returns its id."""
        self._next_id += 1
        request = {"id": self._next_id, "op": op, **fields}
        try:
            self.proc.stdin.write(json.dumps(request) + "\n")
            self.proc.stdin.flush()
        except (BrokenPipeError, ValueError) as e:
            raise LensblurError(f"lensblur serve ended: {' '.join(self._stderr[-4:])}") from e
        return self._next_id

    def answer(self, request_id):
        """The answer to `request_id` once it has come, else None."""
        with self._changed:
            return self._answers.pop(request_id, None)

    def wait(self, request_id, timeout=600):
        with self._changed:
            self._changed.wait_for(
                lambda: request_id in self._answers or self.proc.poll() is not None, timeout=timeout
            )
            answer = self._answers.pop(request_id, None)
        if answer is None:
            raise LensblurError(f"lensblur serve gave no answer: {' '.join(self._stderr[-4:])}")
        return answer

    def close(self):
        if self.proc.poll() is None:
            try:
                self.send("shutdown")
                self.proc.stdin.close()
                self.proc.wait(timeout=30)
            except (LensblurError, OSError, subprocess.TimeoutExpired):
                self.proc.kill()
                self.proc.wait()


def checked(answer):
    if not answer.get("ok"):
        raise LensblurError(f"lensblur: {answer.get('error', answer)}")
    return answer


def render_settings(scene):
    """What a render of the scene's current settings sends: the camera and the options."""
    _flags, c, _warnings = camera.camera_flags(scene)
    s = scene.lensblur
    options = {
        "aperture": c["aperture"],
        "scene_unit": c["scene_unit"],
        "near_blur": float(camera.fmt(s.near_blur)),
        "far_blur": float(camera.fmt(s.far_blur)),
    }
    if s.live_focus_at[0] >= 0:
        options["focus_at"] = list(s.live_focus_at)
    lens = {
        "focal_length_mm": float(camera.fmt(c["focal_length"])),
        "sensor_width_mm": float(camera.fmt(c["sensor_width"])),
        "fstop": float(camera.fmt(c["fstop"])),
        "focus_distance": float(camera.fmt(c["focus_distance"])),
    }
    return {"camera": lens, **options}


class LiveSession:
    """One stack loaded into a server, and the result image it keeps up to date."""

    def __init__(self, context):
        s = context.scene.lensblur
        binary = preferences.find_binary(context)
        self.tmp = tempfile.mkdtemp(prefix="lensblur-live-", dir=_shared_memory_dir())
        self.server = None
        try:
            stack_path, chosen, _ = stack.write_chosen(context, binary, s.filepath, s.layers, s.exclude, self.tmp)
            self.server = Server(binary)
            loaded = checked(self.server.wait(self.server.send("load", path=stack_path, layers=chosen, method=s.method)))
            self.stack = loaded["stack"]
        except BaseException:
            self.close()
            raise
        self.output = os.path.join(self.tmp, "live.raw")
        self.in_flight = None  # (request id, settings sent, when it was sent)
        self.shown = None  # the settings the image shows
        self.last = None  # (milliseconds from request to image, the server's render ms)
        self.error = None  # why the settings shown last did not render

    def update(self, context):
        """Takes a finished render into the image, then sends the current settings if the image
        does not show them and nothing is rendering. True when the image or the error changed.
        A value lensblur refuses (a focus behind the camera) is kept in `error`, not raised: the
        next change renders again."""
        changed = False
        if self.in_flight is not None:
            request_id, sent, started = self.in_flight
            answer = self.server.answer(request_id)
            if answer is None:
                return False
            self.in_flight, self.shown, changed = None, sent, True
            if answer.get("ok"):
                self._show(answer)
                self.error = None
                self.last = ((time.perf_counter() - started) * 1e3, answer["timings_ms"]["render"])
            else:
                self.error = answer.get("error", str(answer))
        try:
            wanted = render_settings(context.scene)
        except LensblurError as e:
            changed = changed or self.error != str(e)
            self.error = str(e)
            return changed
        if wanted != self.shown:
            request_id = self.server.send("render", stack=self.stack, output=self.output, **wanted)
            self.in_flight = (request_id, wanted, time.perf_counter())
        return changed

    def settle(self, context, timeout=600):
        """Renders until the image shows the current settings (scripts and tests)."""
        deadline = time.monotonic() + timeout
        while True:
            self.update(context)
            if self.in_flight is None and self.shown == render_settings(context.scene):
                if self.error:
                    raise LensblurError(self.error)
                return
            if time.monotonic() > deadline:
                raise LensblurError("lensblur live: no render within the time allowed")
            time.sleep(0.002)

    def _show(self, answer):
        import numpy as np

        width, height = answer["width"], answer["height"]
        pixels = np.fromfile(self.output, dtype="<f4").reshape(height, width, 4)
        image = bpy.data.images.get(result.IMAGE_NAME)
        if image is None or image.source != "GENERATED" or tuple(image.size) != (width, height):
            fresh = bpy.data.images.new("lensblur_live", width, height, alpha=True, float_buffer=True)
            fresh.alpha_mode = "PREMUL"
            image = result.replace_datablock(fresh)
        # Blender's rows run bottom-up; the server's top-down.
        image.pixels.foreach_set(np.ascontiguousarray(pixels[::-1]).ravel())
        image.update()

    def close(self):
        if self.server is not None:
            self.server.close()
            self.server = None
        shutil.rmtree(self.tmp, ignore_errors=True)


def _shared_memory_dir():
    """/dev/shm where the system has one (the result never touches a disk), else the default."""
    return "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None


def image_pixel_under_mouse(context, event):
    """[x, y] of the result image under the mouse in an Image Editor showing it (rows from the
    top, as lensblur counts them), else None."""
    area, region = context.area, context.region
    if area is None or area.type != "IMAGE_EDITOR" or region is None or region.type != "WINDOW":
        return None
    image = area.spaces.active.image
    if image is None or image.name != result.IMAGE_NAME:
        return None
    u, v = region.view2d.region_to_view(event.mouse_region_x, event.mouse_region_y)
    width, height = image.size
    x, y = int(u * width), int((1.0 - v) * height)
    return [x, y] if 0 <= x < width and 0 <= y < height else None


class LENSBLUR_OT_live(bpy.types.Operator):
    """Live mode: re-render as the focus distance, f-stop, aperture or blur sliders change, or
    click the result in an Image Editor to focus there; Esc leaves"""

    bl_idname = "lensblur.live"
    bl_label = "Live"

    def invoke(self, context, event):
        context.scene.lensblur.live_focus_at = (-1, -1)
        try:
            self._session = LiveSession(context)
        except (LensblurError, RuntimeError, OSError) as e:
            return report_failure(self, e)
        begin_polling(self, context, POLL_SECONDS, "lensblur live: rendering (Esc leaves)")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self.end(context)
            return {"FINISHED"}
        if event.type == "LEFTMOUSE" and event.value == "PRESS":
            pixel = image_pixel_under_mouse(context, event)
            if pixel is not None:
                context.scene.lensblur.live_focus_at = pixel
                return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            changed = self._session.update(context)
        except (LensblurError, OSError) as e:
            # The server ended or the result could not be read: Live mode cannot go on.
            self.end(context)
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        if changed:
            session = self._session
            if session.error:
                status = f"lensblur live: {session.error} - Esc leaves"
            else:
                total, render = session.last
                status = f"lensblur live: {total:.0f} ms ({render:.0f} ms rendering) - Esc leaves"
            context.workspace.status_text_set(status)
            for area in context.screen.areas if context.screen else ():
                if area.type in {"IMAGE_EDITOR", "NODE_EDITOR"}:
                    area.tag_redraw()
        return {"PASS_THROUGH"}

    def end(self, context):
        end_polling(self, context)
        self._session.close()
