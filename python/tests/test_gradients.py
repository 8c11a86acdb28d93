"""render_backward against float64 central differences of the forward.

Each check is a directional derivative: the analytic dL/dx . v against
(L(x + h v) - L(x - h v)) / 2h, with L = sum(w * render[..., :3]) summed in float64 for a fixed
random w. The forward runs in float32 on the device, so the difference carries ~1e-7 relative
rounding of L over h; the steps below keep that and the curvature term under the tolerances.
"""
import numpy as np
import pytest

import lensblur
from conftest import two_layer_stack

H, W = 20, 24
# A long lens, so the 24 px frame blurs by a few pixels: CoC 2.2 px on the card and the wall.
CAMERA = dict(focal_length_mm=200.0, fstop=2.0, focus_distance=2.0)


def loss(layers, depth, camera, weights):
    image = lensblur.render(layers, depth, camera)
    return float(np.sum(weights.astype(np.float64) * image[..., :3].astype(np.float64)))


@pytest.fixture(scope="module")
def setup():
    layers, depth = two_layer_stack(H, W, seed=3)
    weights = np.random.default_rng(7).uniform(-1, 1, size=(H, W, 3)).astype(np.float32)
    camera = lensblur.Camera.physical(**CAMERA)
    grads = lensblur.render_backward(layers, depth, camera, weights)
    return layers, depth, weights, camera, grads


def directional(f, h):
    return (f(h) - f(-h)) / (2 * h)


def check(name, analytic, numeric, rtol):
    assert abs(analytic - numeric) <= rtol * abs(numeric), f"{name}: analytic {analytic:.6g}, finite difference {numeric:.6g}"
    assert abs(numeric) > 0, f"{name}: the direction must change the loss"


def test_colour_gradient(setup):
    # The render is linear in premultiplied colour: 1e-4 relative.
    layers, depth, weights, camera, grads = setup
    v = np.zeros_like(layers)
    v[..., :3] = np.random.default_rng(1).uniform(-1, 1, size=layers[..., :3].shape)
    analytic = float(np.sum(grads["layers"].astype(np.float64) * v))
    numeric = directional(lambda h: loss((layers + h * v).astype(np.float32), depth, camera, weights), 0.05)
    check("colour", analytic, numeric, 1e-4)


def test_alpha_gradient(setup):
    # Alpha enters through occlusion (nonlinear); every alpha stays in (0, 1]: 2e-3 relative.
    layers, depth, weights, camera, grads = setup
    v = np.zeros_like(layers)
    v[0, ..., 3] = np.random.default_rng(2).uniform(-1, 1, size=(H, W)) * (layers[0, ..., 3] < 0.95)
    analytic = float(np.sum(grads["layers"].astype(np.float64) * v))
    numeric = directional(lambda h: loss((layers + h * v).astype(np.float32), depth, camera, weights), 1e-2)
    check("alpha", analytic, numeric, 2e-3)


def test_depth_gradient(setup):
    # Planar Z through the CoC and the soft occlusion steps: 1e-2 relative.
    layers, depth, weights, camera, grads = setup
    v = np.random.default_rng(3).uniform(-1, 1, size=depth.shape) * depth
    analytic = float(np.sum(grads["depth"].astype(np.float64) * v))
    numeric = directional(lambda h: loss(layers, (depth + h * v).astype(np.float32), camera, weights), 1e-3)
    check("depth", analytic, numeric, 1e-2)


@pytest.mark.parametrize("parameter", ["focus_distance", "fstop", "focal_length_mm"])
def test_camera_gradient(setup, parameter):
    # Through K = (f / 2N)(f / sensor) width and the focus disparity 1 / D, with a step of 1e-3
    # of the value: 3e-2 relative (the differences scatter by about 1% between steps of 1e-3
    # and 1e-2 of the value: float32 rounding of a loss that moves by ~1e-3).
    layers, depth, weights, camera, grads = setup
    step = 1e-3 * CAMERA[parameter]

    def moved(h):
        return lensblur.Camera.physical(**{**CAMERA, parameter: CAMERA[parameter] + h})

    numeric = directional(lambda h: loss(layers, depth, moved(h), weights), step)
    check(parameter, grads["camera"][parameter], numeric, 3e-2)


def test_normalised_camera_has_no_physical_gradients(setup):
    layers, depth, weights, _, _ = setup
    grads = lensblur.render_backward(layers, depth, lensblur.Camera.normalised(8.0, 0.4), weights, depth_kind="inverse-z")
    assert grads["camera"]["fstop"] is None and grads["camera"]["k_px"] != 0
    assert grads["layers"].shape == (2, H, W, 4) and grads["depth"].shape == (2, H, W)
