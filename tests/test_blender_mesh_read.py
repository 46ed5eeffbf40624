"""The mesh reader, the one change check and the singularity tool's index rule in the installed add-on
(headless PyPI ``bpy``). Fixtures and helpers: tests/blender_support.py.

* ``mesh_read.overlay_geometry`` computes polygon centroids, normals, areas and mean edge lengths with numpy
  from the one mesh read; they must equal what Blender itself reports for the same polygons (quads, an
  n-gon, triangles);
* the mesh signature is the only change check: moving a single vertex (of thousands) changes it, and the
  picking BVH and the overlay geometry follow at once (the checks they replaced sampled the coordinates and
  could miss such a move);
* the singularity tool offers exactly the numerators ``DesignSession.set_singularity`` accepts.
"""
from __future__ import annotations

import importlib
import types

import numpy as np
import pytest
from blender_support import blender_module, bpy, nf, object_from_arrays, scene  # noqa: F401  (fixtures)
from mathutils import Vector

pytestmark = pytest.mark.blender

#: Blender computes its polygon quantities from the float32 coordinates in float32, mesh_read in float64 from
#: the same float32 coordinates: they agree to float32 rounding, ~1e-7 relative to the coordinates (size ~1
#: here); 1e-5 is far below any real difference (a wrong polygon or corner is off by ~0.1).
F32_TOL = 1e-5


def _bent_grid(nx: int = 40, ny: int = 30):
    """A bent sheet of nx x ny quads whose first row of quads is merged into one n-gon, plus a fan of
    triangles: every polygon kind the reader meets. Returns (vertices, polygons)."""
    xs, ys = np.linspace(0.0, 2.0, nx + 1), np.linspace(0.0, 1.5, ny + 1)
    V = [(x, y, 0.3 * np.sin(2.0 * x) * np.cos(1.5 * y)) for y in ys for x in xs]
    idx = lambda i, j: j * (nx + 1) + i  # noqa: E731
    polys = [[idx(i, 0) for i in range(nx + 1)] + [idx(i, 1) for i in range(nx, -1, -1)]]  # the n-gon
    polys += [[idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)]
              for j in range(1, ny - 1) for i in range(nx)]
    for i in range(nx):  # the last row as two triangles per cell
        a, b, c, d = idx(i, ny - 1), idx(i + 1, ny - 1), idx(i + 1, ny), idx(i, ny)
        polys += [[a, b, c], [a, c, d]]
    return np.array(V), polys


def _object(name="sheet"):
    V, P = _bent_grid()
    me = bpy.data.meshes.new(name)
    me.from_pydata(V.tolist(), [], P)
    me.update()
    obj = bpy.data.objects.new(name, me)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    return obj


def _blender_polygons(me):
    n = len(me.polygons)
    out = {}
    for key, width in (("center", 3), ("normal", 3), ("area", 1)):
        buf = np.empty(n * width, dtype=np.float32)
        me.polygons.foreach_get(key, buf)
        out[key] = buf.reshape(n, width) if width == 3 else buf
    return out


def test_overlay_geometry_matches_blender(scene):
    mr = blender_module(scene, "mesh_read")
    obj = _object()
    me = obj.data
    g = mr.overlay_geometry(obj)
    ref = _blender_polygons(me)
    assert len(me.polygons[0].vertices) == 82  # the n-gon is there
    assert np.abs(g.centroids - ref["center"]).max() < F32_TOL
    assert np.abs(g.normals - ref["normal"]).max() < F32_TOL
    assert np.abs(g.areas - ref["area"]).max() < F32_TOL * ref["area"].max()
    co = np.array([v.co for v in me.vertices])
    mean_edge = [np.mean([np.linalg.norm(co[a] - co[b]) for a, b in p.edge_keys]) for p in me.polygons]
    assert np.abs(g.edge_len - mean_edge).max() < F32_TOL
    vn = np.array([v.normal for v in me.vertices])
    assert np.abs(g.vnormals - vn).max() < F32_TOL


def test_one_change_check_follows_a_single_vertex(scene):
    """Raise one interior vertex of ~1300 by 0.25: the signature changes (the topology part does not), a ray
    cast straight down onto that vertex hits it at its new height, and the overlay's centroids moved."""
    mr = blender_module(scene, "mesh_read")
    obj = _object()
    me = obj.data
    a0 = mr.mesh_arrays(obj)
    tree0, _ = mr.bvh(obj)
    g0 = mr.overlay_geometry(obj)
    v = 17 * 41 + 23  # an interior vertex of the quad rows
    p = Vector(me.vertices[v].co)
    hit0 = tree0.ray_cast(p + Vector((0, 0, 5)), Vector((0, 0, -1)))[0]
    assert hit0 is not None and abs(hit0.z - p.z) < F32_TOL
    me.vertices[v].co.z += 0.25
    me.update()
    a1 = mr.mesh_arrays(obj)
    assert a1.signature != a0.signature and mr.topology_of(a1.signature) == mr.topology_of(a0.signature)
    tree1, triangle_polygon = mr.bvh(obj)
    assert tree1 is not tree0
    loc, _, tri, _ = tree1.ray_cast(p + Vector((0, 0, 5)), Vector((0, 0, -1)))
    assert abs(loc.z - (p.z + 0.25)) < F32_TOL
    assert v in me.polygons[int(triangle_polygon[tri])].vertices
    g1 = mr.overlay_geometry(obj)
    moved = np.flatnonzero(np.abs(g1.centroids - g0.centroids).max(axis=1) > 0)
    assert sorted(moved) == sorted(poly.index for poly in me.polygons if v in poly.vertices)  # its four quads
    assert mr.mesh_arrays(obj).signature == a1.signature and mr.bvh(obj)[0] is tree1  # unchanged: reused


def test_singularity_tool_offers_what_the_session_accepts(scene):
    """The numerators the tool cycles through (from DesignSession.index_range) are exactly the ones
    set_singularity accepts: one beyond either end is refused; a boundary vertex offers none, with the
    session's message."""
    nb = importlib.import_module(scene.__name__ + ".blender")
    api = blender_module(scene, "api")
    tool = blender_module(scene, "tool_singularity").NFIELD_OT_singularity_tool
    obj = _object()
    nb.configure(obj, n=4, live_update=False)
    _, _, session = api.open_session(obj)
    for vertex in (17 * 41 + 23, 5 * 41 + 7):
        probe = types.SimpleNamespace(_session=session, _vertex=vertex)
        valid, why = tool._valid_numerators(probe, 4)
        assert valid and 0 not in valid and valid == sorted(valid), (valid, why)
        for k in valid:
            session.set_singularity(vertex, k / 4)
        for k in (min(valid) - 1, max(valid) + 1):
            with pytest.raises(ValueError, match="cannot carry index"):
                session.set_singularity(vertex, k / 4)
        session.remove_singularity(vertex)
    valid, why = tool._valid_numerators(types.SimpleNamespace(_session=session, _vertex=0), 4)  # a corner
    assert valid == [] and "vertex 0" in why
