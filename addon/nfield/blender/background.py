"""Long solver work off the UI thread: the modal operators ``nfield.solve_background`` and
``nfield.precompute_spectral``.

A solve that must first factor (new settings, first solve, a region edit) takes about a second per 100k
faces, minutes for a spectral basis. In an interactive Blender the Solve button, live updates after a
settings change and the modal tools hand such solves to this modal operator: the factorization runs in a
worker thread (the native code releases the GIL), the status bar shows it, Esc cancels it (the session
keeps its previous state), and the result is stored and written when it is done. Fast incremental solves
stay synchronous. In background Blender (``blender -b``, PyPI ``bpy``) everything is synchronous.

While a worker owns an object's session, nothing else may touch that session: ``jobs.busy(obj)`` says so;
the api refuses to solve it (NFieldError) and live updates are deferred until the worker is done.

``nfield.precompute_spectral`` computes the spectral basis (k eigenfields, minutes on large meshes) the same
way when invoked from the UI (progress in the status bar, Esc cancels and restores the previous settings);
executed from a script it blocks.
"""
from __future__ import annotations

import threading
import time

import bpy
from bpy.props import IntProperty, StringProperty

from . import api, jobs
from .jobs import lower_worker_priority
from .operator_base import NFieldObjectOperator

#: the last background solve (scripts and tests): state "running" | "finished" | "cancelled" | "failed"
status: dict = {"state": "idle", "object": "", "work": "", "message": "", "thread": "", "seconds": 0.0}


