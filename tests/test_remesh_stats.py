"""The quality statistics of quad meshes (native/include/nfield/remesh/quad_stats.hpp, nfield.core.quad_mesh_stats)
on hand-made polygon meshes whose answers are known exactly."""
from __future__ import annotations

import math

import numpy as np
import pytest

from nfield.core import Mesh, native, quad_mesh_stats
from nfield.core.remesh import polygons_to_arrays


def quad_grid(nx: int, ny: int, h: float = 1.0, z: float = 0.0):
    """(nx x ny) unit quads in the plane z, counter-clockwise seen from +z."""
    V = np.array([[i * h, j * h, z] for j in range(ny + 1) for i in range(nx + 1)], dtype=float)
    vid = lambda i, j: j * (nx + 1) + i  # noqa: E731
    F = [[vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)] for j in range(ny) for i in range(nx)]
    return V, F


def triangulate(V, F):
    T = []
    for f in F:
        T += [[f[0], f[k], f[k + 1]] for k in range(1, len(f) - 1)]
    return np.asarray(T, dtype=np.int64)


def cube():
    V = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], dtype=float)
    F = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return V, F


def manifold(V, F):
    off, idx = polygons_to_arrays(F)
    return native().polygon_manifold_report(np.asarray(V, float), off, idx)


def irregular(V, F):
    off, idx = polygons_to_arrays(F)
    return native().polygon_irregular_vertices(np.asarray(V, float), off, idx)


def test_regular_grid_has_no_irregular_vertex_and_is_manifold():
    V, F = quad_grid(4, 3)
    inner, boundary, valence, on_boundary = irregular(V, F)
    # Interior vertices have 4 edges, straight boundary vertices 3 (1 + 180/90), corners 2 (1 + 90/90).
    assert len(inner) == 0 and len(boundary) == 0
    assert sorted(set(np.asarray(valence).tolist())) == [2, 3, 4]
    r = manifold(V, F)
    assert r["manifold"] and r["oriented"]
    assert r["boundary_edges"] == 2 * (4 + 3)
    assert r["nonmanifold_edges"] == r["inconsistent_edges"] == r["nonmanifold_vertices"] == 0


def test_cube_corners_are_eight_valence_three_vertices():
    V, F = cube()
    inner, boundary, valence, _ = irregular(V, F)
    assert sorted(np.asarray(inner).tolist()) == list(range(8)) and len(boundary) == 0
    assert set(np.asarray(valence).tolist()) == {3}
    r = manifold(V, F)
    assert r["manifold"] and r["oriented"] and r["boundary_edges"] == 0


def test_flipped_face_breaks_orientation_and_has_negative_jacobian():
    V, F = quad_grid(3, 3)
    ref_T = triangulate(V, F)
    F[4] = F[4][::-1]  # the middle quad, reversed
    r = manifold(V, F)
    assert r["manifold"] and not r["oriented"]
    assert r["inconsistent_edges"] == 4  # its four edges are each traversed twice in the same direction
    off, idx = polygons_to_arrays(F)
    q = native().polygon_quality(V, off, idx, V, ref_T)
    jac = np.asarray(q["scaled_jacobians"])
    # Against the reference normal +z a reversed unit square has corners (e1 x e2).z / (|e1||e2|) = -1.
    assert jac[4] == pytest.approx(-1.0, abs=1e-12)
    assert np.allclose(np.delete(jac, 4), 1.0, atol=1e-12)


