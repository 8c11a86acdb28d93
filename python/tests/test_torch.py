"""lensblur.torch.render: the same render and gradients as the numpy API, and depth from
defocus with torch.optim on a ray-traced scene (examples/python/depth_from_defocus.py)."""
import sys

import numpy as np
import pytest
import torch

import lensblur
import lensblur.torch as lbt
from conftest import REPO, two_layer_stack

sys.path.insert(0, str(REPO / "examples" / "python"))
import depth_from_defocus  # noqa: E402  (the example is what is tested)


def test_the_op_renders_and_differentiates_as_the_numpy_api():
    layers, depth = two_layer_stack(16, 20, seed=5)
    weights = np.random.default_rng(9).uniform(-1, 1, size=(16, 20, 3)).astype(np.float32)
    camera = dict(focal_length_mm=torch.tensor(50.0, requires_grad=True), fstop=torch.tensor(2.0, requires_grad=True),
                  focus_distance=torch.tensor(2.0, requires_grad=True))
    t_layers = torch.from_numpy(layers).requires_grad_()
    t_depth = torch.from_numpy(depth).requires_grad_()
    image = lbt.render(t_layers, t_depth, camera)
    physical = lensblur.Camera.physical(50.0, 2.0, 2.0)
    assert np.array_equal(image.detach().numpy(), lensblur.render(layers, depth, physical))
    (image[..., :3] * torch.from_numpy(weights)).sum().backward()
    expected = lensblur.render_backward(layers, depth, physical, weights)
    assert np.array_equal(t_layers.grad.numpy(), expected["layers"])
    assert np.array_equal(t_depth.grad.numpy(), expected["depth"])
    for name in ("focal_length_mm", "fstop", "focus_distance"):
        assert camera[name].grad.item() == pytest.approx(expected["camera"][name], rel=1e-6), name


def test_a_loss_on_the_renders_alpha_is_refused():
    layers, depth = two_layer_stack(8, 8)
    image = lbt.render(torch.from_numpy(layers).requires_grad_(), torch.from_numpy(depth), lensblur.Camera.physical(50, 2, 3))
    with pytest.raises(lensblur.LensblurError, match="alpha is not differentiated"):
        image.sum().backward()


def test_depth_from_defocus_reduces_the_loss_and_the_depth_error():
    history = depth_from_defocus.fit(iterations=25)
    (loss0, error0), (loss1, error1) = history[0], history[-1]
    print(f"loss {loss0:.5f} -> {loss1:.5f}, depth error {error0:.4f} -> {error1:.4f} 1/m")
    assert loss1 < 0.8 * loss0, (loss0, loss1)
    assert error1 < 0.8 * error0, (error0, error1)


def test_the_normalised_cameras_parameters_get_gradients():
    layers, depth = two_layer_stack(12, 12, seed=2)
    k, focus = torch.tensor(6.0, requires_grad=True), torch.tensor(0.4, requires_grad=True)
    image = lbt.render(torch.from_numpy(layers), torch.from_numpy(depth), {"k_px": k, "focus_disparity": focus}, depth_kind="inverse-z")
    image[..., :3].sum().backward()
    camera = lensblur.Camera.normalised(6.0, 0.4)
    expected = lensblur.render_backward(layers, depth, camera, np.ones((12, 12, 3), np.float32), depth_kind="inverse-z")
    assert k.grad.item() == pytest.approx(expected["camera"]["k_px"], rel=1e-6)
    assert focus.grad.item() == pytest.approx(expected["camera"]["focus_disparity"], rel=1e-6)
    assert k.grad.item() != 0
