"""The rendered EXR as the image datablock `lensblur_result`, optionally saved and shown in
a compositor Image node."""
import os
import shutil

import bpy

from . import compat
from .errors import LensblurError

IMAGE_NAME = "lensblur_result"
NODE_NAME = "lensblur_result"


def load_result(out_path, save_path, report_json):
    """Loads `out_path` (a file in a temporary directory that is about to be deleted).
    With `save_path` the result is copied there and the image refers to it; without, the
    image is packed into the .blend so it survives the temporary file."""
    if save_path:
        target = bpy.path.abspath(save_path)
        try:
            os.makedirs(os.path.dirname(target) or ".", exist_ok=True)
            shutil.copyfile(out_path, target)
        except OSError as e:
            raise LensblurError(f"cannot save the result to {target}: {e}") from e
        image = load_image(target)
        image.filepath = save_path  # keep a relative '//' path relative
    else:
        image = load_image(out_path)
        try:
            image.pack()
        except RuntimeError as e:
            raise LensblurError(f"cannot pack the result into the .blend: {e}") from e
    image["lensblur_report"] = report_json
    return replace_datablock(image)


def load_image(path):
    try:
        return bpy.data.images.load(path, check_existing=False)
    except RuntimeError as e:
        raise LensblurError(f"Blender cannot load the result {path}: {e}") from e


def replace_datablock(image):
    """Renames `image` to IMAGE_NAME, moving every user of an older result onto it
    (Image nodes, image editors), so re-running updates the comp in place."""
    old = bpy.data.images.get(IMAGE_NAME)
    if old is not None and old != image:
        old.user_remap(image)
        bpy.data.images.remove(old)
    image.name = IMAGE_NAME
    # Ensure pixels are read now, while we know the file is there.
    if image.size[0] == 0:
        raise LensblurError(f"Blender could not read the result {image.filepath}")
    return image


def wire_image_node(scene, image, name=NODE_NAME):
    """An Image node named `name` in the compositor showing `image`."""
    tree = compat.compositor_tree(scene)
    node = tree.nodes.get(name)
    if node is None or node.bl_idname != "CompositorNodeImage":
        node = tree.nodes.new("CompositorNodeImage")
        node.name = name
        node.label = "lensblur"
    node.image = image
    return node
