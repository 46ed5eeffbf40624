"""nfield operators (``bpy.ops.nfield.*``): thin wrappers around :mod:`nfield.blender.api`.

All operators act on the active object, take explicit arguments for scripting, report problems with
``self.report({'ERROR'}, ...)`` (a RuntimeError carrying the message when called from Python), and register
one undo step (``bl_options = {'REGISTER', 'UNDO'}``). Edit operators re-solve when the object's *Live
Update* setting is on. The two operators that run solver work in a worker thread (``solve_background``,
``precompute_spectral``) are in ``background``; the material, hatching and viewport-tool operators are in
their own modules.
"""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatVectorProperty, IntProperty, StringProperty

from . import api, jobs
from .choices import CONSTRAINT_KIND_ITEMS
from .operator_base import NFieldObjectOperator


def _active_item(items, active_index: int, what: str):
    """The item the panel's list highlights (the last one if the stored index ran past the end); for the
    remove operators called without an explicit face / vertex."""
    if not items:
        raise api.NFieldError(f"the object has no {what}")
    return items[min(active_index, len(items) - 1)]


def _remove_given_or_active(op, context, value: int, items: str, active: str, key: str, what: str, remove):
    """Run `remove(obj, value)`, or with the `key` (face / vertex) of the list's active item when `value` is
    negative, re-solving after it (the remove operators)."""
    def fn(obj):
        v = value
        if v < 0:
            st = obj.nfield
            v = getattr(_active_item(getattr(st, items), getattr(st, active), what), key)
        remove(obj, v)

    return op.run(context, fn, solve_after=True)


class NFIELD_OT_solve(NFieldObjectOperator, bpy.types.Operator):
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
        obj = context.active_object
        if jobs.interactive() and not self.report_native_error():
            try:
                if api.pending_work(obj) == "factorization":
                    return bpy.ops.nfield.solve_background("INVOKE_DEFAULT", object_name=obj.name)
            except (ValueError, RuntimeError, MemoryError):
                pass  # execute() reports it
        return self.execute(context)


class NFIELD_OT_write_attributes(NFieldObjectOperator, bpy.types.Operator):
    """Write the field to the output attributes (face direction, smoothed point direction, singularity index)"""

    bl_idname = "nfield.write_attributes"
    bl_label = "Write Attributes"
    keeps_design_on_failure = True

    def execute(self, context):
        return self.run(context, lambda obj: "nfield: wrote " + ", ".join(api.write_attributes(obj)))


class NFIELD_OT_constraint_add(NFieldObjectOperator, bpy.types.Operator):
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


class NFIELD_OT_constraint_remove(NFieldObjectOperator, bpy.types.Operator):
    """Remove the constraint on a face (default: the active constraint in the list)"""

    bl_idname = "nfield.constraint_remove"
    bl_label = "Remove Constraint"
    keeps_design_on_failure = True

    face: IntProperty(name="Face", default=-1, min=-1, description="Polygon index (-1: the active constraint)")

    def execute(self, context):
        return _remove_given_or_active(self, context, self.face, "constraints", "active_constraint_index", "face",
                                       "constraints", api.remove_constraint)


class NFIELD_OT_constraint_clear(NFieldObjectOperator, bpy.types.Operator):
    """Remove all constraints (or only the stale ones)"""

    bl_idname = "nfield.constraint_clear"
    bl_label = "Clear Constraints"
    keeps_design_on_failure = True

    stale_only: BoolProperty(name="Stale Only", default=False)

    def invoke(self, context, event):
        if self.stale_only:  # removing what no longer applies needs no confirmation
            return self.execute(context)
        return context.window_manager.invoke_confirm(self, event)

    def execute(self, context):
        return self.run(context, lambda obj: f"nfield: removed {api.clear_constraints(obj, self.stale_only)} "
                                             f"constraint(s)", solve_after=True)


class NFIELD_OT_singularity_add(NFieldObjectOperator, bpy.types.Operator):
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


class NFIELD_OT_singularity_remove(NFieldObjectOperator, bpy.types.Operator):
    """Remove the prescribed singularity at a vertex (default: the active one in the list)"""

    bl_idname = "nfield.singularity_remove"
    bl_label = "Remove Singularity"
    keeps_design_on_failure = True

    vertex: IntProperty(name="Vertex", default=-1, min=-1)

    def execute(self, context):
        return _remove_given_or_active(self, context, self.vertex, "singularities", "active_singularity_index",
                                       "vertex", "prescribed singularities", api.remove_singularity)


class NFIELD_OT_region_begin(NFieldObjectOperator, bpy.types.Operator):
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


class NFIELD_OT_region_commit(NFieldObjectOperator, bpy.types.Operator):
    """Keep the region's field as a layer and return to global editing"""

    bl_idname = "nfield.region_commit"
    bl_label = "Commit Region"

    def execute(self, context):
        return self.run(context, lambda obj: f"nfield: committed {api.commit_region(obj).name}")


class NFIELD_OT_region_cancel(NFieldObjectOperator, bpy.types.Operator):
    """Discard the region edit (back to the field before it began)"""

    bl_idname = "nfield.region_cancel"
    bl_label = "Cancel Region"

    def execute(self, context):
        return self.run(context, api.cancel_region)


class NFIELD_OT_layer_release(NFieldObjectOperator, bpy.types.Operator):
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
)

register, unregister = bpy.utils.register_classes_factory(classes)
