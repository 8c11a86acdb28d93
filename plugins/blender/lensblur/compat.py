"""What differs between the Blender versions the add-on runs on (3.4 to 5.x), in one place, so
the rest of the add-on has one code path:
- Blender 5.0 moved multilayer EXR from `file_format` to the new `media_type`, and writes it
  multi-part (one part per pass) unless `use_exr_interleave` asks for the single-part layout.
  lensblur reads both; the add-on asks for the single part, which other tools read too.
- Blender 5.0's compositor is a node group (`scene.compositing_node_group`, a Group Output node
  where the Composite node was); before, `scene.use_nodes` made `scene.node_tree`.
- The Unit Scale (`scene.unit_settings.scale_length`): one Blender unit is that many metres."""
import contextlib


@contextlib.contextmanager
def multilayer_exr(settings):
    """`settings` (an ImageFormatSettings) set to a 32-bit float, ZIP-compressed multilayer
    EXR for the duration, then restored as they were."""
    # Restored in this order: the media type (5.0) decides which file formats are allowed, the
    # file format which colour depths.
    fields = ["media_type"] if hasattr(settings, "media_type") else []
    fields += ["file_format", "color_depth", "exr_codec"]
    fields += ["use_exr_interleave"] if hasattr(settings, "use_exr_interleave") else []
    saved = [(field, getattr(settings, field)) for field in fields]
    try:
        if "media_type" in fields:
            settings.media_type = "MULTI_LAYER_IMAGE"
        else:
            settings.file_format = "OPEN_EXR_MULTILAYER"
        settings.color_depth = "32"
        settings.exr_codec = "ZIP"
        if "use_exr_interleave" in fields:
            settings.use_exr_interleave = True
        yield settings
    finally:
        for field, value in saved:
            setattr(settings, field, value)


def compositor_tree(scene):
    """The scene's compositor node tree, made if it has none yet: in 5.0 a new node group with
    Render Layers -> Group Output (what the compositor's New button makes), before that
    `use_nodes`, which makes Render Layers -> Composite."""
    if not hasattr(scene, "compositing_node_group"):
        scene.use_nodes = True
        return scene.node_tree
    tree = scene.compositing_node_group
    if tree is None:
        import bpy

        tree = bpy.data.node_groups.new("Compositing Nodes", "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        layers = tree.nodes.new("CompositorNodeRLayers")
        output = tree.nodes.new("NodeGroupOutput")
        output.location = (layers.location.x + 400, layers.location.y)
        tree.links.new(layers.outputs["Image"], output.inputs[0])
        scene.compositing_node_group = tree
    return tree


def metres_per_unit(scene):
    """Metres in one Blender unit (Scene > Units > Unit Scale; 1 unless changed)."""
    return scene.unit_settings.scale_length
