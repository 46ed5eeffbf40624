"""Long solver work off the UI thread: ``nfield.solve_background``.

A solve that must first factor (new settings, first solve, a region edit) takes about a second per 100k
faces, minutes for a spectral basis. In an interactive Blender the Solve button, live updates after a
settings change and the modal tools hand such solves to this modal operator: the factorization runs in a
worker thread (the native code releases the GIL), the status bar shows it, Esc cancels it (the session
keeps its previous state), and the result is stored and written when it is done. Fast incremental solves
stay synchronous. In background Blender (``blender -b``, PyPI ``bpy``) everything is synchronous.

While a worker owns an object's session, nothing else may touch that session: ``busy(obj)`` says so; the
api refuses to solve it (NFieldError) and live updates are deferred until the worker is done.
"""
from __future__ import annotations

import threading
import time

import bpy

from . import session_cache

#: object name -> the running operator's shared state
_running: dict[str, dict] = {}
#: the last background solve (scripts and tests): state "running" | "finished" | "cancelled" | "failed"
status: dict = {"state": "idle", "object": "", "work": "", "message": "", "thread": "", "seconds": 0.0}


def busy(obj) -> bool:
    """True while a worker thread solves `obj`'s session."""
    return getattr(obj, "name", None) in _running


def interactive() -> bool:
    """True in a Blender with windows (background work makes sense only there)."""
    return not bpy.app.background and bool(getattr(bpy.context.window_manager, "windows", None))


def start_later(obj_name: str) -> None:
    """Invoke the background solve for an object from a timer (safe from property update callbacks)."""

    def launch():
        obj = bpy.data.objects.get(obj_name)
        wm = bpy.context.window_manager
        if obj is None or busy(obj) or not wm.windows:
            return None
        win = wm.windows[0]
        area = next((a for a in win.screen.areas if a.type == "VIEW_3D"), win.screen.areas[0])
        with bpy.context.temp_override(window=win, area=area, screen=win.screen, object=obj, active_object=obj):
            bpy.ops.nfield.solve_background("INVOKE_DEFAULT", object_name=obj_name)
        return None

    bpy.app.timers.register(launch, first_interval=0.0)


class NFIELD_OT_solve_background(bpy.types.Operator):
    """Solve the field in a worker thread (factorization or basis first); Esc cancels"""

    bl_idname = "nfield.solve_background"
    bl_label = "Solve Field (Background)"
    bl_options = {"REGISTER", "UNDO"}

    object_name: bpy.props.StringProperty(name="Object", default="", description="Default: the active object")

    def execute(self, context):  # scripts: the plain, blocking solve
        return bpy.ops.nfield.solve()

    def invoke(self, context, event):
        from . import api

        obj = bpy.data.objects.get(self.object_name) if self.object_name else context.active_object
        if obj is None or obj.type != "MESH":
            self.report({"ERROR"}, "no mesh object to solve")
            return {"CANCELLED"}
        if busy(obj):
            self.report({"INFO"}, f"nfield: '{obj.name}' is already being solved in the background")
            return {"CANCELLED"}
        try:
            arrays, _ = api.sync(obj)
            entry = session_cache.get_entry(obj, arrays)
            session = session_cache.ensure_session(obj, entry)
            work = session.pending_work() or "solve"
        except (ValueError, RuntimeError, MemoryError) as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        shared = {"cancel": False, "outcome": None, "t0": time.perf_counter()}

        def progress(_fraction):
            return not shared["cancel"]

        def work_fn():
            session.progress = progress
            try:
                shared["outcome"] = ("ok", session.solve())
            except BaseException as exc:  # noqa: BLE001 - reported in the main thread
                shared["outcome"] = ("error", exc)
            finally:
                session.progress = None

        self._obj_name, self._entry, self._arrays, self._shared = obj.name, entry, arrays, shared
        _running[obj.name] = shared
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
        from . import api, attributes

        context.window_manager.event_timer_remove(self._timer)
        self._status(context, None)
        shared = _running.pop(self._obj_name, self._shared)
        seconds = time.perf_counter() - shared["t0"]
        outcome = shared["outcome"] or ("error", RuntimeError("the solver thread ended without a result"))
        obj = bpy.data.objects.get(self._obj_name)
        if outcome[0] == "error":
            cancelled = shared["cancel"] or type(outcome[1]).__name__ == "Cancelled"
            status.update(state="cancelled" if cancelled else "failed", message=str(outcome[1]), seconds=seconds)
            if obj is not None:
                obj.nfield.last_message = "Solve cancelled" if cancelled else f"Solve failed: {outcome[1]}"
            self.report({"WARNING"} if cancelled else {"ERROR"},
                        "nfield: solve cancelled" if cancelled else f"nfield: solve failed: {outcome[1]}")
            return {"CANCELLED"}
        if obj is None:
            status.update(state="failed", message="the object was deleted", seconds=seconds)
            return {"CANCELLED"}
        result = outcome[1]
        api._store_result(obj, self._entry, result)
        if obj.nfield.write_attributes:
            attributes.write(obj, self._arrays, result, obj.nfield.n)
        message = f"nfield: solved '{obj.name}' in {seconds:.1f} s ({status['work']})"
        status.update(state="finished", message=message, seconds=seconds)
        self.report({"INFO"}, message)
        if shared.get("again"):  # settings changed while the worker ran
            start_later(obj.name)
        return {"FINISHED"}


def defer(obj) -> None:
    """A live update arrived while `obj` is being solved: solve again when the worker is done."""
    shared = _running.get(obj.name)
    if shared is not None:
        shared["again"] = True


classes = (NFIELD_OT_solve_background,)
register, unregister = bpy.utils.register_classes_factory(classes)
