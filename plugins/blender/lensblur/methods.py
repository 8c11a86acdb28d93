"""The rendering methods the add-on offers: what `lensblur methods --json` lists, asked of the
binary the add-on runs, so the menu is always the tool's own registry (never a copy that could
fall behind it). Answers are cached per binary. Plain Python (no bpy): the tests run it
without Blender."""
import json
import subprocess
import time

from .errors import LensblurError

# The method `lensblur render` uses without --method: the menu's one item while the tool cannot
# be asked (the render then fails with the same reason).
DEFAULT = "drbokeh"
# How long a failed answer is kept before the binary is asked again (the menu is rebuilt on every
# redraw; a missing tool must not be started each time).
RETRY_SECONDS = 5.0
# Seconds `lensblur methods --json` may take (it only prints the registry).
TIMEOUT_SECONDS = 10.0

# binary path -> (items, error or None, time.monotonic() of the answer). Blender needs the menu's
# strings to stay referenced while it shows them: the cache holds them.
_answers = {}
# error -> the fallback menu for it, kept for the same reason.
_fallbacks = {}



def parse(text):
    """[(name, label, summary)] of every method in the output of `lensblur methods --json`, in
    the tool's order (its default first)."""
    listing = json.loads(text)
    items = [(m["name"], m["label"], m["summary"]) for m in listing["methods"]]
    if not items:
        raise ValueError("it listed no method")
    return items


def ask(binary):
    """The menu items `binary methods --json` gives; LensblurError when it cannot be run or its
    answer cannot be read."""
    try:
        run = subprocess.run(
            [binary, "methods", "--json"], capture_output=True, text=True, timeout=TIMEOUT_SECONDS
        )
    except (OSError, subprocess.SubprocessError) as e:
        raise LensblurError(f"cannot run '{binary} methods --json': {e}") from e
    if run.returncode != 0:
        message = run.stderr.strip().splitlines()[-1:] or [f"exit status {run.returncode}"]
        raise LensblurError(f"'{binary} methods --json' failed: {message[0]}")
    try:
        return parse(run.stdout)
    except (ValueError, KeyError, TypeError) as e:
        raise LensblurError(f"'{binary} methods --json' gave no method list ({e}): is the lensblur binary older than the add-on?") from e


def menu(find_binary):
    """(items, error) of the method menu: the tool's methods and None, or, when the binary
    (`find_binary()`, which raises LensblurError when there is none) cannot be found or asked,
    the default method alone and the reason, for the panel to show."""
    try:
        binary = find_binary()
    except LensblurError as e:
        return fallback(str(e)), str(e)
    cached = _answers.get(binary)
    if cached is not None and (cached[1] is None or time.monotonic() - cached[2] < RETRY_SECONDS):
        return cached[0], cached[1]
    try:
        items, error = ask(binary), None
    except LensblurError as e:
        error = f"{e}; only {DEFAULT} is offered"
        items = fallback(error)
    _answers[binary] = (items, error, time.monotonic())
    return items, error


def fallback(error):
    """The menu while the tool cannot be asked: its default method, described by `error`."""
    return _fallbacks.setdefault(error, [(DEFAULT, DEFAULT, error)])
