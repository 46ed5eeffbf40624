"""The singularity tool: pin singularities of a chosen index at vertices (3D view, object mode).

* ``nfield.singularity_tool`` (modal): press near a vertex, pick the index with the mouse wheel, +/-, or the
  number keys (a number key sets |numerator|, minus flips the sign); the indices offered are the ones the
  solver accepts at that vertex (``DesignSession.index_range``: |index - K/2pi| < k/(2n) for a ring of k faces
  and angle defect K), and a refused one is explained in the header; click/Enter confirms, Esc/right-click
  restores. Clicking a pinned singularity edits it, X / Delete removes it.
* ``nfield.singularity_delete``: remove the pinned singularity nearest to the cursor.

Every write of the stored singularity goes through ``design``; the previews solve the session directly and
are recorded with ``api.store_result``.
"""
from __future__ import annotations

import bpy
from bpy.props import IntProperty
from bpy.types import Operator
from mathutils import Vector

from . import api, design, mesh_read
from .tool_common import (
    ModalViewportTool,
    clear_status,
    pinned_singularity_under_cursor,
    poll_object,
    ray_cast,
    remove_design_item,
    set_status,
)


class NFIELD_OT_singularity_tool(ModalViewportTool, Operator):
    """Click near a vertex and pick a singularity index (wheel / +- / number keys)"""

    bl_idname = "nfield.singularity_tool"
    bl_label = "Pin Field Singularity"

    def invoke(self, context, event):
        obj = context.active_object
        mouse = (event.mouse_region_x, event.mouse_region_y)
        vertex = self._pick_vertex(context, obj, mouse)
        if vertex is None:
            return {"CANCELLED"}  # off the mesh: nothing (no fall-through to select / move)
        if not self._open_session(obj):
            return {"CANCELLED"}
        self._obj_name = obj.name
        self._vertex = vertex
        item = design.singularity_item(obj, vertex)
        self._before = None if item is None else design.singularity_numerator(item, obj.nfield.n)
        self._before_result = self._entry.result
        self._numerator = self._before if self._before is not None else 1
        self._changed = False
        self._valid, self._explain = self._valid_numerators(obj.nfield.n)
        if self._numerator not in self._valid and self._valid:
            self._numerator = min(self._valid, key=lambda k: (abs(k - 1), -k))
        context.window_manager.modal_handler_add(self)
        self._preview(context, obj, self._numerator)
        return {"RUNNING_MODAL"}

    def _pick_vertex(self, context, obj, mouse):
        arrays = mesh_read.mesh_arrays(obj)
        pinned = pinned_singularity_under_cursor(context, obj, mouse, arrays)
        if pinned is not None:
            return pinned
        hit = ray_cast(context, obj, mouse, arrays)
        if hit is None:
            return None
        loc, _, face = hit
        verts = mesh_read.polygon_vertices(arrays, face)
        return int(min(verts, key=lambda v: (Vector(tuple(arrays.vertices[v])) - loc).length))

    def _valid_numerators(self, n: int) -> tuple[list[int], str]:
        """(the numerators k != 0 the solver accepts at this vertex, why others are refused), from the
        session's own rule (DesignSession.index_range)."""
        try:
            lo, hi = self._session.index_range(self._vertex)
        except ValueError as exc:  # a boundary / non-manifold vertex has no index
            return [], str(exc)
        lo_k, hi_k = round(lo * n), round(hi * n)
        return ([k for k in range(lo_k, hi_k + 1) if k != 0],
                f"vertex {self._vertex} can carry the indices {lo_k}/{n} .. {hi_k}/{n} only")

    def _header(self, context, obj, extra=""):
        n = obj.nfield.n
        rng = ""
        if self._valid:
            rng = f" | valid at this vertex: {min(self._valid)}/{n} .. {max(self._valid)}/{n}"
        else:
            rng = " | this vertex cannot carry a singularity"
        set_status(context, f"Singularity at vertex {self._vertex}: index {self._numerator}/{n}{rng}"
                             f"{(' | ' + extra) if extra else ''} | Wheel/+-/1-9: index, Minus: sign, "
                             f"LMB/Enter: confirm, Esc/RMB: cancel")

    def _preview(self, context, obj, k):
        """Pin index k/n at the vertex and solve; returns False (state unchanged) if the solver refuses."""
        n = obj.nfield.n
        if k == 0 or k not in self._valid:
            why = "index 0 is no singularity" if k == 0 else self._explain
            self._header(context, obj, f"{k}/{n} refused: {why}")
            return False
        try:
            self._session.set_singularity(self._vertex, k / n)
            result = self._session.solve()
        except (ValueError, RuntimeError, MemoryError) as exc:
            self._header(context, obj, f"{k}/{n} refused: {exc}")
            # put the session back to the last accepted numerator
            try:
                if self._changed or self._before is not None:
                    self._session.set_singularity(self._vertex, self._numerator / n)
                else:
                    self._session.remove_singularity(self._vertex)
            except ValueError:
                pass
            return False
        design.set_singularity(obj, self._vertex, k, self._entry.arrays.vertices[self._vertex])
        self._numerator = k
        self._changed = True
        self._store(obj, result)
        self._header(context, obj)
        return True

    def _step(self, k, delta):
        """Next numerator from k by delta, skipping 0 and (when known) invalid values."""
        nxt = k + delta
        if nxt == 0:
            nxt += delta
        if self._valid:
            cand = [x for x in self._valid if (x - k) * delta > 0]
            if cand:
                nxt = min(cand, key=lambda x: abs(x - k))
        return nxt

    def modal(self, context, event):
        obj = bpy.data.objects.get(self._obj_name)
        if obj is None:
            return self._finish(context, True)
        if event.value == "PRESS":
            t = event.type
            if t in {"WHEELUPMOUSE", "NUMPAD_PLUS", "EQUAL", "UP_ARROW"}:
                self._preview(context, obj, self._step(self._numerator, +1))
            elif t in {"WHEELDOWNMOUSE", "NUMPAD_MINUS", "DOWN_ARROW"}:
                self._preview(context, obj, self._step(self._numerator, -1))
            elif t == "MINUS":
                self._preview(context, obj, -self._numerator)
            elif t in _NUMBER_KEYS:
                k = _NUMBER_KEYS[t]
                self._preview(context, obj, k if self._numerator > 0 else -k)
            elif t in {"LEFTMOUSE", "RET", "NUMPAD_ENTER", "SPACE"}:
                if not self._changed:
                    self._restore(obj)
                    return self._finish(context, True)
                self._write_attributes(obj)
                return self._finish(context, False)
            elif t in {"ESC", "RIGHTMOUSE"}:
                self._restore(obj)
                return self._finish(context, True)
            elif t in {"X", "DEL"}:
                self._before_remove(obj)
                return self._finish(context, False)
            return {"RUNNING_MODAL"}
        if event.type in {"MOUSEMOVE", "INBETWEEN_MOUSEMOVE", "TIMER"}:
            return {"RUNNING_MODAL"}
        return {"RUNNING_MODAL"}

    def _before_remove(self, obj):
        """X/Del while choosing: remove the singularity pinned at this vertex."""
        if design.singularity_item(obj, self._vertex) is not None:
            design.remove_singularity(obj, self._vertex)
        try:
            self._session.remove_singularity(self._vertex)
        except ValueError:
            pass
        try:
            self._store(obj, self._session.solve())
            if obj.nfield.write_attributes:
                api.write_attributes(obj, self._entry.result)
        except (ValueError, RuntimeError, MemoryError) as exc:
            self.report({"WARNING"}, str(exc))

    def _restore(self, obj):
        n = obj.nfield.n
        try:
            if self._before is None:
                if design.singularity_item(obj, self._vertex) is not None:
                    design.remove_singularity(obj, self._vertex)
                self._session.remove_singularity(self._vertex)
            else:
                design.set_singularity(obj, self._vertex, self._before, self._entry.arrays.vertices[self._vertex])
                self._session.set_singularity(self._vertex, self._before / n)
        except ValueError:
            pass
        if self._changed:
            try:
                self._store(obj, self._session.solve())
            except (ValueError, RuntimeError, MemoryError):
                if self._before_result is not None:
                    self._store(obj, self._before_result)

    def _finish(self, context, cancelled):
        clear_status(context)
        return {"CANCELLED"} if cancelled else {"FINISHED"}


