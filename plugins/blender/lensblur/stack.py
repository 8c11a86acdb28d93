"""Which view layers form the stack, and how they reach lensblur as one multilayer EXR."""
import fnmatch
import json
import subprocess

from . import compat
from .errors import LensblurError
from .job import tool_message


def split_patterns(text):
    return [p.strip() for p in text.split(",") if p.strip()]


def select_layers(available, layers, exclude):
    """View-layer names matching any of `layers` (names or globs, comma-separated; empty:
    all of `available`) and none of `exclude`, in `available` order."""
    wanted = split_patterns(layers)
    for pattern in wanted:
        if not fnmatch.filter(available, pattern):
            raise LensblurError(
                f"no view layer matches '{pattern}' (available: {', '.join(available) or 'none'})"
            )
    dropped = split_patterns(exclude)
    chosen = [
        name
        for name in available
        if (not wanted or any(fnmatch.fnmatchcase(name, p) for p in wanted))
        and not any(fnmatch.fnmatchcase(name, p) for p in dropped)
    ]
    if not chosen:
        raise LensblurError(
            f"no view layer left (layers '{layers or '*'}', exclude '{exclude}'; "
            f"available: {', '.join(available) or 'none'})"
        )
    bad = [name for name in chosen if "," in name]
    if bad:
        raise LensblurError(f"view-layer names with commas cannot be passed to lensblur: {bad}")
    return chosen


def rendered_view_layers(context):
    """View layers the last render produced: every enabled one, or only the active one
    with "Render Single Layer"."""
    scene = context.scene
    if scene.render.use_single_layer:
        return [context.view_layer.name]
    return [layer.name for layer in scene.view_layers if layer.use]


def check_depth_passes(scene, names):
    missing = [n for n in names if n in scene.view_layers and not scene.view_layers[n].use_pass_z]
    if missing:
        raise LensblurError(
            f"view layer(s) {', '.join(missing)} have no Depth pass: enable View Layer "
            "Properties > Passes > Data > Z and render again"
        )


def export_render_result(scene, path):
    """Writes the Render Result with all its view layers and passes as a float multilayer
    EXR, restoring the scene's output format afterwards."""
    import bpy

    image = bpy.data.images.get("Render Result")
    if image is None:
        raise LensblurError("there is no Render Result: render first (F12)")
    try:
        with compat.multilayer_exr(scene.render.image_settings):
            image.save_render(filepath=path, scene=scene)
    except RuntimeError as e:
        raise LensblurError(f"cannot save the Render Result (render first, F12): {e}") from e


def file_layers(binary, path):
    """Layer names lensblur finds in a multilayer EXR (`lensblur info --json`)."""
    proc = subprocess.run(
        [binary, "info", path, "--json"], capture_output=True, text=True, check=False
    )
    if proc.returncode != 0:
        raise LensblurError(f"lensblur info {path}: {tool_message(proc.stderr)}")
    try:
        info = json.loads(proc.stdout)
    except json.JSONDecodeError as e:
        raise LensblurError(f"lensblur info printed no JSON: {e}") from e
    if "stack_error" in info:
        raise LensblurError(f"{path}: {info['stack_error']}")
    return [layer["name"] for layer in info.get("layers", [])]


def write_chosen(context, binary, filepath, layers, exclude, tmp):
    """The stack lensblur reads: the EXR `filepath` (blend-relative; empty: the Render Result,
    written into `tmp` as stack.exr) and the layers `layers`/`exclude` choose of it. Returns
    (stack path, chosen layer names, whether it came from the Render Result)."""
    import os

    import bpy

    source = bpy.path.abspath(filepath) if filepath else ""
    if source:
        if not os.path.isfile(source):
            raise LensblurError(f"no such file: {source}")
        stack_path, available = source, file_layers(binary, source)
    else:
        stack_path, available = os.path.join(tmp, "stack.exr"), rendered_view_layers(context)
    chosen = select_layers(available, layers, exclude)
    if not source:
        check_depth_passes(context.scene, chosen)
        export_render_result(context.scene, stack_path)
    return stack_path, chosen, not source
