"""Viewport overlay of the designed field (gpu module; Blender 3.4 and 4.2-5.0).

What is drawn, per mesh object with an nfield design (``obj.nfield``):

* **glyphs**: the n directions of the field on a subset of faces spread evenly *on screen* (about
  ``GLYPH_SPACING_PX`` / sqrt(``glyph_density``) pixels apart, at most ``GLYPH_CAP``; see
  ``glyphs.sample_on_screen``), as short line segments through the face centroids (even n: n/2 segments
  centred on the centroid, one per pair of opposite directions; odd n: n half-segments starting at the
  centroid, with arrowheads). Half-length = 0.4 x the local glyph spacing (the face's mean edge length, or
  the sample's cell size where that is larger) x ``glyph_scale``. Zooming in shows more glyphs, closer
  together on the surface; zooming out fewer;
* **constraint arrows**: thicker, orange, from the face centroid along the constraint direction, with a head;
  at least ``MIN_ARROW_PX`` pixels long on screen (object-space length stretched up to ``MAX_ARROW_STRETCH``
  times; see :func:`constraint_arrows` for picking them);
* **singularity markers**: points at the singular vertices, red for positive and blue for negative index;
  singularities pinned by the user are drawn larger with a white rim;

Everything is built in **object space** and drawn with the object's ``matrix_world`` pushed on the gpu matrix
stack, so the overlay follows the object's transform without any rebuild.

Performance contract
--------------------
Batches are built in :func:`refresh` (called by ``results.store_result`` after every solve and by the
interactive tools), or in a one-shot timer when a display setting changed -- **never in the draw callback**, which only
binds a shader and draws prebuilt ``GPUBatch`` objects. Each object has a version counter (Python memory,
:func:`tag_changed`); the draw callback compares it with the version the batches were built from and only
*schedules* a rebuild when they differ.

The glyphs and the arrows depend on the view, so each 3D view region (keyed by its pointer; a quad view has
four) has batches of its own. The draw callback records the region's view (size, perspective, the object's
transform) and, when it differs from the one the region's batches were built for, schedules their rebuild
in a timer ``VIEW_DELAY`` seconds later: while the user orbits or zooms, at most one rebuild per delay, for
the latest view, and the previous batches are drawn meanwhile.

Geometry (centroids, normals, edge lengths, vertex normals) comes from ``mesh_read.overlay_geometry``,
keyed by the mesh signature like everything else that reads the mesh.

Subsampling: a deterministic spatial hash picks one face per grid cell, the cells sized from the view. The
sample depends on the mesh geometry, the density, which faces have a field and the view, so it is cached per
region and reused by every later solve: a live re-solve only gathers the directions of the sampled faces and
re-uploads one vertex buffer.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import bpy
import gpu
import numpy as np
from gpu_extras.batch import batch_for_shader

from . import mesh_read, session_cache
from .glyphs import (
    constraint_arrow_segments, glyph_segments, pixels_per_unit, sample_on_screen, screen_min_length,
)

__all__ = ["GLYPH_CAP", "GLYPH_SPACING_PX", "register", "unregister", "refresh", "tag_changed", "forget",
           "results_reset", "last_build_stats", "view_stats", "constraint_arrows"]

#: the most glyphs drawn on one object in one view
GLYPH_CAP = 20000
#: glyph spacing on screen at glyph_density 1 (pixels); density d spaces them GLYPH_SPACING_PX / sqrt(d)
GLYPH_SPACING_PX = 12.0
#: seconds between a view change and the rebuild of the view's glyphs and arrows (coalesces navigation)
VIEW_DELAY = 0.1

COLOR_GLYPH = (0.05, 0.05, 0.05, 0.9)
COLOR_GLYPH_ON_DARK = (0.95, 0.95, 0.95, 0.9)
COLOR_CONSTRAINT = (1.0, 0.55, 0.0, 1.0)
COLOR_SING_POS = (0.9, 0.1, 0.1, 1.0)
COLOR_SING_NEG = (0.1, 0.3, 1.0, 1.0)
COLOR_RIM = (1.0, 1.0, 1.0, 1.0)
COLOR_PICK = (1.0, 1.0, 0.0, 1.0)

#: a constraint arrow is drawn at least this long on screen (stretched up to MAX_ARROW_STRETCH x its length)
MIN_ARROW_PX = 48.0
MAX_ARROW_STRETCH = 8.0

WIDTH_GLYPH = 1.5
WIDTH_CONSTRAINT = 4.0
POINT_SINGULARITY = 10.0
POINT_PINNED = 16.0


# ================================================================================= per-object batches
@dataclass
class _View:
    """One 3D view region's batches of one object: they depend on the view."""
    key: tuple  # region size, perspective matrix and object transform (rounded) the view was recorded with
    size: tuple  # (width, height) pixels
    mvp: np.ndarray  # object space -> clip space
    built: Any = None  # (key, state.built) the batches were made for
    batches: dict = field(default_factory=dict)  # "glyphs", "constraints"
    arrows: dict = field(default_factory=dict)  # face -> (tail, tip) object space, as drawn
    sample: Any = None  # (sample key, faces, cell sizes)
    stats: dict = field(default_factory=dict)
    used: float = 0.0  # time of the last draw (the least recently drawn region is dropped first)


