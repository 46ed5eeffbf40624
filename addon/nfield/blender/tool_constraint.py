"""The constraint tool: aim direction constraints by dragging on the mesh (3D view, object mode).

* ``nfield.constraint_tool`` (modal): press on a face and drag to aim its direction constraint in the face's
  tangent plane; the field follows live during the drag (the session's re-aim path: no new factorization).
  Pressing on a constrained face, or within ``PICK_PIXELS`` of any point of a constraint arrow (shaft or
  head, as drawn), re-aims that constraint. A press off the mesh does nothing.
  A click without a drag pins the current field direction of the face. Release: one undo step.
  Esc / right-click: restore the state before the drag.
* ``nfield.constraint_delete``: delete the constraint under the cursor (X / Delete in the tool).

The dragged direction is (drag point - press point) in object space, projected onto the face's object-space
tangent plane (see ``tool_common`` for the picking geometry). Every write of the stored constraint goes
through ``design``; the live solves edit the session directly and are recorded with ``api.store_result``.
"""
from __future__ import annotations

import time

import bpy
import numpy as np
from bpy.props import IntProperty
from bpy.types import Operator
from mathutils import Vector

from . import api, design, mesh_read
from .operator_base import failure_message
from .tool_common import (
    DRAG_PIXELS,
    ModalViewportTool,
    clear_status,
    constraint_under_cursor,
    last_press,
    poll_object,
    ray_cast,
    ray_plane,
    remove_design_item,
    set_status,
)


def _face_direction(entry, face):
    """The field's current first direction on `face` (object space), None without a field there."""
    res = entry.result
    if res is None:
        return None
    d = np.asarray(res.directions[face], dtype=np.float64)
    return None if not np.any(d) else Vector(d.tolist())


