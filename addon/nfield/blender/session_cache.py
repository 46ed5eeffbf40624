"""In-memory solver sessions, one per object.

A :class:`nfield.core.DesignSession` (warm factorization, spectral basis, regions) is expensive to build, so
one is kept per object in memory, keyed by the object's name and its mesh signature (``mesh_read``: any
change of the mesh drops the object's session). Nothing here is saved: the .blend holds the design
(``obj.nfield``, read through ``design``) and a session is rebuilt from it on demand (after reload, undo,
a mesh change ...). :func:`ensure_session` makes the cached session match the object's settings and stored
design, applying only the differences, so a live edit never refactors what it does not need to.

Work that must not touch Blender data (a worker thread) uses :func:`session_recipe` (main thread) and
:func:`build_session` (any thread), then :func:`install_session` (main thread).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core import DesignSession, DirectionConstraint, SingularityConstraint, VectorConstraint
from . import design, guide_session, mesh_read
from .errors import NFieldError
from .mesh_read import MeshArrays


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
    """Drop the cached sessions (all, or one object's)."""
    if obj_name is None:
        _cache.clear()
    else:
        _cache.pop(obj_name, None)


def cached_names() -> list[str]:
    """Names of the objects that have a cached session entry."""
    return list(_cache)


def get_entry(obj, arrays: MeshArrays | None = None) -> CacheEntry:
    """The cache entry of `obj` for its current mesh (rebuilt when the mesh signature changed)."""
    if arrays is None:
        arrays = mesh_read.mesh_arrays(obj)
    entry = _cache.get(obj.name)
    if entry is None or entry.signature != arrays.signature:
        mesh = mesh_read.core_mesh(arrays)
        entry = CacheEntry(arrays.signature, mesh, arrays)
        _cache[obj.name] = entry
    else:
        entry.arrays = arrays
    return entry


def get_result(obj):
    """The last FieldResult stored for `obj` (results.store_result), None if none since its mesh last changed
    or the file was loaded. Never solves."""
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
        kw["alignment_field"] = mesh_read.read_face_vectors(obj, st.alignment_attribute, mesh.num_faces)
    return kw


def ensure_session(obj, entry: CacheEntry, progress=None):
    """The session of `entry`, created or reconfigured from the object's settings, with the stored design
    applied (diffed against what the session already has). A mode or k change reconfigures the same
    session, so switching between exact and spectral mode keeps both the factorization and the basis."""
    kw = session_settings(obj, entry.mesh)
    state = design.design_state(obj)
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
    else:
        # the callback belongs to this call only: a cached session must not keep (and later call) an old one,
        # e.g. one that cancelled
        entry.session.progress = progress
    if entry.session is not None and _settings_differ(entry.extra.get("settings"), kw):
        try:
            if (entry.extra.get("settings") or {}).get("n", kw["n"]) != kw["n"]:
                # a new n may make a stored index invalid (+1/2 at n = 1): the session's singularities go and
                # apply_design below sets the ones valid for the new n (design.desired_design)
                for c in entry.session.constraints:
                    if isinstance(c, SingularityConstraint):
                        entry.session.remove_singularity(c.vertex)
            entry.session.configure(**kw)
        except ValueError as exc:
            raise NFieldError(str(exc)) from None
        entry.extra["settings"] = kw
    entry.session.progress = progress
    if entry.extra.get("design_state") is None:
        _restore_layers_and_region(obj, entry)
    apply_design(obj, entry.session)
    guide_session.apply_guides(entry.session, guide_session.desired_guides(obj))
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
    return dict(mesh=entry.mesh, settings=settings, design=design.desired_design(obj),
                guides=guide_session.desired_guides(obj))


def build_session(recipe: dict, progress=None):
    """Build a session from a recipe and solve it (no Blender data is read: safe in a worker thread).
    Returns (session, result)."""
    session = DesignSession(recipe["mesh"], **recipe["settings"], progress=progress)
    apply_design(None, session, recipe["design"])
    guide_session.apply_guides(session, recipe.get("guides"))
    result = session.solve()
    session.progress = None
    return session, result


def install_session(obj, entry: CacheEntry, recipe: dict, session) -> None:
    """Adopt a session built by build_session (main thread)."""
    entry.session = session
    entry.extra["settings"] = recipe["settings"]
    entry.extra["design_state"] = None
    _restore_layers_and_region(obj, entry)


def _restore_layers_and_region(obj, entry: CacheEntry) -> None:
    """Fresh session: re-create committed layers (frozen values) and the active region from the design."""
    st = obj.nfield
    session = entry.session
    for layer in st.layers:
        if layer.stale:
            continue
        faces, values = design.layer_arrays(layer)
        try:
            session.restore_layer(faces, values)
        except ValueError as exc:
            layer.stale = True
            st.last_message = f"layer '{layer.name}' cannot be restored: {exc}"
    if st.region_active:
        faces = [it.face for it in st.region_faces]
        try:
            apply_design(obj, session)
            guide_session.apply_guides(session, guide_session.desired_guides(obj))
            if session.field is None:
                session.solve()
            session.begin_region(faces)
        except (ValueError, NFieldError) as exc:
            st.region_active = False
            st.last_message = f"region edit ended: {exc}"
    entry.extra["design_state"] = design.design_state(obj)


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


def apply_design(obj, session, wanted=None) -> None:
    """Make the session's constraints equal to the stored design (only the differences are applied).

    `wanted`: a (constraints, singularities) pair from design.desired_design() gathered earlier; then `obj`
    is not touched (worker threads must not read Blender data)."""
    want_dirs, want_sings = wanted if wanted is not None else design.desired_design(obj)
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
