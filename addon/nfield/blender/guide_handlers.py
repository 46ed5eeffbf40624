"""Live curve guides: when a curve object that guides a mesh changes (points edited, moved), the mesh
re-solves (only with Live Update on and a field already solved).

In an interactive Blender with the exact solver, the edit is solved live: ``DesignSession.solve(live=True)``
solves a region around the faces whose guide changed exactly, the rest held at the last global solution (a
soft curve's band changes the weights there, and a global solve would have to factor again), and the
global solve that the session then asks for (``pending_work``) runs in the background operator when the
drag pauses. Elsewhere (scripts, headless, spectral mode) it re-solves as if a setting had changed
(``handlers.on_setting_changed``).

One ``depsgraph_update_post`` handler. The curve is read in the mesh's object space.
"""
from __future__ import annotations

import bpy

from . import api, design, handlers, jobs, session_cache
from .guides import CURVE_TYPES

_running = False  # a re-solve writes attributes, which posts another depsgraph update: ignore our own


def _guided_meshes(changed: set[str]) -> list:
    """Mesh objects with a curve guide whose curve (or the mesh itself, when it moved) is in `changed`."""
    out = []
    for obj in bpy.data.objects:
        g = getattr(obj, "nfield_guides", None) if obj.type == "MESH" else None
        if g is None or len(g.curves) == 0:
            continue
        if any(c.curve is not None and c.curve.name in changed for c in g.curves):
            out.append(obj)
    return out


def resolve_after_curve_edit(obj) -> None:
    """Re-solve `obj` after one of its guide curves changed (see the module docstring); problems go to the
    panel message, never out of the handler."""
    st = obj.nfield
    entry = session_cache.get_entry_cached(obj)
    if not st.live_update or entry is None or entry.result is None or design.updates_suspended():
        return
    if not jobs.interactive() or st.solver_mode != "EXACT":
        handlers.on_setting_changed(obj.nfield_guides, bpy.context)
        return
    if jobs.busy(obj):  # the worker owns the session: solve again when it is done
        jobs.defer(obj)
        return
    try:
        _arrays, entry, session = api.open_session(obj)  # applies the moved curve
        if session.field is None:  # nothing to hold fixed: the global solve, in the background
            jobs.start_later(obj.name)
            return
        api.store_result(obj, entry, session.solve(live=True))
        if session.pending_work() == "factorization":
            st.last_message = "Curve guide solved live; the global solve runs in the background (Esc cancels)"
            jobs.start_later(obj.name)
    except Exception as exc:  # noqa: BLE001 - handlers must not raise
        st.last_message = f"Solve failed: {exc}"


@bpy.app.handlers.persistent
def on_depsgraph_update(scene, depsgraph) -> None:
    global _running
    if _running:
        return
    changed = set()
    for update in depsgraph.updates:
        idb = update.id
        original = getattr(idb, "original", idb)
        if isinstance(original, bpy.types.Object) and original.type in CURVE_TYPES and (
                update.is_updated_geometry or update.is_updated_transform):
            changed.add(original.name)
    if not changed:
        return
    _running = True
    try:
        for obj in _guided_meshes(changed):
            resolve_after_curve_edit(obj)
    finally:
        _running = False


def register():
    if on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)


def unregister():
    if on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(on_depsgraph_update)
