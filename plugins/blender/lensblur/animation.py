"""`bpy.ops.lensblur.defocus_animation()`: the scene's frame range (or a given one) rendered to
a multilayer EXR sequence, the camera of every frame (focus distance, f-stop, lens, sensor as
animated) written to a lensblur camera file, one `lensblur render --frames` over the sequence,
and the result loaded as an image sequence in a compositor Image node. Also
`bpy.ops.lensblur.farm_bundle()`: the same layers and camera file, and an Open Job Description
job bundle that renders them on a farm (`deadline bundle submit DIR`) or locally (`openjd run`).

From a script (and `blender -b`) both run to the end; from the UI they render one frame per
timer tick and then poll lensblur, with progress in the status bar, and Esc cancels."""
import contextlib
import json
import math
import os
import shlex
import subprocess

import bpy

from . import camera, checks, compat, methods, preferences, result, settings, stack
from .errors import LensblurError
from .job import RenderJob, tool_message
from .operator import POLL_SECONDS, end_polling, report_failure

SEQUENCE_NAME = "lensblur_sequence"
DIRECTORY_HELP = "Folder for the layer frames, the camera file and the defocused frames"
RANGE_HELP = "First and last frame (both 0: the scene's frame range)"


def frame_list(scene, start, end):
    if start == 0 and end == 0:
        start, end = scene.frame_start, scene.frame_end
    if end < start:
        raise LensblurError(f"frame range {start}-{end} is empty: the last frame comes before the first")
    return list(range(start, end + 1, max(1, scene.frame_step)))


def frame_size(render):
    """The rendered frame's pixel size (resolution scaled by its percentage)."""
    scale = render.resolution_percentage / 100
    return round(render.resolution_x * scale), round(render.resolution_y * scale)


