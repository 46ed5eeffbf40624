"""Viewport overlay of the designed field (gpu module; Blender 3.4 and 4.2-5.0).

What is drawn, per mesh object with an nfield design (``obj.nfield``):

* **glyphs**: the n directions of the field on an evenly spread subset of faces, as short line segments
  through the face centroids (even n: n/2 segments centred on the centroid, one per pair of opposite
  directions; odd n: n half-segments starting at the centroid). Half-length = 0.4 x the local glyph spacing
  (the face's mean edge length, or the sample spacing when the mesh is subsampled) x ``glyph_scale``;
* **constraint arrows**: thicker, orange, from the face centroid along the constraint direction, with a head;
  at least ``MIN_ARROW_PX`` pixels long on screen (object-space length stretched up to ``MAX_ARROW_STRETCH``
  times; rebuilt in a timer when the view changes, see :func:`constraint_arrows` for picking them);
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

Geometry (centroids, normals, edge lengths, vertex normals) comes from ``mesh_read.overlay_geometry``,
keyed by the mesh signature like everything else that reads the mesh.

Subsampling: at most ``GLYPH_BUDGET`` x ``glyph_density`` glyphs (budget 20 000). When the mesh has more faces,
a deterministic spatial hash picks one face per grid cell (the face whose centroid is closest to the cell's
centre; cell size from the surface area, adjusted so the count is close to the target). The sample only
depends on the mesh geometry and the density, so it is cached and reused by every later solve: a live
re-solve only gathers the directions of the sampled faces and re-uploads one vertex buffer.
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
from .glyphs import constraint_arrow_segments, glyph_segments, sample_faces, screen_min_length

__all__ = ["GLYPH_BUDGET", "register", "unregister", "refresh", "tag_changed", "forget", "results_reset",
           "last_build_stats"]

#: the most glyphs drawn on one object (glyph_density scales it)
GLYPH_BUDGET = 20000

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
class _State:
    version: int = 0
    built: Any = None  # (version, settings key) the batches were built from
    batches: dict = field(default_factory=dict)  # name -> GPUBatch
    result: Any = None  # last FieldResult handed over by refresh()/tag_changed()
    samples: dict = field(default_factory=dict)  # (mesh signature, target, faces with a field) -> glyph faces
    stats: dict = field(default_factory=dict)
    spacing: float = 0.0  # glyph sample spacing of the last build (arrow lengths follow it)
    view: Any = None  # (key, width, height, perspective matrix) of the view the arrows were last sized for
    arrows: dict = field(default_factory=dict)  # face -> (tail, tip) object space, as drawn
    geo: Any = None  # the overlay geometry of the last full build (arrow resizing reuses it: no mesh read)


_states: dict[str, _State] = {}
_handle = None
_pending: set[str] = set()
_pending_arrows: set[str] = set()
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
    """(Re)build every batch of ``obj`` from the current field and design. Not called from draw.
    `arrays`: the mesh read the caller just made (see refresh), else the mesh is read here."""
    state = _states.setdefault(obj.name, _State())
    t0 = time.perf_counter()
    s = obj.nfield
    n = s.n
    geo = mesh_read.overlay_geometry(obj, arrays)
    t_geo = time.perf_counter()
    num_polys = len(geo.centroids)
    fld = _field_for(obj, state, geo, n)
    t_field = time.perf_counter()

    target = max(1, int(round(GLYPH_BUDGET * float(s.glyph_density))))
    batches: dict[str, Any] = {}
    line = _shader("line")
    point = _shader("point")
    n_glyphs = 0
    if fld is not None and num_polys:
        valid = np.any(fld[:, 0, :] != 0.0, axis=1)
        skey = (geo.signature, target, int(valid.sum()))
        if skey not in state.samples:
            state.samples = {skey: sample_faces(geo.centroids, geo.areas, target, valid)}
        faces, spacing = state.samples[skey]
        t_sample = time.perf_counter()
        local = np.maximum(geo.edge_len[faces], 0.8 * spacing)
        half = 0.4 * local * float(s.glyph_scale)
        lift = 0.02 * local
        verts = glyph_segments(geo.centroids[faces], geo.normals[faces], half, fld[faces], lift)
        n_glyphs = len(faces)
        if len(verts):
            batches["glyphs"] = batch_for_shader(line[0], "LINES", {"pos": verts})
    else:
        t_sample = time.perf_counter()
        spacing = 0.0
    t_glyph = time.perf_counter()

    # constraint arrows (from the stored design: always the user's latest edit, even mid-drag)
    state.spacing = spacing
    state.geo = geo
    batches.update(_arrow_batches(obj, state, geo))

    # singularity markers
    sings = _singularities_for(obj, state)
    nv = len(geo.positions)
    scale = float(np.median(geo.edge_len)) if len(geo.edge_len) else 0.0
    for name, sel in (("sing_pos", lambda i: i > 0), ("sing_neg", lambda i: i < 0)):
        vs = [v for v, i in sings if sel(i) and v < nv]
        if vs:
            vi = np.array(vs, dtype=np.int64)
            p = geo.positions[vi] + geo.vnormals[vi] * (0.05 * scale)
            batches[name] = batch_for_shader(point[0], "POINTS", {"pos": np.ascontiguousarray(p, np.float32)})
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

    t_end = time.perf_counter()
    state.batches = batches
    state.built = _built_key(obj, state)
    state.stats = {
        "faces": num_polys, "glyphs": n_glyphs, "spacing": spacing,
        "geometry_s": t_geo - t0, "field_s": t_field - t_geo, "sample_s": t_sample - t_field,
        "glyph_batch_s": t_glyph - t_sample, "total_s": t_end - t0,
    }
    _last_stats.clear()
    _last_stats.update(state.stats)
    _last_stats["object"] = obj.name


def _arrow_batches(obj, state: _State, geo) -> dict:
    """The constraint arrows' batch (and state.arrows) for the view state.view was last drawn with."""
    s = obj.nfield
    num_polys = len(geo.centroids)
    state.arrows = {}
    cons = [(c.face, tuple(c.direction)) for c in s.constraints if not c.stale and c.face < num_polys]
    if not cons:
        return {}
    faces_c = np.array([f for f, _ in cons], dtype=np.int64)
    d = np.array([v for _, v in cons], dtype=np.float64)
    nrm = geo.normals[faces_c].astype(np.float64)
    d = d - nrm * np.sum(d * nrm, axis=1, keepdims=True)
    ok = np.linalg.norm(d, axis=1) > 0
    d[ok] /= np.linalg.norm(d[ok], axis=1, keepdims=True)
    local = np.maximum(geo.edge_len[faces_c], 0.8 * state.spacing)
    org = geo.centroids[faces_c] + nrm * (0.04 * local)[:, None]
    length = 1.6 * local * float(s.glyph_scale)
    if state.view is not None:
        _key, width, height, persp = state.view
        mvp = np.asarray(persp, dtype=np.float64) @ np.array(obj.matrix_world, dtype=np.float64)
        length = screen_min_length(org, d, length, mvp, (width, height), MIN_ARROW_PX, MAX_ARROW_STRETCH)
    state.arrows = {int(f): (org[i].copy(), org[i] + d[i] * length[i]) for i, f in enumerate(faces_c) if ok[i]}
    verts = constraint_arrow_segments(org[ok], nrm[ok], d[ok], length[ok])
    return {"constraints": batch_for_shader(_shader("line")[0], "LINES", {"pos": verts})} if len(verts) else {}