_NUMBER_KEYS = {name: i for i, name in enumerate(
    ("ZERO", "ONE", "TWO", "THREE", "FOUR", "FIVE", "SIX", "SEVEN", "EIGHT", "NINE")) if i}
_NUMBER_KEYS.update({f"NUMPAD_{i}": i for i in range(1, 10)})


class NFIELD_OT_singularity_delete(Operator):
    """Remove the pinned singularity nearest to the cursor"""

    bl_idname = "nfield.singularity_delete"
    bl_label = "Remove Field Singularity"
    bl_options = {"REGISTER", "UNDO"}

    vertex: IntProperty(name="Vertex", default=-1, min=-1,
                        description="Vertex whose pinned singularity to remove (-1: the one under the cursor)")

    @classmethod
    def poll(cls, context):
        return poll_object(context) and len(context.active_object.nfield.singularities) > 0

    def invoke(self, context, event):
        obj = context.active_object
        vertex = pinned_singularity_under_cursor(context, obj, (event.mouse_region_x, event.mouse_region_y),
                                                 mesh_read.mesh_arrays(obj))
        if vertex is None:
            self.report({"INFO"}, "No pinned singularity under the cursor")
            return {"CANCELLED"}
        self.vertex = vertex
        return self.execute(context)

    def execute(self, context):
        return remove_design_item(self, context, api.remove_singularity, self.vertex,
                                  f"Removed the singularity at vertex {self.vertex}")


classes = (NFIELD_OT_singularity_tool, NFIELD_OT_singularity_delete)
