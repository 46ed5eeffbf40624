"""The comb tool: paint guide directions by dragging over the surface (3D view, object mode), like Instant
Meshes' orientation comb.

* ``nfield.comb_tool`` (modal): press on the mesh and drag. The drag leaves samples (a surface point and the
  drag direction there) at most a quarter of the brush radius apart along the path, so a fast drag leaves
  no gaps; the
  faces within the brush radius of a sample take its direction with the brush's falloff and strength
  (``DesignSession`` comb strokes, docs/guides.md section 4). The samples go into one comb stroke of the
  session (``begin_comb_stroke`` / ``extend_comb_stroke``): after every timer tick the comb field is that of
  one stroke of all the samples so far, and the field follows the brush live (``solve(live=True)``: the
  changed faces are solved exactly in a region, the rest held). Release: the stroke is stored in the comb
  face attributes (one undo step), and the global solve runs in the background once the brush pauses (it
  writes the output attributes).
  Esc / right-click: the comb field and the field go back to before the stroke. A press off the mesh does
  nothing; a path that leaves the mesh continues where it comes back. With mirror symmetry on, every sample
  is mirrored onto the other side in the same stroke (samples on faces without a partner: the header says
  so).
* The brush settings are the operator's properties: the tool header shows them (the toolbar entry's
  ``draw_settings``), and Blender passes them to the operator on each press. The radius is in screen pixels
  (as Blender's own brushes) and becomes an object-space radius at the pressed point.
* :func:`draw_cursor`: the brush circle around the mouse while the tool is active (the toolbar entry's
  cursor callback).
"""
from __future__ import annotations

import math
import time

from bpy.props import EnumProperty, FloatProperty, IntProperty
from bpy.types import Operator
from bpy_extras import view3d_utils
from gpu_extras.presets import draw_circle_2d
from mathutils import Vector

from . import api, jobs, mesh_read
from .choices import COMB_FALLOFF_ITEMS
from .operator_base import failure_message
from .tool_common import ModalViewportTool, last_press, ray_cast, set_status

#: samples along the drag path, every this fraction of the brush radius
SAMPLE_SPACING = 0.25
#: the global solve starts in the background once the brush has rested this long (seconds)
IDLE_SECONDS = 0.75
#: the brush circle's colour (RGBA)
CURSOR_COLOR = (1.0, 0.85, 0.3, 0.9)

#: the last stroke (object-space radius, samples, faces changed, live solve times in ms): for scripted checks
last_stroke: dict = {}


def object_radius(context, obj, location, pixels: float) -> float:
    """The object-space length that `pixels` spans on screen at `location` (object space), measured across
    the view (non-uniform scale: along the screen's x direction)."""
    region, rv3d = context.region, context.region_data
    mw = obj.matrix_world
    world = mw @ location
    centre = view3d_utils.location_3d_to_region_2d(region, rv3d, world)
    if centre is None:
        return 0.0
    side = view3d_utils.region_2d_to_location_3d(region, rv3d, centre + Vector((pixels, 0.0)), world)
    return (mw.inverted_safe().to_3x3() @ (side - world)).length


