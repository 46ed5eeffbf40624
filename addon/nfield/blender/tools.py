"""Interactive viewport tools: aim direction constraints and pin singularities by clicking on the mesh.

Operators (also bound by the toolbar tools below, 3D view, object mode):

* ``nfield.constraint_tool`` (modal): press on a face and drag to aim its direction constraint in the face's
  tangent plane; the field follows live during the drag (the session's re-aim path: no new factorization).
  Pressing on a constrained face, or within ``PICK_PIXELS`` of a constraint arrow, re-aims that constraint.
  A click without a drag pins the current field direction of the face. Release: one undo step.
  Esc / right-click: restore the state before the drag.
* ``nfield.constraint_delete``: delete the constraint under the cursor (X / Delete in the tool).
* ``nfield.singularity_tool`` (modal): press near a vertex, pick the index with the mouse wheel, +/-, or the
  number keys (a number key sets |numerator|, minus flips the sign); the index is validated by the solver
  for that vertex (the error explains the valid range, shown in the header); click/Enter confirms,
  Esc/right-click restores. Clicking a pinned singularity edits it, X / Delete removes it.
* ``nfield.singularity_delete``: remove the pinned singularity nearest to the cursor.

Geometry: the mouse ray is taken to **object space** with the inverse of ``matrix_world`` (points with the
full affine inverse, the direction with its linear part) and cast against a BVH of the *base* mesh, so face
indices are polygon indices of ``obj.data`` and rotation / non-uniform scale are handled exactly: an affine
map keeps lines and planes, so intersecting the transformed ray with the face's plane in object space gives
the same surface point as in world space. The dragged direction is (drag point - press point) in object
space, projected onto the face's object-space tangent plane -- the frame the solver and the stored design
use.
"""
from __future__ import annotations

import time

import bpy
import numpy as np
from bpy.props import IntProperty
from bpy.types import Operator, WorkSpaceTool
from bpy_extras import view3d_utils
from mathutils import Vector
from mathutils.bvhtree import BVHTree

from . import overlay

#: a click within this many pixels of a constraint's centroid / a pinned singularity picks it
PICK_PIXELS = 24
#: minimum drag (pixels) before the direction follows the mouse
DRAG_PIXELS = 4

CONSTRAINT_HINT = ("Field Constraint: drag on a face to aim | drag from an arrow to re-aim | "
                   "X/Del: delete constraint under cursor | Esc/RMB during drag: cancel")
SINGULARITY_HINT = ("Field Singularity: click near a vertex, then Wheel / +- / 1-9 to pick the index, "
                    "Minus flips sign, LMB/Enter to confirm, Esc/RMB to cancel | X/Del: remove pinned singularity")


# ============================================================================================ helpers
def _poll_object(context):
    obj = context.active_object
    return (obj is not None and obj.type == "MESH" and obj.mode == "OBJECT" and hasattr(obj, "nfield")
            and len(obj.data.polygons) > 0)


_bvh_cache: dict = {}
#: the last press handled by the constraint/singularity tools (region pixel, object, face/vertex): for
#: scripted checks and bug reports
last_press: dict = {}


