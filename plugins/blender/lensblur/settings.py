"""Per-scene settings the panel edits; the operator's properties mirror them."""
import bpy

from . import methods, preferences


def _method_menu(context):
    """(items, error) of the method menu for the binary in use (see `methods.menu`)."""
    return methods.menu(lambda: preferences.find_binary(context or bpy.context))


def method_items(context):
    """The method menu: [(name, label, summary)] of `lensblur methods --json`, asked of the
    binary in use and cached; its first item is the tool's default."""
    return _method_menu(context)[0]


def method_error(context):
    """Why the method menu holds only the default method (the tool could not be asked), or None."""
    return _method_menu(context)[1]


LAYERS_HELP = (
    "View layers forming the stack: names or globs, comma-separated (empty: every view "
    "layer that renders); they are sorted front to back by depth"
)
EXCLUDE_HELP = "View layers to leave out: names or globs, comma-separated"
FILEPATH_HELP = "Multilayer EXR to defocus instead of the Render Result (empty: Render Result)"
SAVE_HELP = "Also save the result as an EXR here (empty: keep it packed in the .blend)"
NEAR_BLUR_HELP = "Multiplies the blur in front of the focus (lensblur --near-blur)"
FAR_BLUR_HELP = "Multiplies the blur behind the focus (lensblur --far-blur)"
NODE_HELP = "Show the result in a compositor Image node named 'lensblur_result'"


class LensblurSettings(bpy.types.PropertyGroup):
    filepath: bpy.props.StringProperty(name="EXR", description=FILEPATH_HELP, subtype="FILE_PATH")
    layers: bpy.props.StringProperty(name="Layers", description=LAYERS_HELP)
    exclude: bpy.props.StringProperty(name="Exclude", description=EXCLUDE_HELP)
    # A name, picked from the tool's own list in the panel (LENSBLUR_MT_methods): not an enum
    # whose items come from a callback, since any such property makes the bpy 4.2 module crash
    # (SIGSEGV) at exit. `lensblur render --method` refuses a name it does not know.
    method: bpy.props.StringProperty(name="Method", default=methods.DEFAULT)
    save_path: bpy.props.StringProperty(name="Save to", description=SAVE_HELP, subtype="FILE_PATH")
    use_node: bpy.props.BoolProperty(name="Image node", description=NODE_HELP, default=True)
    near_blur: bpy.props.FloatProperty(name="Near blur", description=NEAR_BLUR_HELP, default=1.0, min=0.0, soft_max=4.0)
    far_blur: bpy.props.FloatProperty(name="Far blur", description=FAR_BLUR_HELP, default=1.0, min=0.0, soft_max=4.0)
    # Live mode's focus pick: the result's pixel clicked last ([-1, -1]: the camera's focus).
    live_focus_at: bpy.props.IntVectorProperty(name="Focus at", size=2, default=(-1, -1))
