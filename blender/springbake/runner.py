"""Runs `springbake bake` as a background process: finds the binary, reads its per-frame
progress lines (`--progress lines`), cancels it, and turns a failure into one readable message.

Blender-free on purpose (plain `subprocess` and threads), so it is the same code whether the
operator waits for it (`blender -b`, `bpy` as a module) or polls it from a modal timer.
"""

import os
import queue
import re
import shutil
import subprocess
import threading

_PROGRESS = re.compile(r"^progress: frame (\d+)/(\d+)$")


class RunnerError(Exception):
    """The binary cannot be found or started."""


def find_binary(configured):
    """The springbake executable: `configured` (a path, or a name on PATH) or `springbake`."""
    name = (configured or "").strip()
    if name:
        path = os.path.abspath(os.path.expanduser(name))
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return path
        found = shutil.which(name)
        if found:
            return found
        raise RunnerError(
            f"the springbake binary '{name}' was not found or is not executable; set its path "
            "in Edit → Preferences → Add-ons → springbake (or Scene → springbake binary)"
        )
    found = shutil.which("springbake")
    if found:
        return found
    raise RunnerError(
        "the springbake binary was not found on PATH; set its path in Edit → Preferences → "
        "Add-ons → springbake (build it with `cargo build --release`)"
    )


class BakeJob:
    """One `springbake bake SCENE` process with its progress, warnings and outcome."""

    def __init__(self, binary, scene_file, report_file):
        self.done_frames = 0
        self.total_frames = 0
        self.warnings = []
        self._errors = []
        self._lines = queue.Queue()
        self.cancelled = False
        if os.sep in binary:
            binary = os.path.abspath(binary)  # the process runs in the scene's folder
        command = [
            binary,
            "bake",
            scene_file,
            "--progress",
            "lines",
            "--report",
            report_file,
        ]
        try:
            self._process = subprocess.Popen(
                command,
                cwd=os.path.dirname(scene_file),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                text=True,
                encoding="utf-8",
                errors="replace",
            )
        except OSError as e:
            raise RunnerError(f"cannot start {binary}: {e.strerror or e}") from e
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self._process.stderr:
            self._lines.put(line.rstrip("\n"))
        self._lines.put(None)

    def poll(self):
        """Takes in what the process printed; True while it still runs."""
        while True:
            try:
                line = self._lines.get_nowait()
            except queue.Empty:
                break
            if line is None:
                continue
            match = _PROGRESS.match(line)
            if match:
                self.done_frames, self.total_frames = int(match[1]), int(match[2])
            elif "warning:" in line:
                self.warnings.append(line.split("warning:", 1)[1].strip())
            elif line.strip():
                self._errors.append(line.strip())
        return self._process.poll() is None

    @property
    def fraction(self):
        return self.done_frames / self.total_frames if self.total_frames else 0.0

    def wait(self):
        """Blocks until the process ends; returns its exit code."""
        self._process.wait()
        self._reader.join(timeout=5)
        self.poll()
        return self._process.returncode

    def cancel(self):
        """Stops the process (terminate, then kill after 2 s)."""
        self.cancelled = True
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(timeout=2)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        self._reader.join(timeout=5)

    @property
    def returncode(self):
        return self._process.returncode

    def error_message(self):
        """What the CLI said about its failure, without its `springbake: error:` prefix."""
        lines = [re.sub(r"^springbake:\s*(error:\s*)?", "", e) for e in self._errors]
        text = "; ".join(line for line in lines if line)
        return text or f"springbake exited with code {self.returncode}"
