"""The operators: `springbake.bake` (bake the selected objects and play the result on them),
`springbake.free_bake` (remove it) and `springbake.cancel_bake`.

From a script or without a window (`blender -b`, `bpy` as a module) `bake` runs to completion
before it returns; from a button it runs in the background, shows its progress in the status
bar and the panel, and stops on Esc or Cancel. A bake that fails or is cancelled leaves the
previous one in place: results are read and converted first, then swapped in.
"""

import hashlib
import os
import re
import shutil
import tempfile
import time

import bpy

from . import cache, properties, runner, scene_writer

_running_jobs = set()


def is_running():
    """Whether a bake started from this Blender session is still running."""
    return bool(_running_jobs)


def cancel_running_bakes():
    """Stops every bake still running (the add-on is being disabled)."""
    for job in list(_running_jobs):
        job.cancel()
    _running_jobs.clear()


def cache_root(scene):
    """The folder this scene's bakes go to (absolute)."""
    configured = scene.springbake.cache_dir or "//springbake_cache"
    if configured.startswith("//") and not bpy.data.filepath:
        base = os.path.join(tempfile.gettempdir(), "springbake_cache")
        configured = configured[2:]
        root = os.path.join(base, configured) if configured else base
    else:
        root = bpy.path.abspath(configured)
    scene_part = re.sub(r"[^A-Za-z0-9_-]", "_", scene.name) or "scene"
    return os.path.join(os.path.abspath(root), scene_part)


def cache_file_for(root, obj):
    """The object's own PC2 in the cache folder: its name made safe, plus a short hash so
    names that differ only in characters dropped stay apart."""
    digest = hashlib.sha1(obj.name.encode("utf-8")).hexdigest()[:8]
    stem = re.sub(r"[^A-Za-z0-9_-]", "_", obj.name)[:48] or "object"
    return os.path.join(root, f"{stem}_{digest}.pc2")


def _binary(context):
    prefs = properties.preferences(context)
    configured = context.scene.springbake.binary or (prefs.binary if prefs else "")
    return runner.find_binary(configured)


def _explain(job, plan):
    """The CLI's error with the bodies' OBJ files named by their objects."""
    message = job.error_message()
    for body in plan.bodies:
        message = message.replace(body.obj_path, f"'{body.obj.name}'")
    return message


