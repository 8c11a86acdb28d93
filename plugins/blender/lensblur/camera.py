"""The scene camera's depth-of-field settings as lensblur `render` flags.

lensblur's physical camera is Cycles' thin lens: aperture radius focal_length / (2 f-stop),
field of view from the focal length and the sensor width, and a planar focus distance in the
units of the depth pass. Blender's Z pass and focus distance are in Blender units, the lens in
millimetres; `--scene-unit` tells lensblur how many metres a Blender unit is (the Unit Scale,
Scene > Units), so a scene built in centimetres blurs as it would in metres. The camera's
"Depth of Field" checkbox is ignored on purpose: the layers are rendered with it off (pinhole)
and its settings describe the lens to simulate.
"""
import math
import struct

from . import compat
from .errors import LensblurError

# lensblur's polygon apertures have 3 to 16 blades.
MAX_BLADES = 16


def camera_flags(scene):
    """Returns (flags, summary, warnings) for the scene camera."""
    obj = scene.camera
    if obj is None or obj.type != "CAMERA":
        raise LensblurError("the scene has no camera: set Scene Properties > Camera")
    cam = obj.data
    if cam.type != "PERSP":
        raise LensblurError(
            f"camera '{obj.name}' is {cam.type.lower()}: lensblur needs a perspective camera"
        )
    dof = cam.dof
    summary = {
        "focal_length": cam.lens,
        "sensor_width": effective_sensor_width(scene, cam),
        "fstop": dof.aperture_fstop,
        "focus_distance": focus_distance(obj, dof),
        "scene_unit": scene_unit(scene),
        "aperture": aperture_spec(dof),
    }
    if summary["focus_distance"] <= 0.0:
        raise LensblurError(
            f"camera '{obj.name}' focuses at {summary['focus_distance']:.3g}: "
            "the focus distance (or focus object) must be in front of the camera"
        )
    flags = [
        "--focal-length", fmt(summary["focal_length"]),
        "--sensor-width", fmt(summary["sensor_width"]),
        "--fstop", fmt(summary["fstop"]),
        "--focus-distance", fmt(summary["focus_distance"]),
        "--scene-unit", summary["scene_unit"],
        "--aperture", summary["aperture"],
    ]
    return flags, summary, warnings_for(scene, dof)


# lensblur's unit names, by the shortest f32 spelling of their metres (what `fmt` prints).
UNIT_NAMES = {"1": "m", "0.01": "cm", "0.001": "mm", "1000": "km", "0.0254": "in", "0.3048": "ft"}


def scene_unit(scene):
    """What one Blender unit is, as `--scene-unit` takes it: a unit name where the Unit Scale
    is one (`cm` at 0.01), else metres per unit."""
    metres = fmt(compat.metres_per_unit(scene))
    return UNIT_NAMES.get(metres, metres)


def fmt(value):
    """The shortest decimal that reads back as the same 32-bit float. Blender stores camera
    settings as f32 and hands them to Python widened to f64, whose repr prints the widening
    noise (an f-stop of 1.4 as 1.399999976158142); lensblur parses flags as f32, so the
    shortest f32 spelling loses nothing. Negative zero prints as 0."""
    value = float(value) + 0.0  # -0.0 + 0.0 is +0.0
    as_f32 = struct.unpack("f", struct.pack("f", value))[0]
    for digits in range(1, 10):
        text = f"{value:.{digits}g}"
        short = float(text)
        if struct.unpack("f", struct.pack("f", short))[0] == as_f32:
            # Whole numbers without exponent or ".0" (5e+01 -> 50), others as Python spells them.
            return str(int(short)) if short.is_integer() and abs(short) < 1e15 else repr(short)
    return repr(value)


def fitted_axis(scene, cam):
    """The image side Blender fits the sensor to: "HORIZONTAL" or "VERTICAL" (AUTO fits the
    larger side, measured with the pixel aspect)."""
    render = scene.render
    if cam.sensor_fit != "AUTO":
        return cam.sensor_fit
    width = render.resolution_x * render.pixel_aspect_x
    height = render.resolution_y * render.pixel_aspect_y
    return "HORIZONTAL" if width >= height else "VERTICAL"


def effective_sensor_width(scene, cam):
    """Sensor width (mm) spanning the image width, following Blender's sensor fit."""
    render = scene.render
    width = render.resolution_x * render.pixel_aspect_x
    height = render.resolution_y * render.pixel_aspect_y
    fit = fitted_axis(scene, cam)
    # AUTO keeps its size in sensor_width whichever side it fits.
    size = cam.sensor_height if cam.sensor_fit == "VERTICAL" else cam.sensor_width
    return size if fit == "HORIZONTAL" else size * width / height


def focus_distance(obj, dof):
    """Planar distance of the focus plane: the focus object's depth along the view axis
    (what Cycles uses), else the distance setting."""
    if dof.focus_object is None:
        return dof.focus_distance
    cam_matrix = obj.matrix_world
    view_axis = -(cam_matrix.to_3x3() @ _z_axis()).normalized()
    offset = dof.focus_object.matrix_world.translation - cam_matrix.translation
    return abs(offset.dot(view_axis))


def _z_axis():
    from mathutils import Vector

    return Vector((0.0, 0.0, 1.0))


def aperture_spec(dof):
    """Blender: 0-2 blades = circle. Rotation: Blender turns the polygon counter-clockwise
    in camera space (y up); lensblur's image rows grow downwards, hence the sign flip."""
    if dof.aperture_blades < 3 or dof.aperture_blades > MAX_BLADES:
        return "disk"
    rotation = -math.degrees(dof.aperture_rotation)
    return f"polygon:{dof.aperture_blades}:rotation={fmt(rotation)}"


def warnings_for(scene, dof):
    out = []
    if abs(dof.aperture_ratio - 1.0) > 1e-6:
        out.append(f"anamorphic aperture ratio {dof.aperture_ratio:.3g} is ignored (round bokeh)")
    if scene.render.pixel_aspect_x != scene.render.pixel_aspect_y:
        out.append("non-square pixels: blur is computed for square pixels")
    if dof.aperture_blades > MAX_BLADES:
        out.append(f"more than {MAX_BLADES} blades: rendered as a disk")
    return out
