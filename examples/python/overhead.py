"""Per-call overhead of the Python package: a 256^2 two-layer forward + backward (Dr.Bokeh,
exact gradient) from Python against the same calls from Rust, both with the device kept open.
Blocks of repeats alternate between the two (the Rust example in its own process, Python in
this one), so both see the same machine load; reported: medians over all repeats.

    python examples/python/overhead.py [BLOCKS [REPEATS]]   (default 4 blocks of 8)
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
KEYS = ("forward_ms", "backward_ms", "total_ms")


def rust_block(stack_path, repeats):
    """The Rust example's per-call times (it writes the stack it times to stack_path)."""
    command = ["cargo", "run", "-q", "--release", "--example", "forward_backward_overhead", "--", str(stack_path), str(repeats)]
    return json.loads(subprocess.run(command, cwd=REPO, check=True, capture_output=True, text=True).stdout)


def python_block(renderer, stack, repeats):
    layers, depth, camera = stack["layers"], stack["depth"], stack["camera"]
    times = {key: [] for key in KEYS}
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
            for key, value in zip(KEYS, (rendered, differentiated, rendered + differentiated)):
                times[key].append(value)
    return times


def main(blocks, repeats):
    renderer = lensblur.Renderer()
    python = {key: [] for key in KEYS}
    rust = {key: [] for key in KEYS}
    with tempfile.TemporaryDirectory() as folder:
        stack_path = pathlib.Path(folder) / "stack.exr"
        for _ in range(blocks):
            for key, values in rust_block(stack_path, repeats)["samples"].items():
                rust[key].extend(values)
            stack = lensblur.read_stack(stack_path)
            for key, values in python_block(renderer, stack, repeats).items():
                python[key].extend(values)
    print(f"device: {renderer.device}; medians of {blocks} x {repeats} calls each, alternating")
    for key in KEYS:
        p, r = statistics.median(python[key]), statistics.median(rust[key])
        print(f"{key:12} python {p:8.2f}  rust {r:8.2f}  ratio {p / r:.3f}")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]) if len(sys.argv) > 1 else (4, 8))
