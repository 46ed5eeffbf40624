"""Blender's callbacks into nfield: the settings' update callback, file load and undo/redo.

* :func:`on_setting_changed` is the ``update`` callback of every field setting (``properties``): with *Live
  Update* on it solves (also before the first solve; a solve that needs a factorization goes to the
  background operator; defers while a worker owns the session; never computes a spectral basis in the UI).
  A setting the solver refuses is reverted to the last one that solved, and the message says why.
* :func:`on_load_post`: a file was loaded, every cached mesh read, session and overlay batch belonged to the
  previous file.
* :func:`on_undo_redo`: undo/redo restored the design (``obj.nfield``) and the attributes. It never solves
  in the UI thread: the field solved earlier for the restored state is put back (``results`` history), or
  the field is shown stale and the solve is handed to the background operator.

:func:`register` installs the app handlers (load_post, undo_post, redo_post); the update callback is wired
by the properties themselves.
"""
from __future__ import annotations

import bpy

from . import api, design, jobs, mesh_read, overlay, results, session_cache


def on_setting_changed(settings, context) -> None:
    """Property update callback of properties.NFieldSettings: with Live Update on, solve for the new setting
    (also before the first solve). A change the solver refuses is reverted, and the message says why."""
    obj = settings.id_data
    if obj is None or getattr(obj, "type", None) != "MESH" or design.updates_suspended():
        return
    st = obj.nfield
    if not st.live_update:
        return
    if jobs.busy(obj):  # the worker owns the session: solve again when it is done
        jobs.defer(obj)
        return
    if st.alignment == "ATTRIBUTE" and not st.alignment_attribute:
        st.last_message = "Choose the face attribute to align to (Alignment: Face Attribute)"
        return  # half-way through a two-step choice: nothing to solve or revert yet
    try:
        arrays, entry, _session = api.open_session(obj)
        if session_cache.spectral_basis_pending(obj, entry):
            st.last_message = (f"Spectral basis of {st.spectral_k} eigenfields not computed yet: "
                               f"press Precompute (runs in the background, Esc cancels)")
            return
        if jobs.interactive() and entry.session.pending_work() == "factorization":
            st.last_message = "Solving in the background (Esc cancels)"
            jobs.start_later(obj.name)
            return
        api.solve(obj)
    except Exception as exc:  # a bad setting must not raise from an update callback
        _revert_setting(obj, exc)


def _revert_setting(obj, exc: Exception) -> None:
    """The solver refused the new settings: put back the last settings that solved (if any) and say why."""
    reverted = api.revert_settings(obj)
    obj.nfield.last_message = f"Solve failed: {exc}" + (f". Reverted: {', '.join(reverted)}" if reverted else "")


@bpy.app.handlers.persistent
def on_load_post(*_args) -> None:
    """A file was loaded: everything cached belongs to the previous file."""
    forget_everything()


@bpy.app.handlers.persistent
def on_undo_redo(*_args) -> None:
    """Undo/redo restored the designs and attributes. Never solves here (the UI thread): the field of the
    restored state is put back if it was solved before (results history), otherwise the field is marked
    stale and, with Live Update on, the solve goes to the background operator (or waits for a running one)."""
    overlay.results_reset()
    for name in session_cache.cached_names():
        obj = bpy.data.objects.get(name)
        if obj is None or obj.type != "MESH":
            session_cache.clear(name)
            continue
        entry = session_cache.get_entry_cached(obj)
        try:
            same_mesh = entry.signature == mesh_read.mesh_arrays(obj).signature
            restored = results.remembered_result(obj, entry) if same_mesh else None
        except Exception:  # noqa: BLE001 - handlers must not raise
            restored = None
        entry.result = restored
        entry.version += 1
        if restored is not None:
            entry.extra.pop("stale_reason", None)
            results.notify_overlay(obj, restored, entry.arrays)
            continue
        entry.extra["stale_reason"] = "undo"
        results.notify_overlay(obj)
        if not obj.nfield.live_update:
            continue
        if jobs.busy(obj):
            jobs.defer(obj)
        elif jobs.interactive():
            jobs.start_later(name)


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