def _bvh(obj):
    """BVH of the base mesh (object space), cached per mesh state."""
    me = obj.data
    nv, np_, nl = len(me.vertices), len(me.polygons), len(me.loops)
    co = np.empty(nv * 3, dtype=np.float32)
    me.vertices.foreach_get("co", co)
    key = (me.as_pointer(), nv, np_, nl, hash(co[:: max(1, (3 * nv) // 4096)].tobytes()))
    hit = _bvh_cache.get(obj.name)
    if hit is not None and hit[0] == key:
        return hit[1]
    loops = np.empty(nl, dtype=np.int32)
    me.loops.foreach_get("vertex_index", loops)
    totals = np.empty(np_, dtype=np.int32)
    me.polygons.foreach_get("loop_total", totals)
    if np.all(totals == 3):
        polys = loops.reshape(-1, 3).tolist()
    elif np.all(totals == 4):
        polys = loops.reshape(-1, 4).tolist()
    else:
        polys = [a.tolist() for a in np.split(loops, np.cumsum(totals)[:-1])]
    tree = BVHTree.FromPolygons(co.reshape(nv, 3).tolist(), polys, all_triangles=bool(np.all(totals == 3)))
    _bvh_cache[obj.name] = (key, tree)
    return tree


def _mouse_ray_object(context, obj, mouse):
    """(origin, direction) of the mouse ray in object space."""
    region, rv3d = context.region, context.region_data
    o = view3d_utils.region_2d_to_origin_3d(region, rv3d, mouse)
    d = view3d_utils.region_2d_to_vector_3d(region, rv3d, mouse)
    inv = obj.matrix_world.inverted_safe()
    return inv @ o, (inv.to_3x3() @ d)


def _ray_cast(context, obj, mouse):
    """(location, normal, polygon index) in object space, or None."""
    o, d = _mouse_ray_object(context, obj, mouse)
    if d.length == 0:
        return None
    loc, nrm, idx, _ = _bvh(obj).ray_cast(o, d.normalized())
    if loc is None:
        return None
    return loc, nrm, idx


def _ray_plane(context, obj, mouse, point, normal):
    """Intersection (object space) of the mouse ray with the plane (point, normal), or None if grazing."""
    o, d = _mouse_ray_object(context, obj, mouse)
    denom = d.dot(normal)
    if abs(denom) < 1e-9 * d.length * normal.length:
        return None
    t = (point - o).dot(normal) / denom
    return o + d * t


def _to_region(context, obj, p_obj):
    return view3d_utils.location_3d_to_region_2d(context.region, context.region_data, obj.matrix_world @ p_obj)


def _nearest_on_screen(context, obj, points_obj, mouse, limit):
    """Index of the point (object space) nearest to `mouse` on screen within `limit` pixels, or None."""
    best, best_d = None, limit
    m = Vector(mouse)
    for i, p in enumerate(points_obj):
        q = _to_region(context, obj, Vector(p))
        if q is None:
            continue
        dist = (q - m).length
        if dist <= best_d:
            best, best_d = i, dist
    return best


def _session(obj):
    """(api, entry, session) with a solved field (the first call may factorize)."""
    from . import api, session_cache

    arrays, _ = api.sync(obj)
    entry = session_cache.get_entry(obj, arrays)
    if session_cache.spectral_basis_pending(obj, entry):
        # computing the basis here would freeze the viewport for minutes
        raise ValueError(f"the spectral basis ({obj.nfield.spectral_k} eigenfields) is not computed yet: "
                         f"press Precompute in the nfield panel, or switch the solver to Exact")
    session = session_cache.ensure_session(obj, entry)
    from . import background

    if background.busy(obj):
        raise ValueError(f"'{obj.name}' is being solved in the background: wait for it or press Esc")
    if background.interactive() and session.pending_work() == "factorization":
        # the first factorization would freeze the viewport: do it in the background, then drag again
        background.start_later(obj.name)
        raise ValueError("preparing the solver in the background (Esc cancels): drag again when it is done")
    if session.field is None:
        _store(api, obj, entry, session.solve())
    return api, entry, session


def _store(api, obj, entry, result):
    store = getattr(api, "_store_result", None)
    if store is not None:
        store(obj, entry, result)
    else:
        entry.result = result
        entry.version += 1
        overlay.refresh(obj, result)


def _face_direction(entry, face):
    res = entry.result
    if res is None:
        return None
    d = np.asarray(res.directions[face], dtype=np.float64)
    return None if not np.any(d) else Vector(d.tolist())


def _set_status(context, text):
    """Show `text` in the 3D view's header and the status bar (None: back to Blender's default)."""
    if context.area is not None:
        context.area.header_text_set(text)
    ws = getattr(context, "workspace", None)
    if ws is not None:
        ws.status_text_set(text)


def _clear_status(context):
    _set_status(context, None)  # None restores Blender's own header / status bar


def _constraint_item(obj, face):
    return next((c for c in obj.nfield.constraints if c.face == face and not c.stale), None)


def _constraint_under_cursor(context, obj, mouse, hit):
    """Face of the constraint the user points at: the constrained face under the cursor (`hit`, from
    _ray_cast), else the arrow nearest on screen (its face may be small or hidden behind the arrow); or None."""
    if hit is not None and _constraint_item(obj, hit[2]) is not None:
        return hit[2]
    items = [c for c in obj.nfield.constraints if not c.stale and c.face < len(obj.data.polygons)]
    i = _nearest_on_screen(context, obj, [obj.data.polygons[c.face].center for c in items], mouse, PICK_PIXELS)
    return None if i is None else items[i].face


def _pinned_singularity_under_cursor(context, obj, mouse):
    """Vertex of the pinned singularity nearest on screen to `mouse`, or None."""
    me = obj.data
    pinned = [s for s in obj.nfield.singularities if not s.stale and s.vertex < len(me.vertices)]
    i = _nearest_on_screen(context, obj, [me.vertices[s.vertex].co for s in pinned], mouse, PICK_PIXELS)
    return None if i is None else pinned[i].vertex


def _remove_design_item(op, context, remove, key, done_message):
    """`remove(obj, key)` (an api removal), then re-solve (Live Update) or just redraw the overlay; reports
    like the other tool operators."""
    from . import api
    from .operators import failure_message

    obj = context.active_object
    saved = None
    try:
        api.sync(obj)
        saved = api.snapshot(obj)
        remove(obj, key)
        if obj.nfield.live_update:
            api.solve(obj)
        else:
            api.notify_overlay(obj)
    except (ValueError, RuntimeError, MemoryError) as exc:
        if saved is not None:
            api.restore(obj, saved)  # a failed re-solve keeps the removed item
        op.report({"ERROR"}, failure_message(exc))
        return {"CANCELLED"}
    op.report({"INFO"}, done_message)
    return {"FINISHED"}


class _ModalViewportTool:
    """Mixin of the two modal tools: poll for a 3D view with a mesh in object mode; the solver session."""

    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return _poll_object(context) and context.area is not None and context.area.type == "VIEW_3D"

    def _open_session(self, obj) -> bool:
        """Get (api, entry, session) with a solved field; False (reported) if the design cannot be solved."""
        from .operators import failure_message

        try:
            self._api, self._entry, self._session = _session(obj)
        except (ValueError, RuntimeError, MemoryError) as exc:
            self.report({"ERROR"}, failure_message(exc))
            return False
        return True

    def _write_attributes(self, obj):
        if obj.nfield.write_attributes and self._entry.result is not None:
            try:
                self._api.write_attributes(obj, self._entry.result)
            except ValueError as exc:
                self.report({"WARNING"}, str(exc))


# ============================================================================================ constraint tool
class NFIELD_OT_constraint_tool(_ModalViewportTool, Operator):
    """Click a face and drag to aim its direction constraint (the field follows live)"""

    bl_idname = "nfield.constraint_tool"
    bl_label = "Aim Field Constraint"

    def invoke(self, context, event):
        obj = context.active_object
        mouse = (event.mouse_region_x, event.mouse_region_y)
        hit = _ray_cast(context, obj, mouse)
        face = _constraint_under_cursor(context, obj, mouse, hit)
        if face is None and hit is not None:
            face = hit[2]  # an unconstrained face: a new constraint
        last_press.clear()
        last_press.update(tool="constraint", mouse=list(mouse), object=obj.name, face=face,
                          hit_face=None if hit is None else hit[2])
        if face is None:
            return {"PASS_THROUGH"}
        if not self._open_session(obj):
            return {"CANCELLED"}
        poly = obj.data.polygons[face]
        self._obj_name = obj.name
        self._face = face
        self._normal = poly.normal.copy()
        self._anchor = poly.center.copy() if hit is None or hit[2] != face else hit[0].copy()
        self._press = Vector(mouse)
        self._dragged = False
        item = _constraint_item(obj, face)
        self._before = None if item is None else (item.kind, tuple(item.direction))
        self._accepted = self._before  # the last (kind, direction) the solver accepted in this drag
        self._before_result = self._entry.result
        self._target = None
        self._solved_target = None
        self._timer = context.window_manager.event_timer_add(1.0 / 60.0, window=context.window)
        context.window_manager.modal_handler_add(self)
        _set_status(context, f"Aim constraint on face {face}: drag to aim, release to confirm, "
                             f"Esc/RMB to cancel")
        return {"RUNNING_MODAL"}

    # -- live aim
    def _aim(self, context, obj, mouse):
        p = _ray_plane(context, obj, mouse, self._anchor, self._normal)
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
            from .operators import failure_message

            self._session_back_to(self._accepted)
            self.report({"WARNING"}, failure_message(exc))
            return False
        item = _constraint_item(obj, face)
        if item is None:
            item = obj.nfield.constraints.add()
            obj.nfield.active_constraint_index = len(obj.nfield.constraints) - 1
            item.face = face
            item.centroid = obj.data.polygons[face].center
        item.kind = kind
        item.direction = tuple(direction)
        self._accepted = (kind, tuple(direction))
        _store(self._api, obj, self._entry, result)
        ms = (time.perf_counter() - t0) * 1e3
        d = tuple(round(x, 3) for x in direction)
        _set_status(context, f"Face {face}: direction {d} (object space), live solve {ms:.0f} ms | "
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
        st = obj.nfield
        if self._before is None:
            idx = next((i for i, c in enumerate(st.constraints) if c.face == face and not c.stale), None)
            if idx is not None:
                st.constraints.remove(idx)
                st.active_constraint_index = max(0, min(st.active_constraint_index, len(st.constraints) - 1))
            try:
                if any(getattr(c, "face", None) == face and not hasattr(c, "vertex")
                       for c in self._session.constraints):
                    self._session.remove(face)
            except ValueError:
                pass
        else:
            kind, d = self._before
            item = _constraint_item(obj, face)
            if item is not None:
                item.kind, item.direction = kind, d
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
            _store(self._api, obj, self._entry, result)

    def _finish(self, context, cancelled):
        context.window_manager.event_timer_remove(self._timer)
        _clear_status(context)
        obj = bpy.data.objects.get(self._obj_name)
        if obj is not None:
            overlay.refresh(obj)
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
        return _poll_object(context) and len(context.active_object.nfield.constraints) > 0

    def invoke(self, context, event):
        obj = context.active_object
        mouse = (event.mouse_region_x, event.mouse_region_y)
        face = _constraint_under_cursor(context, obj, mouse, _ray_cast(context, obj, mouse))
        if face is None:
            self.report({"INFO"}, "No constraint under the cursor")
            return {"CANCELLED"}
        self.face = face
        return self.execute(context)

    def execute(self, context):
        from . import api

        return _remove_design_item(self, context, api.remove_constraint, self.face,
                                   f"Removed the constraint on face {self.face}")


# ============================================================================================ singularity tool
class NFIELD_OT_singularity_tool(_ModalViewportTool, Operator):
    """Click near a vertex and pick a singularity index (wheel / +- / number keys)"""

    bl_idname = "nfield.singularity_tool"
    bl_label = "Pin Field Singularity"

    def invoke(self, context, event):
        obj = context.active_object
        mouse = (event.mouse_region_x, event.mouse_region_y)
        vertex = self._pick_vertex(context, obj, mouse)
        if vertex is None:
            return {"PASS_THROUGH"}
        if not self._open_session(obj):
            return {"CANCELLED"}
        st = obj.nfield
        self._obj_name = obj.name
        self._vertex = vertex
        item = next((s for s in st.singularities if s.vertex == vertex and not s.stale), None)
        self._before = None if item is None else int(item.numerator)
        self._before_result = self._entry.result
        self._numerator = self._before if self._before is not None else 1
        self._explain = ""
        self._changed = False
        self._valid = self._valid_numerators()
        if self._valid is not None and self._numerator not in self._valid and self._valid:
            self._numerator = min(self._valid, key=lambda k: (abs(k - 1), -k))
        context.window_manager.modal_handler_add(self)
        self._preview(context, obj, self._numerator)
        return {"RUNNING_MODAL"}

    def _pick_vertex(self, context, obj, mouse):
        pinned = _pinned_singularity_under_cursor(context, obj, mouse)
        if pinned is not None:
            return pinned
        me = obj.data
        hit = _ray_cast(context, obj, mouse)
        if hit is None:
            return None
        loc, _, face = hit
        verts = list(me.polygons[face].vertices)
        return min(verts, key=lambda v: (me.vertices[v].co - loc).length)

    def _valid_numerators(self):
        """The numerators the solver accepts at this vertex, probed through the session's validation
        (DesignSession.set_singularity raises ValueError with the valid range)."""
        n = int(bpy.data.objects[self._obj_name].nfield.n)
        v = self._vertex
        had = next((c.index for c in self._session.constraints
                    if getattr(c, "vertex", None) == v), None)
        ok = []
        for k in range(-4 * n, 4 * n + 1):
            if k == 0:
                continue
            try:
                self._session.set_singularity(v, k / n)
            except ValueError as exc:
                self._explain = str(exc)
                continue
            ok.append(k)
        try:
            if had is None:
                self._session.remove_singularity(v)
            else:
                self._session.set_singularity(v, had)
        except ValueError:
            pass
        return ok

    def _header(self, context, obj, extra=""):
        n = obj.nfield.n
        rng = ""
        if self._valid:
            rng = f" | valid at this vertex: {min(self._valid)}/{n} .. {max(self._valid)}/{n}"
        elif self._valid is not None:
            rng = " | this vertex cannot carry a singularity"
        _set_status(context, f"Singularity at vertex {self._vertex}: index {self._numerator}/{n}{rng}"
                             f"{(' | ' + extra) if extra else ''} | Wheel/+-/1-9: index, Minus: sign, "
                             f"LMB/Enter: confirm, Esc/RMB: cancel")

    def _preview(self, context, obj, k):
        """Pin index k/n at the vertex and solve; returns False (state unchanged) if the solver refuses."""
        n = obj.nfield.n
        if k == 0 or (self._valid is not None and k not in self._valid):
            why = self._explain or "index 0 is no singularity"
            self._header(context, obj, f"{k}/{n} refused: {why}")
            return False
        st = obj.nfield
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
        item = next((s for s in st.singularities if s.vertex == self._vertex and not s.stale), None)
        if item is None:
            item = st.singularities.add()
            st.active_singularity_index = len(st.singularities) - 1
            item.vertex = self._vertex
            item.position = obj.data.vertices[self._vertex].co
        item.numerator = k
        self._numerator = k
        self._changed = True
        _store(self._api, obj, self._entry, result)
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
        st = obj.nfield
        idx = next((i for i, s in enumerate(st.singularities) if s.vertex == self._vertex and not s.stale), None)
        if idx is not None:
            st.singularities.remove(idx)
            st.active_singularity_index = max(0, min(st.active_singularity_index, len(st.singularities) - 1))
        try:
            self._session.remove_singularity(self._vertex)
        except ValueError:
            pass
        try:
            _store(self._api, obj, self._entry, self._session.solve())
            if obj.nfield.write_attributes:
                self._api.write_attributes(obj, self._entry.result)
        except (ValueError, RuntimeError, MemoryError) as exc:
            self.report({"WARNING"}, str(exc))

    def _restore(self, obj):
        st = obj.nfield
        n = st.n
        item_idx = next((i for i, s in enumerate(st.singularities) if s.vertex == self._vertex and not s.stale),
                        None)
        try:
            if self._before is None:
                if item_idx is not None:
                    st.singularities.remove(item_idx)
                self._session.remove_singularity(self._vertex)
            else:
                st.singularities[item_idx].numerator = self._before
                self._session.set_singularity(self._vertex, self._before / n)
        except (ValueError, TypeError, IndexError):
            pass
        if self._changed:
            try:
                _store(self._api, obj, self._entry, self._session.solve())
            except (ValueError, RuntimeError, MemoryError):
                if self._before_result is not None:
                    _store(self._api, obj, self._entry, self._before_result)

    def _finish(self, context, cancelled):
        _clear_status(context)
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
        return _poll_object(context) and len(context.active_object.nfield.singularities) > 0

    def invoke(self, context, event):
        vertex = _pinned_singularity_under_cursor(context, context.active_object,
                                                  (event.mouse_region_x, event.mouse_region_y))
        if vertex is None:
            self.report({"INFO"}, "No pinned singularity under the cursor")
            return {"CANCELLED"}
        self.vertex = vertex
        return self.execute(context)

    def execute(self, context):
        from . import api

        return _remove_design_item(self, context, api.remove_singularity, self.vertex,
                                   f"Removed the singularity at vertex {self.vertex}")


# ============================================================================================ toolbar tools
class NFIELD_TL_constraint(WorkSpaceTool):
    bl_space_type = "VIEW_3D"
    bl_context_mode = "OBJECT"
    bl_idname = "nfield.tool_constraint"
    bl_label = "Field Constraint"
    bl_description = CONSTRAINT_HINT
    bl_icon = "ops.gpencil.primitive_line"
    bl_widget = None
    bl_keymap = (
        ("nfield.constraint_tool", {"type": "LEFTMOUSE", "value": "PRESS"}, None),
        ("nfield.constraint_delete", {"type": "X", "value": "PRESS"}, None),
        ("nfield.constraint_delete", {"type": "DEL", "value": "PRESS"}, None),
    )


class NFIELD_TL_singularity(WorkSpaceTool):
    bl_space_type = "VIEW_3D"
    bl_context_mode = "OBJECT"
    bl_idname = "nfield.tool_singularity"
    bl_label = "Field Singularity"
    bl_description = SINGULARITY_HINT
    bl_icon = "ops.transform.tosphere"
    bl_widget = None
    bl_keymap = (
        ("nfield.singularity_tool", {"type": "LEFTMOUSE", "value": "PRESS"}, None),
        ("nfield.singularity_delete", {"type": "X", "value": "PRESS"}, None),
        ("nfield.singularity_delete", {"type": "DEL", "value": "PRESS"}, None),
    )


classes = (
    NFIELD_OT_constraint_tool,
    NFIELD_OT_constraint_delete,
    NFIELD_OT_singularity_tool,
    NFIELD_OT_singularity_delete,
)
_tools = (NFIELD_TL_constraint, NFIELD_TL_singularity)
_registered_tools: list = []


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    if bpy.app.background:
        return  # no toolbar without a window
    after = {"builtin.scale_cage"}
    for i, tool in enumerate(_tools):
        try:
            bpy.utils.register_tool(tool, after=after, separator=(i == 0), group=False)
            _registered_tools.append(tool)
        except Exception as exc:  # noqa: BLE001 - an older/newer toolbar layout must not block the add-on
            print(f"nfield: cannot add the toolbar tool {tool.bl_label!r}: {exc}")


def unregister():
    for tool in reversed(_registered_tools):
        try:
            bpy.utils.unregister_tool(tool)
        except Exception:  # noqa: BLE001
            pass
    _registered_tools.clear()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
    _bvh_cache.clear()
