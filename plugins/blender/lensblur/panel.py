"""A small panel in Properties > Render: the settings, the camera in use, and the button."""
import bpy

from . import camera, compat, settings
from .errors import LensblurError


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
        for name in ("filepath", "layers", "exclude", "method", "save_path", "use_node"):
            layout.prop(s, name)
        error = settings.method_error(context)
        if error:
            layout.label(text=f"Methods: {error}", icon="ERROR")
        self.draw_camera(layout, context.scene)
        op = layout.operator("lensblur.defocus", icon="RENDER_RESULT")
        for name in ("filepath", "layers", "exclude", "method", "save_path", "use_node"):
            setattr(op, name, getattr(s, name))
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
