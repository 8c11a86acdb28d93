"""Runs `lensblur render` on a stack file and returns its JSON report."""
from .job import RenderJob


def render_command(binary, stack_path, out_path, layers, camera_flags, method, character_flags=()):
    return [
        binary, "render", stack_path, "-o", out_path,
        "--layers", ",".join(layers),
        "--method", method,
        *camera_flags,
        *character_flags,
        "--json",
    ]


def run_render(command):
    """Runs the command to the end (scripts, `blender -b`); returns (report, the tool's
    warnings)."""
    job = RenderJob(command)
    return job.wait(), job.warnings


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
