"""nfield's scripting API for Blender (batch scripts, ``blender -b file.blend --python script.py``, PyPI bpy).

    import nfield.blender as nb          # inside Blender with the extension: import bl_ext.user_default.nfield.blender
    obj = bpy.data.objects["Mesh"]
    nb.add_constraint(obj, face=12, direction=(1, 0, 0))
    nb.add_singularity(obj, vertex=7, index=0.25)
    result = nb.solve(obj, n=4, order=2, align="curvature-max", strength=1.0)
    result.directions                    # (polygons, 3) first unit direction per polygon, object space

Every function takes the object (a mesh object) first, works on its base mesh (modifiers ignored) in object
space, stores the design in ``obj.nfield`` (saved with the .blend, undoable) and raises ``ValueError`` (an
:class:`NFieldError`) with a message naming the problem. Face indices are polygon indices, vertex indices
are mesh vertex indices. The operators (``bpy.ops.nfield.*``) are thin wrappers around these functions.

Solving happens only in :func:`solve` (and in the operators when *Live Update* is on): edit functions only
change the stored design, so adding many constraints from a script costs nothing until the next solve.
"""
from __future__ import annotations

import math
from typing import Any, Iterable

import numpy as np

from . import attributes, session_cache
from .properties import ALIGNMENT_CORE, CORE_ALIGNMENT, ORDER_ENERGY
from .session_cache import NFieldError

__all__ = [
    "NFieldError", "configure", "add_constraint", "remove_constraint", "clear_constraints", "add_singularity",
    "remove_singularity", "clear_singularities", "solve", "field", "write_attributes", "begin_region",
    "commit_region", "cancel_region", "release_layer", "precompute_spectral", "sync", "stale_items",
    "build_anisotropic_material", "build_hatching",
]

_SYMMETRIES = (1, 2, 3, 4, 6)
#: the solver's admissible strengths (nfield.core.solve.MIN_STRENGTH / MAX_STRENGTH)
MIN_STRENGTH, MAX_STRENGTH = 1e-6, 1e6
#: the settings configure() may change (restored when a solve with new settings fails)
_SETTING_KEYS = ("symmetry", "energy", "alignment", "alignment_attribute", "strength", "solver_mode", "spectral_k",
                 "live_update")


def _check_object(obj):
    if obj is None:
        raise NFieldError("no active object: select a mesh object")
    if getattr(obj, "type", None) != "MESH":
        kind = getattr(obj, "type", type(obj).__name__)
        raise NFieldError(f"object '{getattr(obj, 'name', obj)}' is a {str(kind).lower()}, not a mesh")
    if len(obj.data.polygons) == 0:
        raise NFieldError(f"mesh '{obj.data.name}' of object '{obj.name}' is empty (it has no faces)")
    return obj


def sync(obj):
    """Read the mesh and remap the stored design if the mesh changed. Returns (MeshArrays, notes)."""
    _check_object(obj)
    arrays = session_cache.mesh_arrays(obj)
    notes = session_cache.remap_design(obj, arrays)
    if notes:
        obj.nfield.last_message = "; ".join(notes)
    return arrays, notes


def stale_items(obj) -> list[str]:
    """Descriptions of the constraints / singularities / layers flagged stale."""
    st = obj.nfield
    out = [f"constraint on face {c.face}" for c in st.constraints if c.stale]
    out += [f"singularity at vertex {s.vertex}" for s in st.singularities if s.stale]
    out += [f"layer '{l.name}'" for l in st.layers if l.stale]
    return out


# ------------------------------------------------------------------------------------------ settings
_updating = False


