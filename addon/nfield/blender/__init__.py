"""nfield's Blender layer: settings, operators, panels, scripting API, viewport overlay and tools.

Scripting API (see ``api``)::

    import nfield.blender as nb     # an installed extension is bl_ext.<repo>.nfield.blender
    nb.add_constraint(obj, 12, (1, 0, 0))
    nb.add_singularity(obj, 7, 0.25)
    result = nb.solve(obj, n=4, order=2, align="curvature-max", strength=1.0)

Data model: per-object settings and design in ``obj.nfield`` (``properties``), object space, base mesh
(modifiers are ignored). This package holds no field math: it only calls ``nfield.core``.

``register()`` registers every class of this package, including the overlay (``overlay``) and the
interactive tools (``tools``) when those modules are present. If the compiled solver cannot be loaded
(built for another Python), registration still succeeds and the panel shows the loader's message instead
of a traceback.
"""
from __future__ import annotations

import importlib

import bpy

from . import state
from .api import (  # noqa: F401  (public scripting API)
    NFieldError,
    add_constraint,
    add_singularity,
    begin_region,
    build_anisotropic_material,
    build_hatching,
    cancel_region,
    clear_constraints,
    clear_singularities,
    commit_region,
    configure,
    field,
    precompute_spectral,
    release_layer,
    remove_constraint,
    remove_singularity,
    solve,
    stale_items,
    sync,
    write_attributes,
)

#: modules registered in this order (optional ones may be missing in partial installs)
_MODULES = ("properties", "operators", "background", "material", "hatching", "panels")
_OPTIONAL_MODULES = ("overlay", "tools")
_registered: list = []


def _app_handlers() -> tuple:
    """(handler list, function) pairs that keep the session cache in step with file load and undo/redo."""
    from . import session_cache

    return ((bpy.app.handlers.load_post, session_cache.on_load_post),
            (bpy.app.handlers.undo_post, session_cache.on_undo_redo),
            (bpy.app.handlers.redo_post, session_cache.on_undo_redo))


def _unregister_at_exit() -> None:
    if _registered:
        unregister()


def register():
    if not bpy.app.binary_path and not _registered:
        # Blender as a Python module (PyPI bpy): nothing unregisters add-ons when the interpreter exits, and
        # bpy 4.5 then hangs in its exit handlers when a property with an update callback is still registered
        # (a plain PropertyGroup with update= shows it). Unregistering first lets the process exit.
        import atexit

        atexit.unregister(_unregister_at_exit)
        atexit.register(_unregister_at_exit)
    state.native_problem = state.native_error() or ""
    if state.native_problem:
        print(f"nfield: {state.native_problem}")
    for name in _MODULES + _OPTIONAL_MODULES:
        try:
            mod = importlib.import_module(f"{__name__}.{name}")
        except ImportError as exc:
            if name in _OPTIONAL_MODULES and getattr(exc, "name", "") == f"{__name__}.{name}":
                continue  # that part is not installed
            raise
        mod.register()
        _registered.append(mod)
    for lst, fn in _app_handlers():
        if fn not in lst:
            lst.append(fn)


def unregister():
    from . import session_cache

    for lst, fn in _app_handlers():
        if fn in lst:
            lst.remove(fn)
    while _registered:
        mod = _registered.pop()
        try:
            mod.unregister()
        except Exception as exc:  # noqa: BLE001 - keep unregistering the rest
            print(f"nfield: unregistering {mod.__name__} failed: {exc}")
    session_cache.clear()
