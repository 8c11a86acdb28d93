"""``lensblur.torch.render``: the lens blur as a differentiable PyTorch op.

Gradients flow to the layers' colour and alpha, their depth and the camera parameters. The
render runs on the Vulkan device through the numpy API: CPU tensors cross without a copy;
tensors on another device are copied to the CPU and the result is copied back.
"""
import torch

from . import Camera, renderer

_PHYSICAL = ("focal_length_mm", "fstop", "focus_distance")
_NORMALISED = ("k_px", "focus_disparity")


def _numpy(tensor):
    return tensor.detach().to("cpu").contiguous().numpy()


def _scalar(value):
    return float(value.detach()) if torch.is_tensor(value) else float(value)


def _camera(camera):
    """(a Camera, the names of the parameters given, their values as given) for a Camera or a
    dict of the physical (``focal_length_mm``, ``fstop``, ``focus_distance``, optionally
    ``sensor_width_mm``) or normalised (``k_px``, ``focus_disparity``) parameters, each a
    number or a 0-d tensor."""
    if isinstance(camera, Camera):
        return camera, (), ()
    if set(_PHYSICAL) <= camera.keys():
        params = tuple(camera[k] for k in _PHYSICAL)
        sensor = _scalar(camera.get("sensor_width_mm", 36.0))
        return Camera.physical(*(_scalar(p) for p in params), sensor_width_mm=sensor), _PHYSICAL, params
    if set(_NORMALISED) <= camera.keys():
        params = tuple(camera[k] for k in _NORMALISED)
        return Camera.normalised(*(_scalar(p) for p in params)), _NORMALISED, params
    raise TypeError(
        "camera must be a lensblur.Camera or a dict with focal_length_mm, fstop, focus_distance "
        f"(and optionally sensor_width_mm), or with k_px, focus_disparity; got keys {sorted(camera)}"
    )


class _Render(torch.autograd.Function):
    @staticmethod
    def forward(ctx, options, camera, names, layers, depth, *params):
        ctx.options, ctx.camera, ctx.names = options, camera, names
        ctx.param_dtypes = [p.dtype for p in params]
        ctx.save_for_backward(layers, depth)
        image = renderer(options["device"]).render(_numpy(layers), _numpy(depth), camera, **_render_options(options))
        return torch.from_numpy(image).to(layers.device)

    @staticmethod
    def backward(ctx, grad_image):
        layers, depth = ctx.saved_tensors
        grads = renderer(ctx.options["device"]).render_backward(
            _numpy(layers), _numpy(depth), ctx.camera, _numpy(grad_image.float()), **_render_options(ctx.options)
        )
        d_layers = torch.from_numpy(grads["layers"]).to(layers.device) if ctx.needs_input_grad[3] else None
        d_depth = torch.from_numpy(grads["depth"]).to(depth.device) if ctx.needs_input_grad[4] else None
        d_params = tuple(
            torch.tensor(grads["camera"][name], dtype=ctx.param_dtypes[i]) if ctx.needs_input_grad[5 + i] else None
            for i, name in enumerate(ctx.names)
        )
        return (None, None, None, d_layers, d_depth) + d_params


def _render_options(options):
    return {k: v for k, v in options.items() if k != "device"}


def render(layers, depth, camera, *, method="drbokeh", aperture="disk", depth_kind="z", leaky=False, device=None):
    """Renders premultiplied RGBA ``layers`` (L, H, W, 4) float32 with ``depth`` (L, H, W)
    stored as ``depth_kind`` through ``camera``; returns the premultiplied RGBA render
    (H, W, 4). Differentiable w.r.t. ``layers``, ``depth`` and the camera parameters given as
    tensors in a dict (see ``_camera``). The render's alpha is not differentiated: a loss must
    read its R, G, B channels only. ``leaky=True`` uses the leaky soft steps (forward and
    backward alike), which let an optimisation started far from the answer see which way to go.
    """
    cam, names, params = _camera(camera)
    options = dict(method=method, aperture=aperture, depth_kind=depth_kind, leaky=leaky, device=device)
    tensors = tuple(p if torch.is_tensor(p) else torch.tensor(float(p), dtype=torch.float64) for p in params)
    image = _Render.apply(options, cam, names, layers, depth, *tensors)
    return image


__all__ = ["render"]
