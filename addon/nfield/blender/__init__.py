"""nfield's Blender layer: settings, operators, panels, scripting API, viewport overlay and tools.

Scripting API (see ``api``)::

    import nfield.blender as nb     # the same name in Blender 4.2+ (the extension installs the nfield wheel)
    nb.add_constraint(obj, 12, (1, 0, 0))
    nb.add_singularity(obj, 7, 0.25)
    result = nb.solve(obj, n=4, order=2, align="curvature-max", strength=1.0)

Data model: per-object settings and design in ``obj.nfield`` (``properties``), object space, base mesh
(modifiers are ignored). This package holds no field math: it only calls ``nfield.core``.

The modules form layers that import only downwards; docs/architecture.md lists them (tests/test_layering.py
checks it). ``register()`` registers every module with Blender classes or handlers, in ``_MODULES`` order.
If the compiled solver cannot be loaded (built for another Python), registration still succeeds and the
panel shows the loader's message instead of a traceback.
"""
from __future__ import annotations

import atexit

import bpy

from . import (
    background,
    guide_handlers,
    guide_operators,
    guide_panels,
    guide_properties,
    handlers,
    hatching,
    material,
    operators,
    overlay,
    panels,
    properties,
    remesh_operator,
    remesh_panel,
    remesh_properties,
    state,
    tools,
)
from .api import (  # noqa: F401  (public scripting API)
    NFieldError,
    add_constraint,
    add_curve_guide,
    add_singularity,
    begin_region,
    cancel_region,
    clear_comb,
    clear_constraints,
    clear_singularities,
    comb,
    commit_region,
    configure,
    field,
    field_state,
    guide_report,
    mirror_design,
    precompute_spectral,
    quad_remesh,
    release_layer,
    remove_constraint,
    remove_curve_guide,
    remove_singularity,
    set_cuts,
    set_feature_alignment,
    set_guide_attributes,
    set_mirror_symmetry,
    solve,
    stale_items,
    sync,
    write_attributes,
)
from .hatching import build as build_hatching  # noqa: F401  (public scripting API)
from .material import build as build_anisotropic_material  # noqa: F401  (public scripting API)

#: modules registered in this order (unregistered in reverse)
_MODULES = (properties, guide_properties, remesh_properties, operators, guide_operators, background, material,
            hatching, remesh_operator, panels, guide_panels, remesh_panel, overlay, tools, handlers, guide_handlers)
_registered: list = []


def _unregister_at_exit() -> None:
    if _registered:
        unregister()


def register():
    if not bpy.app.binary_path and not _registered:
        # Blender as a Python module (PyPI bpy): nothing unregisters add-ons when the interpreter exits, and
        # bpy 4.5 then hangs in its exit handlers when a property with an update callback is still registered
        # (a plain PropertyGroup with update= shows it). Unregistering first lets the process exit.
        atexit.unregister(_unregister_at_exit)
        atexit.register(_unregister_at_exit)
    state.native_problem = state.native_error() or ""
    if state.native_problem:
        print(f"nfield: {state.native_problem}")
    for mod in _MODULES:
        mod.register()
        _registered.append(mod)


def unregister():
    while _registered:
        mod = _registered.pop()
        try:
            mod.unregister()
        except Exception as exc:  # noqa: BLE001 - keep unregistering the rest
            print(f"nfield: unregistering {mod.__name__} failed: {exc}")
    handlers.forget_everything()
