"""nfield's scripting API for Blender (batch scripts, ``blender -b file.blend --python script.py``, PyPI bpy).

    import nfield.blender as nb          # the same name with the extension (it installs the nfield wheel)
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

from ..core import native
from ..core import quad_remesh as core_quad_remesh
from . import attributes, design, mesh_read, remesh_object, results, session_cache
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
from .guide_api import (  # noqa: F401  (the guide part of the scripting API)
    add_curve_guide,
    clear_comb,
    comb,
    comb_samples,
    guide_report,
    guide_summary,
    mirror_design,
    mirror_placements,
    remove_curve_guide,
    set_cuts,
    set_feature_alignment,
    set_guide_attributes,
    set_mirror_symmetry,
    store_comb,
)
from .mesh_read import check_mesh_object
from .object_session import (  # noqa: F401  (what operators, tools and handlers reach through the facade)
    adopt_result,
    adopt_session,
    background_recipe,
    build_from_recipe,
    ensure_idle,
    open_session,
    pending_work,
    revert_settings,
    sync,
    synced_entry,
)
from .results import notify_overlay, store_result  # noqa: F401  (part of the facade)

__all__ = [
    "NFieldError", "configure", "add_constraint", "remove_constraint", "clear_constraints", "add_singularity",
    "remove_singularity", "clear_singularities", "solve", "field", "write_attributes", "begin_region",
    "commit_region", "cancel_region", "release_layer", "precompute_spectral", "sync", "stale_items",
    "set_feature_alignment", "set_guide_attributes", "add_curve_guide", "remove_curve_guide", "set_mirror_symmetry",
    "set_cuts", "guide_report", "guide_summary", "mirror_design", "comb", "clear_comb",
    "quad_remesh", "field_state",
]


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
    ensure_idle(obj)
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


def _end_region_in_session(obj, method: str, not_active: str):
    """Call the session's region method `method` (commit_region / cancel_region) for `obj`, whose region edit
    must be active (else NFieldError(not_active)). Returns the cache entry and the session."""
    check_mesh_object(obj)
    if not obj.nfield.region_active:
        raise NFieldError(not_active)
    _arrays, entry, session = _session_with_field(obj)
    try:
        getattr(session, method)()
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    return entry, session


def commit_region(obj):
    """Make the region's field a layer (frozen in later global solves). Returns the new NFieldLayer."""
    entry, session = _end_region_in_session(obj, "commit_region", "no region edit in progress (begin a region first)")
    st = obj.nfield
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
    entry, session = _end_region_in_session(obj, "cancel_region", "no region edit in progress")
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
    `solve_first` has it solved again by remesh_from_recipe, before the remesh and in the same thread
    (NFieldError here if that needs a spectral basis first: the Solve button computes it in the background);
    off, the last solved field is remeshed. Either way recipe["notes"] says so. Run it with
    remesh_from_recipe (any thread; while it runs, a recipe with recipe["solve"] owns the object's session,
    see jobs.claim), then adopt_remesh, or adopt_recipe_solve alone when the remesh failed."""
    check_mesh_object(obj)
    ensure_idle(obj)
    notes = []
    solve_job = None
    if field_state(obj) == "outdated":
        if solve_first:
            arrays, entry, session = open_session(obj)
            if session.pending_work() == "basis":
                raise NFieldError(f"the design of '{obj.name}' changed since its last solve, and solving it again "
                                  f"needs the spectral basis first: press Solve (it runs in the background), then "
                                  f"remesh")
            solve_job = {"session": session, "entry": entry, "arrays": arrays}
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
    return {"object": obj.name, "mesh": entry.mesh, "field": result, "options": options, "notes": notes,
            "solve": solve_job}


#: the share of the progress bar the solve of an outdated design takes before its remesh
_SOLVE_SHARE = 0.3


def remesh_from_recipe(recipe: dict, progress=None):
    """In any thread: the solve of an outdated design (recipe["solve"], see remesh_recipe), then
    nfield.core.quad_remesh on the recipe (reads no Blender data; releases the GIL). progress(fraction)
    returning False cancels (nfield.core.Cancelled). NFieldError for what the solver or the remesher refuses
    (a field that is not a cross, line or vector field, a target it cannot meet)."""
    field, remesh_progress = recipe["field"], progress
    job = recipe.get("solve")
    if job is not None:
        session = job["session"]
        session.progress = None if progress is None else (lambda f: progress(_SOLVE_SHARE * f))
        try:
            job["result"] = field = session.solve()
        except (ValueError, RuntimeError) as exc:
            if type(exc).__name__ == "Cancelled":
                raise
            raise NFieldError(f"solving the changed design before remeshing failed: {exc}") from None
        finally:
            session.progress = None
        if progress is not None:
            remesh_progress = lambda f: progress(_SOLVE_SHARE + (1.0 - _SOLVE_SHARE) * f)  # noqa: E731
    try:
        qm = core_quad_remesh(recipe["mesh"], field, progress=remesh_progress, **recipe["options"])
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    qm.stats["messages"] = list(recipe.get("notes", ())) + qm.stats["messages"]
    return qm


def adopt_recipe_solve(obj, recipe: dict) -> bool:
    """Main thread: keep the field remesh_from_recipe solved for an outdated design (stored as the object's
    field, attributes written), also when the remesh after it failed or was cancelled. True if there was one."""
    job = recipe.get("solve")
    if job is None or job.get("result") is None or job.get("adopted"):
        return False
    adopt_result(obj, job["entry"], job["arrays"], job["result"])
    job["adopted"] = True
    return True


def adopt_remesh(obj, recipe: dict, quad_mesh):
    """Main thread: the new object from a remesh result (beside `obj`, selected and active), after keeping the
    field solved for it (adopt_recipe_solve). Returns it."""
    adopt_recipe_solve(obj, recipe)
    V, faces, stats = quad_mesh
    if not faces:
        raise NFieldError(f"the remesh of '{obj.name}' produced no faces: "
                          + ("; ".join(stats.get("messages", [])) or "try a larger target face count"))
    info = {k: stats[k] for k in REMESH_INFO_KEYS if k in stats}
    info["source"] = obj.name
    solved = (recipe.get("solve") or {}).get("result")
    info["field_n"] = int((recipe["field"] if solved is None else solved).n)
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
    try:
        qm = remesh_from_recipe(recipe, progress)
    finally:
        adopt_recipe_solve(obj, recipe)  # a field solved for the remesh is kept even if the remesh failed
    return adopt_remesh(obj, recipe, qm), qm.stats
