"""Runs `lensblur render` on a stack file and returns its JSON report."""
import json
import shlex
import subprocess

from .errors import LensblurError
from .stack import tool_message


def render_command(binary, stack_path, out_path, layers, camera_flags, method):
    return [
        binary, "render", stack_path, "-o", out_path,
        "--layers", ",".join(layers),
        "--method", method,
        *camera_flags,
        "--json",
    ]


def run_render(command):
    """Runs the command (printed first, so the console shows what ran); returns the report."""
    print("lensblur: " + shlex.join(command), flush=True)
    try:
        proc = subprocess.run(command, capture_output=True, text=True, check=False)
    except OSError as e:
        raise LensblurError(f"cannot run {command[0]}: {e}") from e
    if proc.returncode != 0:
        raise LensblurError(f"lensblur failed: {tool_message(proc.stderr)}")
    try:
        return json.loads(proc.stdout)
    except json.JSONDecodeError as e:
        raise LensblurError(f"lensblur printed no JSON report ({e}): {proc.stdout[-300:]}") from e


def summary(report):
    layers = ", ".join(
        f"{l['name']} ({l['coc_range_px'][0]:.1f}-{l['coc_range_px'][1]:.1f} px)"
        for l in report.get("layers", [])
    )
    ms = report.get("timings_ms", {}).get("total", 0.0)
    return (
        f"lensblur: {report.get('width')}x{report.get('height')}, {report.get('method')}, "
        f"layers front to back: {layers}; {ms:.0f} ms"
    )