def configure(obj, *, n: int | None = None, order: int | None = None, align: str | None = None,
              strength: float | None = None, mode: str | None = None, k: int | None = None,
              alignment_attribute: str | None = None, live_update: bool | None = None) -> None:
    """Change the object's settings (None keeps a setting). align: "none", "curvature-max", "curvature-min",
    or "attribute" / "field" (then alignment_attribute names a face FLOAT_VECTOR attribute). mode: "exact" or
    "spectral" (k eigenfields)."""
    global _updating
    _check_object(obj)
    st = obj.nfield
    values: dict[str, Any] = {}
    if n is not None:
        if isinstance(n, bool) or int(n) != n or int(n) not in _SYMMETRIES:
            raise NFieldError(f"n must be one of {', '.join(map(str, _SYMMETRIES))} (got {n!r})")
        values["symmetry"] = str(int(n))
    if order is not None:
        if isinstance(order, bool) or int(order) != order or int(order) not in ORDER_ENERGY:
            raise NFieldError(f"order must be 1 (harmonic), 2 (biharmonic) or 3 (triharmonic) (got {order!r})")
        values["energy"] = ORDER_ENERGY[int(order)]
    if align is not None:
        a = "field" if align == "attribute" else align
        if a not in CORE_ALIGNMENT:
            raise NFieldError(f"unknown align {align!r} (expected none, curvature-max, curvature-min or attribute)")
        values["alignment"] = CORE_ALIGNMENT[a]
    if alignment_attribute is not None:
        values["alignment_attribute"] = alignment_attribute
    if strength is not None:
        try:
            s = float(strength)
        except (TypeError, ValueError):
            s = math.nan
        if isinstance(strength, bool) or not (math.isfinite(s) and MIN_STRENGTH <= s <= MAX_STRENGTH):
            raise NFieldError(f"strength must be a finite number in [{MIN_STRENGTH:g}, {MAX_STRENGTH:g}] "
                              f"(got {strength!r})")
        values["strength"] = s
    if mode is not None:
        if str(mode).lower() not in ("exact", "spectral"):
            raise NFieldError(f"mode must be 'exact' or 'spectral' (got {mode!r})")
        values["solver_mode"] = str(mode).upper()
    if k is not None:
        if isinstance(k, bool) or int(k) != k or int(k) < 2:
            raise NFieldError(f"k must be an integer >= 2 (got {k!r})")
        values["spectral_k"] = int(k)
    if live_update is not None:
        values["live_update"] = bool(live_update)
    _updating = True
    try:
        for key, val in values.items():
            if getattr(st, key) != val:
                setattr(st, key, val)
    finally:
        _updating = False


def updates_suspended() -> bool:
    """True while configure() changes settings (property update callbacks must not re-solve then)."""
    return _updating


def snapshot(obj) -> tuple:
    """The user's settings and design (constraints, singularities, list positions) of `obj`, for restore()."""
    st = obj.nfield
    settings = tuple(getattr(st, k) for k in _SETTING_KEYS)
    return settings, _snapshot_design(st), (st.active_constraint_index, st.active_singularity_index)


def restore(obj, saved: tuple) -> bool:
    """Put back what snapshot() saw, without re-solving (update callbacks are suspended). Only what differs is
    written. Returns True if anything was changed."""
    global _updating
    st = obj.nfield
    settings, design, active = saved
    changed = False
    _updating = True
    try:
        for key, value in zip(_SETTING_KEYS, settings):
            if getattr(st, key) != value:
                setattr(st, key, value)
                changed = True
        if _snapshot_design(st) != design:
            _restore_design(st, design)
            changed = True
        if (st.active_constraint_index, st.active_singularity_index) != active:
            st.active_constraint_index, st.active_singularity_index = active
    finally:
        _updating = False
    return changed


# ------------------------------------------------------------------------------------------ constraints
def _vec3(value, what: str) -> tuple[float, float, float]:
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise NFieldError(f"{what} must be three numbers, got {value!r}") from None
    if len(v) != 3 or not all(math.isfinite(x) for x in v):
        raise NFieldError(f"{what} must be three finite numbers, got {value!r}")
    return v  # type: ignore[return-value]


def _check_face(arrays, face) -> int:
    if isinstance(face, bool) or not isinstance(face, (int, np.integer)):
        raise NFieldError(f"face index must be an integer, got {face!r}")
    face = int(face)
    if not 0 <= face < arrays.num_polygons:
        raise NFieldError(f"face {face} is out of range: the mesh has {arrays.num_polygons} faces "
                          f"(valid indices 0..{arrays.num_polygons - 1})")
    return face


def _check_vertex(arrays, vertex) -> int:
    if isinstance(vertex, bool) or not isinstance(vertex, (int, np.integer)):
        raise NFieldError(f"vertex index must be an integer, got {vertex!r}")
    vertex = int(vertex)
    nv = arrays.vertices.shape[0]
    if not 0 <= vertex < nv:
        raise NFieldError(f"vertex {vertex} is out of range: the mesh has {nv} vertices "
                          f"(valid indices 0..{nv - 1})")
    return vertex