class NFIELD_OT_constraint_tool(ModalViewportTool, Operator):
    """Click a face and drag to aim its direction constraint (the field follows live)"""

    bl_idname = "nfield.constraint_tool"
    bl_label = "Aim Field Constraint"

    def invoke(self, context, event):
        obj = context.active_object
        mouse = (event.mouse_region_x, event.mouse_region_y)
        arrays = mesh_read.mesh_arrays(obj)
        hit = ray_cast(context, obj, mouse, arrays)
        face = constraint_under_cursor(context, obj, mouse, hit, arrays)
        if face is None and hit is not None:
            face = hit[2]  # an unconstrained face: a new constraint
        last_press.clear()
        last_press.update(tool="constraint", mouse=list(mouse), object=obj.name, face=face,
                          hit_face=None if hit is None else hit[2])
        if face is None:
            # off the mesh: nothing, and the press must not fall through to select / move while this tool
            # is active (a cancelled keymap operator ends the event's handling)
            return {"CANCELLED"}
        if not self._open_session(obj):
            return {"CANCELLED"}
        self._obj_name = obj.name
        self._face = face
        self._normal = Vector(tuple(arrays.polygon_normals[face]))
        self._anchor = Vector(tuple(arrays.polygon_centers[face])) if hit is None or hit[2] != face else hit[0].copy()
        self._press = Vector(mouse)
        self._dragged = False
        item = design.constraint_item(obj, face)
        self._before = None if item is None else (item.kind, tuple(item.direction))
        self._accepted = self._before  # the last (kind, direction) the solver accepted in this drag
        self._before_result = self._entry.result
        self._target = None
        self._solved_target = None
        self._timer = context.window_manager.event_timer_add(1.0 / 60.0, window=context.window)
        context.window_manager.modal_handler_add(self)
        set_status(context, f"Aim constraint on face {face}: drag to aim, release to confirm, "
                             f"Esc/RMB to cancel")
        return {"RUNNING_MODAL"}

    # -- live aim
    def _aim(self, context, obj, mouse):
        p = ray_plane(context, obj, mouse, self._anchor, self._normal)
        if p is None:
            return
        d = p - self._anchor
        d -= self._normal * d.dot(self._normal) / max(self._normal.length_squared, 1e-30)
        if d.length <= 1e-12:
            return
        self._target = d.normalized()

    def _apply(self, context, obj, direction, kind="DIRECTION"):
        """Re-solve through the session's re-aim path with `direction`; store it in the design only if the
        solve succeeds (otherwise the session goes back to the last accepted direction; returns False)."""
        face = self._face
        t0 = time.perf_counter()
        try:
            if kind == "VECTOR":
                self._session.set_vector(face, tuple(direction))
            else:
                self._session.set_direction(face, tuple(direction))
            result = self._session.solve()
        except (ValueError, RuntimeError, MemoryError) as exc:
            self._session_back_to(self._accepted)
            self.report({"WARNING"}, failure_message(exc))
            return False
        design.set_constraint(obj, face, direction, kind, self._entry.arrays.polygon_centers[face])
        self._accepted = (kind, tuple(direction))
        self._store(obj, result)
        ms = (time.perf_counter() - t0) * 1e3
        d = tuple(round(x, 3) for x in direction)
        set_status(context, f"Face {face}: direction {d} (object space), live solve {ms:.0f} ms | "
                             f"release to confirm, Esc/RMB to cancel")
        return True

    def modal(self, context, event):
        obj = bpy.data.objects.get(self._obj_name)
        if obj is None:
            return self._finish(context, cancelled=True)
        if event.type == "MOUSEMOVE":
            mouse = Vector((event.mouse_region_x, event.mouse_region_y))
            if self._dragged or (mouse - self._press).length >= DRAG_PIXELS:
                self._dragged = True
                self._aim(context, obj, mouse)
            return {"RUNNING_MODAL"}
        if event.type == "TIMER":
            # coalesced: one solve per timer tick for the latest mouse position
            if self._target is not None and self._target != self._solved_target:
                self._solved_target = self._target.copy()
                self._apply(context, obj, self._target)
            return {"RUNNING_MODAL"}
        if event.type == "LEFTMOUSE" and event.value == "RELEASE":
            if self._target is not None and self._target != self._solved_target:
                self._apply(context, obj, self._target)
            elif not self._dragged and self._before is None:
                d = _face_direction(self._entry, self._face)  # click: pin the current direction
                if d is None or not self._apply(context, obj, d):
                    return self._finish(context, cancelled=True)
            elif self._target is None:
                return self._finish(context, cancelled=True)  # nothing changed: no undo step
            self._write_attributes(obj)
            return self._finish(context, cancelled=False)
        if event.type in {"ESC", "RIGHTMOUSE"} and event.value == "PRESS":
            self._restore(obj)
            return self._finish(context, cancelled=True)
        return {"RUNNING_MODAL"}

    def _session_back_to(self, state):
        """Put the session's constraint on this face back to `state` ((kind, direction) or None)."""
        face = self._face
        try:
            if state is None:
                if any(getattr(c, "face", None) == face for c in self._session.constraints):
                    self._session.remove(face)
            else:
                kind, d = state
                (self._session.set_vector if kind == "VECTOR" else self._session.set_direction)(face, d)
        except ValueError:
            pass

    def _restore(self, obj):
        face = self._face
        if self._before is None:
            if design.constraint_item(obj, face) is not None:
                design.remove_constraint(obj, face)
            try:
                if any(getattr(c, "face", None) == face for c in self._session.constraints):
                    self._session.remove(face)
            except ValueError:
                pass
        else:
            kind, d = self._before
            design.set_constraint(obj, face, d, kind, self._entry.arrays.polygon_centers[face])
            try:
                (self._session.set_vector if kind == "VECTOR" else self._session.set_direction)(face, d)
            except ValueError:
                pass
        if self._solved_target is None:
            return  # the field never changed
        try:
            result = self._session.solve()
        except (ValueError, RuntimeError, MemoryError):
            result = self._before_result
        if result is not None:
            self._store(obj, result)

    def _finish(self, context, cancelled):
        context.window_manager.event_timer_remove(self._timer)
        clear_status(context)
        obj = bpy.data.objects.get(self._obj_name)
        if obj is not None:
            api.notify_overlay(obj)
        return {"CANCELLED"} if cancelled else {"FINISHED"}


class NFIELD_OT_constraint_delete(Operator):
    """Delete the direction constraint under the cursor"""

    bl_idname = "nfield.constraint_delete"
    bl_label = "Delete Field Constraint"
    bl_options = {"REGISTER", "UNDO"}

    face: IntProperty(name="Face", default=-1, min=-1,
                      description="Polygon whose constraint to delete (-1: the one under the cursor)")

    @classmethod
    def poll(cls, context):
        return poll_object(context) and len(context.active_object.nfield.constraints) > 0

    def invoke(self, context, event):
        obj = context.active_object
        mouse = (event.mouse_region_x, event.mouse_region_y)
        arrays = mesh_read.mesh_arrays(obj)
        face = constraint_under_cursor(context, obj, mouse, ray_cast(context, obj, mouse, arrays), arrays)
        if face is None:
            self.report({"INFO"}, "No constraint under the cursor")
            return {"CANCELLED"}
        self.face = face
        return self.execute(context)

    def execute(self, context):
        return remove_design_item(self, context, api.remove_constraint, self.face,
                                   f"Removed the constraint on face {self.face}")


classes = (NFIELD_OT_constraint_tool, NFIELD_OT_constraint_delete)
