import os
import pathlib
import subprocess

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def cli():
    """The lensblur command line the forward is compared with: LENSBLUR_BIN (cargo test's
    tests/python_package.rs sets it to the binary it built), else a release build in target/."""
    path = os.environ.get("LENSBLUR_BIN") or str(REPO / "target" / "release" / "lensblur")
    if not os.access(path, os.X_OK):
        pytest.fail(
            f"no lensblur binary at {path}: build it with `cargo build --release` "
            "or run these tests through `cargo test --test python_package`"
        )
    return path


@pytest.fixture(scope="session")
def example(cli, tmp_path_factory):
    """The built-in example's layers (the quick start's scene, `lensblur raytrace branches`)."""
    out = tmp_path_factory.mktemp("example")
    subprocess.run([cli, "raytrace", "branches", "-o", str(out), "--samples", "1", "--min-rounds", "2", "--max-rounds", "2"], check=True, capture_output=True)
    return out


def two_layer_stack(height, width, seed=0):
    """A textured card in front of a textured wall, every pixel partly covered (alpha in
    [0.3, 1]) so that no depth is filled: planar Z in metres, float32."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    card_alpha = np.clip(1.0 - np.hypot(x - width * 0.4, y - height * 0.5) / (0.35 * width), 0.3, 1.0)
    wall_alpha = np.ones((height, width), np.float32)
    colour = rng.uniform(0.1, 0.9, size=(2, height, width, 3)).astype(np.float32)
    alpha = np.stack([card_alpha, wall_alpha]).astype(np.float32)
    layers = np.concatenate([colour * alpha[..., None], alpha[..., None]], axis=-1).astype(np.float32)
    depth = np.stack([np.full((height, width), 1.2, np.float32) + 0.002 * x, np.full((height, width), 6.0, np.float32) + 0.01 * y])
    return np.ascontiguousarray(layers), np.ascontiguousarray(depth.astype(np.float32))