def constraint_arrows(obj) -> dict:
    """face -> (tail, tip) in object space of the constraint arrows as last drawn (for picking)."""
    state = _states.get(getattr(obj, "name", ""))
    return {} if state is None else dict(state.arrows)


def _view_key(region, rv3d) -> tuple:
    m = rv3d.perspective_matrix
    return (region.width, region.height, tuple(round(m[i][j], 6) for i in range(4) for j in range(4)))


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


def _schedule_arrows(name: str) -> None:
    _pending_arrows.add(name)
    if not bpy.app.timers.is_registered(_rebuild_pending):
        bpy.app.timers.register(_rebuild_pending, first_interval=0.0)


def _rebuild_pending():
    names = list(_pending)
    _pending.clear()
    for name in [a for a in _pending_arrows if a not in names]:
        obj = bpy.data.objects.get(name)
        state = _states.get(name)
        if obj is not None and state is not None and state.geo is not None:
            try:
                state.batches.pop("constraints", None)
                state.batches.update(_arrow_batches(obj, state, state.geo))
            except Exception as exc:  # noqa: BLE001 - never break the UI
                print(f"nfield overlay: cannot size the arrows of {name!r}: {exc}")
    _pending_arrows.clear()
    for name in names:
        obj = bpy.data.objects.get(name)
        if obj is not None and obj.type == "MESH" and hasattr(obj, "nfield"):
            try:
                _build(obj)
            except Exception as exc:  # noqa: BLE001 - never break the UI; report in the console
                print(f"nfield overlay: cannot build overlay for {name!r}: {exc}")
                _states.setdefault(name, _State()).built = None
                _states[name].batches = {}
                _states[name].built = _built_key(obj, _states[name])
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
            if len(s.constraints):
                view = _view_key(region, context.region_data)
                if state.view is None or state.view[0] != view:
                    # the arrows keep a minimum size on screen: resize them for this view (in a timer)
                    state.view = (view, region.width, region.height,
                                  [list(row) for row in context.region_data.perspective_matrix])
                    _schedule_arrows(obj.name)
            b = state.batches
            if not b:
                continue
            gpu.matrix.push()
            gpu.matrix.multiply_matrix(obj.matrix_world)
            try:
                if s.show_field and "glyphs" in b:
                    dark = _dark_background(context)
                    _draw_lines(b["glyphs"], line, COLOR_GLYPH_ON_DARK if dark else COLOR_GLYPH, WIDTH_GLYPH,
                                region)
                if s.show_constraints and "constraints" in b:
                    _draw_lines(b["constraints"], line, COLOR_CONSTRAINT, WIDTH_CONSTRAINT, region)
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
    if bpy.app.timers.is_registered(_rebuild_pending):
        bpy.app.timers.unregister(_rebuild_pending)
    _states.clear()
    _shaders.clear()
    _pending.clear()
    _pending_arrows.clear()
