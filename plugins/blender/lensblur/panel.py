"""A small panel in Properties > Render: the settings, the camera in use, and the button."""
import bpy

from . import camera, compat, settings
from .errors import LensblurError


class LENSBLUR_OT_set_method(bpy.types.Operator):
    """Render with this method"""

    bl_idname = "lensblur.set_method"
    bl_label = "Set method"
    bl_options = {"INTERNAL", "UNDO"}
    name: bpy.props.StringProperty()

    @classmethod
    def description(cls, context, properties):
        summaries = {name: summary for name, _, summary in settings.method_items(context)}
        return summaries.get(properties.name, properties.name)

    def execute(self, context):
        context.scene.lensblur.method = self.name
        return {"FINISHED"}


class LENSBLUR_MT_methods(bpy.types.Menu):
    """The rendering methods of the lensblur binary in use, as `lensblur methods --json` lists
    them: drawn anew each time the menu opens, so it is never a copy of the tool's list."""

    bl_idname = "LENSBLUR_MT_methods"
    bl_label = "Method"

    def draw(self, context):
        for name, label, _ in settings.method_items(context):
            self.layout.operator(LENSBLUR_OT_set_method.bl_idname, text=label).name = name


class LENSBLUR_PT_render(bpy.types.Panel):
    bl_label = "Lensblur"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        s = context.scene.lensblur
        layout.use_property_split = True
        for name in ("filepath", "layers", "exclude"):
            layout.prop(s, name)
        # The method, picked from the tool's own list (`lensblur methods --json`).
        labels = {name: label for name, label, _ in settings.method_items(context)}
        layout.menu(LENSBLUR_MT_methods.bl_idname, text=f"Method: {labels.get(s.method, s.method)}")
        for name in ("save_path", "use_node", "near_blur", "far_blur"):
            layout.prop(s, name)
        error = settings.method_error(context)
        if error:
            layout.label(text=f"Methods: {error}", icon="ERROR")
        self.draw_camera(layout, context.scene)
        row = layout.row()
        op = row.operator("lensblur.defocus", icon="RENDER_RESULT")
        for name in ("filepath", "layers", "exclude", "method", "save_path", "use_node", "near_blur", "far_blur"):
            setattr(op, name, getattr(s, name))
        # Re-renders as the focus, f-stop, aperture or blur sliders move (lensblur serve).
        row.operator("lensblur.live", icon="PLAY")
        # The frame range into //lensblur/ (animated camera), locally or as a farm job bundle.
        row = layout.row()
        for idname, icon in (("lensblur.defocus_animation", "RENDER_ANIMATION"), ("lensblur.farm_bundle", "NETWORK_DRIVE")):
            op = row.operator(idname, icon=icon)
            for name in ("layers", "exclude", "method"):
                setattr(op, name, getattr(s, name))

    @staticmethod
    def draw_camera(layout, scene):
        try:
            _, c, _ = camera.camera_flags(scene)
        except LensblurError as e:
            layout.label(text=str(e), icon="ERROR")
            return
        layout.label(
            text=f"{c['focal_length']:.0f} mm, f/{c['fstop']:.2g}, focus "
            f"{c['focus_distance'] * compat.metres_per_unit(scene):.3g} m, {c['aperture']}",
            icon="CAMERA_DATA",
        )
