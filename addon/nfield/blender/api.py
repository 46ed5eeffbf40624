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

This module is also the facade the rest of the add-on calls: the operators, the modal tools, the material and
the hatching go through it (the section "for the add-on" at the end is for them, not the scripting API). It
validates, then delegates: ``mesh_read`` reads the mesh, ``design`` writes the stored design,
``session_cache`` holds the solver session, ``results`` records a new field, ``attributes`` writes it out.
The material and hatching builders are exported by the package (``nfield.blender``) from their own modules.
"""
from __future__ import annotations

import math
from typing import Any, Iterable

import numpy as np

from ..core import DirectionConstraint, SingularityConstraint, VectorConstraint, native
from ..core import quad_remesh as core_quad_remesh
from . import attributes, design, guides, jobs, mesh_read, remesh_object, results, session_cache
from .choices import (
    CORE_ALIGNMENT,
    INDEX_TOLERANCE,
    MAX_STRENGTH,
    MIN_STRENGTH,
    ORDER_ENERGY,
    SYMMETRIES,
    TANGENT_TOLERANCE,
)
from .design import restore, snapshot, stale_items  # noqa: F401  (part of the facade)
from .errors import NFieldError
from .mesh_read import check_mesh_object
from .results import notify_overlay, store_result  # noqa: F401  (part of the facade)

__all__ = [
    "NFieldError", "configure", "add_constraint", "remove_constraint", "clear_constraints", "add_singularity",
    "remove_singularity", "clear_singularities", "solve", "field", "write_attributes", "begin_region",
    "commit_region", "cancel_region", "release_layer", "precompute_spectral", "sync", "stale_items",
    "set_feature_alignment", "set_guide_attributes", "add_curve_guide", "remove_curve_guide", "set_mirror_symmetry",
    "set_cuts", "guide_report", "guide_summary", "mirror_design", "comb", "clear_comb",
    "quad_remesh", "field_state",
]


def sync(obj):
    """Read the mesh and remap the stored design if the mesh changed. Returns (MeshArrays, notes)."""
    check_mesh_object(obj)
    arrays = mesh_read.mesh_arrays(obj)
    if any(s.denominator == 0 for s in obj.nfield.singularities):
        design.pin_denominators(obj)
    notes = design.remap_design(obj, arrays)
    if notes:
        obj.nfield.last_message = "; ".join(notes)
    return arrays, notes


# ------------------------------------------------------------------------------------------ settings
def configure(obj, *, n: int | None = None, order: int | None = None, align: str | None = None,
              strength: float | None = None, mode: str | None = None, k: int | None = None,
              alignment_attribute: str | None = None, live_update: bool | None = None) -> None:
    """Change the object's settings (None keeps a setting). align: "none", "curvature-max", "curvature-min",
    or "attribute" / "field" (then alignment_attribute names a face FLOAT_VECTOR attribute). mode: "exact" or
    "spectral" (k eigenfields)."""
    check_mesh_object(obj)
    st = obj.nfield
    values: dict[str, Any] = {}
    if n is not None:
        if isinstance(n, bool) or int(n) != n or int(n) not in SYMMETRIES:
            raise NFieldError(f"n must be one of {', '.join(map(str, SYMMETRIES))} (got {n!r})")
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
    with design.suspended_updates():
        for key, val in values.items():
            if getattr(st, key) != val:
                setattr(st, key, val)


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
    if np.linalg.norm(dn - normal * float(dn @ normal)) < TANGENT_TOLERANCE * length:
        raise NFieldError(f"direction {list(d)} of the constraint on face {face} is parallel to the face normal "
                          f"(it has no tangent component)")
    return design.set_constraint(obj, face, d, kind_u, arrays.polygon_centers[face])


def remove_constraint(obj, face: int) -> None:
    """Remove the constraint on polygon `face` (a stale one with that face number if no live one)."""
    check_mesh_object(obj)
    design.remove_constraint(obj, face)


def clear_constraints(obj, stale_only: bool = False) -> int:
    """Remove all constraints (or only the stale ones). Returns how many were removed."""
    check_mesh_object(obj)
    return design.clear_constraints(obj, stale_only)


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
    if not math.isfinite(num) or abs(num - round(num)) > INDEX_TOLERANCE:
        raise NFieldError(f"singularity index {index!r} at vertex {vertex} is not a multiple of 1/{n} "
                          f"(for n = {n} use k/{n}, e.g. {round(num) / n!r})")
    if round(num) == 0:
        raise NFieldError(f"singularity index at vertex {vertex} is 0; use remove_singularity to unpin it")
    lo, hi = _numerator_range(obj, arrays, vertex, n)
    if not lo <= round(num) <= hi:
        raise NFieldError(f"vertex {vertex} cannot carry index {round(num)}/{n}: the indices it can carry are "
                          f"{lo}/{n} .. {hi}/{n} (|index - K/2pi| < k/(2n) for its ring of k faces and angle "
                          f"defect K)")
    return design.set_singularity(obj, vertex, int(round(num)), arrays.vertices[vertex])


def _numerator_range(obj, arrays, vertex: int, n: int) -> tuple[int, int]:
    """The index numerators (index = numerator / n) vertex can carry, from the solver's own rule
    (nfield._native.singularity_numerator_range). NFieldError for a boundary / non-manifold / unused vertex."""
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
    """Remove the singularity pinned at `vertex` (a stale one with that vertex number if no live one)."""
    check_mesh_object(obj)
    design.remove_singularity(obj, vertex)


def clear_singularities(obj) -> int:
    """Remove every pinned singularity. Returns how many were removed."""
    check_mesh_object(obj)
    return design.clear_singularities(obj)


# ------------------------------------------------------------------------------------------ solving
def solve(obj, *, n: int | None = None, order: int | None = None, align: str | None = None,
          strength: float | None = None, mode: str | None = None, k: int | None = None,
          alignment_attribute: str | None = None, write: bool | None = None, progress=None):
    """Solve the field of `obj` with its stored design; keyword settings are stored first (see configure).

    Writes the output attributes when `write` is True (default: the object's Write Attributes setting).
    Returns the nfield.core.FieldResult (per polygon; object space).
    """
    if jobs.busy(obj):
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
    store_result(obj, entry, result)
    if write if write is not None else st.write_attributes:
        attributes.write(obj, arrays, result, st.n)
    return result


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
    arrays, entry, session = open_session(obj)
    if session.field is None:
        try:
            store_result(obj, entry, session.solve())
        except (ValueError, RuntimeError) as exc:
            raise NFieldError(str(exc)) from None
    return arrays, entry, session


def begin_region(obj, faces: Iterable[int] | None = None) -> int:
    """Start a region edit on `faces` (default: the selected polygons): later edits change only those faces.
    Returns the number of region faces."""
    check_mesh_object(obj)
    st = obj.nfield
    if st.region_active:
        raise NFieldError("a region edit is already in progress: commit or cancel it first")
    faces = mesh_read.selected_polygons(obj) if faces is None else [int(f) for f in faces]
    if not faces:
        raise NFieldError("the region is empty: select faces in edit mode (or pass face indices)")
    arrays, entry, session = _session_with_field(obj)
    for f in faces:
        _check_face(arrays, f)
    try:
        session.begin_region(faces)
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    design.start_region(obj, faces)
    entry.extra["region_saved_design"] = design.snapshot_design(obj)
    entry.extra["design_state"] = design.design_state(obj)
    return len(faces)


def commit_region(obj):
    """Make the region's field a layer (frozen in later global solves). Returns the new NFieldLayer."""
    check_mesh_object(obj)
    st = obj.nfield
    if not st.region_active:
        raise NFieldError("no region edit in progress (begin a region first)")
    arrays, entry, session = _session_with_field(obj)
    try:
        session.commit_region()
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    result = session.field if session.field is not None else entry.result
    store_result(obj, entry, result)
    faces = [it.face for it in st.region_faces]
    # frozen value per face: first direction scaled by |raw solution| of the face's first triangle
    # (object space; DesignSession.restore_layer maps it back to the representation vector)
    dirs = np.asarray(result.directions)
    mags = np.abs(entry.mesh.per_face(np.asarray(result.raw_solution)))
    layer = design.add_layer(obj, faces, [dirs[f] * mags[f] for f in faces])
    entry.extra.pop("region_saved_design", None)
    design.end_region(obj)
    entry.extra["design_state"] = design.design_state(obj)
    return layer


def cancel_region(obj) -> None:
    """Drop the region edit: back to the field before begin_region."""
    check_mesh_object(obj)
    st = obj.nfield
    if not st.region_active:
        raise NFieldError("no region edit in progress")
    arrays, entry, session = _session_with_field(obj)
    try:
        session.cancel_region()
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    design.end_region(obj)
    saved = entry.extra.pop("region_saved_design", None)
    if saved is not None:  # the stored design goes back to its state before begin_region, like the session
        design.restore_design(obj, saved)
    entry.extra["design_state"] = design.design_state(obj)
    if session.field is not None:
        store_result(obj, entry, session.field)


def release_layer(obj, index: int) -> None:
    """Drop committed layer `index`: its faces follow the global solve again."""
    check_mesh_object(obj)
    st = obj.nfield
    if not 0 <= int(index) < len(st.layers):
        raise NFieldError(f"layer {index} does not exist (the object has {len(st.layers)} layers)")
    layer = st.layers[int(index)]
    if not layer.stale:
        arrays, entry, session = _session_with_field(obj)
        try:
            session.release_layer(design.live_layer_position(obj, index))
        except (ValueError, IndexError) as exc:
            raise NFieldError(str(exc)) from None
        design.remove_layer(obj, index)
        entry.extra["design_state"] = design.design_state(obj)
    else:
        design.remove_layer(obj, index)


# ------------------------------------------------------------------------------------------ guides
# Guides are stored settings (obj.nfield_guides, guide_properties) read again at every solve
# (session_cache -> guide_session). Each function writes them, then checks them against the mesh at once (the
# session is configured, not solved): on a problem the previous settings come back and NFieldError names it.
_GUIDE_MODES = ("soft", "hard")


def _guide_settings(obj):
    check_mesh_object(obj)
    g = getattr(obj, "nfield_guides", None)
    if g is None:
        raise NFieldError("the guide settings are not registered (enable the nfield add-on)")
    return g


def _guide_snapshot(g) -> dict:
    keep = {p.identifier: getattr(g, p.identifier) for p in g.bl_rna.properties
            if p.identifier not in ("rna_type", "curves") and not p.is_readonly}
    keep["curves"] = [{p.identifier: getattr(c, p.identifier) for p in c.bl_rna.properties
                       if p.identifier != "rna_type" and not p.is_readonly} for c in g.curves]
    return keep


def _guide_restore(g, saved: dict) -> None:
    for key, value in saved.items():
        if key != "curves" and getattr(g, key) != value:
            setattr(g, key, value)
    g.curves.clear()
    for values in saved["curves"]:
        item = g.curves.add()
        for key, value in values.items():
            setattr(item, key, value)


def _edit_guides(obj, edit) -> None:
    """Apply edit(guide settings) without re-solving per property, then check the guides against the mesh by
    configuring the session; restore the previous settings on a problem."""
    g = _guide_settings(obj)
    if jobs.busy(obj):
        raise NFieldError(f"'{obj.name}' is being solved in the background: wait for it to finish or press Esc")
    saved = _guide_snapshot(g)
    try:
        with design.suspended_updates():
            edit(g)
        open_session(obj)
    except (ValueError, RuntimeError) as exc:
        with design.suspended_updates():
            _guide_restore(g, saved)
        if isinstance(exc, NFieldError):
            raise
        raise NFieldError(str(exc)) from None


def _guide_mode(mode: str, what: str) -> str:
    m = str(mode).lower()
    if m not in _GUIDE_MODES:
        raise NFieldError(f"{what} mode must be 'soft' or 'hard' (got {mode!r})")
    return m.upper()


def set_feature_alignment(obj, enabled: bool = True, *, boundary: bool | None = None, dihedral: bool | None = None,
                          angle: float | None = None, marked: Iterable[str] | None = None, mode: str | None = None,
                          weight: float | None = None, width: int | None = None, every: int | None = None) -> None:
    """Align the field with feature edges (None keeps a setting). Features: boundary edges, edges bending by
    more than `angle` degrees (dihedral=True), and `marked` edges: any of "sharp", "seam", "face_sets",
    "materials" (edges marked sharp / seam, face-set and material-slot borders). mode "soft": alignment on
    `width` edge rings with `weight` (relative to the base guide); "hard": direction constraints on the faces
    next to every `every`-th feature edge, contradictions at corners dropped and reported (guide_report)."""
    sources = None
    if marked is not None:
        sources = {str(m).upper() for m in ([marked] if isinstance(marked, str) else marked)}
        unknown = sources - set(guides.MARKED_SOURCES)
        if unknown:
            raise NFieldError(f"unknown marked edge source(s) {sorted(unknown)} (expected sharp, seam, face_sets, "
                              f"materials)")
    m = None if mode is None else _guide_mode(mode, "feature")

    def edit(g):
        g.use_features = bool(enabled)
        if boundary is not None:
            g.feature_boundary = bool(boundary)
        if dihedral is not None:
            g.feature_use_angle = bool(dihedral)
        if angle is not None:
            g.feature_angle = _number(angle, "feature angle (degrees)", 0.0, 179.0)
        if sources is not None:
            g.feature_sharp, g.feature_seam = "SHARP" in sources, "SEAM" in sources
            g.feature_face_sets, g.feature_materials = "FACE_SETS" in sources, "MATERIALS" in sources
        if m is not None:
            g.feature_mode = m
        if weight is not None:
            g.feature_weight = _number(weight, "feature weight", 0.0, None)
        if width is not None:
            g.feature_width = _whole(width, "feature width (edge rings)")
        if every is not None:
            g.feature_every = _whole(every, "feature 'every'")

    _edit_guides(obj, edit)


def _number(value, what: str, lo: float | None, hi: float | None) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if isinstance(value, bool) or not math.isfinite(x) or (lo is not None and x < lo) or (hi is not None and x > hi):
        rng = " and ".join(t for t in ((f">= {lo:g}" if lo is not None else ""), (f"<= {hi:g}" if hi is not None
                                                                                    else "")) if t)
        raise NFieldError(f"{what} must be a finite number {rng} (got {value!r})")
    return x


def _whole(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) < 1:
        raise NFieldError(f"{what} must be an integer >= 1 (got {value!r})")
    return int(value)


def set_guide_attributes(obj, *, weight: str | None = None, rotation: str | None = None) -> None:
    """Per-face guide weight and rotation from face FLOAT attributes (e.g. painted with Blender's attribute
    painting): `weight` (>= 0) scales the base alignment per face, 0 removes it there; `rotation` (radians)
    turns it. "" switches one off, None keeps it."""
    def edit(g):
        if weight is not None:
            g.weight_attribute = str(weight)
        if rotation is not None:
            g.rotation_attribute = str(rotation)

    _edit_guides(obj, edit)


def add_curve_guide(obj, curve, *, mode: str = "soft", weight: float = 1.0, width: float = 0.02,
                    tolerance: float = 0.01, every: int = 1):
    """Guide the field with the tangents of curve object `curve` (a curve or curves object), projected onto
    the surface; re-adding a curve changes its options. width and tolerance are fractions of the mesh's
    bounding-box diagonal; parts farther than `tolerance` from the surface are ignored and reported. The
    guide keeps a reference to the curve: editing the curve re-solves (Live Update). Returns the item."""
    if getattr(curve, "type", None) not in guides.CURVE_TYPES:
        raise NFieldError(f"{getattr(curve, 'name', curve)!r} is not a curve or curves object")
    m = _guide_mode(mode, "curve")
    values = dict(mode=m, weight=_number(weight, "curve weight", 0.0, None),
                  width=_number(width, "curve width", 0.0, 1.0),
                  tolerance=_number(tolerance, "curve tolerance", 0.0, 1.0), every=_whole(every, "curve 'every'"))

    def edit(g):
        item = next((c for c in g.curves if c.curve == curve), None)
        if item is None:
            item = g.curves.add()
            item.curve = curve
            g.active_curve_index = len(g.curves) - 1
        for key, value in values.items():
            setattr(item, key, value)

    _edit_guides(obj, edit)
    return next(c for c in _guide_settings(obj).curves if c.curve == curve)


def remove_curve_guide(obj, curve) -> None:
    """Stop guiding with `curve` (the curve object, or the index of the curve guide)."""
    g = _guide_settings(obj)
    if isinstance(curve, (int, np.integer)) and not isinstance(curve, bool):
        index = int(curve)
        if not 0 <= index < len(g.curves):
            raise NFieldError(f"curve guide {index} does not exist (the object has {len(g.curves)})")
    else:
        index = next((i for i, c in enumerate(g.curves) if c.curve == curve), None)
        if index is None:
            raise NFieldError(f"{getattr(curve, 'name', curve)!r} is not a curve guide of '{obj.name}'")

    def edit(g):
        g.curves.remove(index)
        g.active_curve_index = max(0, min(g.active_curve_index, len(g.curves) - 1))

    _edit_guides(obj, edit)


def set_mirror_symmetry(obj, axis: str | None, *, offset: float = 0.0, tolerance: float = 1e-5,
                        partial: bool = False) -> dict | None:
    """Make the field mirror-symmetric about the plane {axis = offset} of the object ("x", "y", "z"; None:
    off): the solve holds u(mirror f) = reflect(u(f)) exactly. Faces without a partner within `tolerance`
    (fraction of the diagonal) refuse with their list, or with partial=True the symmetry holds on the
    matched faces. Returns the matching summary (matched, unmatched faces, largest mismatch)."""
    a = "NONE" if axis is None else str(axis).upper()
    if a not in ("NONE", "X", "Y", "Z"):
        raise NFieldError(f"mirror axis must be 'x', 'y', 'z' or None (got {axis!r})")
    off = _number(offset, "mirror offset", None, None)
    tol = _number(tolerance, "mirror tolerance (fraction of the diagonal)", 0.0, 0.1)

    def edit(g):
        g.mirror_axis, g.mirror_offset, g.mirror_tolerance, g.mirror_partial = a, off, tol, bool(partial)

    _edit_guides(obj, edit)
    if a == "NONE":
        return None
    return open_session(obj)[2].symmetry_info


def set_cuts(obj, source: str | None, attribute: str = "") -> None:
    """Cut the connection along marked edges: source "seams" (edges marked as seams), "attribute" (the edges
    where the EDGE attribute `attribute` is set) or None (no cuts). The field may jump across a cut."""
    s = "NONE" if source is None else str(source).upper()
    if s not in ("NONE", "SEAMS", "ATTRIBUTE"):
        raise NFieldError(f"cut source must be 'seams', 'attribute' or None (got {source!r})")

    def edit(g):
        g.cut_source = s
        if s == "ATTRIBUTE":
            g.cut_attribute = str(attribute)

    _edit_guides(obj, edit)


def guide_report(obj) -> dict | None:
    """What the guides did in the last solve of `obj` (nfield.core GuideReport.to_dict(): feature edges and
    chains, corners, hard constraints and the dropped ones with reasons, curves that miss the surface, cuts,
    symmetry), or None when it was not solved since the mesh last changed."""
    entry = session_cache.get_entry_cached(obj)
    report = None if entry is None or entry.session is None else entry.session.guide_report
    return None if report is None else report.to_dict()


def comb(obj, points, directions, *, radius: float = 0.03, falloff: str = "smooth", strength: float = 1.0) -> int:
    """One comb stroke: samples (points on the surface and drag directions, object space) paint guide
    directions within `radius` (fraction of the bounding-box diagonal) with a falloff ("smooth", "linear",
    "constant") and a strength in (0, 1]. Strokes accumulate into the comb field, stored in the face attributes
    guides.COMB_DIRECTION / COMB_WEIGHT (saved, undoable); the comb field guides the next solve. Returns the
    number of faces the stroke changed."""
    if jobs.busy(obj):
        raise NFieldError(f"'{obj.name}' is being solved in the background: wait for it to finish or press Esc")
    _arrays, _entry, session = open_session(obj)
    try:
        changed = session.comb(points, directions, radius, falloff, strength)
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    guides.write_comb_field(obj, *session.comb_field)
    session.set_comb(*guides.comb_field(obj))  # the session holds what the file holds (float32 attributes)
    return int(len(changed))


def clear_comb(obj) -> bool:
    """Remove the comb field (its attributes). Returns True if there was one."""
    check_mesh_object(obj)
    found = guides.remove_comb_field(obj)
    open_session(obj)
    return found


def guide_summary(obj) -> list[str]:
    """guide_report as readable lines (the panel shows them); [] when there is nothing to say."""
    entry = session_cache.get_entry_cached(obj)
    report = None if entry is None or entry.session is None else entry.session.guide_report
    return [] if report is None else report.summary()


def mirror_design(obj) -> int:
    """Add the mirror image of every constraint and singularity of the design that has none yet (mirror
    symmetry must be on). Returns how many items were added."""
    arrays, entry, session = open_session(obj)
    if session.symmetry is None:
        raise NFieldError("mirror symmetry is off: set a mirror axis first")
    st = obj.nfield
    dirs, sings = design.desired_design(obj)
    added = 0
    for face, (kind, d) in sorted(dirs.items()):
        c = (VectorConstraint if kind == "VECTOR" else DirectionConstraint)(face, d)
        m = session.mirrored(c)
        if m is None or m.face in dirs:
            continue
        design.set_constraint(obj, m.face, m.vector if kind == "VECTOR" else m.direction, kind,
                              arrays.polygon_centers[m.face])
        added += 1
    for vertex, index in sorted(sings.items()):
        m = session.mirrored(SingularityConstraint(vertex, index))
        if m is None or m.vertex in sings:
            continue
        design.set_singularity(obj, m.vertex, int(round(index * st.n)), arrays.vertices[m.vertex])
        added += 1
    return added


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


# ------------------------------------------------------------------------------------------ quad remeshing
#: the remesher's quality figures copied onto the new object (custom property ``nfield_remesh``) and reported
REMESH_INFO_KEYS = ("num_faces", "num_quads", "quad_fraction", "irregular_vertices", "field_singularities",
                    "alignment_mean_deg", "alignment_p95_deg", "hausdorff_relative", "min_scaled_jacobian",
                    "inverted_faces", "manifold", "oriented", "edge_length", "seconds")


def field_state(obj) -> str:
    """Whether the object's last solved field is the one of its current settings and design: "current",
    "outdated" (a constraint, singularity, layer or setting changed since, or undo put back an older
    design), "unknown" (guides read mesh data the design key does not cover: edges, attributes, curves)
    or "none" (no field solved for the current mesh)."""
    _, entry = synced_entry(obj)
    if entry.result is None:
        return "none"
    if entry.extra.get("stale_reason"):
        return "outdated"
    try:
        key = results.design_key(obj, entry)
    except results.Unkeyable:
        return "unknown"
    for k, r in entry.extra.get("history", ()):
        if r is entry.result:
            return "current" if k == key else "outdated"
    return "unknown"


def remesh_recipe(obj, *, target_faces: int | None = 5000, edge_length: float | None = None,
                  pure_quads: bool = False, keep_boundary: bool = True, sharp_angle: float | None = 40.0,
                  seed: int = 0, cancel_position_singularities: bool = True, solve_first: bool = True) -> dict:
    """Everything a quad remesh of `obj` needs, read in the main thread: the core mesh of its base mesh and
    its current field (the last solve; NFieldError if it has none: solve first). Options as in
    nfield.core.quad_remesh (`edge_length` in object units wins over `target_faces`; `sharp_angle` in degrees,
    None keeps only the boundary). When the design changed since the last solve (field_state "outdated"),
    `solve_first` solves it again here (NFieldError if that needs a spectral basis first: the Solve button
    computes it in the background); off, the last solved field is remeshed. Either way recipe["notes"] says
    so. Run it with remesh_from_recipe (any thread), then adopt_remesh."""
    check_mesh_object(obj)
    if jobs.busy(obj):
        raise NFieldError(f"'{obj.name}' is being solved in the background: wait for it to finish or press Esc")
    notes = []
    if field_state(obj) == "outdated":
        if solve_first:
            if pending_work(obj) == "basis":
                raise NFieldError(f"the design of '{obj.name}' changed since its last solve, and solving it again "
                                  f"needs the spectral basis first: press Solve (it runs in the background), then "
                                  f"remesh")
            solve(obj)
            notes.append("the design changed since the last solve: solved it again before remeshing")
        else:
            notes.append("the design changed since the last solve: remeshed the last solved field "
                         "(solve to follow the current design)")
    _, entry = synced_entry(obj)
    result = entry.result
    if result is None:
        raise NFieldError(f"'{obj.name}' has no field to follow: solve its field first (nfield panel, Solve)")
    if edge_length is not None:
        edge_length = float(edge_length)
        if not math.isfinite(edge_length) or edge_length <= 0:
            raise NFieldError(f"the edge length must be a positive number of object units, got {edge_length}")
        target_faces = None
    elif target_faces is None or int(target_faces) < 1:
        raise NFieldError(f"the target face count must be at least 1, got {target_faces}")
    options = {"target_faces": None if target_faces is None else int(target_faces), "edge_length": edge_length,
               "pure_quads": bool(pure_quads), "keep_boundary": bool(keep_boundary),
               "sharp_angle": None if sharp_angle is None else float(sharp_angle), "seed": int(seed),
               "cancel_position_singularities": bool(cancel_position_singularities)}
    return {"object": obj.name, "mesh": entry.mesh, "field": result, "options": options, "notes": notes}


def remesh_from_recipe(recipe: dict, progress=None):
    """In any thread: nfield.core.quad_remesh on the recipe (reads no Blender data; releases the GIL).
    progress(fraction) returning False cancels (nfield.core.Cancelled). NFieldError for what the remesher
    refuses (a field that is not a cross, line or vector field, a target it cannot meet)."""
    try:
        qm = core_quad_remesh(recipe["mesh"], recipe["field"], progress=progress, **recipe["options"])
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    qm.stats["messages"] = list(recipe.get("notes", ())) + qm.stats["messages"]
    return qm


def adopt_remesh(obj, recipe: dict, quad_mesh):
    """Main thread: the new object from a remesh result (beside `obj`, selected and active). Returns it."""
    V, faces, stats = quad_mesh
    if not faces:
        raise NFieldError(f"the remesh of '{obj.name}' produced no faces: "
                          + ("; ".join(stats.get("messages", [])) or "try a larger target face count"))
    info = {k: stats[k] for k in REMESH_INFO_KEYS if k in stats}
    info["source"] = obj.name
    info["field_n"] = int(recipe["field"].n)
    info["seed"] = recipe["options"]["seed"]
    return remesh_object.create(obj, V, faces, name=f"{obj.name}_quads", info=info)


def quad_remesh(obj, *, target_faces: int | None = 5000, edge_length: float | None = None,
                pure_quads: bool = False, keep_boundary: bool = True, sharp_angle: float | None = 40.0,
                seed: int = 0, cancel_position_singularities: bool = True, solve_first: bool = True,
                progress=None):
    """A new quad mesh object beside `obj` whose edges follow its designed field (blocking; `obj` is left
    as it is; a design changed since the last solve is solved again first unless `solve_first` is False,
    see remesh_recipe). Returns (new object, stats) (stats: nfield.core.quad_remesh's quality figures;
    stats["messages"] starts with what was done about an outdated field)."""
    recipe = remesh_recipe(obj, target_faces=target_faces, edge_length=edge_length, pure_quads=pure_quads,
                           keep_boundary=keep_boundary, sharp_angle=sharp_angle, seed=seed,
                           cancel_position_singularities=cancel_position_singularities, solve_first=solve_first)
    qm = remesh_from_recipe(recipe, progress)
    return adopt_remesh(obj, recipe, qm), qm.stats


# ------------------------------------------------------------------------------------------ for the add-on
# Not part of the scripting API: what the operators, the modal tools and the handlers need beyond it.
def synced_entry(obj):
    """(MeshArrays, session cache entry) of `obj` after a sync: ``entry.mesh`` is the core Mesh of the current
    mesh, ``entry.result`` its last field (None if none since the mesh changed). Builds no session."""
    arrays, _ = sync(obj)
    return arrays, session_cache.get_entry(obj, arrays)


def open_session(obj):
    """(MeshArrays, session cache entry, DesignSession) of `obj` after a sync, matching its settings and
    design. The session may still have to factor or compute a basis (see pending_work). Callers that may
    run while a worker thread owns the session check ``jobs.busy(obj)`` first."""
    arrays, entry = synced_entry(obj)
    return arrays, entry, session_cache.ensure_session(obj, entry)


def pending_work(obj) -> str | None:
    """What the next solve of `obj` must compute first: "factorization", "basis" or None."""
    return open_session(obj)[2].pending_work()


def adopt_result(obj, entry, arrays, result) -> None:
    """A worker thread solved `entry`'s session: record `result` and write the attributes (if set to)."""
    store_result(obj, entry, result)
    if obj.nfield.write_attributes:
        attributes.write(obj, arrays, result, obj.nfield.n)


def revert_settings(obj) -> list[str]:
    """Put back the settings of the object's last successful solve (a new setting was refused). Returns what
    was changed, as "Alignment back to None" texts (empty if nothing differed or nothing was solved yet)."""
    entry = session_cache.get_entry_cached(obj)
    good = None if entry is None else entry.extra.get("good_settings")
    if good is None:
        return []
    st = obj.nfield
    reverted = []
    with design.suspended_updates():
        for key, value in zip(design.SETTING_KEYS, good):
            if key != "live_update" and getattr(st, key) != value:
                reverted.append(f"{st.bl_rna.properties[key].name} back to {_shown(st, key, value)}")
                setattr(st, key, value)
    return reverted


def _shown(st, key: str, value) -> str:
    prop = st.bl_rna.properties[key]
    if prop.type == "ENUM":
        return next((it.name for it in prop.enum_items if it.identifier == value), str(value))
    return f"{value:g}" if isinstance(value, float) else str(value)


def background_recipe(obj):
    """(MeshArrays, entry, recipe) for building `obj`'s session in a worker thread (session_cache.build_session,
    which reads no Blender data), after a sync. Adopt the outcome with adopt_session."""
    arrays, entry = synced_entry(obj)
    return arrays, entry, session_cache.session_recipe(obj, entry)


def build_from_recipe(recipe: dict, progress=None):
    """In a worker thread: build and solve the session a recipe describes (reads no Blender data).
    Returns (session, result)."""
    return session_cache.build_session(recipe, progress)


def adopt_session(obj, entry, arrays, recipe, session, result) -> None:
    """Install a session built from background_recipe and record its first result."""
    session_cache.install_session(obj, entry, recipe, session)
    adopt_result(obj, entry, arrays, result)