def add_constraint(obj, face: int, direction: Iterable[float], kind: str = "direction"):
    """Constrain polygon `face` to `direction` (object space; projected onto the face). An existing
    constraint on that face is re-aimed. kind: "direction" (one of the n directions points along it) or
    "vector" (direction and magnitude). Returns the stored NFieldConstraint."""
    arrays, _ = sync(obj)
    face = _check_face(arrays, face)
    d = _vec3(direction, f"direction of the constraint on face {face}")
    kind_u = str(kind).upper()
    if kind_u not in ("DIRECTION", "VECTOR"):
        raise NFieldError(f"constraint kind must be 'direction' or 'vector' (got {kind!r})")
    dn = np.asarray(d)
    length = float(np.linalg.norm(dn))
    if length == 0.0:
        raise NFieldError(f"direction of the constraint on face {face} is the zero vector")
    core_mesh = session_cache.get_entry(obj, arrays).mesh  # NFieldError if the mesh cannot be used
    if not core_mesh.native.face_active[core_mesh.face_triangle(face)]:
        raise NFieldError(f"face {face} is excluded from the field (degenerate: zero area, repeated vertex, "
                          f"needle or duplicate face): it cannot carry a constraint")
    normal = arrays.polygon_normals[face]
    if np.linalg.norm(dn - normal * float(dn @ normal)) < 1e-6 * length:
        raise NFieldError(f"direction {list(d)} of the constraint on face {face} is parallel to the face normal "
                          f"(it has no tangent component)")
    st = obj.nfield
    item = next((c for c in st.constraints if c.face == face and not c.stale), None)
    if item is None:
        item = st.constraints.add()
        st.active_constraint_index = len(st.constraints) - 1
    item.face = face
    item.direction = d
    item.kind = kind_u
    item.stale = False
    item.centroid = arrays.polygon_centers[face]
    return item


def _index_of(items, key: str, value) -> int | None:
    """Index of the live item whose `key` (face / vertex) is `value`, else of a stale one, else None."""
    idx = next((i for i, it in enumerate(items) if getattr(it, key) == value and not it.stale), None)
    if idx is None:
        idx = next((i for i, it in enumerate(items) if getattr(it, key) == value), None)
    return idx


def _clamped_index(index: int, items) -> int:
    """`index` moved inside `items` (0 when empty): a list's active index after an item was removed."""
    return max(0, min(index, len(items) - 1))


def remove_constraint(obj, face: int) -> None:
    """Remove the constraint on polygon `face` (a stale one with that face number if no live one)."""
    _check_object(obj)
    st = obj.nfield
    idx = _index_of(st.constraints, "face", face)
    if idx is None:
        faces = sorted(c.face for c in st.constraints)
        raise NFieldError(f"face {face} has no constraint (constrained faces: {faces or 'none'})")
    st.constraints.remove(idx)
    st.active_constraint_index = _clamped_index(st.active_constraint_index, st.constraints)


def clear_constraints(obj, stale_only: bool = False) -> int:
    """Remove all constraints (or only the stale ones). Returns how many were removed."""
    _check_object(obj)
    st = obj.nfield
    removed = 0
    for i in reversed(range(len(st.constraints))):
        if not stale_only or st.constraints[i].stale:
            st.constraints.remove(i)
            removed += 1
    st.active_constraint_index = 0
    return removed


def add_singularity(obj, vertex: int, index: float):
    """Prescribe a singularity of `index` (a multiple of 1/n, e.g. 0.25 or -0.25 for n = 4) at interior
    `vertex`; replaces an existing one there. Returns the stored NFieldSingularity."""
    arrays, _ = sync(obj)
    vertex = _check_vertex(arrays, vertex)
    st = obj.nfield
    n = st.n
    try:
        x = float(index)
    except (TypeError, ValueError):
        raise NFieldError(f"singularity index must be a number, got {index!r}") from None
    num = x * n
    if not math.isfinite(num) or abs(num - round(num)) > 1e-9:
        raise NFieldError(f"singularity index {index!r} at vertex {vertex} is not a multiple of 1/{n} "
                          f"(for n = {n} use k/{n}, e.g. {round(num) / n!r})")
    if round(num) == 0:
        raise NFieldError(f"singularity index at vertex {vertex} is 0; use remove_singularity to unpin it")
    lo, hi = _numerator_range(obj, arrays, vertex, n)
    if not lo <= round(num) <= hi:
        raise NFieldError(f"vertex {vertex} cannot carry index {round(num)}/{n}: the indices it can carry are "
                          f"{lo}/{n} .. {hi}/{n} (|index - K/2pi| < k/(2n) for its ring of k faces and angle "
                          f"defect K)")
    item = next((s for s in st.singularities if s.vertex == vertex and not s.stale), None)
    if item is None:
        item = st.singularities.add()
        st.active_singularity_index = len(st.singularities) - 1
    item.vertex = vertex
    item.numerator = int(round(num))
    item.stale = False
    item.position = arrays.vertices[vertex]
    return item