@dataclass
class _State:
    version: int = 0
    built: Any = None  # (version, settings key) the batches were built from
    batches: dict = field(default_factory=dict)  # name -> GPUBatch (the view-independent ones)
    result: Any = None  # last FieldResult handed over by refresh()/tag_changed()
    stats: dict = field(default_factory=dict)
    geo: Any = None  # the overlay geometry of the last full build (view rebuilds reuse it: no mesh read)
    directions: Any = None  # (P, n, 3) field directions of the last full build, None without a field
    views: dict = field(default_factory=dict)  # region pointer -> _View


#: regions remembered per object (a quad view has four; closed areas leave stale entries behind)
MAX_VIEWS = 8

_states: dict[str, _State] = {}
_handle = None
_pending: set[str] = set()
_pending_views: set[tuple[str, int]] = set()
_shaders: dict[str, Any] = {}
_last_stats: dict = {}


def last_build_stats() -> dict:
    """Timings (seconds) and counts of the most recent batch build (for tests and the panel)."""
    return dict(_last_stats)


def _shader(kind: str):
    """Builtin shaders by role, with the Blender 3.4 names as fallbacks. kind: 'line' | 'flat' | 'point'."""
    if kind in _shaders:
        return _shaders[kind]
    names = {
        "line": ("POLYLINE_UNIFORM_COLOR", "3D_POLYLINE_UNIFORM_COLOR", "UNIFORM_COLOR", "3D_UNIFORM_COLOR"),
        "point": ("POINT_UNIFORM_COLOR", "UNIFORM_COLOR", "3D_UNIFORM_COLOR"),
    }[kind]
    sh = None
    for name in names:
        try:
            sh = (gpu.shader.from_builtin(name), name)
            break
        except (ValueError, TypeError):
            continue
    _shaders[kind] = sh
    return sh


def _session_version(obj) -> int:
    """The session cache's result counter for ``obj`` (bumped on every solve), -1 if none. Cheap."""
    entry = session_cache.get_entry_cached(obj)
    return -1 if entry is None else int(entry.version)


def _built_key(obj, state) -> tuple:
    return (state.version, _session_version(obj), _settings_key(obj))


def _settings_key(obj) -> tuple:
    s = obj.nfield
    return (round(float(s.glyph_density), 4), round(float(s.glyph_scale), 4), s.symmetry)


def _field_for(obj, state: _State, geo: mesh_read.OverlayGeometry, n: int) -> np.ndarray | None:
    """(P, n, 3) object-space unit directions per polygon, or None when no field is known yet."""
    res = state.result
    if res is None:
        res = session_cache.get_result(obj)
    if res is not None:
        try:
            dirs = res.all_directions()
            if dirs is not None and dirs.shape[0] == len(geo.centroids):
                return np.asarray(dirs, dtype=np.float32)
        except Exception:  # noqa: BLE001 - a stale result object: fall back to the attribute
            pass
    return _field_from_attribute(obj, geo, n)


def _field_from_attribute(obj, geo: mesh_read.OverlayGeometry, n: int) -> np.ndarray | None:
    """The persisted output attribute (first direction per face), fanned out to the n directions by
    rotating about the face normal in steps of 2 pi / n (display only: used after a reload, before the
    session has re-solved)."""
    d = mesh_read.attribute_values(obj, obj.nfield.direction_attribute, "FACE", "FLOAT_VECTOR")
    num_polys = len(geo.centroids)
    if d is None or num_polys == 0:
        return None
    perp = np.cross(geo.normals, d)
    out = np.empty((num_polys, n, 3), dtype=np.float32)
    for j in range(n):
        a = 2.0 * np.pi * j / n
        out[:, j, :] = np.cos(a) * d + np.sin(a) * perp
    return out


