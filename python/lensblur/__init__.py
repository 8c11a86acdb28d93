"""lensblur: physically based, occlusion-aware lens blur on Vulkan compute, with exact gradients.

numpy in and out: ``render`` takes premultiplied RGBA layers (L, H, W, 4) float32, front to back,
with their depth (L, H, W), or one image (H, W, 4) with its depth (H, W), which a layered method
splits into layers. ``render_backward`` returns dL/d(colour, alpha, depth) and the camera
gradients. ``lensblur.torch.render`` is the same render as a differentiable PyTorch op.
Every check and message is the Rust library's; failures raise ``LensblurError`` (a ValueError),
and arrays of the wrong dtype or layout raise ``TypeError``.
"""
from ._lensblur import (
    Camera,
    LensblurError,
    Renderer,
    methods,
    raytrace,
    read_image,
    read_stack,
    write_image,
)

__all__ = [
    "Camera",
    "LensblurError",
    "Renderer",
    "methods",
    "raytrace",
    "read_image",
    "read_stack",
    "render",
    "render_backward",
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


def render(layers, depth, camera, *, method="drbokeh", aperture="disk", depth_kind="z", device=None, leaky=False):
    """Renders ``layers`` with ``depth`` through ``camera`` (a ``Camera``); see ``Renderer.render``."""
    return renderer(device).render(
        layers, depth, camera, method=method, aperture=aperture, depth_kind=depth_kind, leaky=leaky
    )


def render_backward(
    layers, depth, camera, grad_output, *, method="drbokeh", aperture="disk", depth_kind="z", device=None, leaky=False
):
    """dL/d(inputs) of ``render`` for ``grad_output`` = dL/d(render); see ``Renderer.render_backward``."""
    return renderer(device).render_backward(
        layers, depth, camera, grad_output, method=method, aperture=aperture, depth_kind=depth_kind, leaky=leaky
    )