def _numerator_range(obj, arrays, vertex: int, n: int) -> tuple[int, int]:
    """The index numerators (index = numerator / n) vertex can carry, from the solver's own rule
    (nfield._native.singularity_numerator_range). NFieldError for a boundary / non-manifold / unused vertex."""
    from ..core import native

    entry = session_cache.get_entry(obj, arrays)
    key = ("index_operators", n)
    ops = entry.extra.get(key)
    if ops is None:
        for old in [k for k in entry.extra if isinstance(k, tuple) and k[:1] == ("index_operators",)]:
            del entry.extra[old]  # keep one set of operators per object
        try:
            ops = entry.extra[key] = native().FieldOperators(entry.mesh.native, n, "geometric")
        except ValueError as exc:
            raise NFieldError(str(exc)) from None
    try:
        lo, hi = native().singularity_numerator_range(ops, vertex)
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    return int(lo), int(hi)


def remove_singularity(obj, vertex: int) -> None:
    _check_object(obj)
    st = obj.nfield
    idx = _index_of(st.singularities, "vertex", vertex)
    if idx is None:
        verts = sorted(s.vertex for s in st.singularities)
        raise NFieldError(f"vertex {vertex} has no prescribed singularity (pinned vertices: {verts or 'none'})")
    st.singularities.remove(idx)
    st.active_singularity_index = _clamped_index(st.active_singularity_index, st.singularities)


def clear_singularities(obj) -> int:
    _check_object(obj)
    st = obj.nfield
    k = len(st.singularities)
    st.singularities.clear()
    st.active_singularity_index = 0
    return k


# ------------------------------------------------------------------------------------------ solving
def solve(obj, *, n: int | None = None, order: int | None = None, align: str | None = None,
          strength: float | None = None, mode: str | None = None, k: int | None = None,
          alignment_attribute: str | None = None, write: bool | None = None, progress=None):
    """Solve the field of `obj` with its stored design; keyword settings are stored first (see configure).

    Writes the output attributes when `write` is True (default: the object's Write Attributes setting).
    Returns the nfield.core.FieldResult (per polygon; object space).
    """
    from . import background

    if background.busy(obj):
        raise NFieldError(f"'{obj.name}' is being solved in the background: wait for it to finish or press Esc")
    arrays, _ = sync(obj)  # first: a mesh change remaps the design before anything is saved
    saved = snapshot(obj)
    try:
        configure(obj, n=n, order=order, align=align, strength=strength, mode=mode, k=k,
                  alignment_attribute=alignment_attribute)
        st = obj.nfield
        entry = session_cache.get_entry(obj, arrays)
        session = session_cache.ensure_session(obj, entry, progress=progress)
        try:
            result = session.solve()
        except (ValueError, RuntimeError) as exc:
            if type(exc).__name__ == "Cancelled":
                raise
            raise NFieldError(str(exc)) from None
    except BaseException as exc:
        # A failed or cancelled solve changes nothing the user set: settings given here go back.
        restore(obj, saved)
        obj.nfield.last_message = f"Solve failed: {exc}"
        raise
    _store_result(obj, entry, result)
    if write if write is not None else st.write_attributes:
        attributes.write(obj, arrays, result, st.n)
    return result


def _store_result(obj, entry, result) -> None:
    st = obj.nfield
    entry.result = result
    entry.version += 1
    st.last_solve_seconds = float(getattr(result, "seconds", 0.0))
    st.last_energy = float(getattr(result, "energy", 0.0))
    stale = stale_items(obj)
    st.last_message = (f"Solved: {len(result.singularities)} singularities"
                       + (f"; {len(stale)} stale item(s) ignored" if stale else ""))
    session = getattr(entry, "session", None)
    st.spectral_ready = bool(session is not None and session.has_basis)
    notify_overlay(obj, result)