def _singularities_for(obj, state: _State) -> list[tuple[int, float]]:
    res = state.result if state.result is not None else session_cache.get_result(obj)
    if res is not None and getattr(res, "singularities", None) is not None:
        return [(int(v), float(i)) for v, i in res.singularities]
    vals = mesh_read.attribute_values(obj, obj.nfield.singularity_attribute, "POINT", "FLOAT")
    if vals is None:
        return []
    nz = np.flatnonzero(vals != 0.0)
    return [(int(v), float(vals[v])) for v in nz]


def _build(obj, arrays: mesh_read.MeshArrays | None = None) -> None:
    """(Re)build every batch of ``obj`` from the current field and design: the view-independent ones and those
    of every view region it was drawn in. Not called from draw. `arrays`: the mesh read the caller just made
    (see refresh), else the mesh is read here."""
    state = _states.setdefault(obj.name, _State())
    t0 = time.perf_counter()
    s = obj.nfield
    geo = mesh_read.overlay_geometry(obj, arrays)
    t_geo = time.perf_counter()
    fld = _field_for(obj, state, geo, s.n) if len(geo.centroids) else None
    t_field = time.perf_counter()
    state.geo, state.directions = geo, fld
    state.batches = _singularity_batches(obj, state, geo)
    state.built = _built_key(obj, state)
    for view in list(state.views.values()):
        _build_view(obj, state, view)
    t_end = time.perf_counter()
    state.stats = {"faces": len(geo.centroids), "geometry_s": t_geo - t0, "field_s": t_field - t_geo,
                   "total_s": t_end - t0}
    _last_stats.clear()
    _last_stats.update(state.stats, object=obj.name)


def _singularity_batches(obj, state: _State, geo) -> dict:
    """The singularity markers (they do not depend on the view)."""
    point = _shader("point")
    batches = {}
    sings = _singularities_for(obj, state)
    nv = len(geo.positions)
    scale = float(np.median(geo.edge_len)) if len(geo.edge_len) else 0.0
    for name, sel in (("sing_pos", lambda i: i > 0), ("sing_neg", lambda i: i < 0)):
        vs = [v for v, i in sings if sel(i) and v < nv]
        if vs:
            vi = np.array(vs, dtype=np.int64)
            p = geo.positions[vi] + geo.vnormals[vi] * (0.05 * scale)
            batches[name] = batch_for_shader(point[0], "POINTS", {"pos": np.ascontiguousarray(p, np.float32)})
    s = obj.nfield
    pin_list = [sg.vertex for sg in s.singularities if not sg.stale and sg.vertex < nv]
    if pin_list:
        vi = np.array(pin_list, dtype=np.int64)
        p = geo.positions[vi] + geo.vnormals[vi] * (0.05 * scale)
        p = np.ascontiguousarray(p, np.float32)
        batches["pinned_rim"] = batch_for_shader(point[0], "POINTS", {"pos": p})
        sign = {sg.vertex: sg.numerator for sg in s.singularities}
        for name, pos in (("pinned_pos", True), ("pinned_neg", False)):
            sel = [k for k, v in enumerate(pin_list) if (sign[v] > 0) == pos]
            if sel:
                batches[name] = batch_for_shader(point[0], "POINTS", {"pos": p[sel]})
    return batches


def _glyph_spacing_px(obj) -> float:
    return GLYPH_SPACING_PX / np.sqrt(max(float(obj.nfield.glyph_density), 1e-4))


