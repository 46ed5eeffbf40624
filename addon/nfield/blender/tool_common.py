"""What the viewport tools share: picking on the mesh under the mouse, the header/status text, the solver
session a modal tool edits live, the mixin of the modal tools (press, drag, timer, release, cancel) and the
mixin of their delete operators.

Geometry: the mouse ray is taken to **object space** with the inverse of ``matrix_world`` (points with the
full affine inverse, the direction with its linear part) and cast against a BVH of the *base* mesh
(``mesh_read.bvh``, rebuilt when the mesh signature changes), so face indices are polygon indices of
``obj.data`` and rotation / non-uniform scale are handled exactly: an affine map keeps lines and planes, so
intersecting the transformed ray with the face's plane in object space gives the same surface point as in
world space. Directions are in object space, projected onto the face's tangent plane: the frame the solver
and the stored design use.
"""
from __future__ import annotations

import bpy
from bpy.props import IntProperty
from bpy.types import Operator
from bpy_extras import view3d_utils
from mathutils import Vector

from . import api, design, jobs, mesh_read, overlay
from .operator_base import failure_message, guarded_edit

#: a click within this many pixels of a constraint's centroid / a pinned singularity picks it
PICK_PIXELS = 24
#: minimum drag (pixels) before the direction follows the mouse
DRAG_PIXELS = 4

#: the last press handled by the viewport tools (tool, region pixel, object, face/vertex): for scripted checks
#: and bug reports
last_press: dict = {}


def poll_object(context) -> bool:
    """An active mesh object with faces, in object mode."""
    obj = context.active_object
    return (obj is not None and obj.type == "MESH" and obj.mode == "OBJECT" and hasattr(obj, "nfield")
            and len(obj.data.polygons) > 0)


# ------------------------------------------------------------------------------------------ picking
def mouse_ray_object(context, obj, mouse):
    """(origin, direction) of the mouse ray in object space."""
    region, rv3d = context.region, context.region_data
    o = view3d_utils.region_2d_to_origin_3d(region, rv3d, mouse)
    d = view3d_utils.region_2d_to_vector_3d(region, rv3d, mouse)
    inv = obj.matrix_world.inverted_safe()
    return inv @ o, (inv.to_3x3() @ d)


def ray_cast(context, obj, mouse, arrays: mesh_read.MeshArrays):
    """(location, normal, polygon index) in object space of the first hit of the mouse ray, or None.
    `arrays`: the object's mesh_read.mesh_arrays (read once per event)."""
    o, d = mouse_ray_object(context, obj, mouse)
    if d.length == 0:
        return None
    tree, triangle_polygon = mesh_read.bvh(obj, arrays)
    loc, nrm, tri, _ = tree.ray_cast(o, d.normalized())
    if loc is None:
        return None
    return loc, nrm, int(triangle_polygon[tri])


def ray_plane(context, obj, mouse, point, normal):
    """Intersection (object space) of the mouse ray with the plane (point, normal), or None if grazing."""
    o, d = mouse_ray_object(context, obj, mouse)
    denom = d.dot(normal)
    if abs(denom) < 1e-9 * d.length * normal.length:
        return None
    t = (point - o).dot(normal) / denom
    return o + d * t


def _to_region(context, obj, p_obj):
    return view3d_utils.location_3d_to_region_2d(context.region, context.region_data, obj.matrix_world @ p_obj)


def nearest_on_screen(context, obj, points_obj, mouse, limit):
    """Index of the point (object space) nearest to `mouse` on screen within `limit` pixels, or None."""
    best, best_d = None, limit
    m = Vector(mouse)
    for i, p in enumerate(points_obj):
        q = _to_region(context, obj, Vector(tuple(p)))
        if q is None:
            continue
        dist = (q - m).length
        if dist <= best_d:
            best, best_d = i, dist
    return best


def constraint_under_cursor(context, obj, mouse, hit, arrays: mesh_read.MeshArrays):
    """Face of the constraint the user points at: the constrained face under the cursor (`hit`, from
    ray_cast), else the arrow nearest on screen within PICK_PIXELS of any point of its shaft or head (as the
    overlay drew it: pressing the arrowhead, which reaches over neighbouring faces, grabs that arrow); or
    None."""
    if hit is not None and design.constraint_item(obj, hit[2]) is not None:
        return hit[2]
    items = [c for c in obj.nfield.constraints if not c.stale and c.face < arrays.num_polygons]
    drawn = overlay.constraint_arrows(obj, context.region)
    best, best_d = None, float(PICK_PIXELS)
    m = Vector(mouse)
    for c in items:
        tail, tip = drawn.get(c.face, (arrays.polygon_centers[c.face], arrays.polygon_centers[c.face]))
        a = _to_region(context, obj, Vector(tuple(tail)))
        b = _to_region(context, obj, Vector(tuple(tip)))
        if a is None or b is None:
            continue
        dist = _segment_distance(m, a, b)
        if dist <= best_d:
            best, best_d = c.face, dist
    return best


