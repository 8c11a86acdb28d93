"""lensblur for Blender: physically based, occlusion-aware lens blur of a layered render.

Each view layer of the Render Result (or of a multilayer EXR) is one layer of the stack; the
scene camera's depth-of-field settings give the lens. The add-on writes the stack to a
temporary EXR, runs the `lensblur` command-line tool, and loads the result as the image
`lensblur_result`. Works in the UI and in `blender -b`:

    bpy.ops.lensblur.defocus(layers="L_*", exclude="L_fx", save_path="//defocus.exr")
    bpy.ops.lensblur.defocus_animation(directory="//shot/")     # the frame range, animated camera
    bpy.ops.lensblur.farm_bundle(directory="//shot/", chunk_size=10)  # for `deadline bundle submit`

Debian's and Ubuntu's Blender are built without OpenImageDenoise: rendering the layers with
denoising on fails ("Build without OpenImageDenoiser"); turn Render > Sampling > Denoise off
(scene.cycles.use_denoising = False). In a fresh profile the add-ons folder does not exist yet:
create it (mkdir -p ~/.config/blender/<version>/scripts/addons) before linking this folder.
"""

bl_info = {
    "name": "lensblur",
    "author": "lensblur authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Lensblur",
    "description": "Occlusion-aware lens blur of view layers with the lensblur tool (Dr.Bokeh)",
    "category": "Compositing",
}

if "bpy" in locals():
    # Script reload (F8 / Reload Scripts): pick up edited submodules.
    import importlib

    for _module in (errors, compat, job, camera, checks, stack, runner, result, preferences, methods, settings, operator, animation, live, panel):
        importlib.reload(_module)

import bpy

from . import errors, compat, job, camera, checks, stack, runner, result, preferences, methods, settings, operator, animation, live, panel

_classes = (
    preferences.LensblurPreferences,
    settings.LensblurSettings,
    operator.LENSBLUR_OT_defocus,
    animation.LENSBLUR_OT_defocus_animation,
    animation.LENSBLUR_OT_farm_bundle,
    live.LENSBLUR_OT_live,
    panel.LENSBLUR_OT_set_method,
    panel.LENSBLUR_MT_methods,
    panel.LENSBLUR_PT_render,
)


def register():
    for cls in _classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.lensblur = bpy.props.PointerProperty(type=settings.LensblurSettings)
    checks.register()


def unregister():
    checks.unregister()
    del bpy.types.Scene.lensblur
    for cls in reversed(_classes):
        bpy.utils.unregister_class(cls)
