"""`bpy.ops.lensblur.defocus()`: view layers -> temporary EXR -> lensblur -> `lensblur_result`."""
import json
import os
import tempfile
import traceback

import bpy

from . import camera, preferences, result, runner, settings, stack
from .errors import LensblurError


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
    method: bpy.props.EnumProperty(name="Method", items=settings.METHODS, default="drbokeh")
    save_path: bpy.props.StringProperty(
        name="Save to", description=settings.SAVE_HELP, subtype="FILE_PATH"
    )
    use_node: bpy.props.BoolProperty(
        name="Image node", description=settings.NODE_HELP, default=False
    )

    def execute(self, context):
        try:
            image, report, warnings = self.defocus(context)
        except LensblurError as e:
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        except (RuntimeError, OSError) as e:
            # Blender's own calls (image loading, file output) fail with these: a report
            # says what failed, the console keeps the traceback for a bug report.
            traceback.print_exc()
            self.report({"ERROR"}, f"lensblur: {type(e).__name__}: {e}")
            return {"CANCELLED"}
        for warning in warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, runner.summary(report))
        if context.area is not None:
            context.area.tag_redraw()
        return {"FINISHED"}

    def defocus(self, context):
        scene = context.scene
        binary = preferences.find_binary(context)
        flags, _summary, warnings = camera.camera_flags(scene)
        source = bpy.path.abspath(self.filepath) if self.filepath else ""
        self.check_save_path(source)
        # Everything temporary lives in this directory, removed on success and on error.
        with tempfile.TemporaryDirectory(prefix="lensblur-") as tmp:
            if source:
                if not os.path.isfile(source):
                    raise LensblurError(f"no such file: {source}")
                stack_path = source
                available = stack.file_layers(binary, source)
            else:
                stack_path = os.path.join(tmp, "stack.exr")
                available = stack.rendered_view_layers(context)
            chosen = stack.select_layers(available, self.layers, self.exclude)
            if not source:
                stack.check_depth_passes(scene, chosen)
                stack.export_render_result(scene, stack_path)
            out_path = os.path.join(tmp, "lensblur_result.exr")
            command = runner.render_command(
                binary, stack_path, out_path, chosen, flags, self.method
            )
            report = runner.run_render(command)
            image = result.load_result(out_path, self.save_path, json.dumps(report))
        if self.use_node:
            result.wire_image_node(scene, image)
        return image, report, warnings

    def check_save_path(self, source):
        if not self.save_path or not source:
            return
        target = os.path.realpath(bpy.path.abspath(self.save_path))
        if target == os.path.realpath(source):
            raise LensblurError(f"'Save to' is the input file {source}: choose another path")
