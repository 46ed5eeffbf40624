"""nfield operators (``bpy.ops.nfield.*``): thin wrappers around :mod:`nfield.blender.api`.

All operators act on the active object, take explicit arguments for scripting, report problems with
``self.report({'ERROR'}, ...)`` (a RuntimeError carrying the message when called from Python), and register
one undo step (``bl_options = {'REGISTER', 'UNDO'}``). Edit operators re-solve when the object's *Live
Update* setting is on. ``nfield.precompute_spectral`` runs the eigenbasis computation in a worker thread
(modal, progress in the status bar, Esc cancels) when invoked from the UI, and blocks when executed from a
script.
"""
from __future__ import annotations

import threading

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatVectorProperty, IntProperty, StringProperty

from . import api, session_cache, state
from .properties import CONSTRAINT_KIND_ITEMS


class _NFieldObjectOperator:
    """Mixin: poll for an active mesh object; run an api call with error reporting.

    Also used by the material and hatching operators, so every nfield operator reports problems alike."""

    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        if obj is None:
            cls.poll_message_set("No active object: select a mesh object")
            return False
        if obj.type != "MESH":
            cls.poll_message_set(f"Active object '{obj.name}' is not a mesh")
            return False
        return True

    def report_native_error(self) -> bool:
        """Report why the compiled solver cannot be loaded; True if it cannot (the operator must cancel)."""
        problem = state.native_error()
        if problem is not None:
            self.report({"ERROR"}, problem)
        return problem is not None

    #: snapshot the object's settings and design before running and put them back if the operator fails
    #: (a cancelled operator gets no undo step, so a half-done edit would otherwise stay)
    keeps_design_on_failure = False

    def run(self, context, fn, *, solve_after: bool = False):
        """fn(obj) -> message or None, then a re-solve if `solve_after` and Live Update is on.

        Every failure of the core or the compiled solver becomes an ERROR report and {'CANCELLED'}:
        ValueError (bad input, constraints, parameters: the message as is), RuntimeError (numerical failure,
        or Cancelled), MemoryError (std::bad_alloc in the solver)."""
        obj = context.active_object
        if self.report_native_error():
            return {"CANCELLED"}
        saved = None
        try:
            if self.keeps_design_on_failure:
                api.sync(obj)  # a mesh change remaps the design first: that remapping is kept
                saved = api.snapshot(obj)
            message = fn(obj)
            if solve_after and obj.nfield.live_update:
                api.solve(obj)
        except (ValueError, RuntimeError, MemoryError) as exc:
            if saved is not None:
                api.restore(obj, saved)
            self.report({"ERROR"}, failure_message(exc))
            return {"CANCELLED"}
        if message:
            self.report({"INFO"}, message)
        return {"FINISHED"}


def failure_message(exc: BaseException) -> str:
    """The report text for an exception from the core / the compiled solver."""
    if isinstance(exc, MemoryError):
        return (f"out of memory in the solver ({exc or 'MemoryError'}): the mesh or the number of constraints is "
                f"too large for this machine")
    if type(exc).__name__ == "Cancelled":
        return f"cancelled: {exc}"
    if isinstance(exc, ValueError):  # NFieldError and the core's ValueErrors: the message names the problem
        return str(exc)
    return f"numerical failure: {exc}"


def _active_item(items, active_index: int, what: str):
    """The item the panel's list highlights (the last one if the stored index ran past the end); for the
    remove operators called without an explicit face / vertex."""
    if not items:
        raise api.NFieldError(f"the object has no {what}")
    return items[min(active_index, len(items) - 1)]