def test_flipped_means_a_corner_against_the_surface_normal_there():
    """A face is flipped when one of its corners has a scaled Jacobian <= 0 against the input's normal just
    inside that corner (quad_stats.hpp). A dart (a vertex pushed past the diagonal) has a reflex corner; a
    face on the upper side of a thin slab is measured against the upper sheet although the lower one is near;
    a quad on one side of a 90 degree crease, corners on the crease, is measured against its own side."""
    # a dart: (0,0) (2,0) (1,0.5) (1,2) has a reflex corner at (1, 0.5), scaled Jacobian -sin(angle)
    V = np.array([[0, 0, 0], [2, 0, 0], [1, 2, 0], [1, 0.5, 0]], float)
    ref_V = np.array([[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], float)
    ref_T = np.array([[0, 1, 2], [0, 2, 3]])
    off, idx = polygons_to_arrays([[0, 1, 3, 2]])
    jac = np.asarray(native().polygon_quality(V, off, idx, ref_V, ref_T)["scaled_jacobians"])
    e1, e2 = V[2] - V[3], V[1] - V[3]  # at (1, 0.5): to the next vertex (1, 2) and the previous one (2, 0)
    assert jac[0] == pytest.approx(np.cross(e1, e2)[2] / (np.linalg.norm(e1) * np.linalg.norm(e2)), abs=1e-12)
    assert jac[0] < 0
    # a thin slab: two sheets 0.01 apart, facing up (z = 0.01) and down (z = 0); a unit quad lying on the upper
    # sheet, much larger than the gap, is unflipped (1) and the same quad reversed is flipped (-1)
    top, _ = quad_grid(4, 4, h=0.5, z=0.01)
    bottom, _ = quad_grid(4, 4, h=0.5, z=0.0)
    slab_V = np.concatenate([top, bottom])
    T_top = triangulate(*quad_grid(4, 4, h=0.5, z=0.01))
    slab_T = np.concatenate([T_top, T_top[:, ::-1] + len(top)])
    Q = np.array([[0.5, 0.5, 0.01], [1.5, 0.5, 0.01], [1.5, 1.5, 0.01], [0.5, 1.5, 0.01]])
    off, idx = polygons_to_arrays([[0, 1, 2, 3], [3, 2, 1, 0]])
    jac = np.asarray(native().polygon_quality(Q, off, idx, slab_V, slab_T)["scaled_jacobians"])
    assert jac[0] == pytest.approx(1.0, abs=1e-12) and jac[1] == pytest.approx(-1.0, abs=1e-12)
    # a 90 degree crease along the x axis (the plane y >= 0, z = 0 facing +z, the plane z <= 0, y = 0 facing
    # -y): a square on the horizontal side with two corners on the crease scores 1 at every corner
    crease_V = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [0, 0, -2], [2, 0, -2]], float)
    crease_T = np.array([[0, 1, 2], [0, 2, 3], [0, 4, 5], [0, 5, 1]])
    S = np.array([[0.5, 0, 0], [1.5, 0, 0], [1.5, 1, 0], [0.5, 1, 0]])
    off, idx = polygons_to_arrays([[0, 1, 2, 3]])
    jac = np.asarray(native().polygon_quality(S, off, idx, crease_V, crease_T)["scaled_jacobians"])
    assert jac[0] == pytest.approx(1.0, abs=1e-12)


def test_nonmanifold_edge_and_pinched_vertex_are_reported():
    # Three quads on one edge (0, 1).
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, -1, 0], [0, -1, 0], [1, 0, 1], [0, 0, 1]], float)
    F = [[0, 1, 2, 3], [1, 0, 5, 4], [0, 1, 6, 7]]
    r = manifold(V, F)
    assert r["nonmanifold_edges"] == 1 and not r["manifold"]
    # Two squares touching at one vertex (a bow tie).
    V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 1, 0], [2, 2, 0], [1, 2, 0]], float)
    F = [[0, 1, 2, 3], [2, 4, 5, 6]]
    r = manifold(V, F)
    assert r["nonmanifold_vertices"] == 1 and r["nonmanifold_edges"] == 0 and not r["manifold"]


def test_parallelogram_scaled_jacobian_is_sine_of_its_angle():
    a = math.radians(60)
    V = np.array([[0, 0, 0], [1, 0, 0], [1 + math.cos(a), math.sin(a), 0], [math.cos(a), math.sin(a), 0]])
    off, idx = polygons_to_arrays([[0, 1, 2, 3]])
    q = native().polygon_quality(V, off, idx, V, np.array([[0, 1, 2], [0, 2, 3]]))
    assert np.asarray(q["scaled_jacobians"])[0] == pytest.approx(math.sin(a), abs=1e-12)