def _build_view(obj, state: _State, view: _View) -> None:
    """The glyphs and constraint arrows of ``obj`` for one view region (from state.geo / state.directions)."""
    t0 = time.perf_counter()
    geo, fld = state.geo, state.directions
    batches: dict[str, Any] = {}
    n_glyphs = 0
    if geo is not None and fld is not None:
        valid = np.any(fld[:, 0, :] != 0.0, axis=1)
        spacing_px = _glyph_spacing_px(obj)
        skey = (view.key, geo.signature, round(spacing_px, 4), int(valid.sum()))
        if view.sample is None or view.sample[0] != skey:
            view.sample = (skey, *sample_on_screen(geo.centroids, geo.normals, view.mvp, view.size, spacing_px,
                                                   GLYPH_CAP, valid))
        _key, faces, cells = view.sample
        t_sample = time.perf_counter()
        local = np.maximum(geo.edge_len[faces], 0.8 * cells)
        half = 0.4 * local * float(obj.nfield.glyph_scale)
        verts = glyph_segments(geo.centroids[faces], geo.normals[faces], half, fld[faces], 0.02 * local)
        n_glyphs = len(faces)
        if len(verts):
            batches["glyphs"] = batch_for_shader(_shader("line")[0], "LINES", {"pos": verts})
        view.stats = {"glyphs": n_glyphs, "spacing_px": spacing_px,
                      "median_cell": float(np.median(cells)) if len(cells) else 0.0,
                      "sample_s": t_sample - t0}
    else:
        view.stats = {"glyphs": 0}
    if geo is not None:
        batches.update(_arrow_batches(obj, view, geo))
    view.batches = batches
    view.built = (view.key, state.built)
    view.stats["total_s"] = time.perf_counter() - t0
    _last_stats.update(glyphs=n_glyphs, view_s=view.stats["total_s"])


def _arrow_batches(obj, view: _View, geo) -> dict:
    """The constraint arrows' batch (and view.arrows) for one view: at least MIN_ARROW_PX long on screen."""
    s = obj.nfield
    num_polys = len(geo.centroids)
    view.arrows = {}
    cons = [(c.face, tuple(c.direction)) for c in s.constraints if not c.stale and c.face < num_polys]
    if not cons:
        return {}
    faces_c = np.array([f for f, _ in cons], dtype=np.int64)
    d = np.array([v for _, v in cons], dtype=np.float64)
    nrm = geo.normals[faces_c].astype(np.float64)
    d = d - nrm * np.sum(d * nrm, axis=1, keepdims=True)
    ok = np.linalg.norm(d, axis=1) > 0
    d[ok] /= np.linalg.norm(d[ok], axis=1, keepdims=True)
    speed = pixels_per_unit(geo.centroids[faces_c], view.mvp, view.size)
    cell = np.where(speed > 0, _glyph_spacing_px(obj) / np.maximum(speed, 1e-30), 0.0)
    local = np.maximum(geo.edge_len[faces_c], 0.8 * cell)  # as long as the glyphs around it, at least
    org = geo.centroids[faces_c] + nrm * (0.04 * local)[:, None]
    length = screen_min_length(org, d, 1.6 * local * float(s.glyph_scale), view.mvp, view.size, MIN_ARROW_PX,
                               MAX_ARROW_STRETCH)
    view.arrows = {int(f): (org[i].copy(), org[i] + d[i] * length[i]) for i, f in enumerate(faces_c) if ok[i]}
    verts = constraint_arrow_segments(org[ok], nrm[ok], d[ok], length[ok])
    return {"constraints": batch_for_shader(_shader("line")[0], "LINES", {"pos": verts})} if len(verts) else {}


def constraint_arrows(obj, region=None) -> dict:
    """face -> (tail, tip) in object space of the constraint arrows as drawn in `region` (for picking; None or
    a region not drawn yet: the region drawn last)."""
    state = _states.get(getattr(obj, "name", ""))
    if state is None or not state.views:
        return {}
    view = state.views.get(region.as_pointer()) if region is not None else None
    if view is None:
        view = max(state.views.values(), key=lambda v: v.used)
    return dict(view.arrows)


def view_stats(obj) -> list[dict]:
    """Per view region the object was drawn in: glyph count, spacing on screen (pixels), median cell size
    (object units), build seconds; the most recently drawn first (for tests and benchmarks)."""
    state = _states.get(getattr(obj, "name", ""))
    views = [] if state is None else sorted(state.views.values(), key=lambda v: -v.used)
    return [dict(v.stats, size=v.size) for v in views]


def _view_key(region, rv3d, obj) -> tuple:
    m = rv3d.perspective_matrix
    w = obj.matrix_world
    return (region.width, region.height, tuple(round(m[i][j], 6) for i in range(4) for j in range(4)),
            tuple(round(w[i][j], 6) for i in range(3) for j in range(4)))


def _can_draw() -> bool:
    return not bpy.app.background


def _mark_changed(obj, result) -> None:
    """Bump the object's version (its batches are rebuilt before the next draw); keep `result` if given."""
    state = _states.setdefault(obj.name, _State())
    if result is not None:
        state.result = result
    state.version += 1