class NFIELD_OT_solve(_NFieldObjectOperator, bpy.types.Operator):
    """Solve the n-direction field of the active object with its settings and constraints"""

    bl_idname = "nfield.solve"
    bl_label = "Solve Field"
    keeps_design_on_failure = True

    def execute(self, context):
        def fn(obj):
            result = api.solve(obj)
            stale = api.stale_items(obj)
            extra = f"; ignored stale: {', '.join(stale)}" if stale else ""
            return (f"nfield: solved {result.num_faces} faces in {result.seconds * 1000:.0f} ms, "
                    f"{len(result.singularities)} singularities{extra}")

        return self.run(context, fn)

    def invoke(self, context, event):
        """From the UI: a solve that must factor first runs in the background (nfield.solve_background)."""
        from . import background

        obj = context.active_object
        if background.interactive() and not self.report_native_error():
            try:
                arrays, _ = api.sync(obj)
                entry = session_cache.get_entry(obj, arrays)
                if session_cache.ensure_session(obj, entry).pending_work() == "factorization":
                    return bpy.ops.nfield.solve_background("INVOKE_DEFAULT", object_name=obj.name)
            except (ValueError, RuntimeError, MemoryError):
                pass  # execute() reports it
        return self.execute(context)


class NFIELD_OT_write_attributes(_NFieldObjectOperator, bpy.types.Operator):
    """Write the field to the output attributes (face direction, smoothed point direction, singularity index)"""

    bl_idname = "nfield.write_attributes"
    bl_label = "Write Attributes"
    keeps_design_on_failure = True

    def execute(self, context):
        return self.run(context, lambda obj: "nfield: wrote " + ", ".join(api.write_attributes(obj)))


class NFIELD_OT_constraint_add(_NFieldObjectOperator, bpy.types.Operator):
    """Constrain a face to a direction (object space, projected onto the face)"""

    bl_idname = "nfield.constraint_add"
    bl_label = "Add Constraint"
    keeps_design_on_failure = True

    face: IntProperty(name="Face", min=0, description="Polygon index")
    direction: FloatVectorProperty(name="Direction", size=3, default=(1.0, 0.0, 0.0), subtype="XYZ")
    kind: EnumProperty(name="Kind", items=CONSTRAINT_KIND_ITEMS, default="DIRECTION")

    def execute(self, context):
        return self.run(context, lambda obj: api.add_constraint(obj, self.face, self.direction, self.kind)
                        and None, solve_after=True)


class NFIELD_OT_constraint_remove(_NFieldObjectOperator, bpy.types.Operator):
    """Remove the constraint on a face (default: the active constraint in the list)"""

    bl_idname = "nfield.constraint_remove"
    bl_label = "Remove Constraint"
    keeps_design_on_failure = True

    face: IntProperty(name="Face", default=-1, min=-1, description="Polygon index (-1: the active constraint)")

    def execute(self, context):
        def fn(obj):
            face = self.face
            if face < 0:
                st = obj.nfield
                face = _active_item(st.constraints, st.active_constraint_index, "constraints").face
            api.remove_constraint(obj, face)

        return self.run(context, fn, solve_after=True)


class NFIELD_OT_constraint_clear(_NFieldObjectOperator, bpy.types.Operator):
    """Remove all constraints (or only the stale ones)"""

    bl_idname = "nfield.constraint_clear"
    bl_label = "Clear Constraints"
    keeps_design_on_failure = True

    stale_only: BoolProperty(name="Stale Only", default=False)

    def execute(self, context):
        return self.run(context, lambda obj: f"nfield: removed {api.clear_constraints(obj, self.stale_only)} "
                                             f"constraint(s)", solve_after=True)


class NFIELD_OT_singularity_add(_NFieldObjectOperator, bpy.types.Operator):
    """Prescribe a singularity of index numerator/n at an interior vertex"""

    bl_idname = "nfield.singularity_add"
    bl_label = "Add Singularity"
    keeps_design_on_failure = True

    vertex: IntProperty(name="Vertex", min=0)
    numerator: IntProperty(name="Index x n", default=1, description="Singularity index times n (e.g. 1 = +1/n)")

    def execute(self, context):
        # a failed live solve puts the previous singularities back (keeps_design_on_failure)
        return self.run(context, lambda obj: api.add_singularity(obj, self.vertex, self.numerator / obj.nfield.n)
                        and None, solve_after=True)


