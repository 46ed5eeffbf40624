"""The singularity tool: pin singularities of a chosen index at vertices (3D view, object mode).

* ``nfield.singularity_tool`` (modal): press near a vertex, pick the index with the mouse wheel, +/-, or the
  number keys (a number key sets |numerator|, minus flips the sign); the indices offered are the ones the
  solver accepts at that vertex (``DesignSession.index_range``: |index - K/2pi| < k/(2n) for a ring of k faces
  and angle defect K), and a refused one is explained in the header; click/Enter confirms, Esc/right-click
  restores. Clicking a pinned singularity edits it, X / Delete removes it. With mirror symmetry on, the mirror
  vertex gets the same index in the same step (a vertex without a partner: the header says so).
* ``nfield.singularity_delete``: remove the pinned singularity nearest to the cursor.

Every write of the stored singularity goes through ``design``; the previews solve the session directly and
are recorded with ``api.store_result``.
"""
from __future__ import annotations

from bpy.types import Operator
from mathutils import Vector

from ..core import SingularityConstraint
from . import api, design, mesh_read
from .tool_common import (
    ModalViewportTool,
    delete_operator,
    pinned_singularity_under_cursor,
    ray_cast,
    set_status,
)


class NFIELD_OT_singularity_tool(ModalViewportTool, Operator):
    """Click near a vertex and pick a singularity index (wheel / +- / number keys)"""

    bl_idname = "nfield.singularity_tool"
    bl_label = "Pin Field Singularity"

    def begin(self, context, obj, mouse) -> bool:
        vertex = self._pick_vertex(context, obj, mouse)
        if vertex is None or not self._open_session(obj):
            return False  # off the mesh: nothing (no fall-through to select / move)
        self._vertex = vertex
        n = obj.nfield.n
        # the vertices this edit sets: the pressed one and, with mirror symmetry, its partner
        placed, self._note = api.mirror_placements(self._session, SingularityConstraint(vertex, 1.0 / n))
        self._before = {}
        for s in placed:
            item = design.singularity_item(obj, s.vertex)
            self._before[s.vertex] = None if item is None else design.singularity_numerator(item, n)
        self._before_result = self._entry.result
        self._numerator = self._before[vertex] if self._before[vertex] is not None else 1
        self._changed = False
        self._valid, self._explain = self._valid_numerators(n)
        if self._numerator not in self._valid and self._valid:
            self._numerator = min(self._valid, key=lambda k: (abs(k - 1), -k))
        self._preview(context, obj, self._numerator)
        return True

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
        mirror = [v for v in self._before if v != self._vertex]
        where = f"vertex {self._vertex}" + (f" (and its mirror vertex {mirror[0]})" if mirror else "")
        notes = " | ".join(x for x in (extra, self._note) if x)
        set_status(context, f"Singularity at {where}: index {self._numerator}/{n}{rng}"
                            f"{(' | ' + notes) if notes else ''} | Wheel/+-/1-9: index, Minus: sign, "
                            f"LMB/Enter: confirm, Esc/RMB: cancel")

    def _set_numerators(self, numerators: dict, n: int) -> None:
        """Put the session's singularities at the edited vertices to `numerators` (vertex -> k or None)."""
        for v, k in numerators.items():
            try:
                if k is not None:
                    self._session.set_singularity(v, k / n)
                else:
                    self._session.remove_singularity(v)
            except ValueError:  # refused, or nothing pinned there to remove
                pass

    def _preview(self, context, obj, k):
        """Pin index k/n at the vertex (and its mirror vertex) and solve; returns False (state unchanged) if
        the solver refuses."""
        n = obj.nfield.n
        if k == 0 or k not in self._valid:
            why = "index 0 is no singularity" if k == 0 else self._explain
            self._header(context, obj, f"{k}/{n} refused: {why}")
            return False
        try:
            for v in self._before:
                self._session.set_singularity(v, k / n)
            result = self._session.solve()
        except (ValueError, RuntimeError, MemoryError) as exc:
            self._header(context, obj, f"{k}/{n} refused: {exc}")
            # put the session back to the last accepted numerator
            last = self._numerator if self._changed else None
            self._set_numerators({v: last if last is not None else self._before[v] for v in self._before}, n)
            return False
        for v in self._before:
            design.set_singularity(obj, v, k, self._entry.arrays.vertices[v])
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

    def key(self, context, obj, event):
        if event.value != "PRESS":
            return {"RUNNING_MODAL"}
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
                self.restore(context, obj)
                return self._finish(context, True)
            self._write_attributes(obj)
            return self._finish(context, False)
        elif t in {"X", "DEL"}:
            self._before_remove(obj)
            return self._finish(context, False)
        return {"RUNNING_MODAL"}

    def _before_remove(self, obj):
        """X/Del while choosing: remove the singularities pinned at the edited vertices."""
        for v in self._before:
            if design.singularity_item(obj, v) is not None:
                design.remove_singularity(obj, v)
        self._set_numerators({v: None for v in self._before}, obj.nfield.n)
        try:
            self._store(obj, self._session.solve())
            if obj.nfield.write_attributes:
                api.write_attributes(obj, self._entry.result)
        except (ValueError, RuntimeError, MemoryError) as exc:
            self.report({"WARNING"}, str(exc))

    def restore(self, context, obj):
        n = obj.nfield.n
        for v, before in self._before.items():
            if before is None:
                if design.singularity_item(obj, v) is not None:
                    design.remove_singularity(obj, v)
            else:
                design.set_singularity(obj, v, before, self._entry.arrays.vertices[v])
        self._set_numerators(dict(self._before), n)
        if self._changed:
            self._solve_or_put_back(obj)


_NUMBER_KEYS = {name: i for i, name in enumerate(
    ("ZERO", "ONE", "TWO", "THREE", "FOUR", "FIVE", "SIX", "SEVEN", "EIGHT", "NINE")) if i}
_NUMBER_KEYS.update({f"NUMPAD_{i}": i for i in range(1, 10)})


NFIELD_OT_singularity_delete = delete_operator(
    "NFIELD_OT_singularity_delete", "Remove the pinned singularity nearest to the cursor",
    "nfield.singularity_delete", "Remove Field Singularity", "singularities", "vertex",
    "Vertex whose pinned singularity to remove (-1: the one under the cursor)", api.remove_singularity,
    ("No pinned singularity under the cursor", "Removed the singularity at vertex {}"), pinned_singularity_under_cursor)


classes = (NFIELD_OT_singularity_tool, NFIELD_OT_singularity_delete)
