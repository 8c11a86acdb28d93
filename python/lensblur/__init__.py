"""lensblur: physically based, occlusion-aware lens blur on Vulkan compute, with exact gradients.

numpy in and out: ``render`` takes premultiplied RGBA layers (L, H, W, 4) float32, front to back,
with their depth (L, H, W), or one image (H, W, 4) with its depth (H, W), which a layered method
splits into layers. ``render_file`` reads a file as ``lensblur render`` does and renders it.
Both take every image-changing option of ``lensblur render`` as a keyword, in snake_case
(``RENDER_OPTIONS``; ``FILE_OPTIONS`` for how a file is read): ``near_blur=1.5``,
``focus_at=(x, y)``, ``bloom=(threshold, gain)``, ``chromatic=(r, g, b)``, ``cats_eye=0.5``,
``samples=256``, ``tilt_shift=(x, y)``, ``focal_planes=[1.5, 6]``, ``overscan=16``, ...
``render_backward`` returns dL/d(colour, alpha, depth) and the camera gradients.
``lensblur.torch.render`` is the same render as a differentiable PyTorch op.
Every check and message is the Rust library's; failures raise ``LensblurError`` (a ValueError),
and arrays of the wrong dtype or layout raise ``TypeError``.
"""
from ._lensblur import (
    Camera,
    LensblurError,
    Renderer,
    Session,
    methods,
    raytrace,
    read_image,
    read_stack,
    render_options,
    write_image,
)

RENDER_OPTIONS, FILE_OPTIONS = (tuple(names) for names in render_options())

__all__ = [
    "Camera",
    "FILE_OPTIONS",
    "LensblurError",
    "RENDER_OPTIONS",
    "Renderer",
    "Session",
    "methods",
    "raytrace",
    "read_image",
    "read_stack",
    "render",
    "render_backward",
    "render_file",
    "renderer",
    "write_image",
]

_renderers = {}


def renderer(device=None):
    """The process's Renderer on ``device`` (see ``Renderer``), opened on first use and kept,
    so that repeated calls pay for the device and the pipelines once."""
    if device not in _renderers:
        _renderers[device] = Renderer(device)
    return _renderers[device]


def render(layers, depth, camera, *, depth_kind="z", device=None, leaky=False, **options):
    """Renders ``layers`` with ``depth`` through ``camera`` (a ``Camera``) with the keyword
    ``options`` (``RENDER_OPTIONS``: ``method``, ``aperture``, the lens character, the method's
    settings, ``overscan``, ...); see ``Renderer.render``."""
    return renderer(device).render(layers, depth, camera, depth_kind=depth_kind, leaky=leaky, **options)


def render_file(path, camera=None, *, device=None, **options):
    """Reads ``path`` as ``lensblur render`` does and renders it through ``camera`` (None: the
    file's header) with the keyword ``options`` (``RENDER_OPTIONS`` and ``FILE_OPTIONS``);
    returns the image ``lensblur render`` writes, (H, W, 4) float32. See ``Renderer.render_file``."""
    return renderer(device).render_file(path, camera, **options)


def render_backward(
    layers, depth, camera, grad_output, *, method="drbokeh", aperture="disk", depth_kind="z", device=None, leaky=False
):
    """dL/d(inputs) of ``render`` for ``grad_output`` = dL/d(render); see ``Renderer.render_backward``."""
    return renderer(device).render_backward(
        layers, depth, camera, grad_output, method=method, aperture=aperture, depth_kind=depth_kind, leaky=leaky
    )