def refresh(obj, result=None, arrays: mesh_read.MeshArrays | None = None) -> None:
    """The field or design of ``obj`` changed (call after every solve / edit): rebuild its batches now and
    redraw. ``result``: the new FieldResult (else the session cache's or the output attribute is used).
    ``arrays``: the mesh read the result was solved on, if the caller holds it: a live drag rebuilds the
    batches after every solve, and reading the mesh again each time would cost more than the drawing (the
    signature of that read still decides whether the overlay's geometry is current)."""
    if obj is None or obj.type != "MESH":
        return
    _mark_changed(obj, result)
    if _can_draw():
        _build(obj, arrays)
        _tag_redraw()


def tag_changed(obj, result=None) -> None:
    """Cheaper variant of :func:`refresh`: bump the version; the rebuild happens in a timer before the
    next draw (use when several changes happen in one go)."""
    if obj is None:
        return
    _mark_changed(obj, result)
    _schedule(obj.name)


def forget(obj_or_name=None) -> None:
    """Drop the cached batches of one object (or all): e.g. on file load or when the mesh changed."""
    if obj_or_name is None:
        _states.clear()
    else:
        _states.pop(getattr(obj_or_name, "name", obj_or_name), None)


def results_reset() -> None:
    """Undo/redo restored the designs: forget the results handed over and rebuild every object's batches
    from its design and whatever field the session cache or the attributes hold (before the next draw)."""
    for name, st in list(_states.items()):
        st.result = None
        st.version += 1
        _schedule(name)


def _schedule(name: str) -> None:
    if not _can_draw() or name in _pending:
        return
    _pending.add(name)
    if not bpy.app.timers.is_registered(_rebuild_pending):
        bpy.app.timers.register(_rebuild_pending, first_interval=0.0)


def _schedule_view(name: str, region_ptr: int) -> None:
    """Rebuild one region's view batches of object `name` in VIEW_DELAY seconds (coalesced)."""
    _pending_views.add((name, region_ptr))
    if not bpy.app.timers.is_registered(_rebuild_views):
        bpy.app.timers.register(_rebuild_views, first_interval=VIEW_DELAY)


def _rebuild_pending():
    names = list(_pending)
    _pending.clear()
    for name in names:
        obj = bpy.data.objects.get(name)
        if obj is not None and obj.type == "MESH" and hasattr(obj, "nfield"):
            try:
                _build(obj)
            except Exception as exc:  # noqa: BLE001 - never break the UI; report in the console
                print(f"nfield overlay: cannot build overlay for {name!r}: {exc}")
                state = _states.setdefault(name, _State())
                state.batches, state.directions = {}, None
                for view in state.views.values():
                    view.batches = {}
                state.built = _built_key(obj, state)
    _tag_redraw()
    return None


def _rebuild_views():
    """The views some regions were drawn with changed: rebuild those regions' glyphs and arrows (for the
    view each region was last drawn with)."""
    pending = list(_pending_views)
    _pending_views.clear()
    for name, ptr in pending:
        obj = bpy.data.objects.get(name)
        state = _states.get(name)
        view = None if state is None else state.views.get(ptr)
        if obj is None or view is None or state.geo is None or view.built == (view.key, state.built):
            continue
        try:
            _build_view(obj, state, view)
        except Exception as exc:  # noqa: BLE001 - never break the UI
            print(f"nfield overlay: cannot build the view of {name!r}: {exc}")
            view.batches = {}
            view.built = (view.key, state.built)
    _tag_redraw()
    return None


def _tag_redraw() -> None:
    wm = bpy.context.window_manager
    if wm is None:
        return
    for win in wm.windows:
        for area in win.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


def _has_design(obj) -> bool:
    s = obj.nfield
    return bool(len(s.constraints) or len(s.singularities) or obj.data.attributes.get(s.direction_attribute)
                or obj.name in _states)


# ----------------------------------------------------------------------------------------------- drawing
def _draw_lines(batch, shader_pair, color, width, region):
    shader, name = shader_pair
    shader.bind()
    if "POLYLINE" in name:
        shader.uniform_float("viewportSize", (region.width, region.height))
        shader.uniform_float("lineWidth", width)
    else:
        gpu.state.line_width_set(width)
    shader.uniform_float("color", color)
    batch.draw(shader)


