"""Depth from defocus with PyTorch: fit every layer's per-pixel depth of a ray-traced scene so
that its lens blur matches the scene's thin-lens defocused image, starting from a flat scene.

    python examples/python/depth_from_defocus.py [ITERATIONS]
"""
import sys

import torch

import lensblur
import lensblur.torch


def fit(iterations=40, scale=0.5):
    """Returns [(L1 loss, alpha-weighted mean |disparity error| in 1/m)] per iteration."""
    scene = lensblur.raytrace("branches", scale=scale, samples=2)
    layers = torch.from_numpy(scene["layers"])
    target = torch.from_numpy(scene["defocused"][..., :3])
    truth = 1.0 / torch.from_numpy(scene["depth"]).double()
    alpha = layers[..., 3].double()
    # Start flat: every pixel of every layer at the scene's mean disparity.
    disparity = torch.full_like(truth, float((truth * alpha).sum() / alpha.sum())).requires_grad_()
    optimiser = torch.optim.Adam([disparity], lr=0.05)
    history = []
    for _ in range(iterations + 1):
        image = lensblur.torch.render(layers, disparity.float(), scene["camera"], depth_kind="inverse-z", leaky=True)
        loss = (image[..., :3] - target).abs().mean()
        error = ((disparity.detach() - truth).abs() * alpha).sum() / alpha.sum()
        history.append((loss.item(), error.item()))
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        with torch.no_grad():
            disparity.clamp_(min=0.01)  # in front of the camera: Z under 100 m
    return history


if __name__ == "__main__":
    history = fit(int(sys.argv[1]) if len(sys.argv) > 1 else 40)
    (loss0, error0), (loss1, error1) = history[0], history[-1]
    print(f"L1 loss {loss0:.5f} -> {loss1:.5f}; depth error {error0:.4f} -> {error1:.4f} 1/m")
