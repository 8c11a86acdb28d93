"""`bpy.ops.lensblur.defocus()`: view layers -> temporary EXR -> lensblur -> `lensblur_result`.

From a script (and in `blender -b`) the operator runs to the end; from the UI (the panel's
button) it runs in the background: a timer polls lensblur, the status bar shows progress, Esc
cancels (lensblur removes the file it was writing) and the interface stays responsive."""
import json
import os
import shutil
import tempfile
import traceback

import bpy

from . import camera, checks, methods, preferences, result, runner, settings, stack
from .errors import LensblurError
from .job import RenderJob

# How often a running job is polled from the UI.
POLL_SECONDS = 0.1


class Prepared:
    """A stack on disk and the command that renders it; owns the temporary folder."""

    def __init__(self, command, out_path, tmp, warnings):
        self.command, self.out_path, self.tmp, self.warnings = command, out_path, tmp, warnings

    def cleanup(self):
        shutil.rmtree(self.tmp, ignore_errors=True)


def begin_polling(op, context, seconds, status):
    """Runs `op` as a modal operator woken every `seconds` by a window timer, with `status` in
    the status bar (the one-shot render and Live mode; `end_polling` undoes it, for the
    animation operators too)."""
    wm = context.window_manager
    op._timer = wm.event_timer_add(seconds, window=context.window)
    wm.modal_handler_add(op)
    context.workspace.status_text_set(status)


def end_polling(op, context):
    context.window_manager.event_timer_remove(op._timer)
    context.workspace.status_text_set(None)


def report_failure(op, error):
    """LensblurError: the message says what to do. Blender's own calls (image loading, file
    output) fail with RuntimeError/OSError: a report says what failed, the console keeps the
    traceback for a bug report."""
    if isinstance(error, LensblurError):
        op.report({"ERROR"}, str(error))
    else:
        traceback.print_exc()
        op.report({"ERROR"}, f"lensblur: {type(error).__name__}: {error}")
    return {"CANCELLED"}


class LENSBLUR_OT_defocus(bpy.types.Operator):
    """Defocus the view layers with the scene camera's depth-of-field settings (lensblur)"""

    bl_idname = "lensblur.defocus"
    bl_label = "Lens Blur"
    bl_options = {"REGISTER"}

    filepath: bpy.props.StringProperty(
        name="EXR", description=settings.FILEPATH_HELP, subtype="FILE_PATH"
    )
    layers: bpy.props.StringProperty(name="Layers", description=settings.LAYERS_HELP)
    exclude: bpy.props.StringProperty(name="Exclude", description=settings.EXCLUDE_HELP)
    # A name, as the panel's setting holds it (see settings.LensblurSettings.method).
    method: bpy.props.StringProperty(name="Method", default=methods.DEFAULT)
    save_path: bpy.props.StringProperty(
        name="Save to", description=settings.SAVE_HELP, subtype="FILE_PATH"
    )
    use_node: bpy.props.BoolProperty(
        name="Image node", description=settings.NODE_HELP, default=False
    )
    near_blur: bpy.props.FloatProperty(name="Near blur", description=settings.NEAR_BLUR_HELP, default=1.0, min=0.0)
    far_blur: bpy.props.FloatProperty(name="Far blur", description=settings.FAR_BLUR_HELP, default=1.0, min=0.0)

    def execute(self, context):
        try:
            prepared = self.prepare(context)
            try:
                report, tool_warnings = runner.run_render(prepared.command)
                self.finish(context, prepared, report, tool_warnings)
            finally:
                prepared.cleanup()
        except (LensblurError, RuntimeError, OSError) as e:
            return report_failure(self, e)
        return {"FINISHED"}

    def invoke(self, context, event):
        try:
            self._prepared = self.prepare(context)
            self._job = RenderJob(self._prepared.command)
        except (LensblurError, RuntimeError, OSError) as e:
            return report_failure(self, e)
        begin_polling(self, context, POLL_SECONDS, "lensblur: rendering (Esc cancels)")
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            self._job.cancel()
            self._prepared.cleanup()
            end_polling(self, context)
            self.report({"WARNING"}, "lensblur: cancelled; nothing was written")
            return {"CANCELLED"}
        if event.type != "TIMER" or self._job.poll() is None:
            return {"PASS_THROUGH"}
        end_polling(self, context)
        try:
            self.finish(context, self._prepared, self._job.result(), self._job.warnings)
        except (LensblurError, RuntimeError, OSError) as e:
            return report_failure(self, e)
        finally:
            self._prepared.cleanup()
        return {"FINISHED"}

    def prepare(self, context):
        """Writes the stack to a temporary folder; returns what renders it."""
        scene = context.scene
        binary = preferences.find_binary(context)
        flags, _summary, warnings = camera.camera_flags(scene)
        source = bpy.path.abspath(self.filepath) if self.filepath else ""
        self.check_save_path(source)
        tmp = tempfile.mkdtemp(prefix="lensblur-")
        try:
            stack_path, chosen, from_render = stack.write_chosen(context, binary, self.filepath, self.layers, self.exclude, tmp)
            if from_render:
                warnings += checks.setup_warnings(scene, chosen)
                stale = checks.stale_render_warning(scene)
                warnings += [stale] if stale else []
            out_path = os.path.join(tmp, "lensblur_result.exr")
            character = ["--near-blur", camera.fmt(self.near_blur), "--far-blur", camera.fmt(self.far_blur)]
            command = runner.render_command(binary, stack_path, out_path, chosen, flags, self.method, character)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
        return Prepared(command, out_path, tmp, warnings)

    def finish(self, context, prepared, report, tool_warnings):
        """Loads the result, reports the warnings (the add-on's, then the tool's stderr ones)."""
        warnings = prepared.warnings + tool_warnings
        image = result.load_result(prepared.out_path, self.save_path, json.dumps(report))
        image["lensblur_warnings"] = json.dumps(warnings)
        if self.use_node:
            result.wire_image_node(context.scene, image)
        for warning in warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, runner.summary(report))
        if context.area is not None:
            context.area.tag_redraw()

    def check_save_path(self, source):
        if not self.save_path or not source:
            return
        target = os.path.realpath(bpy.path.abspath(self.save_path))
        if target == os.path.realpath(source):
            raise LensblurError(f"'Save to' is the input file {source}: choose another path")