class NFIELD_OT_comb_tool(ModalViewportTool, Operator):
    """Drag over the surface to comb the field: paint guide directions within the brush radius"""

    bl_idname = "nfield.comb_tool"
    bl_label = "Comb Field"
    tick_seconds = 1.0 / 30.0  # live solves: one per tick for the samples the drag left since the last one

    radius: IntProperty(name="Radius", default=50, min=2, max=1000, subtype="PIXEL",
                        description="Brush radius on screen (pixels)")
    strength: FloatProperty(name="Strength", default=1.0, min=0.01, max=1.0, subtype="FACTOR",
                            description="How strongly a stroke paints its direction (1: overwrites)")
    falloff: EnumProperty(name="Falloff", items=COMB_FALLOFF_ITEMS, default="smooth",
                          description="How the brush's influence falls off towards its rim")

    def begin(self, context, obj, mouse) -> bool:
        arrays = mesh_read.mesh_arrays(obj)
        hit = ray_cast(context, obj, mouse, arrays)
        last_press.clear()
        last_press.update(tool="comb", mouse=list(mouse), object=obj.name, face=None if hit is None else hit[2])
        if hit is None or not self._open_session(obj, live=True):
            return False  # off the mesh: nothing (a cancelled keymap operator ends the event's handling)
        radius = object_radius(context, obj, hit[0], self.radius)
        diagonal = float(self._entry.mesh.native.bounding_box_diagonal)
        if not radius > 0 or not diagonal > 0:
            self.report({"ERROR"}, "the brush radius cannot be measured in this view")
            return False
        try:
            self._session.begin_comb_stroke(min(1.0, radius / diagonal), self.falloff, self.strength)
        except ValueError as exc:
            self.report({"ERROR"}, failure_message(exc))
            return False
        jobs.interacting(obj.name, True)
        self._spacing = SAMPLE_SPACING * radius
        self._last = hit[0].copy()  # the last sample's point (object space); None after the path left the mesh
        self._first = True          # the press point becomes a sample once the drag gives it a direction
        self._points: list = []     # samples the session has not had yet
        self._directions: list = []
        self._num_samples = 0
        self._solved = False
        self._note = ""
        self._solve_ms: list = []
        self._before_result = self._entry.result
        last_stroke.clear()
        last_stroke.update(object=obj.name, radius=radius, radius_fraction=radius / diagonal, samples=0)
        set_status(context, f"Comb: drag over the surface (radius {self.radius} px, strength {self.strength:.2f}, "
                            f"{self.falloff}) | release to keep the stroke, Esc/RMB to cancel")
        return True

    def drag(self, context, obj, mouse):
        hit = ray_cast(context, obj, mouse, self._entry.arrays)
        if hit is None:
            self._last = None  # off the mesh: the path continues where it comes back
            return
        if self._last is None:
            self._last, self._first = hit[0].copy(), True
            return
        step = hit[0] - self._last
        length = step.length
        if length < self._spacing:
            return
        count = max(1, math.ceil(length / self._spacing))  # samples at most SAMPLE_SPACING radii apart
        direction = tuple(step / length)
        start = 0 if self._first else 1
        for i in range(start, count + 1):
            self._points.append(tuple(self._last + step * (i / count)))
            self._directions.append(direction)
        self._first = False
        self._last = hit[0].copy()

    def tick(self, context, obj):
        if self._points:
            self._apply(context, obj)

    def _apply(self, context, obj) -> None:
        """Give the new samples (and their mirror images) to the stroke and solve live."""
        t0 = time.perf_counter()
        try:
            points, directions, note = api.comb_samples(self._session, self._points, self._directions)
            self._session.extend_comb_stroke(points, directions)
            self._num_samples += len(self._points)
            self._points, self._directions = [], []
            result = self._session.solve(details=False, live=True)
        except (ValueError, RuntimeError, MemoryError) as exc:
            self._points, self._directions = [], []
            self.report({"WARNING"}, failure_message(exc))
            return
        self._solved = True
        self._note = note or self._note
        self._store(obj, result)
        ms = (time.perf_counter() - t0) * 1e3
        self._solve_ms.append(ms)
        region = f", region {result.live_region:,} faces" if result.live_region else ""
        set_status(context, f"Comb: {self._num_samples} samples, live solve {ms:.0f} ms{region} | release to keep "
                            f"the stroke, Esc/RMB to cancel" + (f" | {self._note}" if self._note else ""))

    def release(self, context, obj):
        if self._points:
            self._apply(context, obj)
        if not self._num_samples:  # a click without a drag has no direction: nothing, no undo step
            self._session.cancel_comb_stroke()
            return False
        changed = self._session.end_comb_stroke()
        try:
            api.store_comb(obj, self._session)  # the comb attributes: this operator's undo step
        except (ValueError, RuntimeError) as exc:
            self.report({"ERROR"}, failure_message(exc))
            return False
        last_stroke.update(samples=self._num_samples, changed=int(len(changed)), solve_ms=list(self._solve_ms),
                           note=self._note)
        if jobs.interactive() and self._session.pending_work() == "factorization":
            jobs.start_when_idle(obj.name, IDLE_SECONDS)
        self.report({"INFO"}, f"nfield: comb stroke of {self._num_samples} samples changed {len(changed)} faces"
                              + (f" ({self._note})" if self._note else ""))
        return True

    def restore(self, context, obj):
        self._session.cancel_comb_stroke()
        if not self._solved:
            return  # the field never changed
        self._solve_or_put_back(obj, live=True)
        if jobs.interactive() and self._session.pending_work() == "factorization":
            jobs.start_when_idle(obj.name, IDLE_SECONDS)

    def _finish(self, context, cancelled):
        jobs.interacting(self._obj_name, False)  # whatever ended the stroke (release, Esc, the object deleted)
        if self._session.comb_stroke_active:
            self._session.cancel_comb_stroke()
        return super()._finish(context, cancelled)


def draw_cursor(_context, tool, xy) -> None:
    """The brush circle around the mouse, with the radius of the tool's settings (Blender calls this with
    the mouse position, in the space it set up for cursors, whenever the cursor is drawn)."""
    try:
        radius = float(tool.operator_properties(NFIELD_OT_comb_tool.bl_idname).radius)
    except (AttributeError, TypeError, ValueError):
        return
    if radius > 0 and math.isfinite(radius):
        draw_circle_2d((float(xy[0]), float(xy[1])), CURSOR_COLOR, radius, segments=48)


classes = (NFIELD_OT_comb_tool,)