def _segment_distance(p: Vector, a: Vector, b: Vector) -> float:
    """Distance (pixels) from p to the segment ab."""
    ab = b - a
    t = 0.0 if ab.length_squared == 0 else max(0.0, min(1.0, (p - a).dot(ab) / ab.length_squared))
    return (p - (a + ab * t)).length


def pinned_singularity_under_cursor(context, obj, mouse, arrays: mesh_read.MeshArrays):
    """Vertex of the pinned singularity nearest on screen to `mouse`, or None."""
    pinned = [s for s in obj.nfield.singularities if not s.stale and s.vertex < arrays.vertices.shape[0]]
    i = nearest_on_screen(context, obj, [arrays.vertices[s.vertex] for s in pinned], mouse, PICK_PIXELS)
    return None if i is None else pinned[i].vertex


# ------------------------------------------------------------------------------------------ status text
def set_status(context, text):
    """Show `text` in the 3D view's header and the status bar (None: back to Blender's default)."""
    if context.area is not None:
        context.area.header_text_set(text)
    ws = getattr(context, "workspace", None)
    if ws is not None:
        ws.status_text_set(text)


def clear_status(context):
    set_status(context, None)  # None restores Blender's own header / status bar


# ------------------------------------------------------------------------------------------ the session
def open_tool_session(obj, live: bool = False):
    """(session cache entry, DesignSession) of `obj` with a solved field, for live edits. ValueError (with
    what to do) when the session cannot be edited live right now: a worker owns it, its spectral basis is
    not computed (that would freeze the viewport for minutes), or in a window it must factor first (that
    starts in the background; drag again when it is done). `live`: the tool solves with
    ``solve(live=True)`` (guide edits in a region), which needs no new global factorization while the last
    solve of the same settings is there to start from."""
    if jobs.busy(obj):
        raise ValueError(f"'{obj.name}' is being solved in the background: wait for it or press Esc")
    _, entry, session = api.open_session(obj)
    if obj.nfield.solver_mode == "SPECTRAL" and not session.basis_available():
        raise ValueError(f"the spectral basis ({obj.nfield.spectral_k} eigenfields) is not computed yet: "
                         f"press Precompute in the nfield panel, or switch the solver to Exact")
    if jobs.interactive() and session.pending_work(live=live) == "factorization":
        jobs.start_later(obj.name)
        raise ValueError("preparing the solver in the background (Esc cancels): drag again when it is done")
    if session.field is None:
        api.store_result(obj, entry, session.solve())
    return entry, session


def remove_design_item(op, context, remove, key, done_message):
    """`remove(obj, key)` (an api removal), then re-solve (Live Update) or just redraw the overlay; reports
    like the other tool operators. A failed re-solve puts the removed item back."""
    return guarded_edit(op, context.active_object, lambda obj: (remove(obj, key), done_message)[1],
                        keep_design=True, solve_after=True, redraw=True)