def notify_overlay(obj, result=None) -> None:
    """Tell the viewport overlay (if loaded) that the field or design of `obj` changed."""
    try:
        from . import overlay
    except ImportError:
        return
    refresh = getattr(overlay, "refresh", None)
    if refresh is not None:
        try:
            refresh(obj, result)
        except Exception as exc:  # noqa: BLE001 - drawing problems must not break solving
            print(f"nfield: overlay refresh failed: {exc}")


def field(obj):
    """The last FieldResult of `obj` (None if it was not solved since the mesh last changed / file load)."""
    return session_cache.get_result(obj)


def write_attributes(obj, result=None) -> list[str]:
    """Write the output attributes from `result` (default: solve if needed). Returns the names written."""
    arrays, _ = sync(obj)
    entry = session_cache.get_entry(obj, arrays)
    if result is None:
        result = entry.result
    if result is None:
        result = solve(obj, write=False)
    return attributes.write(obj, arrays, result, obj.nfield.n)


# ------------------------------------------------------------------------------------------ regions
def _session_with_field(obj):
    arrays, _ = sync(obj)
    entry = session_cache.get_entry(obj, arrays)
    session = session_cache.ensure_session(obj, entry)
    if session.field is None:
        try:
            _store_result(obj, entry, session.solve())
        except (ValueError, RuntimeError) as exc:
            raise NFieldError(str(exc)) from None
    return arrays, entry, session


def selected_faces(obj) -> list[int]:
    """Indices of the selected polygons (edit-mode selection is read through update_from_editmode)."""
    if obj.mode == "EDIT":
        obj.update_from_editmode()
    me = obj.data
    sel = np.zeros(len(me.polygons), dtype=bool)
    me.polygons.foreach_get("select", sel)
    return np.flatnonzero(sel).tolist()


def begin_region(obj, faces: Iterable[int] | None = None) -> int:
    """Start a region edit on `faces` (default: the selected polygons): later edits change only those faces.
    Returns the number of region faces."""
    _check_object(obj)
    st = obj.nfield
    if st.region_active:
        raise NFieldError("a region edit is already in progress: commit or cancel it first")
    faces = selected_faces(obj) if faces is None else [int(f) for f in faces]
    if not faces:
        raise NFieldError("the region is empty: select faces in edit mode (or pass face indices)")
    arrays, entry, session = _session_with_field(obj)
    for f in faces:
        _check_face(arrays, f)
    try:
        session.begin_region(faces)
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    st.region_faces.clear()
    for f in faces:
        st.region_faces.add().face = f
    st.region_active = True
    entry.extra["region_saved_design"] = _snapshot_design(st)
    entry.extra["design_state"] = session_cache.design_state(obj)
    return len(faces)


def commit_region(obj):
    """Make the region's field a layer (frozen in later global solves). Returns the new NFieldLayer."""
    _check_object(obj)
    st = obj.nfield
    if not st.region_active:
        raise NFieldError("no region edit in progress (begin a region first)")
    arrays, entry, session = _session_with_field(obj)
    try:
        session.commit_region()
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    result = session.field if session.field is not None else entry.result
    _store_result(obj, entry, result)
    faces = [it.face for it in st.region_faces]
    layer = st.layers.add()
    layer.name = f"Layer {len(st.layers)}"
    # frozen value per face: first direction scaled by |raw solution| of the face's first triangle
    # (object space; DesignSession.restore_layer maps it back to the representation vector)
    dirs = np.asarray(result.directions)
    mags = np.abs(entry.mesh.per_face(np.asarray(result.raw_solution)))
    for f in faces:
        item = layer.faces.add()
        item.face = f
        item.value = dirs[f] * mags[f]
    entry.extra.pop("region_saved_design", None)
    st.region_active = False
    st.region_faces.clear()
    st.active_layer_index = len(st.layers) - 1
    entry.extra["design_state"] = session_cache.design_state(obj)
    return layer


