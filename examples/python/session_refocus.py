"""Resident refocus, measured: a lensblur.Session pulling focus over one stack, against one-shot
`lensblur render` processes of the same file and camera, and its resident memory over many
renders (a leak shows as growth after the first ten).

    python examples/python/session_refocus.py STACK.exr [LENSBLUR_BINARY] [RENDERS]

Prints medians; nothing is asserted (a benchmark, not a test). A file holding one image is
rendered as the command line does: split into layers, re-layered whenever the focus moves.
"""
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import lensblur


def resident_mib():
    """This process's resident memory now (Linux), in MiB."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def main():
    path = sys.argv[1]
    binary = sys.argv[2] if len(sys.argv) > 2 else "lensblur"
    renders = int(sys.argv[3]) if len(sys.argv) > 3 else 200
    stack = lensblur.read_stack(path)
    layers, depth = stack["layers"], stack["depth"]
    if layers.shape[0] == 1:  # one flat image: auto-layered, as `lensblur render` does with the file
        layers, depth = layers[0].copy(), depth[0].copy()
    focus = [1.5 + 0.25 * i for i in range(20)]

    one_shot = []
    with tempfile.TemporaryDirectory() as out:
        for d in focus[:5]:
            command = [binary, "render", path, "-o", os.path.join(out, "o.exr"), "--focal-length", "50", "--fstop", "1.4", "--focus-distance", str(d)]
            start = time.perf_counter()
            subprocess.run(command, check=True, capture_output=True)
            one_shot.append((time.perf_counter() - start) * 1e3)

    with lensblur.Session(layers, depth) as session:
        session.render(lensblur.Camera.physical(50, 1.4, focus[0]))  # prepares the method
        walls, steps, memory = [], [], {}
        for i in range(renders):
            start = time.perf_counter()
            session.render(lensblur.Camera.physical(50, 1.4, focus[i % len(focus)]))
            walls.append((time.perf_counter() - start) * 1e3)
            steps.append(session.last_render["render_ms"])
            if i + 1 in (10, renders):
                memory[i + 1] = resident_mib()
    h, w = layers.shape[-3], layers.shape[-2]
    print(f"{path}: {w}x{h}, {'one image' if layers.ndim == 3 else f'{layers.shape[0]} layers'}")
    print(f"one-shot `lensblur render` process: median {statistics.median(one_shot):.1f} ms ({len(one_shot)} runs)")
    print(f"session refocus: median {statistics.median(walls):.1f} ms per render, of which rendering "
          f"{statistics.median(steps):.1f} ms ({renders} renders); ratio to one-shot "
          f"{statistics.median(walls) / statistics.median(one_shot):.2f}")
    growth = (memory[renders] / memory[10] - 1) * 100
    print(f"resident memory: {memory[10]:.1f} MiB after 10 renders, {memory[renders]:.1f} MiB after {renders} "
          f"({growth:+.1f} %); peak {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.1f} MiB")


if __name__ == "__main__":
    main()
