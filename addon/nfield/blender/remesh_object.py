"""The object a quad remesh creates: a new mesh object next to its source (the source stays untouched).

Pure Blender data handling, no nfield imports: ``create`` takes the remesher's vertices (object space of the
source) and polygons and returns the new object, linked into the source's collections, with the source's
transform shifted sideways by the source's width so the two sit side by side.
"""
from __future__ import annotations

import bpy
import numpy as np
from mathutils import Matrix, Vector

#: the custom property on the new object recording where it came from and its quality figures
INFO_PROPERTY = "nfield_remesh"


def _side_offset(source) -> Vector:
    """World translation that puts a copy of `source` beside it: its world-space width along X plus a tenth."""
    corners = [source.matrix_world @ Vector(c) for c in source.bound_box]
    xs = [c.x for c in corners]
    width = max(xs) - min(xs)
    return Vector((1.1 * width if width > 0 else 1.0, 0.0, 0.0))


def create(source, vertices, faces, *, name: str | None = None, info: dict | None = None):
    """A new mesh object with `vertices` (V, 3, object space of `source`) and `faces` (lists of vertex
    indices), placed beside `source`, selected and active (the source is deselected). `info` (flat dict of
    numbers and strings) is stored as the custom property ``nfield_remesh``."""
    V = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    me = bpy.data.meshes.new(name or f"{source.name}_quads")
    me.from_pydata(V.tolist(), [], [list(map(int, f)) for f in faces])
    me.update()
    obj = bpy.data.objects.new(me.name, me)
    obj.matrix_world = Matrix.Translation(_side_offset(source)) @ source.matrix_world
    collections = list(source.users_collection) or [bpy.context.scene.collection]
    for coll in collections:
        coll.objects.link(obj)
    if info:
        obj[INFO_PROPERTY] = {k: v for k, v in info.items() if isinstance(v, (int, float, str, bool))}
    view_layer = bpy.context.view_layer
    if view_layer is not None and obj.name in view_layer.objects:
        for other in view_layer.objects.selected:
            other.select_set(False)
        obj.select_set(True)
        view_layer.objects.active = obj
    return obj