def _draw_points(batch, shader_pair, color, size):
    shader, _ = shader_pair
    gpu.state.point_size_set(size)
    shader.bind()
    shader.uniform_float("color", color)
    batch.draw(shader)


def _draw_callback():
    """Draw prebuilt batches only (no geometry work here: a missing/outdated batch schedules a rebuild)."""
    context = bpy.context
    region = context.region
    if region is None:
        return
    objects = [o for o in context.visible_objects if o.type == "MESH"]
    if not objects:
        return
    gpu.state.depth_test_set("LESS_EQUAL")
    gpu.state.blend_set("ALPHA")
    try:
        line = _shader("line")
        point = _shader("point")
        for obj in objects:
            state = _states.get(obj.name)
            if state is None:
                if _has_design(obj):
                    _states[obj.name] = _State(version=1)
                    _schedule(obj.name)
                continue
            s = obj.nfield
            if state.built != _built_key(obj, state):
                _schedule(obj.name)  # keep drawing the previous batches meanwhile
            view = _region_view(obj, state, region, context.region_data)
            b = state.batches
            vb = {} if view is None else view.batches
            if not b and not vb:
                continue
            gpu.matrix.push()
            gpu.matrix.multiply_matrix(obj.matrix_world)
            try:
                if s.show_field and "glyphs" in vb:
                    dark = _dark_background(context)
                    _draw_lines(vb["glyphs"], line, COLOR_GLYPH_ON_DARK if dark else COLOR_GLYPH, WIDTH_GLYPH,
                                region)
                if s.show_constraints and "constraints" in vb:
                    _draw_lines(vb["constraints"], line, COLOR_CONSTRAINT, WIDTH_CONSTRAINT, region)
                if s.show_singularities:
                    if "pinned_rim" in b:
                        _draw_points(b["pinned_rim"], point, COLOR_RIM, POINT_PINNED + 4)
                    for key, col, size in (("pinned_pos", COLOR_SING_POS, POINT_PINNED),
                                           ("pinned_neg", COLOR_SING_NEG, POINT_PINNED),
                                           ("sing_pos", COLOR_SING_POS, POINT_SINGULARITY),
                                           ("sing_neg", COLOR_SING_NEG, POINT_SINGULARITY)):
                        if key in b:
                            _draw_points(b[key], point, col, size)
            finally:
                gpu.matrix.pop()
    finally:
        gpu.state.depth_test_set("NONE")
        gpu.state.blend_set("NONE")
        gpu.state.line_width_set(1.0)
        gpu.state.point_size_set(1.0)


def _region_view(obj, state: _State, region, rv3d) -> _View | None:
    """The region's view record for `obj` (cheap: compares the rounded matrices). When the view changed since
    its batches were built, records the new one and schedules their rebuild (in a timer, never here)."""
    if rv3d is None:
        return None
    ptr = region.as_pointer()
    key = _view_key(region, rv3d, obj)
    view = state.views.get(ptr)
    if view is None or view.key != key:
        mvp = np.asarray(rv3d.perspective_matrix, dtype=np.float64) @ np.asarray(obj.matrix_world, dtype=np.float64)
        if view is None:
            view = _View(key=key, size=(region.width, region.height), mvp=mvp)
            state.views[ptr] = view
            if len(state.views) > MAX_VIEWS:
                oldest = min(state.views, key=lambda p: state.views[p].used)
                state.views.pop(oldest)
        else:
            view.key, view.size, view.mvp = key, (region.width, region.height), mvp
        _schedule_view(obj.name, ptr)
    view.used = time.perf_counter()
    return view


def _dark_background(context) -> bool:
    """Glyph colour contrast: light glyphs when the object is drawn dark (e.g. in wireframe/X-ray)."""
    shading = getattr(context.space_data, "shading", None)
    return shading is not None and shading.type == "WIREFRAME"


def register():
    """Add the draw callback (not in background Blender: nothing is drawn there)."""
    global _handle
    if bpy.app.background or _handle is not None:
        return
    _handle = bpy.types.SpaceView3D.draw_handler_add(_draw_callback, (), "WINDOW", "POST_VIEW")


def unregister():
    global _handle
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
        _handle = None
    for fn in (_rebuild_pending, _rebuild_views):
        if bpy.app.timers.is_registered(fn):
            bpy.app.timers.unregister(fn)
    _states.clear()
    _shaders.clear()
    _pending.clear()
    _pending_views.clear()
