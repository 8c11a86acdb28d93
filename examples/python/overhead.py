"""Per-call overhead of the Python package: a 256^2 two-layer forward + backward (Dr.Bokeh,
exact gradient) from Python against the same calls from Rust, both with the device kept open,
medians over repeats in one run. The Rust example writes the stack it times; Python reads it.

    python examples/python/overhead.py [REPEATS]
"""
import json
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import lensblur

REPO = pathlib.Path(__file__).resolve().parents[2]


def main(repeats):
    with tempfile.TemporaryDirectory() as folder:
        stack_path = pathlib.Path(folder) / "stack.exr"
        command = ["cargo", "run", "-q", "--release", "--example", "forward_backward_overhead", "--", str(stack_path), str(repeats)]
        rust = json.loads(subprocess.run(command, cwd=REPO, check=True, capture_output=True, text=True).stdout)
        stack = lensblur.read_stack(stack_path)
    layers, depth, camera = stack["layers"], stack["depth"], stack["camera"]
    renderer = lensblur.Renderer()
    forward, backward, total = [], [], []
    # One untimed round first, as on the Rust side.
    for round in range(repeats + 1):
        start = time.perf_counter()
        image = renderer.render(layers, depth, camera)
        rendered = (time.perf_counter() - start) * 1e3
        grad_output = np.ascontiguousarray(image[..., :3])
        start = time.perf_counter()
        grads = renderer.render_backward(layers, depth, camera, grad_output)
        differentiated = (time.perf_counter() - start) * 1e3
        assert grads["layers"].shape == (2, 256, 256, 4)
        if round > 0:
            forward.append(rendered)
            backward.append(differentiated)
            total.append(rendered + differentiated)
    python = {name: statistics.median(v) for name, v in (("forward_ms", forward), ("backward_ms", backward), ("total_ms", total))}
    print(f"device: {renderer.device}; medians of {repeats}")
    for name in ("forward_ms", "backward_ms", "total_ms"):
        print(f"{name:12} python {python[name]:8.2f}  rust {rust[name]:8.2f}  ratio {python[name] / rust[name]:.3f}")
    return python, rust


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 15)
