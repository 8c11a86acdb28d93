"""Resident refocus through `lensblur serve`, measured as a host sees it: one server, one stack
loaded once, focus pulled over it; against one-shot `lensblur render` processes of the same file
and camera, and against the device time of the render (LENSBLUR_PROFILE's sum of the compute
shaders' timestamps, the one-shot render run with `--device gpu`). Also the server's resident memory after 10 and after N renders (a leak
shows as growth). Standard library only: any host can run it.

    python3 examples/serve_refocus.py STACK.exr [LENSBLUR_BINARY] [RENDERS] [-- CAMERA FLAGS]

e.g. python3 examples/serve_refocus.py example-out/layers.exr target/release/lensblur 200
Default camera: 50 mm, f/1.4, 36 mm sensor, focus pulled from 1.5 m. Prints medians and
ratios; nothing is asserted (a benchmark, not a test).
"""
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time


def resident_mib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def one_shot(binary, path, out, camera, profile=False):
    """(wall ms, device ms or None) of one `lensblur render` process. Profiled, it renders on the
    device (`--device gpu`): a small frame's one-shot render otherwise opens none."""
    command = [binary, "render", path, "-o", out, *flags(camera), *(["--device", "gpu"] if profile else [])]
    env = dict(os.environ, LENSBLUR_PROFILE="1") if profile else None
    start = time.perf_counter()
    done = subprocess.run(command, check=True, capture_output=True, text=True, env=env)
    wall = (time.perf_counter() - start) * 1e3
    device = re.search(r"^total\s+([\d.]+)", done.stderr, re.M)
    return wall, float(device.group(1)) if device else None


def flags(camera):
    return [
        "--focal-length", str(camera["focal_length_mm"]), "--fstop", str(camera["fstop"]),
        "--sensor-width", str(camera["sensor_width_mm"]), "--focus-distance", str(camera["focus_distance"]),
    ]


class Server:
    def __init__(self, binary):
        self.proc = subprocess.Popen([binary, "serve"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, bufsize=1)
        self.greeting = json.loads(self.proc.stdout.readline())
        self.next_id = 0

    def ask(self, op, **fields):
        self.next_id += 1
        self.proc.stdin.write(json.dumps({"id": self.next_id, "op": op, **fields}) + "\n")
        self.proc.stdin.flush()
        answer = json.loads(self.proc.stdout.readline())
        if not answer.get("ok"):
            raise SystemExit(f"lensblur serve: {answer}")
        return answer

    def close(self):
        self.ask("shutdown")
        self.proc.wait()


def main():
    args = sys.argv[1:]
    path = args[0]
    binary = args[1] if len(args) > 1 else "lensblur"
    renders = int(args[2]) if len(args) > 2 else 200
    focus = [1.5 + 0.25 * i for i in range(20)]
    camera = lambda d: {"focal_length_mm": 50, "fstop": 1.4, "sensor_width_mm": 36, "focus_distance": d}
    shm = "/dev/shm" if os.access("/dev/shm", os.W_OK) else None
    with tempfile.TemporaryDirectory(dir=shm) as out:
        exr = os.path.join(out, "o.exr")
        walls = [one_shot(binary, path, exr, camera(d))[0] for d in focus[:5]]
        devices = [one_shot(binary, path, exr, camera(d), profile=True)[1] for d in focus[:3]]

        server = Server(binary)
        loaded = server.ask("load", path=path)
        first = server.ask("render", stack=loaded["stack"], output=os.path.join(out, "o.raw"), camera=camera(focus[0]))
        resident, rendering, relayered, on_cpu, memory = [], [], 0, 0, {}
        for i in range(renders):
            start = time.perf_counter()
            answer = server.ask("render", stack=loaded["stack"], output=os.path.join(out, "o.raw"), camera=camera(focus[(i + 1) % len(focus)]))
            resident.append((time.perf_counter() - start) * 1e3)
            rendering.append(answer["timings_ms"]["render"])
            relayered += answer["relayered"]
            on_cpu += answer["cpu"]
            if i + 1 in (10, renders):
                memory[i + 1] = resident_mib(server.proc.pid)
        server.close()

    device = statistics.median(devices) if None not in devices else float("nan")
    print(f"{path}: {loaded['width']}x{loaded['height']}, protocol version {server.greeting['version']}")
    print(f"one-shot `lensblur render` process: median {statistics.median(walls):.1f} ms ({len(walls)} runs); "
          f"device time {device:.1f} ms (LENSBLUR_PROFILE, {len(devices)} runs)")
    print(f"serve: load {loaded['timings_ms']['load']:.1f} ms, first render {first['timings_ms']['total']:.1f} ms "
          f"(builds the pipelines)")
    print(f"serve refocus: median {statistics.median(resident):.1f} ms per request at the host, of which "
          f"rendering {statistics.median(rendering):.1f} ms; {relayered} of {renders} re-layered, {on_cpu} on the CPU")
    print(f"  ratio to the one-shot process {statistics.median(resident) / statistics.median(walls):.2f} (goal <= 0.4); "
          f"to its device time {statistics.median(resident) / device:.2f} (goal <= 1.3)")
    growth = (memory[renders] / memory[10] - 1) * 100
    print(f"server resident memory: {memory[10]:.1f} MiB after 10 renders, {memory[renders]:.1f} MiB after "
          f"{renders} ({growth:+.1f} %, goal within 5 %)")


if __name__ == "__main__":
    main()