class SPRINGBAKE_OT_bake(bpy.types.Operator):
    """Bake the selected mesh objects as springbake soft bodies and play the result on them
    (a Mesh Cache modifier first in their stack)"""

    bl_idname = "springbake.bake"
    bl_label = "Bake"
    bl_options = {"REGISTER"}

    _job = None
    _plan = None
    _timer = None
    _started = 0.0

    @classmethod
    def poll(cls, context):
        # The running jobs, not the scene's flag: a file saved during a bake keeps the flag.
        return context.scene is not None and not is_running()

    def _start(self, context):
        """Writes the scene folder and starts the CLI; False (with a report) when it cannot."""
        scene = context.scene
        root = cache_root(scene)
        staging = os.path.join(root, "pending")
        try:
            binary = _binary(context)
            if os.path.isdir(staging):
                shutil.rmtree(staging)
            os.makedirs(staging, exist_ok=True)
            self._plan = scene_writer.plan_bake(context, context.selected_objects, staging)
            self._job = runner.BakeJob(
                binary,
                os.path.join(staging, scene_writer.SCENE_FILE),
                os.path.join(staging, "report.json"),
            )
        except (runner.RunnerError, scene_writer.SceneError) as e:
            self.report({"ERROR"}, f"springbake: {e}")
            return False
        except OSError as e:
            self.report({"ERROR"}, f"springbake: cannot write the bake folder {staging}: {e}")
            return False
        _running_jobs.add(self._job)
        self._started = time.monotonic()
        scene.springbake.is_baking = True
        scene.springbake.cancel_requested = False
        scene.springbake.progress = 0.0
        for note in self._plan.notes:
            self.report({"INFO"}, f"springbake: {note}")
        return True

    def _finish(self, context):
        """Reads the finished bake into the objects; the operator's return value."""
        job, plan = self._job, self._plan
        _running_jobs.discard(job)
        context.scene.springbake.is_baking = False
        if job.cancelled:
            self.report({"WARNING"}, "springbake: bake cancelled; the previous bake is kept")
            return {"CANCELLED"}
        if job.returncode != 0:
            self.report({"ERROR"}, f"springbake: the bake failed: {_explain(job, plan)}")
            return {"CANCELLED"}
        root = cache_root(context.scene)
        try:
            results = []
            for body in plan.bodies:
                frames, _, _ = cache.read_pc2(plan.cache_file_of(body))
                if frames.shape[1] != body.vertex_count:
                    raise cache.CacheError(
                        f"the cache of '{body.obj.name}' has {frames.shape[1]} points, the "
                        f"object {body.vertex_count} vertices"
                    )
                world = scene_writer.from_metres_y_up(frames, plan.unit_scale)
                results.append((body, cache.to_local(world, body.rest_matrix)))
            for body, local in results:
                path = cache_file_for(root, body.obj)
                cache.write_pc2_atomically(path, local)
                cache.attach(body.obj, path, plan.frame_start)
        except (cache.CacheError, OSError) as e:
            self.report({"ERROR"}, f"springbake: cannot read the bake back: {e}")
            return {"CANCELLED"}
        for warning in job.warnings:
            self.report({"WARNING"}, f"springbake: {warning}")
        seconds = time.monotonic() - self._started
        self.report(
            {"INFO"},
            f"springbake: baked {len(plan.bodies)} object(s), {plan.frames} frames in "
            f"{seconds:.1f} s",
        )
        return {"FINISHED"}

    def execute(self, context):
        if not self._start(context):
            return {"CANCELLED"}
        self._job.wait()
        return self._finish(context)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        if not self._start(context):
            return {"CANCELLED"}
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 100)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _end_modal(self, context):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)

    def modal(self, context, event):
        settings = context.scene.springbake
        if event.type == "ESC" or settings.cancel_requested:
            self._job.cancel()
            self._end_modal(context)
            return self._finish(context)
        if event.type != "TIMER":
            return {"PASS_THROUGH"}
        running = self._job.poll()
        settings.progress = self._job.fraction
        context.window_manager.progress_update(int(100 * self._job.fraction))
        if context.workspace is not None:
            context.workspace.status_text_set(
                f"springbake: baking frame {self._job.done_frames}/{self._plan.frames} "
                "(Esc to cancel)"
            )
        for area in context.screen.areas if context.screen else ():
            if area.type in {"PROPERTIES", "VIEW_3D"}:
                area.tag_redraw()
        if running:
            return {"RUNNING_MODAL"}
        self._job.wait()
        self._end_modal(context)
        return self._finish(context)


class SPRINGBAKE_OT_cancel_bake(bpy.types.Operator):
    """Stop the running springbake bake (the previous bake is kept)"""

    bl_idname = "springbake.cancel_bake"
    bl_label = "Cancel bake"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and is_running()

    def execute(self, context):
        context.scene.springbake.cancel_requested = True
        return {"FINISHED"}


class SPRINGBAKE_OT_free_bake(bpy.types.Operator):
    """Remove the springbake bake from the selected objects (they return to their rest shape)"""

    bl_idname = "springbake.free_bake"
    bl_label = "Free bake"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        freed = [obj.name for obj in context.selected_objects if cache.free(obj)]
        if not freed:
            self.report({"INFO"}, "springbake: no bake on the selected objects")
            return {"CANCELLED"}
        self.report({"INFO"}, f"springbake: freed the bake of {', '.join(freed)}")
        return {"FINISHED"}


_classes = (SPRINGBAKE_OT_bake, SPRINGBAKE_OT_cancel_bake, SPRINGBAKE_OT_free_bake)


register, unregister = bpy.utils.register_classes_factory(_classes)
