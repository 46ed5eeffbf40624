"""The constraint tool: aim direction constraints by dragging on the mesh (3D view, object mode).

* ``nfield.constraint_tool`` (modal): press on a face and drag to aim its direction constraint in the face's
  tangent plane; the field follows live during the drag (the session's re-aim path: no new factorization).
  Pressing on a constrained face, or within ``PICK_PIXELS`` of any point of a constraint arrow (shaft or
  head, as drawn), re-aims that constraint. A press off the mesh does nothing.
  A click without a drag pins the current field direction of the face. Release: one undo step.
  Esc / right-click: restore the state before the drag. With mirror symmetry on, the constraint's mirror
  image is placed on the partner face as well, in the same step (a face without a partner: the header says
  so).
* ``nfield.constraint_delete``: delete the constraint under the cursor (X / Delete in the tool).

The dragged direction is (drag point - press point) in object space, projected onto the face's object-space
tangent plane (see ``tool_common`` for the picking geometry). Every write of the stored constraint goes
through ``design``; the live solves edit the session directly and are recorded with ``api.store_result``.
"""
from __future__ import annotations

import time

import numpy as np
from bpy.types import Operator
from mathutils import Vector

from ..core import DirectionConstraint, VectorConstraint
from . import api, design, mesh_read
from .operator_base import failure_message
from .tool_common import (
    ModalViewportTool,
    constraint_under_cursor,
    delete_operator,
    last_press,
    ray_cast,
    ray_plane,
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
    tick_seconds = 1.0 / 60.0  # live solves: one per tick for the latest mouse position

    def begin(self, context, obj, mouse) -> bool:
        arrays = mesh_read.mesh_arrays(obj)
        hit = ray_cast(context, obj, mouse, arrays)
        face = constraint_under_cursor(context, obj, mouse, hit, arrays)
        if face is None and hit is not None:
            face = hit[2]  # an unconstrained face: a new constraint
        last_press.clear()
        last_press.update(tool="constraint", mouse=list(mouse), object=obj.name, face=face,
                          hit_face=None if hit is None else hit[2])
        if face is None or not self._open_session(obj):
            return False  # off the mesh: nothing (a cancelled keymap operator ends the event's handling)
        self._face = face
        self._normal = Vector(tuple(arrays.polygon_normals[face]))
        self._anchor = Vector(tuple(arrays.polygon_centers[face])) if hit is None or hit[2] != face else hit[0].copy()
        # the faces this drag sets: the pressed one and, with mirror symmetry, its partner
        placed, self._note = api.mirror_placements(self._session, DirectionConstraint(face, (1.0, 0.0, 0.0)))
        self._before = {c.face: self._stored(obj, c.face) for c in placed}
        self._accepted = dict(self._before)  # the last (kind, direction) per face the solver accepted
        self._before_result = self._entry.result
        self._target = None
        self._solved_target = None
        set_status(context, f"Aim constraint on face {face}: drag to aim, release to confirm, Esc/RMB to cancel"
                            + (f" | {self._note}" if self._note else ""))
        return True

    @staticmethod
    def _stored(obj, face):
        item = design.constraint_item(obj, face)
        return None if item is None else (item.kind, tuple(item.direction))

    # -- live aim
    def drag(self, context, obj, mouse):
        p = ray_plane(context, obj, mouse, self._anchor, self._normal)
        if p is None:
            return
        d = p - self._anchor
        d -= self._normal * d.dot(self._normal) / max(self._normal.length_squared, 1e-30)
        if d.length <= 1e-12:
            return
        self._target = d.normalized()

    def tick(self, context, obj):
        if self._target is not None and self._target != self._solved_target:
            self._solved_target = self._target.copy()
            self._apply(context, obj, self._target)

    def release(self, context, obj):
        if self._target is not None and self._target != self._solved_target:
            self._apply(context, obj, self._target)
        elif not self._dragged and self._before[self._face] is None:
            d = _face_direction(self._entry, self._face)  # click: pin the current direction
            if d is None or not self._apply(context, obj, d):
                return False
        elif self._target is None:
            return False  # nothing changed: no undo step
        self._write_attributes(obj)
        return True

    def _apply(self, context, obj, direction, kind="DIRECTION"):
        """Re-solve through the session's re-aim path with `direction` (and its mirror image); store them in
        the design only if the solve succeeds (otherwise the session goes back to the last accepted
        directions; returns False)."""
        t0 = time.perf_counter()
        cls = VectorConstraint if kind == "VECTOR" else DirectionConstraint
        placed, _ = api.mirror_placements(self._session, cls(self._face, tuple(direction)))
        values = {c.face: c.vector if kind == "VECTOR" else c.direction for c in placed}
        try:
            for face, d in values.items():
                (self._session.set_vector if kind == "VECTOR" else self._session.set_direction)(face, d)
            result = self._session.solve()
        except (ValueError, RuntimeError, MemoryError) as exc:
            for face in values:
                self._session_back_to(face, self._accepted.get(face))
            self.report({"WARNING"}, failure_message(exc))
            return False
        for face, d in values.items():
            design.set_constraint(obj, face, d, kind, self._entry.arrays.polygon_centers[face])
            self._accepted[face] = (kind, tuple(d))
        self._store(obj, result)
        ms = (time.perf_counter() - t0) * 1e3
        shown = tuple(round(x, 3) for x in direction)
        mirrored = f" (and its mirror image on face {placed[1].face})" if len(placed) > 1 else ""
        set_status(context, f"Face {self._face}: direction {shown} (object space){mirrored}, live solve {ms:.0f} ms"
                            f" | release to confirm, Esc/RMB to cancel" + (f" | {self._note}" if self._note else ""))
        return True

    def _session_back_to(self, face, state):
        """Put the session's constraint on `face` back to `state` ((kind, direction) or None)."""
        try:
            if state is None:
                if any(getattr(c, "face", None) == face for c in self._session.constraints):
                    self._session.remove(face)
            else:
                kind, d = state
                (self._session.set_vector if kind == "VECTOR" else self._session.set_direction)(face, d)
        except ValueError:
            pass

    def restore(self, context, obj):
        for face, before in self._before.items():
            if before is None:
                if design.constraint_item(obj, face) is not None:
                    design.remove_constraint(obj, face)
            else:
                kind, d = before
                design.set_constraint(obj, face, d, kind, self._entry.arrays.polygon_centers[face])
            self._session_back_to(face, before)
        if self._solved_target is not None:  # the field changed
            self._solve_or_put_back(obj)


NFIELD_OT_constraint_delete = delete_operator(
    "NFIELD_OT_constraint_delete", "Delete the direction constraint under the cursor", "nfield.constraint_delete",
    "Delete Field Constraint", "constraints", "face", "Polygon whose constraint to delete (-1: the one under the "
    "cursor)", api.remove_constraint, ("No constraint under the cursor", "Removed the constraint on face {}"),
    lambda context, obj, mouse, arrays: constraint_under_cursor(context, obj, mouse,
                                                                ray_cast(context, obj, mouse, arrays), arrays))


classes = (NFIELD_OT_constraint_tool, NFIELD_OT_constraint_delete)
