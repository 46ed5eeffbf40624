"""The operator "Quad Remesh from Field" (``nfield.quad_remesh``): a new quad mesh object beside the active
one, whose edges follow the object's designed field (nfield.core.quad_remesh, docs/quad_remeshing.md).

The source object is left as it is. Invoked from the UI, the remesher runs in a worker thread (the native
call releases the GIL): progress in the status bar and the window's progress indicator, Esc cancels (the
remesher stops at its next checkpoint and nothing is created). A design changed since its last solve is
solved first in the same worker (Solve First), which owns the object's session meanwhile (jobs.claim: live
updates wait for it); the field it solves is kept even when the remesh is cancelled or fails. Executed from a script it blocks. The new
object is one undo step; its quality figures are reported and stored on it (custom property
``nfield_remesh``: quad fraction, irregular vertices against the field's singularities, alignment,
Hausdorff distance...).
"""
from __future__ import annotations

import time

import bpy

from . import api, jobs
from .operator_base import NFieldObjectOperator, failure_message
from .remesh_properties import OPTION_NAMES, api_options, option_properties

#: the last remesh (scripts and tests): state "idle" | "running" | "cancelled" | "failed" | "finished";
#: ``result`` the new object's name, ``stats`` its quality figures, ``ui_updates`` the progress updates the UI
#: made while the worker ran
remesh_status: dict = {"state": "idle", "object": "", "result": "", "fraction": 0.0, "message": "",
                       "stats": {}, "ui_updates": 0, "seconds": 0.0}


def summary(stats: dict) -> str:
    """One line of the result's quality figures."""
    parts = [f"{stats.get('num_faces', 0)} faces, {100 * stats.get('quad_fraction', 0):.1f}% quads"]
    if "irregular_vertices" in stats:
        text = f"{stats['irregular_vertices']} irregular vertices"
        if "field_singularities" in stats:
            text += f" ({stats['field_singularities']} field singularities)"
        parts.append(text)
    if "alignment_mean_deg" in stats:
        parts.append(f"alignment {stats['alignment_mean_deg']:.1f} deg mean, {stats['alignment_p95_deg']:.1f} deg p95")
    if "hausdorff_relative" in stats:
        parts.append(f"Hausdorff {100 * stats['hausdorff_relative']:.2f}% of the diagonal")
    if not stats.get("manifold", True) or not stats.get("oriented", True):
        parts.append("WARNING: the output is not manifold and consistently oriented")
    if stats.get("inverted_faces", 0):
        parts.append(f"{stats['inverted_faces']} faces with a folded corner")
    return ", ".join(parts)


class NFIELD_OT_quad_remesh(NFieldObjectOperator, bpy.types.Operator):
    """Create a quad mesh beside the active object whose edges follow its designed field (the object is left as it is); Esc cancels"""

    bl_idname = "nfield.quad_remesh"
    bl_label = "Quad Remesh from Field"
    bl_options = {"REGISTER", "UNDO"}

    __annotations__ = option_properties()

    _worker = None

    def _finished(self, obj, new_obj, stats, seconds) -> set:
        message = f"nfield: '{new_obj.name}' from '{obj.name}' in {seconds:.1f} s: {summary(stats)}"
        for line in stats.get("messages", []):
            if not line.startswith("mesh: "):
                self.report({"WARNING"}, f"nfield remesh: {line}")
        remesh_status.update(state="finished", result=new_obj.name, fraction=1.0, message=message,
                             stats=dict(stats), seconds=seconds)
        self.report({"INFO"}, message)
        return {"FINISHED"}

    def execute(self, context):  # scripts, redo panel: blocking
        obj = context.active_object
        if self.report_native_error():
            return {"CANCELLED"}
        remesh_status.update(state="running", object=obj.name, result="", fraction=0.0, message="", stats={},
                             ui_updates=0, seconds=0.0)
        t0 = time.perf_counter()
        try:
            new_obj, stats = api.quad_remesh(obj, **api_options(self))
        except (ValueError, RuntimeError, MemoryError) as exc:
            remesh_status.update(state="failed", message=failure_message(exc))
            self.report({"ERROR"}, failure_message(exc))
            return {"CANCELLED"}
        return self._finished(obj, new_obj, stats, time.perf_counter() - t0)

    def invoke(self, context, event):
        obj = context.active_object
        settings = obj.nfield_remesh
        for name in OPTION_NAMES:  # the panel's settings, unless the caller set an option
            if not self.properties.is_property_set(name):
                setattr(self, name, getattr(settings, name))
        if self.report_native_error():
            return {"CANCELLED"}
        try:
            self._recipe = api.remesh_recipe(obj, **api_options(self))
        except (ValueError, RuntimeError, MemoryError) as exc:
            self.report({"ERROR"}, failure_message(exc))
            return {"CANCELLED"}
        self._obj_name = obj.name
        remesh_status.update(state="running", object=obj.name, result="", fraction=0.0, message="", stats={},
                             ui_updates=0, seconds=0.0)
        recipe = self._recipe
        self._t0 = time.perf_counter()
        self._worker = jobs.Worker(lambda progress: api.remesh_from_recipe(recipe, progress), remesh_status,
                                   "nfield-remesh")
        self._claim = None
        if recipe.get("solve") is not None:  # the worker solves the object's session first
            self._claim = {"cancel": False, "outcome": None, "t0": self._t0}
            jobs.claim(obj.name, self._claim)
        self._worker.start(self, context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if self._worker.step(context, event, f"quad remeshing '{self._obj_name}'"):
            return self._finish(context)
        return self._worker.passed_on(event)

    def _finish(self, context):
        self._worker.stop(context)
        seconds = time.perf_counter() - self._t0
        outcome = self._worker.outcome or ("error", RuntimeError("the remesh thread ended without a result"))
        if self._claim is not None:
            shared = jobs.release(self._obj_name, self._claim)
            obj = bpy.data.objects.get(self._obj_name)
            if obj is not None:
                api.adopt_recipe_solve(obj, self._recipe)
                if shared.get("again"):  # the design changed again while the worker ran
                    jobs.start_later(obj.name)
        if outcome[0] == "error":
            cancelled = self._worker.cancel or type(outcome[1]).__name__ == "Cancelled"
            remesh_status.update(state="cancelled" if cancelled else "failed", message=str(outcome[1]),
                                 seconds=seconds)
            if cancelled:
                self.report({"WARNING"}, "nfield: quad remesh cancelled (nothing was created)")
            else:
                self.report({"ERROR"}, f"nfield: quad remesh failed: {failure_message(outcome[1])}")
            return {"CANCELLED"}
        obj = bpy.data.objects.get(self._obj_name)
        if obj is None:
            remesh_status.update(state="failed", message="the source object was deleted", seconds=seconds)
            self.report({"ERROR"}, "nfield: the source object was deleted while it was being remeshed")
            return {"CANCELLED"}
        try:
            new_obj = api.adopt_remesh(obj, self._recipe, outcome[1])
        except ValueError as exc:
            remesh_status.update(state="failed", message=str(exc), seconds=seconds)
            self.report({"ERROR"}, failure_message(exc))
            return {"CANCELLED"}
        return self._finished(obj, new_obj, outcome[1].stats, seconds)


classes = (NFIELD_OT_quad_remesh,)
register, unregister = bpy.utils.register_classes_factory(classes)
