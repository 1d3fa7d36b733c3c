"""springbake's Ray driver for `springbake wedge --ray ADDRESS` (embedded in the binary).

Usage: python springbake_ray_driver.py REQUEST.json
REQUEST: {"address": "...", "retries": 3, "tasks": [{"index", "folder", "command"}]}; each
command is `springbake wedge SCENE --vary … --only I -o {OUT}`. Every task runs on a Ray worker
in a temporary folder of its own (`{OUT}` replaced by it) and returns the variant folder's
files as base64, so the output folder need not be shared; the scene and its sources must be at
the same path on every worker (a shared file system, as for any farm). A task whose worker
dies is retried by Ray (`max_retries`); a bake that fails reports its error, not a retry.
Prints one JSON line per finished variant, in completion order.
"""

import base64
import json
import os
import subprocess
import sys
import tempfile
import time

import ray


def _die_with_parent():
    """The bake dies with its Ray worker (a killed worker's task is retried elsewhere)."""
    try:
        import ctypes
        import signal

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def bake(task):
    started = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="springbake-wedge-") as out:
        command = [part.replace("{OUT}", out) for part in task["command"]]
        linux = sys.platform.startswith("linux")
        # One core per task (the task reserves num_cpus=1), as `--jobs` gives each bake its share.
        env = dict(os.environ, RAYON_NUM_THREADS="1")
        run = subprocess.run(
            command,
            capture_output=True,
            text=True,
            env=env,
            preexec_fn=_die_with_parent if linux else None,
        )
        result = {
            "index": task["index"],
            "ok": run.returncode == 0,
            "code": run.returncode,
            "pid": os.getpid(),
            "node": ray.get_runtime_context().get_node_id(),
        }
        if run.returncode != 0:
            result["error"] = run.stderr
        else:
            folder = os.path.join(out, task["folder"])
            files = {}
            for name in sorted(os.listdir(folder)):
                with open(os.path.join(folder, name), "rb") as f:
                    files[name] = base64.b64encode(f.read()).decode("ascii")
            result["files"] = files
        result["seconds"] = time.monotonic() - started
        return result


def main():
    with open(sys.argv[1], encoding="utf-8") as f:
        request = json.load(f)
    ray.init(address=request["address"], log_to_driver=False)
    remote = ray.remote(num_cpus=1, max_retries=request.get("retries", 3))(bake)
    pending = {remote.remote(task): task for task in request["tasks"]}
    while pending:
        done, _ = ray.wait(list(pending), num_returns=1)
        for ref in done:
            task = pending.pop(ref)
            try:
                result = ray.get(ref)
            except Exception as e:  # a task that failed after its retries
                result = {"index": task["index"], "ok": False, "code": 1,
                          "error": f"Ray task failed: {type(e).__name__}: {e}", "seconds": 0.0}
            print(json.dumps(result), flush=True)


if __name__ == "__main__":
    main()