class NFIELD_OT_singularity_remove(_NFieldObjectOperator, bpy.types.Operator):
    """Remove the prescribed singularity at a vertex (default: the active one in the list)"""

    bl_idname = "nfield.singularity_remove"
    bl_label = "Remove Singularity"
    keeps_design_on_failure = True

    vertex: IntProperty(name="Vertex", default=-1, min=-1)

    def execute(self, context):
        def fn(obj):
            v = self.vertex
            if v < 0:
                st = obj.nfield
                v = _active_item(st.singularities, st.active_singularity_index, "prescribed singularities").vertex
            api.remove_singularity(obj, v)

        return self.run(context, fn, solve_after=True)


class NFIELD_OT_region_begin(_NFieldObjectOperator, bpy.types.Operator):
    """Start a region edit: later edits change only these faces (default: the selected faces)"""

    bl_idname = "nfield.region_begin"
    bl_label = "Begin Region"

    faces: StringProperty(
        name="Faces", default="", options={"SKIP_SAVE"},
        description="Face indices and ranges, e.g. \"0-39, 52\" (empty: the selected faces)")

    def execute(self, context):
        def fn(obj):
            return f"nfield: region of {api.begin_region(obj, parse_index_list(self.faces))} faces"

        return self.run(context, fn)


def parse_index_list(text: str) -> list[int] | None:
    """ "0-3, 7" -> [0, 1, 2, 3, 7]; "" -> None. Raises NFieldError naming the bad item."""
    if not text.strip():
        return None
    out: list[int] = []
    for part in text.replace(";", ",").split(","):
        part = part.strip()
        if not part:
            continue
        lo, sep, hi = part.partition("-")
        try:
            if sep:
                a, b = int(lo), int(hi)
                if b < a:
                    raise ValueError
                out.extend(range(a, b + 1))
            else:
                out.append(int(part))
        except ValueError:
            raise api.NFieldError(f"bad face list item {part!r} (expected indices and ranges like \"0-39, 52\")") from None
    return out


class NFIELD_OT_region_commit(_NFieldObjectOperator, bpy.types.Operator):
    """Keep the region's field as a layer and return to global editing"""

    bl_idname = "nfield.region_commit"
    bl_label = "Commit Region"

    def execute(self, context):
        return self.run(context, lambda obj: f"nfield: committed {api.commit_region(obj).name}")


class NFIELD_OT_region_cancel(_NFieldObjectOperator, bpy.types.Operator):
    """Discard the region edit (back to the field before it began)"""

    bl_idname = "nfield.region_cancel"
    bl_label = "Cancel Region"

    def execute(self, context):
        return self.run(context, api.cancel_region)


class NFIELD_OT_layer_release(_NFieldObjectOperator, bpy.types.Operator):
    """Release a committed layer: its faces follow the global solve again"""

    bl_idname = "nfield.layer_release"
    bl_label = "Release Layer"
    keeps_design_on_failure = True

    index: IntProperty(name="Layer", default=-1, min=-1, description="Layer index (-1: the active layer)")

    def execute(self, context):
        def fn(obj):
            i = self.index if self.index >= 0 else obj.nfield.active_layer_index
            api.release_layer(obj, i)

        return self.run(context, fn, solve_after=True)


#: State of the last background precompute (read by scripts and tests; the UI shows progress in the
#: status bar): state is "idle", "running", "cancelled", "failed" or "finished".
#: ui_updates counts the progress updates the UI made while the worker ran (the UI stayed responsive).
precompute_status: dict = {"state": "idle", "object": "", "k": 0, "fraction": 0.0, "message": "", "ui_updates": 0}


