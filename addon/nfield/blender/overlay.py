"""Viewport overlay of the designed field (gpu module; Blender 3.4 and 4.2-5.0).

What is drawn, per mesh object with an nfield design (``obj.nfield``):

* **glyphs**: the n directions of the field on an evenly spread subset of faces, as short line segments
  through the face centroids (even n: n/2 segments centred on the centroid, one per pair of opposite
  directions; odd n: n half-segments starting at the centroid). Half-length = 0.4 x the local glyph spacing
  (the face's mean edge length, or the sample spacing when the mesh is subsampled) x ``glyph_scale``;
* **constraint arrows**: thicker, orange, from the face centroid along the constraint direction, with a head;
* **singularity markers**: points at the singular vertices, red for positive and blue for negative index;
  singularities pinned by the user are drawn larger with a white rim;
* **streamlines**: TODO - ``nfield.core`` exposes no streamline tracer yet; the ``show_streamlines`` setting
  is accepted and ignored until the core has one (the add-on holds no field math of its own).

Everything is built in **object space** and drawn with the object's ``matrix_world`` pushed on the gpu matrix
stack, so the overlay follows the object's transform without any rebuild.

Performance contract
--------------------
Batches are built in :func:`refresh` (called by the solve operators and the interactive tools after every
solve), or in a one-shot timer when a display setting changed -- **never in the draw callback**, which only
binds a shader and draws prebuilt ``GPUBatch`` objects. Each object has a version counter (Python memory,
:func:`tag_changed`); the draw callback compares it with the version the batches were built from and only
*schedules* a rebuild when they differ.

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

import numpy as np

try:  # importable without Blender (pure numpy helpers are tested/benchmarked with system Python)
    import bpy
except ImportError:  # pragma: no cover - outside Blender
    bpy = None

__all__ = [
    "GLYPH_BUDGET",
    "register",
    "unregister",
    "refresh",
    "tag_changed",
    "forget",
    "sample_faces",
    "glyph_segments",
    "constraint_arrow_segments",
    "last_build_stats",
]

#: the most glyphs drawn on one object (glyph_density scales it)
GLYPH_BUDGET = 20000

COLOR_GLYPH = (0.05, 0.05, 0.05, 0.9)
COLOR_GLYPH_ON_DARK = (0.95, 0.95, 0.95, 0.9)
COLOR_CONSTRAINT = (1.0, 0.55, 0.0, 1.0)
COLOR_SING_POS = (0.9, 0.1, 0.1, 1.0)
COLOR_SING_NEG = (0.1, 0.3, 1.0, 1.0)
COLOR_RIM = (1.0, 1.0, 1.0, 1.0)
COLOR_PICK = (1.0, 1.0, 0.0, 1.0)

WIDTH_GLYPH = 1.5
WIDTH_CONSTRAINT = 4.0
POINT_SINGULARITY = 10.0
POINT_PINNED = 16.0


# ================================================================================= pure numpy geometry
def sample_faces(centroids: np.ndarray, areas: np.ndarray, target: int, seed_valid: np.ndarray | None = None
                 ) -> tuple[np.ndarray, float]:
    """Evenly spread, deterministic subset of faces (spatial hash, one face per grid cell).

    Returns ``(face indices sorted ascending, spacing)``; ``spacing`` is the cell size (0 when every valid
    face is kept). ``seed_valid``: optional bool mask of faces that may be picked (faces with a field).
    """
    faces = np.arange(len(centroids)) if seed_valid is None else np.flatnonzero(seed_valid)
    target = max(1, int(target))
    if len(faces) <= target:
        return faces, 0.0
    c = centroids[faces]
    total = float(np.sum(areas[faces]))
    lo = c.min(axis=0)
    h = max(np.sqrt(total / target), 1e-12)
    best = None
    for _ in range(4):  # a surface crosses more cells than area/h^2: adjust h towards the target count
        q = np.floor((c - lo) / h).astype(np.int64)
        dims = q.max(axis=0) + 1
        keys = (q[:, 0] * dims[1] + q[:, 1]) * dims[2] + q[:, 2]
        d2 = np.sum((c - lo - (q + 0.5) * h) ** 2, axis=1)
        order = np.lexsort((d2, keys))
        ks = keys[order]
        first = np.ones(len(ks), dtype=bool)
        first[1:] = ks[1:] != ks[:-1]
        picked = order[first]
        best = (picked, h)
        ratio = len(picked) / target
        if 0.85 <= ratio <= 1.0:
            break
        h *= np.sqrt(ratio) * (1.0 if ratio > 1.0 else 1.02)
    picked, h = best
    if len(picked) > target:  # deterministic thinning of the last few percent
        keep = np.linspace(0, len(picked) - 1, target).round().astype(np.int64)
        picked = np.sort(picked)[keep]
    return np.sort(faces[picked]), float(h)


def glyph_segments(centroids: np.ndarray, normals: np.ndarray, half_length: np.ndarray,
                   directions: np.ndarray, lift: np.ndarray) -> np.ndarray:
    """Line-list vertices (float32 (2 * segments, 3)) for n-direction glyphs.

    ``directions`` (k, n, 3) unit directions of the k sampled faces (zero rows = no field: skipped).
    Even n: segments c +- L d_j for j < n/2 (d_{j+n/2} = -d_j). Odd n: c -> c + L d_j for every j.
    """
    k, n, _ = directions.shape
    base = centroids + normals * lift[:, None]
    hl = half_length[:, None, None]
    if n % 2 == 0 and n > 0:
        d = directions[:, : n // 2, :] * hl
        a = base[:, None, :] - d
        b = base[:, None, :] + d
    else:
        d = directions * (2.0 * hl)  # one-sided: same visual length as a centred segment
        a = np.broadcast_to(base[:, None, :], d.shape)
        b = base[:, None, :] + d
    valid = np.any(directions[:, : a.shape[1], :] != 0.0, axis=2)
    seg = np.stack([a, b], axis=2)[valid]  # (m, 2, 3)
    return np.ascontiguousarray(seg.reshape(-1, 3), dtype=np.float32)


def constraint_arrow_segments(origins: np.ndarray, normals: np.ndarray, directions: np.ndarray,
                              length: np.ndarray) -> np.ndarray:
    """Arrow line-list (shaft + two head strokes in the tangent plane) for each constraint."""
    if len(origins) == 0:
        return np.zeros((0, 3), dtype=np.float32)
    d = directions / np.maximum(np.linalg.norm(directions, axis=1, keepdims=True), 1e-30)
    side = np.cross(normals, d)
    tip = origins + d * length[:, None]
    head = 0.3 * length[:, None]
    left = tip - d * head + side * head * 0.6
    right = tip - d * head - side * head * 0.6
    seg = np.stack([origins, tip, tip, left, tip, right], axis=1)
    return np.ascontiguousarray(seg.reshape(-1, 3), dtype=np.float32)


# ================================================================================= Blender side
@dataclass
class _Geometry:
    """Per-mesh geometry read once per mesh state (object space)."""

    key: tuple
    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    edge_len: np.ndarray
    positions: np.ndarray
    vnormals: np.ndarray
    samples: dict = field(default_factory=dict)  # target -> (faces, spacing)


@dataclass
class _State:
    version: int = 0
    built: Any = None  # (version, settings key) the batches were built from
    batches: dict = field(default_factory=dict)  # name -> GPUBatch
    result: Any = None  # last FieldResult handed over by refresh()/tag_changed()
    geometry: _Geometry | None = None
    stats: dict = field(default_factory=dict)


_states: dict[str, _State] = {}
_handle = None
_pending: set[str] = set()
_shaders: dict[str, Any] = {}
_last_stats: dict = {}


def last_build_stats() -> dict:
    """Timings (seconds) and counts of the most recent batch build (for tests and the panel)."""
    return dict(_last_stats)


def _shader(kind: str):
    """Builtin shaders by role, with the Blender 3.4 names as fallbacks. kind: 'line' | 'flat' | 'point'."""
    if kind in _shaders:
        return _shaders[kind]
    import gpu

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
    """The session cache's result counter for ``obj`` (bumped on every solve), -1 if unknown. Cheap."""
    try:
        from . import session_cache
    except ImportError:
        return -1
    get = getattr(session_cache, "get_entry_cached", None)
    entry = get(obj) if get is not None else None
    return -1 if entry is None else int(getattr(entry, "version", -1))


