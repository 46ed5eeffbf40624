"""An object's solver session as the add-on reaches it: the mesh read and the stored design remapped (`sync`),
the cached session configured to match (`open_session`), results of worker threads adopted, a refused setting
reverted. Below the scripting API (`api`, `guide_api`), which validate their arguments and then come here; the
operators, tools and handlers reach these functions through `api`."""
from __future__ import annotations

from . import attributes, design, jobs, mesh_read, session_cache
from .errors import NFieldError
from .mesh_read import check_mesh_object
from .results import store_result


def ensure_idle(obj) -> None:
    """NFieldError when a worker thread owns `obj` (its session must not be touched until it is done)."""
    if jobs.busy(obj):
        raise NFieldError(f"'{obj.name}' is being solved in the background: wait for it to finish or press Esc")


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