class NFIELD_OT_precompute_spectral(_NFieldObjectOperator, bpy.types.Operator):
    """Compute the spectral basis (k lowest eigenfields) in the background; Esc cancels"""

    bl_idname = "nfield.precompute_spectral"
    bl_label = "Precompute Spectral Basis"
    bl_options = {"REGISTER"}  # the basis lives in memory; the mode switch is a setting

    k: IntProperty(name="Eigenfields", default=0, min=0, description="0: the object's Eigenfields setting")

    _thread = None
    _timer = None

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
            arrays, _ = api.sync(obj)
            self._entry = session_cache.get_entry(obj, arrays)
            self._recipe = session_cache.session_recipe(obj, self._entry)
        except ValueError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        self._obj_name = obj.name
        self._arrays = arrays
        self._fraction = 0.0
        self._cancel = False
        self._outcome = None
        precompute_status.update(state="running", object=obj.name, k=int(obj.nfield.spectral_k), fraction=0.0,
                                 message="", ui_updates=0)
        self._thread = threading.Thread(target=self._work, daemon=True)
        self._thread.start()
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _progress(self, fraction):
        self._fraction = float(fraction)
        precompute_status["fraction"] = self._fraction
        return not self._cancel

    def _work(self):
        try:
            self._outcome = ("ok",) + session_cache.build_session(self._recipe, self._progress)
        except BaseException as exc:  # noqa: BLE001 - reported in the main thread
            self._outcome = ("error", exc)

    def modal(self, context, event):
        wm = context.window_manager
        if event.type == "ESC":
            self._cancel = True
        if event.type != "TIMER":
            if not self._thread.is_alive():
                return self._finish(context)
            # other events go on to Blender: the viewport stays usable during the computation
            return {"RUNNING_MODAL"} if event.type == "ESC" else {"PASS_THROUGH"}
        wm.progress_update(int(100 * self._fraction))
        if self._thread.is_alive():
            precompute_status["ui_updates"] += 1
        if context.workspace is not None:
            state = "cancelling" if self._cancel else f"{100 * self._fraction:.0f}%"
            context.workspace.status_text_set(f"nfield: computing spectral basis ({state}), Esc to cancel")
        if self._thread.is_alive():
            return {"RUNNING_MODAL"}
        return self._finish(context)

    def _finish(self, context):
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        outcome = self._outcome or ("error", RuntimeError("worker ended without a result"))
        obj = bpy.data.objects.get(self._obj_name)
        if self._cancel or outcome[0] == "error":
            if obj is not None:
                api.configure(obj, mode=self._previous[0], k=self._previous[1])
            if self._cancel:
                precompute_status.update(state="cancelled", message="cancelled")
                self.report({"WARNING"}, "nfield: spectral basis computation cancelled")
            else:
                precompute_status.update(state="failed", message=str(outcome[1]))
                self.report({"ERROR"}, f"nfield: spectral basis failed: {outcome[1]}")
            return {"CANCELLED"}
        if obj is None:
            precompute_status.update(state="failed", message="the object was deleted")
            return {"CANCELLED"}
        _, session, result = outcome
        session_cache.install_session(obj, self._entry, self._recipe, session)
        api._store_result(obj, self._entry, result)
        if obj.nfield.write_attributes:
            from . import attributes

            attributes.write(obj, self._arrays, result, obj.nfield.n)
        info = session.basis_info
        message = (f"nfield: spectral basis ready ({info.k} eigenfields, {info.source}, "
                   f"{info.seconds:.1f} s, {info.memory_bytes / 2**20:.0f} MB)")
        precompute_status.update(state="finished", fraction=1.0, message=message)
        self.report({"INFO"}, message)
        return {"FINISHED"}


classes = (
    NFIELD_OT_solve,
    NFIELD_OT_write_attributes,
    NFIELD_OT_constraint_add,
    NFIELD_OT_constraint_remove,
    NFIELD_OT_constraint_clear,
    NFIELD_OT_singularity_add,
    NFIELD_OT_singularity_remove,
    NFIELD_OT_region_begin,
    NFIELD_OT_region_commit,
    NFIELD_OT_region_cancel,
    NFIELD_OT_layer_release,
    NFIELD_OT_precompute_spectral,
)

register, unregister = bpy.utils.register_classes_factory(classes)