def _built_key(obj, state) -> tuple:
    return (state.version, _session_version(obj), _settings_key(obj))


def _settings_key(obj) -> tuple:
    s = obj.nfield
    return (round(float(s.glyph_density), 4), round(float(s.glyph_scale), 4), s.symmetry,
            bool(s.show_streamlines))


def _mesh_key(mesh) -> tuple:
    return (mesh.as_pointer(), len(mesh.vertices), len(mesh.polygons), len(mesh.loops))


def _read_geometry(obj, state: _State) -> _Geometry:
    mesh = obj.data
    nv, np_, nl = len(mesh.vertices), len(mesh.polygons), len(mesh.loops)
    co = np.empty(nv * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(nv, 3)
    # cheap position checksum so that moved vertices (edit mode) rebuild the geometry cache
    checksum = float(np.dot(co[:: max(1, nv // 997)].ravel().astype(np.float64),
                            np.arange(1, 1 + 3 * len(co[:: max(1, nv // 997)]), dtype=np.float64)))
    key = (mesh.as_pointer(), nv, np_, nl, checksum)
    g = state.geometry
    if g is not None and g.key == key:
        return g
    cen = np.empty(np_ * 3, dtype=np.float32)
    nor = np.empty(np_ * 3, dtype=np.float32)
    area = np.empty(np_, dtype=np.float32)
    mesh.polygons.foreach_get("center", cen)
    mesh.polygons.foreach_get("normal", nor)
    mesh.polygons.foreach_get("area", area)
    loop_start = np.empty(np_, dtype=np.int32)
    loop_total = np.empty(np_, dtype=np.int32)
    mesh.polygons.foreach_get("loop_start", loop_start)
    mesh.polygons.foreach_get("loop_total", loop_total)
    loop_edge = np.empty(nl, dtype=np.int32)
    mesh.loops.foreach_get("edge_index", loop_edge)
    ev = np.empty(len(mesh.edges) * 2, dtype=np.int32)
    mesh.edges.foreach_get("vertices", ev)
    ev = ev.reshape(-1, 2)
    elen = np.linalg.norm(co[ev[:, 0]] - co[ev[:, 1]], axis=1)
    if np_:
        edge_len = np.add.reduceat(elen[loop_edge], loop_start) / np.maximum(loop_total, 1)
    else:
        edge_len = np.zeros(0, dtype=np.float32)
    vn = _vertex_normals(mesh, nv)
    g = _Geometry(key, cen.reshape(np_, 3), nor.reshape(np_, 3), area, edge_len.astype(np.float32), co, vn)
    state.geometry = g
    return g


def _vertex_normals(mesh, nv: int) -> np.ndarray:
    vn = np.empty(nv * 3, dtype=np.float32)
    try:  # Blender 3.5+: mesh.vertex_normals; 3.4: MeshVertex.normal
        mesh.vertex_normals.foreach_get("vector", vn)
    except AttributeError:
        mesh.vertices.foreach_get("normal", vn)
    return vn.reshape(nv, 3)


def _field_for(obj, state: _State, num_polys: int, n: int) -> np.ndarray | None:
    """(P, n, 3) object-space unit directions per polygon, or None when no field is known yet."""
    res = state.result
    if res is None:
        res = _session_result(obj)
    if res is not None:
        try:
            dirs = res.all_directions()
            if dirs is not None and dirs.shape[0] == num_polys:
                return np.asarray(dirs, dtype=np.float32)
        except Exception:  # noqa: BLE001 - a stale result object: fall back to the attribute
            pass
    return _field_from_attribute(obj, num_polys, n)


def _session_result(obj):
    """The session cache's last result for ``obj`` if the core helper exposes one (no solve is triggered)."""
    try:
        from . import session_cache
    except ImportError:
        return None
    for name in ("get_result", "peek_result"):
        fn = getattr(session_cache, name, None)
        if fn is not None:
            try:
                return fn(obj)
            except Exception:  # noqa: BLE001
                return None
    return None


def _field_from_attribute(obj, num_polys: int, n: int) -> np.ndarray | None:
    """The persisted output attribute (first direction per face), fanned out to the n directions by
    rotating about the face normal in steps of 2 pi / n (display only: used after a reload, before the
    session has re-solved)."""
    mesh = obj.data
    attr = mesh.attributes.get(obj.nfield.direction_attribute)
    if attr is None or attr.domain != "FACE" or attr.data_type != "FLOAT_VECTOR" or num_polys == 0:
        return None
    d = np.empty(num_polys * 3, dtype=np.float32)
    attr.data.foreach_get("vector", d)
    d = d.reshape(num_polys, 3)
    nor = np.empty(num_polys * 3, dtype=np.float32)
    mesh.polygons.foreach_get("normal", nor)
    nor = nor.reshape(num_polys, 3)
    perp = np.cross(nor, d)
    out = np.empty((num_polys, n, 3), dtype=np.float32)
    for j in range(n):
        a = 2.0 * np.pi * j / n
        out[:, j, :] = np.cos(a) * d + np.sin(a) * perp
    return out


def _singularities_for(obj, state: _State) -> list[tuple[int, float]]:
    res = state.result if state.result is not None else _session_result(obj)
    if res is not None and getattr(res, "singularities", None) is not None:
        return [(int(v), float(i)) for v, i in res.singularities]
    attr = obj.data.attributes.get(obj.nfield.singularity_attribute)
    if attr is None or attr.domain != "POINT" or attr.data_type != "FLOAT":
        return []
    vals = np.empty(len(obj.data.vertices), dtype=np.float32)
    attr.data.foreach_get("value", vals)
    nz = np.flatnonzero(vals != 0.0)
    return [(int(v), float(vals[v])) for v in nz]


def _build(obj) -> None:
    """(Re)build every batch of ``obj`` from the current field and design. Not called from draw."""
    import gpu  # noqa: F401
    from gpu_extras.batch import batch_for_shader

    state = _states.setdefault(obj.name, _State())
    t0 = time.perf_counter()
    s = obj.nfield
    n = s.n
    geo = _read_geometry(obj, state)
    t_geo = time.perf_counter()
    num_polys = len(geo.centroids)
    fld = _field_for(obj, state, num_polys, n)
    t_field = time.perf_counter()

    target = max(1, int(round(GLYPH_BUDGET * float(s.glyph_density))))
    batches: dict[str, Any] = {}
    line = _shader("line")
    point = _shader("point")
    n_glyphs = 0
    if fld is not None and num_polys:
        valid = np.any(fld[:, 0, :] != 0.0, axis=1)
        skey = (target, int(valid.sum()))
        if skey not in geo.samples:
            geo.samples = {skey: sample_faces(geo.centroids, geo.areas, target, valid)}
        faces, spacing = geo.samples[skey]
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
    cons = [(c.face, tuple(c.direction)) for c in s.constraints if not c.stale and c.face < num_polys]
    if cons:
        faces_c = np.array([f for f, _ in cons], dtype=np.int64)
        d = np.array([v for _, v in cons], dtype=np.float32)
        nrm = geo.normals[faces_c]
        d = d - nrm * np.sum(d * nrm, axis=1, keepdims=True)
        ok = np.linalg.norm(d, axis=1) > 0
        local = np.maximum(geo.edge_len[faces_c], 0.8 * spacing)
        org = geo.centroids[faces_c] + nrm * (0.04 * local)[:, None]
        verts = constraint_arrow_segments(org[ok], nrm[ok], d[ok], (1.6 * local * float(s.glyph_scale))[ok])
        if len(verts):
            batches["constraints"] = batch_for_shader(line[0], "LINES", {"pos": verts})

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
    # streamlines: TODO(core) -- nfield.core exposes no streamline tracer yet; nothing is drawn.

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


def _can_draw() -> bool:
    return bpy is not None and not bpy.app.background


def _mark_changed(obj, result) -> None:
    """Bump the object's version (its batches are rebuilt before the next draw); keep `result` if given."""
    state = _states.setdefault(obj.name, _State())
    if result is not None:
        state.result = result
    state.version += 1


def refresh(obj, result=None) -> None:
    """The field or design of ``obj`` changed (call after every solve / edit): rebuild its batches now and
    redraw. ``result``: the new FieldResult (else the session cache's or the output attribute is used)."""
    if obj is None or obj.type != "MESH":
        return
    _mark_changed(obj, result)
    if _can_draw():
        _build(obj)
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


def _schedule(name: str) -> None:
    if not _can_draw() or name in _pending:
        return
    _pending.add(name)
    if not bpy.app.timers.is_registered(_rebuild_pending):
        bpy.app.timers.register(_rebuild_pending, first_interval=0.0)


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
        import gpu
        gpu.state.line_width_set(width)
    shader.uniform_float("color", color)
    batch.draw(shader)


def _draw_points(batch, shader_pair, color, size):
    import gpu

    shader, _ = shader_pair
    gpu.state.point_size_set(size)
    shader.bind()
    shader.uniform_float("color", color)
    batch.draw(shader)


def _draw_callback():
    """Draw prebuilt batches only (no geometry work here: a missing/outdated batch schedules a rebuild)."""
    import gpu

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


def _persistent(fn):
    return bpy.app.handlers.persistent(fn) if bpy is not None else fn


@_persistent
def _on_load(_dummy=None):
    forget()


@_persistent
def _on_undo(_dummy=None):
    # after undo/redo the design (obj.nfield) is restored; rebuild from it and the session's field
    for name, st in list(_states.items()):
        st.result = None
        st.version += 1
        _schedule(name)


def register():
    global _handle
    if bpy is None or bpy.app.background or _handle is not None:
        return
    _handle = bpy.types.SpaceView3D.draw_handler_add(_draw_callback, (), "WINDOW", "POST_VIEW")
    for lst, fn in ((bpy.app.handlers.load_post, _on_load), (bpy.app.handlers.undo_post, _on_undo),
                    (bpy.app.handlers.redo_post, _on_undo)):
        if fn not in lst:
            lst.append(fn)


def unregister():
    global _handle
    if bpy is None:
        return
    if _handle is not None:
        bpy.types.SpaceView3D.draw_handler_remove(_handle, "WINDOW")
        _handle = None
    for lst, fn in ((bpy.app.handlers.load_post, _on_load), (bpy.app.handlers.undo_post, _on_undo),
                    (bpy.app.handlers.redo_post, _on_undo)):
        if fn in lst:
            lst.remove(fn)
    if bpy.app.timers.is_registered(_rebuild_pending):
        bpy.app.timers.unregister(_rebuild_pending)
    _states.clear()
    _shaders.clear()
    _pending.clear()
