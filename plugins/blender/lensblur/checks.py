"""Scene setups that cannot give lensblur true layers, and a Render Result older than the
scene: said as warnings (the render still runs) with what to change."""
import bpy
from bpy.app.handlers import persistent

# What the last render was made from (see `render_state`); None before any render.
_last_render = None


def render_state(scene):
    """What makes the Render Result the picture of the scene now: the frame, and the
    camera's place, lens and the resolution (lensblur takes focus and f-stop from the scene
    as they are now, so changing those needs no new render)."""
    cam = scene.camera
    placed = None
    if cam is not None:
        placed = (
            cam.name,
            tuple(round(v, 6) for row in cam.matrix_world for v in row),
            getattr(cam.data, "lens", None),
            getattr(cam.data, "sensor_width", None),
        )
    r = scene.render
    return (scene.name, scene.frame_current, placed, r.resolution_x, r.resolution_y, r.resolution_percentage)


@persistent
def remember_render(scene, *_args):
    global _last_render
    _last_render = render_state(scene)


def stale_render_warning(scene):
    if _last_render is None or _last_render == render_state(scene):
        return None
    then = _last_render
    if then[1] != scene.frame_current:
        why = f"it shows frame {then[1]}, the scene is at frame {scene.frame_current}"
    elif then[0] != scene.name:
        why = f"it was rendered from scene '{then[0]}'"
    else:
        why = "the camera or the resolution changed since"
    return f"the Render Result is stale ({why}): render again (F12)"


def setup_warnings(scene, layers):
    """Warnings for a stack of `scene`'s view layers `layers`, rendered with its settings
    (the Render Result, or the animation operator's own renders)."""
    warnings = []
    if len(layers) > 1 and not scene.render.film_transparent:
        warnings.append(
            "Film > Transparent is off: each view layer's background hides what is behind it, "
            "so the layers are not see-through; turn on Render Properties > Film > Transparent "
            "and render again"
        )
    cam = scene.camera
    if cam is not None and cam.type == "CAMERA" and cam.data.dof.use_dof:
        warnings.append(
            f"camera '{cam.name}' has Depth of Field on: the layers come out already blurred and "
            "lensblur blurs them again; turn it off (Camera > Depth of Field; lensblur reads its "
            "settings either way) and render again"
        )
    return warnings


def register():
    if remember_render not in bpy.app.handlers.render_post:
        bpy.app.handlers.render_post.append(remember_render)


def unregister():
    if remember_render in bpy.app.handlers.render_post:
        bpy.app.handlers.render_post.remove(remember_render)
