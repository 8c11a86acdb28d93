"""Per-scene settings the panel edits; the operator's properties mirror them."""
import bpy

# Every `lensblur render --method`, as `lensblur methods --json` lists them (name, label,
# summary); tests/plugin_blender.rs checks this list equals the tool's registry.
METHODS = [
    ("drbokeh", "Dr.Bokeh", "Layered occlusion-aware gather (Vulkan); the default"),
    ("drbokeh-compat", "Dr.Bokeh (released code)", "Dr.Bokeh with the formulas of its released code (Vulkan)"),
    ("multiview", "Multiview", "Lens rays through the layers (Lee et al. 2009, Vulkan)"),
    ("vdslr", "Virtual DSLR", "Pseudo ray tracing of the flattened image + depth (Yang et al. 2016, Vulkan)"),
    ("oracle", "Per-layer blur", "Blur each layer and composite it over (CPU)"),
    ("gather", "Gather", "Single-image gather baseline, like the Defocus node (Vulkan)"),
    ("scatter", "Scatter", "Single-image scatter baseline (BokehMe's classical renderer, Vulkan)"),
]

LAYERS_HELP = (
    "View layers forming the stack: names or globs, comma-separated (empty: every view "
    "layer that renders); they are sorted front to back by depth"
)
EXCLUDE_HELP = "View layers to leave out: names or globs, comma-separated"
FILEPATH_HELP = "Multilayer EXR to defocus instead of the Render Result (empty: Render Result)"
SAVE_HELP = "Also save the result as an EXR here (empty: keep it packed in the .blend)"
NODE_HELP = "Show the result in a compositor Image node named 'lensblur_result'"


class LensblurSettings(bpy.types.PropertyGroup):
    filepath: bpy.props.StringProperty(name="EXR", description=FILEPATH_HELP, subtype="FILE_PATH")
    layers: bpy.props.StringProperty(name="Layers", description=LAYERS_HELP)
    exclude: bpy.props.StringProperty(name="Exclude", description=EXCLUDE_HELP)
    method: bpy.props.EnumProperty(name="Method", items=METHODS, default="drbokeh")
    save_path: bpy.props.StringProperty(name="Save to", description=SAVE_HELP, subtype="FILE_PATH")
    use_node: bpy.props.BoolProperty(name="Image node", description=NODE_HELP, default=True)
