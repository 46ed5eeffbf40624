"""In-memory solver sessions per object, and keeping the stored design consistent with the mesh.

A :class:`nfield.core.DesignSession` (warm factorization, regions) is expensive to build, so one is kept per
object in memory, keyed by the object's name and a *mesh signature* (vertex/edge/polygon/loop counts plus
hashes of the topology and of the coordinates). Nothing here is saved: the .blend holds the design
(``obj.nfield``, see ``properties``) and a session is rebuilt from it on demand (after reload, undo, ...).

Mesh changes:
* any change of the signature drops the cached session (factorization, eigenbasis) of that object;
* when the *topology* changed (counts or connectivity) the stored design is remapped: a constraint keeps its
  face when the topology is unchanged; otherwise it moves to the face whose centroid is nearest to the
  centroid recorded at placement, if that is within ``REMAP_TOLERANCE`` x the bounding-box diagonal;
  otherwise it is flagged ``stale`` (kept, shown in the panel, ignored by the solver). Singularities are
  remapped the same way by vertex position; layers and the edit region are flagged stale (their face lists
  cannot be remapped safely). Nothing is dropped silently.

The mesh is the object's *base* mesh (``obj.data``, modifiers are ignored); all coordinates are in object
space. Polygons are triangulated with ``mesh.loop_triangles``; input faces of the core mesh are polygons.

Used by ``api`` (and through it by the operators and the interactive tools) and by the overlay
(:func:`get_result`, :func:`get_core_mesh`).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: relative (to the bounding-box diagonal) distance within which a constraint follows its face centroid
REMAP_TOLERANCE = 1e-4


class NFieldError(ValueError):
    """A user-facing problem (no mesh, empty mesh, bad index ...); the message is shown as is."""


# ------------------------------------------------------------------------------------------ mesh arrays
@dataclass
class MeshArrays:
    vertices: np.ndarray          # (V, 3) float64 object space
    triangles: np.ndarray         # (T, 3) int32
    triangle_polygon: np.ndarray  # (T,) int64
    num_polygons: int
    polygon_centers: np.ndarray   # (P, 3)
    polygon_normals: np.ndarray   # (P, 3)
    signature: str
    topology: str                 # the topology part of the signature


_geometry_cache: dict[str, tuple] = {}  # object name -> (signature, polygon centers, polygon normals)
_topology_cache: dict[str, tuple] = {}  # object name -> (topology key, triangles, triangle_polygon, loop_start)


def _corner_verts(me, nl: int) -> np.ndarray:
    out = np.empty(nl, dtype=np.int32)
    attr = me.attributes.get(".corner_vert") if hasattr(me, "attributes") else None
    if attr is not None and attr.domain == "CORNER" and attr.data_type == "INT":
        attr.data.foreach_get("value", out)  # Blender 4.x: raw array, ~100x faster than loops
    else:
        me.loops.foreach_get("vertex_index", out)
    return out


def mesh_arrays(obj) -> MeshArrays:
    """Read the base mesh of `obj` (object space). Raises NFieldError for non-mesh objects.

    Cheap when nothing changed: the triangulation is cached per object and reused while the topology key
    (counts + corner vertices + polygon starts) is unchanged; centroids/normals are computed with numpy.
    """
    if obj is None:
        raise NFieldError("no active object: select a mesh object")
    if obj.type != "MESH":
        raise NFieldError(f"object '{obj.name}' is a {obj.type.lower()}, not a mesh")
    if obj.mode == "EDIT":
        obj.update_from_editmode()
    me = obj.data
    nv, ne, np_, nl = len(me.vertices), len(me.edges), len(me.polygons), len(me.loops)
    verts32 = np.empty(nv * 3, dtype=np.float32)
    me.vertices.foreach_get("co", verts32)
    corner_vert = _corner_verts(me, nl)
    topo = hashlib.blake2b(digest_size=8)
    topo.update(np.array([nv, ne, np_, nl], dtype=np.int64).tobytes())
    topo.update(corner_vert.tobytes())
    prefix_key = (nv, ne, np_, nl, topo.copy().hexdigest())  # everything but the polygon starts
    cached = _topology_cache.get(obj.name)
    loop_start = None
    if cached is not None and cached[0] == prefix_key:
        loop_start = cached[3]
    if loop_start is None:
        loop_start = np.empty(np_, dtype=np.int32)
        me.polygons.foreach_get("loop_start", loop_start)
    topo.update(loop_start.tobytes())
    topology = topo.hexdigest()
    if cached is not None and cached[4] == topology:
        tris, tri_poly = cached[1], cached[2]
    else:
        me.calc_loop_triangles()
        nt = len(me.loop_triangles)
        tris = np.empty(nt * 3, dtype=np.int32)
        me.loop_triangles.foreach_get("vertices", tris)
        tris = tris.reshape(nt, 3)
        tp = np.empty(nt, dtype=np.int32)
        me.loop_triangles.foreach_get("polygon_index", tp)
        tri_poly = tp.astype(np.int64)
    _topology_cache[obj.name] = (prefix_key, tris, tri_poly, loop_start, topology)
    geo = hashlib.blake2b(verts32.tobytes(), digest_size=8).hexdigest()
    verts = verts32.reshape(nv, 3).astype(np.float64)
    sig = f"{nv}/{ne}/{np_}/{nl}:{topology}:{geo}"
    geo_cached = _geometry_cache.get(obj.name)
    if geo_cached is not None and geo_cached[0] == sig:
        centers, normals = geo_cached[1], geo_cached[2]
    else:
        centers, normals = _polygon_centers_normals(verts, corner_vert, loop_start)
        _geometry_cache[obj.name] = (sig, centers, normals)
    return MeshArrays(verts, tris, tri_poly, np_, centers, normals, sig, topology)


def _polygon_centers_normals(verts: np.ndarray, corner_vert: np.ndarray, loop_start: np.ndarray):
    """Mean of the corners and Newell normal (unit) of every polygon."""
    np_ = loop_start.shape[0]
    if np_ == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    order = np.argsort(loop_start, kind="stable")  # loop_start is normally increasing already
    starts = loop_start[order]
    sizes_sorted = np.diff(np.append(starts, corner_vert.shape[0])).astype(np.int64)
    sizes = np.empty(np_, dtype=np.int64)
    sizes[order] = sizes_sorted
    p = verts[corner_vert]
    centers = np.empty((np_, 3))
    centers[order] = np.add.reduceat(p, starts, axis=0) / sizes_sorted[:, None]
    # next corner within the polygon
    idx = np.arange(corner_vert.shape[0])
    poly_of_corner = np.empty(corner_vert.shape[0], dtype=np.int64)
    poly_of_corner[:] = np.repeat(order, sizes_sorted)  # corners are contiguous per polygon
    first = loop_start[poly_of_corner]
    nxt = np.where(idx + 1 < first + sizes[poly_of_corner], idx + 1, first)
    q = verts[corner_vert[nxt]]
    cross = np.cross(p, q)
    normals = np.empty((np_, 3))
    normals[order] = np.add.reduceat(cross, starts, axis=0)
    length = np.linalg.norm(normals, axis=1)
    ok = length > 0
    normals[ok] /= length[ok, None]
    return centers, normals


def topology_of(signature: str) -> str:
    parts = signature.split(":")
    return ":".join(parts[:2]) if len(parts) >= 2 else signature


def build_core_mesh(arrays: MeshArrays):
    """nfield.core.Mesh of the triangulated polygons (input faces = polygons). Raises NFieldError."""
    from ..core import Mesh

    if arrays.vertices.shape[0] == 0 or arrays.num_polygons == 0 or arrays.triangles.shape[0] == 0:
        raise NFieldError("the mesh is empty (it has no faces); nfield needs a mesh with faces")
    try:
        return Mesh(arrays.vertices, arrays.triangles, face_to_polygon=arrays.triangle_polygon,
                    num_polygons=arrays.num_polygons)
    except ValueError as exc:
        raise NFieldError(f"the mesh cannot be used: {exc}") from None


# ------------------------------------------------------------------------------------------ remapping
def remap_design(obj, arrays: MeshArrays) -> list[str]:
    """Bring the stored design of `obj` in line with its current mesh (see module docstring).

    Returns human-readable notes about what was remapped or flagged. Writes ``mesh_signature``.
    """
    st = obj.nfield
    notes: list[str] = []
    old_sig = st.mesh_signature
    if old_sig == arrays.signature:
        return notes
    same_topology = bool(old_sig) and topology_of(old_sig) == topology_of(arrays.signature)
    st.mesh_signature = arrays.signature
    if same_topology or not old_sig:
        if not old_sig:
            # first contact (design created by an older file / by script): validate indices only
            for c in st.constraints:
                if not c.stale and c.face >= arrays.num_polygons:
                    c.stale = True
                    notes.append(f"constraint on face {c.face} flagged stale: face out of range")
            for s in st.singularities:
                if not s.stale and s.vertex >= arrays.vertices.shape[0]:
                    s.stale = True
                    notes.append(f"singularity at vertex {s.vertex} flagged stale: vertex out of range")
        for c in st.constraints:
            if not c.stale and c.face < arrays.num_polygons:
                c.centroid = arrays.polygon_centers[c.face]
        for s in st.singularities:
            if not s.stale and s.vertex < arrays.vertices.shape[0]:
                s.position = arrays.vertices[s.vertex]
        return notes

    diag = float(np.linalg.norm(np.ptp(arrays.vertices, axis=0))) if arrays.vertices.shape[0] else 0.0
    tol = REMAP_TOLERANCE * max(diag, 1e-12)
    taken: set[int] = set()
    for c in st.constraints:
        old = np.asarray(c.centroid, dtype=np.float64)
        face = _nearest(arrays.polygon_centers, old, tol)
        if face is None or face in taken:
            if not c.stale:
                notes.append(f"constraint on face {c.face} flagged stale: its face no longer exists")
            c.stale = True
            continue
        taken.add(face)
        if face != c.face or c.stale:
            notes.append(f"constraint on face {c.face} remapped to face {face}"
                         + (" (was stale)" if c.stale else ""))
        c.face = face
        c.stale = False
    taken_v: set[int] = set()
    for s in st.singularities:
        v = _nearest(arrays.vertices, np.asarray(s.position, dtype=np.float64), tol)
        if v is None or v in taken_v:
            if not s.stale:
                notes.append(f"singularity at vertex {s.vertex} flagged stale: its vertex no longer exists")
            s.stale = True
            continue
        taken_v.add(v)
        if v != s.vertex or s.stale:
            notes.append(f"singularity at vertex {s.vertex} remapped to vertex {v}")
        s.vertex = v
        s.stale = False
    for layer in st.layers:
        if not layer.stale:
            layer.stale = True
            notes.append(f"layer '{layer.name}' flagged stale: the topology changed")
    if st.region_active:
        st.region_active = False
        notes.append("region edit ended: the topology changed (its faces are kept in region_faces)")
    return notes


def _nearest(points: np.ndarray, p: np.ndarray, tol: float) -> int | None:
    if points.shape[0] == 0:
        return None
    d = np.linalg.norm(points - p[None, :], axis=1)
    i = int(np.argmin(d))
    return i if d[i] <= tol else None


# ------------------------------------------------------------------------------------------ sessions
@dataclass
class CacheEntry:
    signature: str
    mesh: Any                     # nfield.core.Mesh
    arrays: MeshArrays
    session: Any = None           # nfield.core.DesignSession
    result: Any = None            # last FieldResult (for the overlay)
    version: int = 0              # bumped on every new result (overlay refresh)
    extra: dict = field(default_factory=dict)


_cache: dict[str, CacheEntry] = {}


def clear(obj_name: str | None = None) -> None:
    """Drop cached sessions and mesh data (all, or one object's)."""
    for d in (_cache, _topology_cache, _geometry_cache):
        if obj_name is None:
            d.clear()
        else:
            d.pop(obj_name, None)


def get_entry(obj, arrays: MeshArrays | None = None) -> CacheEntry:
    """The cache entry of `obj` for its current mesh (rebuilt when the mesh signature changed)."""
    if arrays is None:
        arrays = mesh_arrays(obj)
    entry = _cache.get(obj.name)
    if entry is None or entry.signature != arrays.signature:
        mesh = build_core_mesh(arrays)
        entry = CacheEntry(arrays.signature, mesh, arrays)
        _cache[obj.name] = entry
    else:
        entry.arrays = arrays
    return entry


def get_result(obj):
    """The last solved FieldResult of `obj` if it still matches the cached mesh, else None (no solving)."""
    entry = _cache.get(getattr(obj, "name", ""))
    return None if entry is None else entry.result


def get_entry_cached(obj) -> CacheEntry | None:
    """The cache entry of `obj` without reading the mesh (None if none). For drawing code."""
    return _cache.get(getattr(obj, "name", ""))


def session_settings(obj, mesh) -> dict:
    """Keyword arguments for DesignSession/configure from the object's settings."""
    st = obj.nfield
    kw = dict(n=st.n, order=st.order, align=st.align, strength=float(st.strength), alignment_field=None,
              mode=st.solver_mode.lower(), k=int(st.spectral_k))
    if st.alignment == "ATTRIBUTE":
        kw["alignment_field"] = read_alignment_attribute(obj, st.alignment_attribute, mesh.num_faces)
    return kw


def read_alignment_attribute(obj, name: str, num_faces: int) -> np.ndarray:
    me = obj.data
    if not name:
        raise NFieldError("alignment is 'Face Attribute' but no attribute name is set")
    attr = me.attributes.get(name)
    if attr is None:
        raise NFieldError(f"alignment attribute '{name}' does not exist on mesh '{me.name}'")
    if attr.domain != "FACE" or attr.data_type != "FLOAT_VECTOR":
        raise NFieldError(f"alignment attribute '{name}' must be a FACE-domain FLOAT_VECTOR attribute "
                          f"(it is {attr.domain} {attr.data_type})")
    buf = np.empty(num_faces * 3, dtype=np.float32)
    attr.data.foreach_get("vector", buf)
    return buf.reshape(num_faces, 3).astype(np.float64)


def ensure_session(obj, entry: CacheEntry, progress=None):
    """The session of `entry`, created or reconfigured from the object's settings, with the stored design
    applied (diffed against what the session already has). A mode or k change reconfigures the same
    session, so switching between exact and spectral mode keeps both the factorization and the basis."""
    from ..core import DesignSession

    kw = session_settings(obj, entry.mesh)
    state = design_state(obj)
    if entry.session is not None and entry.extra.get("design_state") != state:
        # region/layer state differs from the session (undo, redo, file reload): start over from the design
        entry.session = None
    if entry.session is None:
        try:
            entry.session = DesignSession(entry.mesh, **kw)
        except ValueError as exc:
            raise NFieldError(str(exc)) from None
        entry.extra["settings"] = kw
        entry.extra["design_state"] = None
    elif hasattr(entry.session, "progress"):
        # the callback belongs to this call only: a cached session must not keep (and later call) an old one,
        # e.g. one that cancelled
        entry.session.progress = progress
    if entry.session is not None and _settings_differ(entry.extra.get("settings"), kw):
        try:
            if (entry.extra.get("settings") or {}).get("n", kw["n"]) != kw["n"]:
                # the design stores index numerators (index = numerator / n): a new n changes every index, so
                # the session's singularities go and apply_design below sets them for the new n
                for c in entry.session.constraints:
                    if hasattr(c, "vertex") and not hasattr(c, "face"):
                        entry.session.remove_singularity(c.vertex)
            entry.session.configure(**kw)
        except ValueError as exc:
            raise NFieldError(str(exc)) from None
        entry.extra["settings"] = kw
    entry.session.progress = progress
    if entry.extra.get("design_state") is None:
        _restore_layers_and_region(obj, entry)
    apply_design(obj, entry.session)
    return entry.session


def spectral_basis_pending(obj, entry: CacheEntry) -> bool:
    """True when the object is in spectral mode and its basis is neither in memory nor in the disk cache:
    a solve would compute it (minutes on large meshes), which only the Precompute operator may do from the
    UI (in a worker thread, with progress and Esc)."""
    if obj.nfield.solver_mode != "SPECTRAL":
        return False
    return not ensure_session(obj, entry).basis_available()


def session_recipe(obj, entry: CacheEntry, mode: str | None = None, k: int | None = None) -> dict:
    """Everything needed to build the object's session away from Blender data (worker thread)."""
    settings = session_settings(obj, entry.mesh)
    if mode is not None:
        settings["mode"] = mode.lower()
    if k is not None:
        settings["k"] = int(k)
    return dict(mesh=entry.mesh, settings=settings, design=desired_design(obj))


def build_session(recipe: dict, progress=None):
    """Build a session from a recipe and solve it (no Blender data is read: safe in a worker thread).
    Returns (session, result)."""
    from ..core import DesignSession

    session = DesignSession(recipe["mesh"], **recipe["settings"], progress=progress)
    apply_design(None, session, recipe["design"])
    result = session.solve()
    session.progress = None
    return session, result


def install_session(obj, entry: CacheEntry, recipe: dict, session) -> None:
    """Adopt a session built by build_session (main thread)."""
    entry.session = session
    entry.extra["settings"] = recipe["settings"]
    entry.extra["design_state"] = None
    _restore_layers_and_region(obj, entry)


def design_state(obj) -> tuple:
    """What of the design lives only in the session: the active region and the committed layers."""
    st = obj.nfield
    return (bool(st.region_active), tuple(len(l.faces) for l in st.layers if not l.stale))


def _restore_layers_and_region(obj, entry: CacheEntry) -> None:
    """Fresh session: re-create committed layers (frozen values) and the active region from the design."""
    st = obj.nfield
    session = entry.session
    restore = getattr(session, "restore_layer", None)
    for layer in st.layers:
        if layer.stale:
            continue
        if restore is None:
            layer.stale = True
            st.last_message = (f"layer '{layer.name}' cannot be restored: this nfield.core has no "
                               f"DesignSession.restore_layer")
            continue
        faces = np.array([it.face for it in layer.faces], dtype=np.int64)
        values = np.array([tuple(it.value) for it in layer.faces], dtype=np.float64).reshape(-1, 3)
        try:
            restore(faces, values)
        except ValueError as exc:
            layer.stale = True
            st.last_message = f"layer '{layer.name}' cannot be restored: {exc}"
    if st.region_active:
        faces = [it.face for it in st.region_faces]
        try:
            apply_design(obj, session)
            if session.field is None:
                session.solve()
            session.begin_region(faces)
        except (ValueError, NFieldError) as exc:
            st.region_active = False
            st.last_message = f"region edit ended: {exc}"
    entry.extra["design_state"] = design_state(obj)


def _settings_differ(old, new) -> bool:
    if old is None:
        return True
    for k, v in new.items():
        o = old.get(k)
        if isinstance(v, np.ndarray) or isinstance(o, np.ndarray):
            if not (isinstance(v, np.ndarray) and isinstance(o, np.ndarray) and np.array_equal(v, o)):
                return True
        elif o != v:
            return True
    return False


def desired_design(obj):
    """(constraints {face: (kind, direction)}, singularities {vertex: index}) from the stored design (non-stale)."""
    st = obj.nfield
    n = st.n
    dirs = {int(c.face): (c.kind, tuple(float(x) for x in c.direction)) for c in st.constraints if not c.stale}
    sings = {int(s.vertex): s.numerator / n for s in st.singularities if not s.stale}
    return dirs, sings


def apply_design(obj, session, design=None) -> None:
    """Make the session's constraints equal to the stored design (only the differences are applied).

    `design`: a (constraints, singularities) pair from desired_design() gathered earlier; then `obj` is not
    touched (worker threads must not read Blender data)."""
    from ..core import DirectionConstraint, SingularityConstraint, VectorConstraint

    want_dirs, want_sings = design if design is not None else desired_design(obj)
    have_dirs: dict[int, tuple] = {}
    have_sings: dict[int, float] = {}
    for c in session.constraints:
        if isinstance(c, DirectionConstraint):
            have_dirs[c.face] = ("DIRECTION", tuple(c.direction))
        elif isinstance(c, VectorConstraint):
            have_dirs[c.face] = ("VECTOR", tuple(c.vector))
        elif isinstance(c, SingularityConstraint):
            have_sings[c.vertex] = c.index
    try:
        for f in set(have_dirs) - set(want_dirs):
            session.remove(f)
        for v in set(have_sings) - set(want_sings):
            session.remove_singularity(v)
        for f, (kind, d) in want_dirs.items():
            if have_dirs.get(f) != (kind, d):
                if not _close(have_dirs.get(f), (kind, d)):
                    (session.set_vector if kind == "VECTOR" else session.set_direction)(f, d)
        for v, idx in want_sings.items():
            if v not in have_sings or abs(have_sings[v] - idx) > 1e-12:
                session.set_singularity(v, idx)
    except ValueError as exc:
        raise NFieldError(str(exc)) from None


def _close(a, b) -> bool:
    if a is None or a[0] != b[0]:
        return False
    return all(abs(x - y) <= 1e-7 * max(1.0, abs(y)) for x, y in zip(a[1], b[1]))


# ------------------------------------------------------------------------------------------ handlers
def on_settings_changed(obj, context) -> None:
    """Property update callback (properties.NFieldSettings): re-solve if live update is on."""
    if obj is None or getattr(obj, "type", None) != "MESH":
        return
    from . import api

    if api.updates_suspended():
        return
    st = obj.nfield
    if not st.live_update or obj.name not in _cache or _cache[obj.name].result is None:
        return
    from . import background

    if background.busy(obj):  # the worker owns the session: solve again when it is done
        background.defer(obj)
        return
    try:
        if spectral_basis_pending(obj, _cache[obj.name]):
            st.last_message = (f"Spectral basis of {st.spectral_k} eigenfields not computed yet: "
                               f"press Precompute (runs in the background, Esc cancels)")
            return
        if background.interactive() and ensure_session(obj, _cache[obj.name]).pending_work() == "factorization":
            st.last_message = "Solving in the background (Esc cancels)"
            background.start_later(obj.name)
            return
        api.solve(obj)
    except Exception as exc:  # a bad setting must not raise from an update callback
        st.last_message = f"Solve failed: {exc}"


#: name used by the overlay (nfield.blender.overlay) to fetch the last result without solving
peek_result = get_result


def _persistent(fn):
    try:
        import bpy
    except ImportError:
        return fn
    return bpy.app.handlers.persistent(fn)


@_persistent
def on_load_post(*_args) -> None:
    """A file was loaded: every cached session belongs to the previous file."""
    clear()


@_persistent
def on_undo_redo(*_args) -> None:
    """Undo/redo restored the design (obj.nfield) and the attributes: re-solve cached objects in memory
    (write=False, the attributes were restored with the design) so the overlay shows the restored field."""
    import bpy

    from . import api

    for name in list(_cache):
        obj = bpy.data.objects.get(name)
        if obj is None or obj.type != "MESH":
            _cache.pop(name, None)
            continue
        entry = _cache[name]
        entry.result = None
        if not obj.nfield.live_update:
            continue
        try:
            api.solve(obj, write=False)
        except Exception as exc:  # noqa: BLE001 - handlers must not raise
            print(f"nfield: re-solve after undo failed for '{name}': {exc}")