class NFIELD_OT_solve_background(bpy.types.Operator):
    """Solve the field in a worker thread (factorization or basis first); Esc cancels"""

    bl_idname = "nfield.solve_background"
    bl_label = "Solve Field (Background)"
    # No undo step of its own: the user action that started it (a setting, an edit) made the step, and the
    # field it computes is not part of the undoable design (undo puts fields back from results' history).
    bl_options = {"REGISTER", "INTERNAL"}

    object_name: StringProperty(name="Object", default="", description="Default: the active object")

    def execute(self, context):  # scripts: the plain, blocking solve
        return bpy.ops.nfield.solve()

    def invoke(self, context, event):
        obj = bpy.data.objects.get(self.object_name) if self.object_name else context.active_object
        if obj is None or obj.type != "MESH":
            self.report({"ERROR"}, "no mesh object to solve")
            return {"CANCELLED"}
        if jobs.busy(obj):
            self.report({"INFO"}, f"nfield: '{obj.name}' is already being solved in the background")
            return {"CANCELLED"}
        try:
            arrays, entry, session = api.open_session(obj)
            work = session.pending_work() or "solve"
        except (ValueError, RuntimeError, MemoryError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        shared = {"cancel": False, "outcome": None, "t0": time.perf_counter()}

        def progress(_fraction):
            return not shared["cancel"]

        def work_fn():
            lower_worker_priority()
            session.progress = progress
            try:
                shared["outcome"] = ("ok", session.solve())
            except BaseException as exc:  # noqa: BLE001 - reported in the main thread
                shared["outcome"] = ("error", exc)
            finally:
                session.progress = None

        self._obj_name, self._entry, self._arrays, self._shared = obj.name, entry, arrays, shared
        jobs.claim(obj.name, shared)
        thread = threading.Thread(target=work_fn, name="nfield-solve", daemon=True)
        status.update(state="running", object=obj.name, work=work, message="", thread=thread.name, seconds=0.0)
        self._thread = thread
        thread.start()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        self._status(context, f"nfield: {work} of '{obj.name}' in the background, Esc to cancel")
        return {"RUNNING_MODAL"}

    @staticmethod
    def _status(context, text):
        if context.workspace is not None:
            context.workspace.status_text_set(text)

    def modal(self, context, event):
        if event.type == "ESC" and event.value == "PRESS":
            self._shared["cancel"] = True
            self._status(context, "nfield: cancelling (the solver stops at its next checkpoint)")
        if self._thread.is_alive():
            # Other events go on to Blender: the viewport stays usable while the worker computes.
            return {"RUNNING_MODAL"} if event.type in ("ESC", "TIMER") else {"PASS_THROUGH"}
        return self._finish(context)

    def _finish(self, context):
        context.window_manager.event_timer_remove(self._timer)
        self._status(context, None)
        shared = jobs.release(self._obj_name, self._shared)
        seconds = time.perf_counter() - shared["t0"]
        outcome = shared["outcome"] or ("error", RuntimeError("the solver thread ended without a result"))
        obj = bpy.data.objects.get(self._obj_name)
        if outcome[0] == "error":
            cancelled = shared["cancel"] or type(outcome[1]).__name__ == "Cancelled"
            status.update(state="cancelled" if cancelled else "failed", message=str(outcome[1]), seconds=seconds)
            if obj is not None:
                # the settings that failed go back to the last ones that solved (the field shown is that one)
                reverted = [] if cancelled else api.revert_settings(obj)
                obj.nfield.last_message = ("Solve cancelled" if cancelled else f"Solve failed: {outcome[1]}"
                                           + (f". Reverted: {', '.join(reverted)}" if reverted else ""))
            self.report({"WARNING"} if cancelled else {"ERROR"},
                        "nfield: solve cancelled" if cancelled else f"nfield: solve failed: {outcome[1]}")
            return {"CANCELLED"}
        if obj is None:
            status.update(state="failed", message="the object was deleted", seconds=seconds)
            return {"CANCELLED"}
        api.adopt_result(obj, self._entry, self._arrays, outcome[1])
        message = f"nfield: solved '{obj.name}' in {seconds:.1f} s ({status['work']})"
        status.update(state="finished", message=message, seconds=seconds)
        self.report({"INFO"}, message)
        if shared.get("again"):  # settings changed while the worker ran
            jobs.start_later(obj.name)
        return {"FINISHED"}


#: State of the last background precompute (read by scripts and tests; the UI shows progress in the
#: status bar): state is "idle", "running", "cancelled", "failed" or "finished".
#: ui_updates counts the progress updates the UI made while the worker ran (the UI stayed responsive).
precompute_status: dict = {"state": "idle", "object": "", "k": 0, "fraction": 0.0, "message": "", "ui_updates": 0}


class NFIELD_OT_precompute_spectral(NFieldObjectOperator, bpy.types.Operator):
    """Compute the spectral basis (k lowest eigenfields) in the background; Esc cancels"""

    bl_idname = "nfield.precompute_spectral"
    bl_label = "Precompute Spectral Basis"
    bl_options = {"REGISTER"}  # the basis lives in memory; the mode switch is a setting

    k: IntProperty(name="Eigenfields", default=0, min=0, description="0: the object's Eigenfields setting")

    _worker = None

    def execute(self, context):
        # scripts / background mode: blocking
        return self.run(context, lambda obj: f"nfield: spectral basis ready "
                        f"({api.precompute_spectral(obj, self.k or None).num_faces} faces)")

    def invoke(self, context, event):
        obj = context.active_object
        if self.report_native_error():
            return {"CANCELLED"}
        self._previous = (obj.nfield.solver_mode, obj.nfield.spectral_k)
        try:
            api.configure(obj, mode="spectral", k=self.k or None)
            arrays, self._entry, self._recipe = api.background_recipe(obj)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._obj_name = obj.name
        self._arrays = arrays
        precompute_status.update(state="running", object=obj.name, k=int(obj.nfield.spectral_k), fraction=0.0,
                                 message="", ui_updates=0)
        recipe = self._recipe
        self._worker = jobs.Worker(lambda progress: api.build_from_recipe(recipe, progress), precompute_status,
                                   "nfield-basis")
        self._worker.start(self, context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if self._worker.step(context, event, "computing spectral basis"):
            return self._finish(context)
        return self._worker.passed_on(event)

    def _finish(self, context):
        self._worker.stop(context)
        outcome = self._worker.outcome or ("error", RuntimeError("worker ended without a result"))
        obj = bpy.data.objects.get(self._obj_name)
        if self._worker.cancel or outcome[0] == "error":
            if obj is not None:
                api.configure(obj, mode=self._previous[0], k=self._previous[1])
            if self._worker.cancel:
                precompute_status.update(state="cancelled", message="cancelled")
                self.report({"WARNING"}, "nfield: spectral basis computation cancelled")
            else:
                precompute_status.update(state="failed", message=str(outcome[1]))
                self.report({"ERROR"}, f"nfield: spectral basis failed: {outcome[1]}")
            return {"CANCELLED"}
        if obj is None:
            precompute_status.update(state="failed", message="the object was deleted")
            return {"CANCELLED"}
        session, result = outcome[1]
        api.adopt_session(obj, self._entry, self._arrays, self._recipe, session, result)
        info = session.basis_info
        message = (f"nfield: spectral basis ready ({info.k} eigenfields, {info.source}, "
                   f"{info.seconds:.1f} s, {info.memory_bytes / 2**20:.0f} MB)")
        precompute_status.update(state="finished", fraction=1.0, message=message)
        self.report({"INFO"}, message)
        return {"FINISHED"}


classes = (NFIELD_OT_solve_background, NFIELD_OT_precompute_spectral)
register, unregister = bpy.utils.register_classes_factory(classes)