@pytest.mark.parametrize("degrees, expected", [(0.0, 0.0), (10.0, 10.0), (60.0, 30.0), (-20.0, 20.0), (45.0, 45.0)])
def test_edge_alignment_is_the_angle_to_the_nearest_cross_direction(degrees, expected):
    V, F = quad_grid(3, 2)
    T = triangulate(V, F)
    t = math.radians(degrees)
    dirs = np.tile([math.cos(t), math.sin(t), 0.0], (len(T), 1))
    off, idx = polygons_to_arrays(F)
    q = native().polygon_quality(V, off, idx, V, T, dirs)
    ang = np.asarray(q["edge_alignment_degrees"])
    assert len(ang) == len(np.asarray(q["edges"])) == 3 * 3 + 4 * 2  # horizontal + vertical edges
    # Every edge is along x or y; the cross {t, t + 90, ...} is off by |t| folded into [0, 45].
    assert np.allclose(ang, expected, atol=1e-9)


def test_hausdorff_of_a_lifted_grid_is_the_lift():
    V, F = quad_grid(4, 4)
    T = triangulate(V, F)
    lifted = V + np.array([0, 0, 0.125])
    off, idx = polygons_to_arrays(F)
    q = native().polygon_quality(lifted, off, idx, V, T)
    assert q["hausdorff"] == pytest.approx(0.125, abs=1e-12)
    assert q["distance_to_reference"] == pytest.approx(0.125, abs=1e-12)
    # A grid covering only half of the reference: the uncovered half's far edge is 2 units away.
    Vh, Fh = quad_grid(2, 4)
    off, idx = polygons_to_arrays(Fh)
    q = native().polygon_quality(Vh, off, idx, V, T)
    assert q["distance_to_reference"] == pytest.approx(0.0, abs=1e-12)
    assert q["hausdorff"] == pytest.approx(2.0, abs=1e-12)


def test_quad_mesh_stats_on_a_cube_against_its_own_surface():
    V, F = cube()
    mesh = Mesh(V, triangulate(V, F))
    # Field along x on every triangle: on the x = const faces x is normal, so the cross there is the
    # projection (zero): those faces carry no direction and their edges are not measured.
    dirs = np.tile([1.0, 0.0, 0.0], (mesh.num_triangles, 1))
    normals = np.asarray(mesh.native.face_normals)
    dirs[np.abs(normals[:, 0]) > 0.5] = [0.0, 1.0, 0.0]
    s = quad_mesh_stats(V, F, mesh, dirs, singularities=[(v, 0.25) for v in range(8)])
    assert s["num_faces"] == 6 and s["num_quads"] == 6 and s["quad_fraction"] == 1.0
    assert s["irregular_vertices"] == 8 and s["field_singularities"] == 8 and s["irregular_per_singularity"] == 1.0
    assert s["hausdorff"] == pytest.approx(0.0, abs=1e-12)
    assert s["min_scaled_jacobian"] == pytest.approx(1.0, abs=1e-12) and s["inverted_faces"] == 0
    assert s["alignment_mean_deg"] == pytest.approx(0.0, abs=1e-9)
    assert s["manifold"] and s["oriented"] and s["closed"]


def test_bad_polygon_input_is_refused():
    V, F = quad_grid(1, 1)
    off, idx = polygons_to_arrays(F)
    with pytest.raises(ValueError, match="out of range"):
        native().polygon_manifold_report(V, off, idx + 10)
    with pytest.raises(ValueError, match="at least 3"):
        native().polygon_manifold_report(V, np.array([0, 2]), np.array([0, 1]))
    with pytest.raises(ValueError, match="offsets"):
        native().polygon_manifold_report(V, np.array([0, 5]), idx)
