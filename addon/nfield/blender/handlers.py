"""Blender's callbacks into nfield: the settings' update callback, file load and undo/redo.

* :func:`on_setting_changed` is the ``update`` callback of every field setting (``properties``): with *Live
  Update* on and a field already solved, it re-solves (or hands a solve that needs a factorization to the
  background operator; defers while a worker owns the session; never computes a spectral basis in the UI).
* :func:`on_load_post`: a file was loaded, every cached mesh read, session and overlay batch belonged to the
  previous file.
* :func:`on_undo_redo`: undo/redo restored the design (``obj.nfield``) and the attributes; cached objects
  are re-solved in memory (``write=False``: the attributes came back with the design) so the overlay shows
  the restored field.

:func:`register` installs the app handlers (load_post, undo_post, redo_post); the update callback is wired
by the properties themselves.
"""
from __future__ import annotations

import bpy

from . import api, design, jobs, mesh_read, overlay, session_cache


def on_setting_changed(settings, context) -> None:
    """Property update callback of properties.NFieldSettings: re-solve if live update is on."""
    obj = settings.id_data
    if obj is None or getattr(obj, "type", None) != "MESH" or design.updates_suspended():
        return
    st = obj.nfield
    entry = session_cache.get_entry_cached(obj)
    if not st.live_update or entry is None or entry.result is None:
        return
    if jobs.busy(obj):  # the worker owns the session: solve again when it is done
        jobs.defer(obj)
        return
    try:
        if session_cache.spectral_basis_pending(obj, entry):
            st.last_message = (f"Spectral basis of {st.spectral_k} eigenfields not computed yet: "
                               f"press Precompute (runs in the background, Esc cancels)")
            return
        if jobs.interactive() and session_cache.ensure_session(obj, entry).pending_work() == "factorization":
            st.last_message = "Solving in the background (Esc cancels)"
            jobs.start_later(obj.name)
            return
        api.solve(obj)
    except Exception as exc:  # a bad setting must not raise from an update callback
        st.last_message = f"Solve failed: {exc}"


@bpy.app.handlers.persistent
def on_load_post(*_args) -> None:
    """A file was loaded: everything cached belongs to the previous file."""
    forget_everything()


@bpy.app.handlers.persistent
def on_undo_redo(*_args) -> None:
    """Undo/redo restored the designs and attributes: rebuild the overlay from them and re-solve cached
    objects in memory."""
    overlay.results_reset()
    for name in session_cache.cached_names():
        obj = bpy.data.objects.get(name)
        if obj is None or obj.type != "MESH":
            session_cache.clear(name)
            continue
        session_cache.get_entry_cached(obj).result = None
        if not obj.nfield.live_update:
            continue
        try:
            api.solve(obj, write=False)
        except Exception as exc:  # noqa: BLE001 - handlers must not raise
            print(f"nfield: re-solve after undo failed for '{name}': {exc}")


def forget_everything() -> None:
    """Drop every cached mesh read, solver session and overlay batch (file load, unregister)."""
    session_cache.clear()
    mesh_read.forget()
    overlay.forget()


def _app_handlers() -> tuple:
    return ((bpy.app.handlers.load_post, on_load_post),
            (bpy.app.handlers.undo_post, on_undo_redo),
            (bpy.app.handlers.redo_post, on_undo_redo))


def register():
    for lst, fn in _app_handlers():
        if fn not in lst:
            lst.append(fn)


def unregister():
    for lst, fn in _app_handlers():
        if fn in lst:
            lst.remove(fn)