class ModalViewportTool:
    """Mixin of the modal tools: poll for a 3D view with a mesh in object mode; the press, drag, timer,
    release and cancel handling they share; the solver session.

    A tool implements ``begin(context, obj, mouse) -> bool`` (the press: pick what it edits; False: off
    the mesh or refused, nothing happens and the press does not fall through to select / move),
    ``drag(context, obj, mouse)`` (the mouse moved at least DRAG_PIXELS from the press, or any amount
    once dragging), ``tick(context, obj)`` (a timer tick: one coalesced live solve), ``release(context, obj)``
    (left button released: True confirms (one undo step), False cancels, None keeps the tool running),
    ``restore(context, obj)`` (Esc / right-click: put everything back) and optionally ``key(context, obj,
    event)`` for other events. ``tick_seconds``: the timer's period (None: no timer)."""

    bl_options = {"REGISTER", "UNDO"}
    tick_seconds: float | None = None

    @classmethod
    def poll(cls, context):
        return poll_object(context) and context.area is not None and context.area.type == "VIEW_3D"

    def invoke(self, context, event):
        obj = context.active_object
        self._press = Vector((event.mouse_region_x, event.mouse_region_y))
        self._dragged = False
        self._timer = None
        self._obj_name = obj.name
        if not self.begin(context, obj, self._press):
            return {"CANCELLED"}
        if self.tick_seconds:
            self._timer = context.window_manager.event_timer_add(self.tick_seconds, window=context.window)
        context.window_manager.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        obj = bpy.data.objects.get(self._obj_name)
        if obj is None:
            return self._finish(context, cancelled=True)
        if event.type in {"ESC", "RIGHTMOUSE"} and event.value == "PRESS":
            self.restore(context, obj)
            return self._finish(context, cancelled=True)
        if event.type in {"MOUSEMOVE", "INBETWEEN_MOUSEMOVE"}:
            mouse = Vector((event.mouse_region_x, event.mouse_region_y))
            if self._dragged or (mouse - self._press).length >= DRAG_PIXELS:
                self._dragged = True
                self.drag(context, obj, mouse)
            return {"RUNNING_MODAL"}
        if event.type == "TIMER":
            if self._timer is not None:
                self.tick(context, obj)
            return {"RUNNING_MODAL"}
        if event.type == "LEFTMOUSE" and event.value == "RELEASE":
            confirmed = self.release(context, obj)
            if confirmed is not None:
                return self._finish(context, cancelled=not confirmed)
            return {"RUNNING_MODAL"}
        return self.key(context, obj, event)

    # what a tool may leave as it is
    def drag(self, context, obj, mouse) -> None:
        pass

    def tick(self, context, obj) -> None:
        pass

    def release(self, context, obj):
        return None

    def key(self, context, obj, event):
        return {"RUNNING_MODAL"}

    def _finish(self, context, cancelled):
        if self._timer is not None:
            context.window_manager.event_timer_remove(self._timer)
            self._timer = None
        clear_status(context)
        obj = bpy.data.objects.get(self._obj_name)
        if obj is not None:
            api.notify_overlay(obj)
        return {"CANCELLED"} if cancelled else {"FINISHED"}

    def _open_session(self, obj, live: bool = False) -> bool:
        """self._entry, self._session with a solved field; False (reported) if the design cannot be solved."""
        try:
            self._entry, self._session = open_tool_session(obj, live=live)
        except (ValueError, RuntimeError, MemoryError) as exc:
            self.report({"ERROR"}, failure_message(exc))
            return False
        return True

    def _solve_or_put_back(self, obj, live: bool = False) -> None:
        """After Esc put the design back: solve the session again (live: solve(live=True), for guide edits), or,
        if that fails, show the field from before the press."""
        try:
            result = self._session.solve(details=not live, live=live)
        except (ValueError, RuntimeError, MemoryError):
            result = self._before_result
        if result is not None:
            self._store(obj, result)

    def _store(self, obj, result) -> None:
        """A live solve of the tool's session produced `result`: record it (panel, overlay)."""
        api.store_result(obj, self._entry, result)

    def _write_attributes(self, obj):
        if obj.nfield.write_attributes and self._entry.result is not None:
            try:
                api.write_attributes(obj, self._entry.result)
            except ValueError as exc:
                self.report({"WARNING"}, str(exc))


class DeleteUnderCursor:
    """Mixin of the tools' delete operators (X / Del): remove the design item under the cursor, or the one
    the operator's property `key_property` names (-1: under the cursor), then re-solve. A tool's operator
    sets ``collection`` (the ``obj.nfield`` collection it edits), ``remove`` (the api removal),
    ``messages`` (nothing under the cursor, done with "{}" for the key) and ``under_cursor(context, obj,
    mouse, arrays)``."""

    bl_options = {"REGISTER", "UNDO"}
    collection = key_property = ""
    messages = ("", "")

    @classmethod
    def poll(cls, context):
        return poll_object(context) and len(getattr(context.active_object.nfield, cls.collection)) > 0

    def invoke(self, context, event):
        obj = context.active_object
        key = self.under_cursor(context, obj, (event.mouse_region_x, event.mouse_region_y),
                                mesh_read.mesh_arrays(obj))
        if key is None:
            self.report({"INFO"}, self.messages[0])
            return {"CANCELLED"}
        setattr(self, self.key_property, key)
        return self.execute(context)

    def execute(self, context):
        key = getattr(self, self.key_property)
        return remove_design_item(self, context, type(self).remove, key, self.messages[1].format(key))


def delete_operator(name: str, doc: str, idname: str, label: str, collection: str, key: str, key_doc: str,
                    remove, messages: tuple[str, str], under_cursor):
    """A tool's delete operator class (see DeleteUnderCursor); `key` names its IntProperty ("face" ...)."""
    return type(name, (DeleteUnderCursor, Operator), {
        "__doc__": doc, "bl_idname": idname, "bl_label": label, "collection": collection, "key_property": key,
        "remove": staticmethod(remove), "messages": messages, "under_cursor": staticmethod(under_cursor),
        "__annotations__": {key: IntProperty(name=key.title(), default=-1, min=-1, description=key_doc)}})