def cancel_region(obj) -> None:
    """Drop the region edit: back to the field before begin_region."""
    _check_object(obj)
    st = obj.nfield
    if not st.region_active:
        raise NFieldError("no region edit in progress")
    arrays, entry, session = _session_with_field(obj)
    try:
        session.cancel_region()
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    st.region_active = False
    st.region_faces.clear()
    saved = entry.extra.pop("region_saved_design", None)
    if saved is not None:  # the stored design goes back to its state before begin_region, like the session
        _restore_design(st, saved)
    entry.extra["design_state"] = session_cache.design_state(obj)
    if session.field is not None:
        _store_result(obj, entry, session.field)


def _snapshot_design(st) -> tuple:
    cons = [(c.face, tuple(c.direction), c.kind, c.stale, tuple(c.centroid)) for c in st.constraints]
    sings = [(s.vertex, s.numerator, s.stale, tuple(s.position)) for s in st.singularities]
    return cons, sings


def _restore_design(st, saved: tuple) -> None:
    cons, sings = saved
    st.constraints.clear()
    for face, d, kind, stale, centroid in cons:
        c = st.constraints.add()
        c.face, c.direction, c.kind, c.stale, c.centroid = face, d, kind, stale, centroid
    st.singularities.clear()
    for vertex, num, stale, pos in sings:
        s = st.singularities.add()
        s.vertex, s.numerator, s.stale, s.position = vertex, num, stale, pos
    st.active_constraint_index = _clamped_index(st.active_constraint_index, st.constraints)
    st.active_singularity_index = _clamped_index(st.active_singularity_index, st.singularities)


def release_layer(obj, index: int) -> None:
    """Drop committed layer `index`: its faces follow the global solve again."""
    _check_object(obj)
    st = obj.nfield
    if not 0 <= int(index) < len(st.layers):
        raise NFieldError(f"layer {index} does not exist (the object has {len(st.layers)} layers)")
    layer = st.layers[int(index)]
    if not layer.stale:
        arrays, entry, session = _session_with_field(obj)
        live = [i for i, l in enumerate(st.layers) if not l.stale]
        try:
            session.release_layer(live.index(int(index)))
        except (ValueError, IndexError) as exc:
            raise NFieldError(str(exc)) from None
        st.layers.remove(int(index))
        entry.extra["design_state"] = session_cache.design_state(obj)
    else:
        st.layers.remove(int(index))
    st.active_layer_index = _clamped_index(st.active_layer_index, st.layers)


# ------------------------------------------------------------------------------------------ spectral
def precompute_spectral(obj, k: int | None = None, progress=None):
    """Compute the spectral basis (k eigenfields) now, blocking, and solve in spectral mode.

    progress(fraction) -> False cancels (raises nfield.core.Cancelled if the core supports it)."""
    st = obj.nfield
    previous = (st.solver_mode, st.spectral_k)
    try:
        return solve(obj, mode="spectral", k=k, progress=progress)
    except Exception:
        configure(obj, mode=previous[0], k=previous[1])  # a failed/cancelled basis leaves the settings as they were
        raise


# ------------------------------------------------------------------------------------------ applications
def build_anisotropic_material(obj, *, anisotropy: float | None = None, direction: str | None = None,
                               source: str | None = None, material: str | None = None, roughness: float = 0.25,
                               metallic: float = 1.0, base_color=(0.8, 0.8, 0.82, 1.0), write: bool = True):
    """Create or update a material whose anisotropic reflection follows the field (Cycles; EEVEE ignores
    anisotropy). anisotropy: 0..1; direction: "field" or "perpendicular" (n = 2, 4); source: "face" or
    "point" attribute (None keeps the material's setting; new: 0.8, "field", "face"); material: an existing
    material to update (default: the object's nfield material, created if needed). Returns the bpy
    Material. See nfield.blender.material."""
    from . import material as _material

    return _material.build(obj, anisotropy=anisotropy, direction=direction, source=source, material=material,
                           roughness=roughness, metallic=metallic, base_color=base_color, write=write)


def build_hatching(obj, **kwargs):
    """Trace hatching strokes along the field (nfield.core.trace_streamlines) and write them as a curves
    object parented to `obj` (created or updated). Returns the curves object. Keyword arguments: see
    nfield.blender.hatching.build (spacing, family, cross_hatch, seed, max_length, min_length, radius,
    density, name, material)."""
    from . import hatching as _hatching

    return _hatching.build(obj, **kwargs)
