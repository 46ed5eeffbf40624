"""Write a designed field to mesh attributes (object space, base mesh).

* face domain, FLOAT_VECTOR (``direction_attribute``, default ``nfield_direction``): the first of the n unit
  directions per polygon, tangent to the polygon (a polygon's direction comes from its first triangle and is
  projected onto the polygon's plane, see nfield.core.shading.polygon_tangent_directions); zero on faces
  excluded from the field (degenerate faces);
* point domain, FLOAT_VECTOR (``smooth_attribute``, default ``nfield_direction_smooth``): the n-symmetry-aware
  vertex average (nfield.core.shading.vertex_smoothed_directions); zero where the average vanishes;
* point domain, FLOAT (``singularity_attribute``, default ``nfield_singularity``): the singularity index of
  each vertex (0 for regular vertices; multiples of 1/n).

An empty name skips that attribute. An existing attribute with the same name but another domain or type
is replaced. In edit mode the values are written into the edit mesh (bmesh layers) so they survive leaving
edit mode.
"""
from __future__ import annotations

import bmesh
import numpy as np

from ..core import shading


def field_arrays(arrays, result, n: int) -> dict:
    """The three attribute arrays for a FieldResult on the mesh described by `arrays` (mesh_read.MeshArrays)."""
    poly_dirs = shading.polygon_tangent_directions(np.asarray(result.directions), arrays.polygon_normals)
    tri_dirs = poly_dirs[arrays.triangle_polygon]
    smooth = shading.vertex_smoothed_directions(arrays.vertices, arrays.triangles, tri_dirs, n)
    sing = shading.vertex_singularity_index(arrays.vertices.shape[0], result.singularities)
    return {"FACE": poly_dirs, "POINT": smooth, "SINGULARITY": sing}


def write(obj, arrays, result, n: int) -> list[str]:
    """Write the attributes named in ``obj.nfield``; returns the names written."""
    st = obj.nfield
    data = field_arrays(arrays, result, n)
    jobs = [
        (st.direction_attribute, "FACE", "FLOAT_VECTOR", data["FACE"]),
        (st.smooth_attribute, "POINT", "FLOAT_VECTOR", data["POINT"]),
        (st.singularity_attribute, "POINT", "FLOAT", data["SINGULARITY"]),
    ]
    jobs = [j for j in jobs if j[0]]
    if obj.mode == "EDIT":
        _write_bmesh(obj, jobs)
    else:
        me = obj.data
        for name, domain, dtype, values in jobs:
            attr = _ensure_attribute(me, name, domain, dtype)
            key = "vector" if dtype == "FLOAT_VECTOR" else "value"
            attr.data.foreach_set(key, np.ascontiguousarray(values, dtype=np.float32).ravel())
        me.update()
    return [j[0] for j in jobs]


def _ensure_attribute(me, name, domain, dtype):
    attr = me.attributes.get(name)
    if attr is not None and (attr.domain != domain or attr.data_type != dtype):
        me.attributes.remove(attr)
        attr = None
    if attr is None:
        attr = me.attributes.new(name=name, type=dtype, domain=domain)
    return attr


def _write_bmesh(obj, jobs) -> None:
    me = obj.data
    bm = bmesh.from_edit_mesh(me)
    for name, domain, dtype, values in jobs:
        seq = bm.faces if domain == "FACE" else bm.verts
        seq.ensure_lookup_table()
        layers = seq.layers.float_vector if dtype == "FLOAT_VECTOR" else seq.layers.float
        # a same-named layer of another type/domain would clash: remove it
        for other in (bm.faces.layers.float_vector, bm.faces.layers.float, bm.verts.layers.float_vector,
                      bm.verts.layers.float):
            lay = other.get(name)
            if lay is not None and other is not layers:
                other.remove(lay)
        layer = layers.get(name) or layers.new(name)
        if dtype == "FLOAT_VECTOR":
            for elem, val in zip(seq, values.tolist()):
                elem[layer] = val
        else:
            for elem, val in zip(seq, values.tolist()):
                elem[layer] = val
    bmesh.update_edit_mesh(me)
