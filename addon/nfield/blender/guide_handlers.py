"""Live curve guides: when a curve object that guides a mesh changes (points edited, moved, modifiers), the
mesh re-solves, as if one of its settings had changed (``handlers.on_setting_changed``: only with Live Update
on and a field already solved; a solve that needs a new factorization goes to the background operator).

One ``depsgraph_update_post`` handler; the mesh object moving relative to its curve counts too (the curve is
read in the mesh's object space).
"""
from __future__ import annotations

import bpy

from . import handlers
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
            handlers.on_setting_changed(obj.nfield_guides, bpy.context)
    finally:
        _running = False


def register():
    if on_depsgraph_update not in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.append(on_depsgraph_update)


def unregister():
    if on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(on_depsgraph_update)
