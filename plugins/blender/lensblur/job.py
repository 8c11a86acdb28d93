"""A `lensblur render` process the UI polls instead of waiting on: Blender's modal operators
call `poll()` from a timer, so the interface stays responsive, shows progress and can cancel.
No bpy here: the tests drive it in plain Python too.

lensblur writes one line per finished frame on stderr ("lensblur: frame 1001 (3/24): ...") and
"lensblur: warning: ..." lines (e.g. the CPU fallback); both are picked up as they come. Every
output of lensblur appears whole (a temporary file renamed into place), and SIGTERM makes it
remove the temporary it is writing, so a cancelled job leaves only complete frames."""
import json
import re
import shlex
import subprocess
import threading

from .errors import LensblurError

WARNING_PREFIX = "lensblur: warning: "
FRAME_LINE = re.compile(r"^lensblur: frame (-?\d+) \((\d+)/(\d+)\): (.*)$")


def tool_message(stderr):
    """The tool's error text without the progress noise: its last non-empty lines."""
    lines = [l.strip() for l in stderr.splitlines() if l.strip()]
    return " ".join(lines[-6:]) if lines else "failed without a message"


class RenderJob:
    """`command` running in the background; `poll()` says how far it is."""

    def __init__(self, command):
        self.command = command
        print("lensblur: " + shlex.join(command), flush=True)
        try:
            self.proc = subprocess.Popen(
                command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
            )
        except OSError as e:
            raise LensblurError(f"cannot run {command[0]}: {e}") from e
        self.frames_done, self.frames_total = 0, 0
        self.failed_frames = []
        self.warnings = []
        self._stderr = []
        self._stdout = ""
        self._lock = threading.Lock()
        # Pipes are drained by threads so a chatty tool never blocks on a full pipe.
        self._readers = [
            threading.Thread(target=self._read_stderr, daemon=True),
            threading.Thread(target=self._read_stdout, daemon=True),
        ]
        for reader in self._readers:
            reader.start()

    def _read_stderr(self):
        for line in self.proc.stderr:
            line = line.rstrip("\n")
            with self._lock:
                self._stderr.append(line)
                self._note(line)

    def _note(self, line):
        if line.startswith(WARNING_PREFIX):
            self.warnings.append(line[len(WARNING_PREFIX):])
        frame = FRAME_LINE.match(line)
        if frame:
            self.frames_done, self.frames_total = int(frame.group(2)), int(frame.group(3))
            if frame.group(4).startswith("FAILED"):
                self.failed_frames.append(int(frame.group(1)))

    def _read_stdout(self):
        text = self.proc.stdout.read()
        with self._lock:
            self._stdout = text

    def poll(self):
        """None while running, else the exit status."""
        return self.proc.poll()

    def progress(self):
        """(frames done, frames in all), (0, 0) before the first frame is done."""
        with self._lock:
            return self.frames_done, self.frames_total

    def cancel(self):
        """Stops the tool (SIGTERM: it removes the file it was writing) and waits for it."""
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._join()

    def _join(self):
        for reader in self._readers:
            reader.join(timeout=10)

    def wait(self):
        self.proc.wait()
        return self.result()

    def result(self):
        """The JSON report of a finished job; a failure raises with the tool's message."""
        self._join()
        stderr = "\n".join(self._stderr)
        if self.proc.returncode != 0:
            raise LensblurError(f"lensblur failed: {tool_message(stderr)}")
        try:
            return json.loads(self._stdout)
        except json.JSONDecodeError as e:
            raise LensblurError(
                f"lensblur printed no JSON report ({e}): {self._stdout[-300:]}"
            ) from e
