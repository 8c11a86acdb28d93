"""Add-on preferences: where the `lensblur` binary is."""
import os
import shutil

import bpy

from .errors import LensblurError

ENV_BINARY = "LENSBLUR_BIN"


class LensblurPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    binary_path: bpy.props.StringProperty(
        name="lensblur binary",
        description="Path of the lensblur executable (empty: $LENSBLUR_BIN, then PATH)",
        subtype="FILE_PATH",
        default="",
    )

    def draw(self, context):
        self.layout.prop(self, "binary_path")
        self.layout.label(text=f"In use: {describe_binary(context)}")


def find_binary(context):
    """The lensblur executable: preferences, then $LENSBLUR_BIN, then PATH."""
    addon = context.preferences.addons.get(__package__)
    configured = addon.preferences.binary_path if addon and addon.preferences else ""
    if configured:
        path = bpy.path.abspath(configured)
        if not os.access(path, os.X_OK):
            raise LensblurError(
                f"lensblur binary '{path}' (add-on preferences) is missing or not executable"
            )
        return path
    from_env = os.environ.get(ENV_BINARY)
    if from_env:
        if not os.access(from_env, os.X_OK):
            raise LensblurError(f"${ENV_BINARY}='{from_env}' is missing or not executable")
        return from_env
    on_path = shutil.which("lensblur")
    if on_path is None:
        raise LensblurError(
            "lensblur binary not found: set it in Preferences > Add-ons > lensblur, "
            f"or ${ENV_BINARY}, or put it on PATH"
        )
    return on_path


def describe_binary(context):
    try:
        return find_binary(context)
    except LensblurError as e:
        return str(e)
