"""Python renders what `lensblur render` renders: every image-changing flag of `render --help`
is a keyword of ``render_file`` (and of ``render``, but for how a file is read), the two give the
same image, and the library's checks raise its messages with the options' Python names."""
import re
import subprocess

import numpy as np
import pytest

import lensblur
from conftest import two_layer_stack

# The camera's flags are the Camera's fields.
CAMERA_FLAGS = {
    "focal-length": "focal_length_mm",
    "sensor-width": "sensor_width_mm",
    "fstop": "fstop",
    "focus-distance": "focus_distance",
    "blur": "k_px",
    "focus-disparity": "focus_disparity",
}
# Flags that change no pixel of the image, each with why: they name outputs, say how to
# report, pick frames of a shot, or bound resources.
NOT_IMAGE_CHANGING = {
    "help": "prints help",
    "output": "where the image is written (render_file returns it)",
    "output-layer": "the channel names the EXR is written with",
    "half": "the sample type the EXR is written with",
    "keep-channels": "copies the input's other channels beside the image",
    "preview": "a second, 8-bit copy of the image",
    "json": "the report's format",
    "debug-out": "writes debug views beside the image",
    "device": "where it runs; every device renders the same image (Python: Renderer(device))",
    "frames": "which frames of a shot (Python: one call per frame)",
    "camera-file": "a shot's per-frame cameras (Python: a Camera per call)",
    "skip-existing": "which frames of a shot are rendered",
}


def render_help_flags(cli):
    text = subprocess.run([cli, "render", "--help"], check=True, capture_output=True, text=True).stdout
    flags = re.findall(r"^\s+(?:-\w, )?--([a-z][a-z0-9-]*)", text, flags=re.MULTILINE)
    assert len(flags) >= 40, f"parsed only {flags} from render --help"
    return flags


def test_every_image_changing_flag_of_render_is_a_python_option(cli):
    options = set(lensblur.RENDER_OPTIONS) | set(lensblur.FILE_OPTIONS)
    fields = {name for name in dir(lensblur.Camera) if not name.startswith("_")}
    missing = []
    for flag in render_help_flags(cli):
        if flag in NOT_IMAGE_CHANGING:
            continue
        if flag in CAMERA_FLAGS:
            if CAMERA_FLAGS[flag] not in fields:
                missing.append(f"--{flag} (Camera.{CAMERA_FLAGS[flag]})")
        elif flag.replace("-", "_") not in options:
            missing.append(f"--{flag} ({flag.replace('-', '_')}=)")
    assert not missing, f"render --help flags Python lacks: {missing}"
    # And no Python option that the command line lacks (a stale name).
    flags = {f.replace("-", "_") for f in render_help_flags(cli)}
    assert options <= flags, f"Python options with no render flag: {sorted(options - flags)}"


def cli_render(cli, tmp_path, name, args):
    out = tmp_path / f"{name}.exr"
    subprocess.run([cli, "render", *args, "-o", str(out)], check=True, capture_output=True)
    return lensblur.read_image(out)


# (CLI flags, Python options): lens character, method settings, overscan and layering, each as
# both front ends spell it. The example's header carries the camera.
CASES = [
    (["--near-blur", "1.5", "--far-blur", "0.5", "--max-blur", "9"], dict(near_blur=1.5, far_blur=0.5, max_blur=9)),
    (["--focus-at", "40,100", "--aperture", "polygon:6"], dict(focus_at=(40, 100), aperture="polygon:6")),
    (["--chromatic", "1.5,0,-1.5", "--bloom", "0.8:3"], dict(chromatic=(1.5, 0, -1.5), bloom=(0.8, 3))),
    (["--cats-eye", "0.6", "--overscan", "8"], dict(cats_eye=0.6, overscan=8)),
    (["--method", "vdslr", "--samples", "64", "--tilt-shift", "0,3"], dict(method="vdslr", samples=64, tilt_shift=(0, 3))),
    (["--method", "vdslr", "--samples", "16", "--focal-planes", "1.5,6", "--iterations", "4"],
     dict(method="vdslr", samples=16, focal_planes=[1.5, 6], iterations=4)),
]


@pytest.mark.parametrize("flags, options", [c for c in CASES if c[1] is not None])
def test_render_file_equals_the_command_lines_render(cli, example, tmp_path, flags, options):
    layers = example / "layers.exr"
    expected = cli_render(cli, tmp_path, "cli", [str(layers), *flags])
    image = lensblur.render_file(layers, **options)
    assert image.shape == expected.shape
    # One library: the same float32 image, up to the command line's CPU path on a small frame
    # with no lens character against the device.
    assert np.abs(image - expected).max() <= 1e-5


def test_render_file_takes_a_camera_and_the_file_options(cli, example, tmp_path):
    layers = example / "layers.exr"
    flags = ["--focal-length", "85", "--fstop", "2", "--focus-distance", "4", "--scene-unit", "m"]
    expected = cli_render(cli, tmp_path, "camera", [str(layers), *flags, "--layers", "*"])
    camera = lensblur.Camera.physical(85, 2, 4)
    image = lensblur.render_file(layers, camera, scene_unit="m", layers=["*"])
    assert np.abs(image - expected).max() <= 1e-5


def test_array_renders_take_the_same_options_as_file_renders(example):
    stack = lensblur.read_stack(example / "layers.exr")
    camera = stack["camera"]
    options = dict(near_blur=2.0, focus_at=(40, 100), chromatic=(1, 0, -1))
    from_arrays = lensblur.render(stack["layers"], stack["depth"], camera, **options)
    from_file = lensblur.render_file(example / "layers.exr", **options)
    # Equal up to the float32 round trip of depth (1/(1/Z)) that read_stack's planar Z adds.
    assert np.abs(from_arrays - from_file).max() <= 1e-5


def test_the_librarys_checks_name_the_python_options():
    layers, depth = two_layer_stack(16, 16)
    camera = lensblur.Camera.physical(50, 2, 3)
    with pytest.raises(lensblur.LensblurError, match=r"`samples` applies to `method` multiview and vdslr, not drbokeh"):
        lensblur.render(layers, depth, camera, samples=64)
    with pytest.raises(lensblur.LensblurError, match="`tilt_shift` and `focal_planes` each set the focus field"):
        lensblur.render(layers, depth, camera, method="vdslr", tilt_shift=(1, 0), focal_planes=[2])
    with pytest.raises(lensblur.LensblurError, match="`cats_eye` cannot be combined with `tilt_shift`"):
        lensblur.render(layers, depth, camera, method="vdslr", tilt_shift=(1, 0), cats_eye=0.5)
    with pytest.raises(lensblur.LensblurError, match="near blur multiplier must be a non-negative number, got -1"):
        lensblur.render(layers, depth, camera, near_blur=-1)
    with pytest.raises(lensblur.LensblurError, match="`overscan` 9 cuts 9 px from each side of a 16x16 frame"):
        lensblur.render(layers, depth, camera, overscan=9)
    with pytest.raises(TypeError, match="unknown option 'nearblur'"):
        lensblur.render(layers, depth, camera, nearblur=2)
    with pytest.raises(TypeError, match=r"unknown option 'deep_flatten' \(a file option"):
        lensblur.render(layers, depth, camera, deep_flatten=True)
    with pytest.raises(TypeError, match="option focus_at"):
        lensblur.render(layers, depth, camera, focus_at=(1, 2, 3))