def overscan_margin(scene, frames):
    """Pixels rendered past every side of the frame, so that light from outside it blurs in
    as Cycles' lens sees it: the largest blur radius over the shot of a point far behind
    focus (`K / focus distance`, K the CoC scale of lensblur's thin lens), plus 2; at most a
    quarter of the frame. Blur in front of focus past that margin is still cut at the edge."""
    width, height = frame_size(scene.render)
    current = scene.frame_current
    largest = 0.0
    try:
        for frame in frames:
            scene.frame_set(frame)
            _flags, summary, _warnings = camera.camera_flags(scene)
            focal_mm = summary["focal_length"]
            # In metres: the aperture f / 2N is in millimetres, the focus distance in Blender units.
            k_px = focal_mm * 1e-3 / (2 * summary["fstop"]) * focal_mm / summary["sensor_width"] * width
            largest = max(largest, k_px / (summary["focus_distance"] * compat.metres_per_unit(scene)))
    finally:
        scene.frame_set(current)
    return min(math.ceil(largest) + 2, max(width, height) // 4)


@contextlib.contextmanager
def overscanned(scene, margin):
    """The render grown by `margin` pixels on every side and the camera's field of view with
    it (the same pixel size, the same centre: the sensor dimension Blender fits grows by the
    same factor, the lens shift, in units of it, shrinks), restored afterwards."""
    render, cam = scene.render, scene.camera.data
    saved = (render.resolution_x, render.resolution_y, render.resolution_percentage,
             cam.sensor_width, cam.sensor_height, cam.shift_x, cam.shift_y)
    width, height = frame_size(render)
    fitted = width if camera.fitted_axis(scene, cam) == "HORIZONTAL" else height
    scale = (fitted + 2 * margin) / fitted
    try:
        render.resolution_x, render.resolution_y = width + 2 * margin, height + 2 * margin
        render.resolution_percentage = 100
        if cam.sensor_fit == "VERTICAL":
            cam.sensor_height *= scale
        else:  # AUTO fits the sensor width to the larger side
            cam.sensor_width *= scale
        cam.shift_x /= scale
        cam.shift_y /= scale
        yield
    finally:
        (render.resolution_x, render.resolution_y, render.resolution_percentage,
         cam.sensor_width, cam.sensor_height, cam.shift_x, cam.shift_y) = saved


def range_expression(frames):
    step = frames[1] - frames[0] if len(frames) > 1 else 1
    if len(frames) == 1:
        return str(frames[0])
    return f"{frames[0]}-{frames[-1]}" + (f":{step}" if step != 1 else "")


class Shot:
    """The layer frames and camera file of a frame range, rendered one frame at a time."""

    def __init__(self, context, directory, frames, layers, exclude):
        self.scene = context.scene
        self.binary = preferences.find_binary(context)
        self.directory = bpy.path.abspath(directory or "//lensblur/")
        if not os.path.isabs(self.directory):
            raise LensblurError(
                f"'{directory}' is relative to the .blend file, which is not saved: save it or give an absolute folder"
            )
        os.makedirs(self.directory, exist_ok=True)
        self.frames = frames
        self.cameras = {}
        self.aperture = None
        self.warnings = []
        self.original_frame = self.scene.frame_current
        available = stack.rendered_view_layers(context)
        self.layers = stack.select_layers(available, layers, exclude)
        stack.check_depth_passes(self.scene, self.layers)
        self.warnings += checks.setup_warnings(self.scene, self.layers)
        self.overscan = overscan_margin(self.scene, frames)

    def path(self, name, frame):
        return os.path.join(self.directory, f"{name}.{frame:04d}.exr")

    def pattern(self, name):
        return os.path.join(self.directory, f"{name}.####.exr")

    @property
    def camera_file(self):
        return os.path.join(self.directory, "camera.json")

    def render_frame(self, index):
        """Renders frame `frames[index]`'s view layers (Blender), overscanned, and notes its
        camera (whose sensor spans the overscanned image)."""
        frame = self.frames[index]
        self.scene.frame_set(frame)
        with overscanned(self.scene, self.overscan):
            self.render_overscanned(frame)

    def render_overscanned(self, frame):
        flags, summary, warnings = camera.camera_flags(self.scene)
        if self.aperture is None:
            self.aperture = summary["aperture"]
            self.warnings += warnings
        elif summary["aperture"] != self.aperture:
            self.warnings.append(f"the aperture changes over the shot; frame {self.frames[0]}'s ({self.aperture}) is used")
        self.cameras[frame] = {
            "focal_length_mm": float(camera.fmt(summary["focal_length"])),
            "sensor_width_mm": float(camera.fmt(summary["sensor_width"])),
            "fstop": float(camera.fmt(summary["fstop"])),
            "focus_distance": float(camera.fmt(summary["focus_distance"])),
        }
        bpy.ops.render.render()
        stack.export_render_result(self.scene, self.path("layers", frame))

    def finish_layers(self):
        """Writes the camera file once every frame is rendered; restores the current frame."""
        self.scene.frame_set(self.original_frame)
        with open(self.camera_file, "w") as f:
            json.dump({"frames": {str(k): v for k, v in self.cameras.items()}}, f, indent=2)

    def render_command(self, method):
        # No camera flags: they would win over the camera file; the aperture and the unit of
        # its distances are not in it.
        return [
            self.binary, "render", self.pattern("layers"), "-o", self.pattern("defocus"),
            "--frames", range_expression(self.frames), "--camera-file", self.camera_file,
            "--scene-unit", camera.scene_unit(self.scene),
            "--layers", ",".join(self.layers), "--method", method, "--aperture", self.aperture,
            "--overscan", str(self.overscan), "--json",
        ]


def load_sequence(shot, report, use_node):
    """The defocused frames as the image sequence `lensblur_sequence`, in an Image node."""
    first = shot.path("defocus", shot.frames[0])
    old = bpy.data.images.get(SEQUENCE_NAME)
    image = result.load_image(first)
    image.source = "SEQUENCE"
    if old is not None and old != image:
        old.user_remap(image)
        bpy.data.images.remove(old)
    image.name = SEQUENCE_NAME
    image["lensblur_report"] = json.dumps(report)
    image["lensblur_warnings"] = json.dumps(shot.warnings)
    if use_node:
        node = result.wire_image_node(shot.scene, image, SEQUENCE_NAME)
        # File numbers are scene frames: frame f of the scene shows file f.
        node.frame_start = shot.frames[0]
        node.frame_offset = shot.frames[0] - 1
        node.frame_duration = shot.frames[-1] - shot.frames[0] + 1
    return image


class ShotOperator:
    """What the animation and farm operators share: their properties (Blender collects a
    mixin's annotations), rendering the layers frame by frame (all at once from a script, one
    per timer tick from the UI)."""

    frame_start: bpy.props.IntProperty(name="Start", description=RANGE_HELP, default=0)
    frame_end: bpy.props.IntProperty(name="End", description=RANGE_HELP, default=0)
    directory: bpy.props.StringProperty(name="Folder", description=DIRECTORY_HELP, subtype="DIR_PATH", default="//lensblur/")
    layers: bpy.props.StringProperty(name="Layers", description=settings.LAYERS_HELP)
    exclude: bpy.props.StringProperty(name="Exclude", description=settings.EXCLUDE_HELP)
    # A name, as the panel's setting holds it (see settings.LensblurSettings.method).
    method: bpy.props.StringProperty(name="Method", default=methods.DEFAULT)

    def start_shot(self, context):
        frames = frame_list(context.scene, self.frame_start, self.frame_end)
        return Shot(context, self.directory, frames, self.layers, self.exclude)

    def render_all_layers(self, context):
        """The layers and camera file of every frame, in one go (scripts, `blender -b`)."""
        shot = self.start_shot(context)
        for index in range(len(shot.frames)):
            shot.render_frame(index)
        shot.finish_layers()
        return shot

    def invoke(self, context, event):
        try:
            self._shot = self.start_shot(context)
        except (LensblurError, RuntimeError, OSError) as e:
            return report_failure(self, e)
        self._next, self._job = 0, None
        wm = context.window_manager
        self._timer = wm.event_timer_add(POLL_SECONDS, window=context.window)
        wm.progress_begin(0, 2 * len(self._shot.frames))
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        shot = self._shot
        if event.type == "ESC":
            if self._job is not None:
                self._job.cancel()
            shot.scene.frame_set(shot.original_frame)
            self.end_modal(context)
            self.report({"WARNING"}, "lensblur: cancelled; frames already written are complete, no partial file is left")
            return {"CANCELLED"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        try:
            return self.step(context)
        except (LensblurError, RuntimeError, OSError) as e:
            if self._job is not None:
                self._job.cancel()
            self._shot.scene.frame_set(self._shot.original_frame)
            self.end_modal(context)
            return report_failure(self, e)

    def step(self, context):
        shot, wm, n = self._shot, context.window_manager, len(self._shot.frames)
        if self._next < n:
            context.workspace.status_text_set(f"lensblur: rendering layers of frame {shot.frames[self._next]} (Esc cancels)")
            shot.render_frame(self._next)
            self._next += 1
            wm.progress_update(self._next)
            if self._next == n:
                shot.finish_layers()
                return self.after_layers(context)
            return {"RUNNING_MODAL"}
        done, _total = self._job.progress()
        wm.progress_update(n + done)
        context.workspace.status_text_set(f"lensblur: defocusing, {done}/{n} frames (Esc cancels)")
        if self._job.poll() is None:
            return {"RUNNING_MODAL"}
        self.end_modal(context)
        self.complete(context, self._job.result(), self._job.warnings)
        return {"FINISHED"}

    def end_modal(self, context):
        context.window_manager.progress_end()
        end_polling(self, context)

    def report_warnings(self, warnings):
        for warning in warnings:
            self.report({"WARNING"}, warning)


class LENSBLUR_OT_defocus_animation(ShotOperator, bpy.types.Operator):
    """Render the frame range's view layers, defocus them with the animated camera (lensblur) and show the image sequence"""

    bl_idname = "lensblur.defocus_animation"
    bl_label = "Lens Blur Animation"
    bl_options = {"REGISTER"}

    use_node: bpy.props.BoolProperty(name="Image node", description=settings.NODE_HELP, default=True)

    def execute(self, context):
        try:
            shot = self.render_all_layers(context)
            job = RenderJob(shot.render_command(self.method))
            self.complete(context, job.wait(), job.warnings, shot)
        except (LensblurError, RuntimeError, OSError) as e:
            return report_failure(self, e)
        return {"FINISHED"}

    def after_layers(self, context):
        self._job = RenderJob(self._shot.render_command(self.method))
        return {"RUNNING_MODAL"}

    def complete(self, context, report, tool_warnings, shot=None):
        shot = shot or self._shot
        shot.warnings += tool_warnings
        load_sequence(shot, report, self.use_node)
        self.report_warnings(shot.warnings)
        self.report({"INFO"}, f"lensblur: {len(report['rendered'])} frame(s) -> {shot.pattern('defocus')}")


PARAMETER_VALUES = "parameter_values.json"


class LENSBLUR_OT_farm_bundle(ShotOperator, bpy.types.Operator):
    """Render the frame range's view layers and camera file, and write an Open Job Description job bundle that defocuses them on a render farm"""

    bl_idname = "lensblur.farm_bundle"
    bl_label = "Lens Blur on Farm"
    bl_options = {"REGISTER"}

    chunk_size: bpy.props.IntProperty(name="Frames per task", min=1, default=10)

    def execute(self, context):
        try:
            self.complete(context, None, [], self.render_all_layers(context))
        except (LensblurError, RuntimeError, OSError) as e:
            return report_failure(self, e)
        return {"FINISHED"}

    def after_layers(self, context):
        self.end_modal(context)
        self.complete(context, None, [])
        return {"FINISHED"}

    def complete(self, context, _report, _tool_warnings, shot=None):
        shot = shot or self._shot
        bundle = write_bundle(shot, self.method, self.chunk_size)
        self.report_warnings(shot.warnings)
        self.report({"INFO"}, f"lensblur: job bundle in {bundle}: deadline bundle submit {bundle}")


def write_bundle(shot, method, chunk_size):
    """DIR/farm-bundle: template.yaml (the template the lensblur binary carries) and the
    shot's job parameters, as Deadline Cloud's parameter_values.json."""
    bundle = os.path.join(shot.directory, "farm-bundle")
    os.makedirs(bundle, exist_ok=True)
    template = os.path.join(bundle, "template.yaml")
    proc = subprocess.run(
        [shot.binary, "farm-template", "-o", template], capture_output=True, text=True, check=False
    )
    if proc.returncode != 0:
        raise LensblurError(f"lensblur farm-template: {tool_message(proc.stderr)}")
    values = {
        "Input": shot.pattern("layers"),
        "Output": shot.pattern("defocus"),
        "Frames": range_expression(shot.frames),
        "ChunkSize": chunk_size,
        "CameraFile": shot.camera_file,
        "Args": shlex.join([
            "--layers", ",".join(shot.layers), "--method", method, "--aperture", shot.aperture,
            "--overscan", str(shot.overscan),
        ]),
    }
    parameters = [{"name": name, "value": value} for name, value in values.items()]
    with open(os.path.join(bundle, PARAMETER_VALUES), "w") as f:
        json.dump({"parameterValues": parameters}, f, indent=2)
    return bundle
