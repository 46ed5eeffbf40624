"""Guide geometry (native/include/nfield: mesh_edges, features, curve_guide, comb, mirror, mesh_cuts).

What is checked, against exact values of simple meshes or invariants:
  * features of a subdivided cube: its 12 edges bend by exactly 90 degrees, meet three at a time in its
    8 corners, and form 12 chains; an open square's boundary turns at 4 corners;
  * hard-direction merging: two feature edges meeting at 90 degrees agree for n = 4 (the cross holds both)
    and contradict for n = 2 (the face is dropped and named);
  * curve projection: a curve on the surface is kept, one lifted off it by more than the tolerance is
    reported sample by sample; hard curve directions are the curve's tangent (to rounding);
  * comb strokes: the blend rule of comb.hpp (weights kappa + a (1 - kappa), strength-1 strokes overwrite);
  * mirror maps: on a mirror-symmetric sphere every face has a partner, the map sends the field's 3D
    directions to their reflections (1e-12), and the projection makes any field symmetric (1e-14);
  * cuts: the cut mesh keeps faces, frames and areas bit-identical, splits exactly the vertices on the
    cut, and has no dual edge across it; an isolated one-edge slit is reported, not cut.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import meshgen
import mesh_reference as mref
from conftest import core_mesh

nfield_core = pytest.importorskip("nfield.core")
from nfield.core import Mesh, native  # noqa: E402


def geometry(V, F):
    mesh = Mesh(V, F)
    return mesh, native().GuideGeometry(mesh.native)


# ---------------------------------------------------------------------------------------- features
def test_cube_features_edges_corners_chains():
    k = 4
    mesh, g = geometry(*meshgen.box(k))
    angles = np.degrees(np.asarray(g.dihedral_angles()))
    # Exact geometry: cube edges bend by 90 degrees, everything else is flat (rounding only).
    assert np.sum(np.abs(angles - 90) < 1e-9) == 12 * k
    assert np.all((np.abs(angles - 90) < 1e-9) | (angles < 1e-9))
    fs = g.detect_features(boundary=True, sharp_angle=30.0)
    assert fs.num_sharp == 12 * k and fs.num_boundary == 0
    corners = np.asarray(fs.corners)
    assert sorted(np.abs(mesh.vertices[corners]).sum(axis=1).round(12).tolist()) == [3.0] * 8
    assert len(fs.chains) == 12
    for c in fs.chains:
        v = np.asarray(c["vertices"])
        assert len(c["edges"]) == k and not c["closed"]
        assert v[0] in corners and v[-1] in corners


def test_open_square_boundary_turns_at_four_corners():
    mesh, g = geometry(*meshgen.grid(6, 6))
    fs = g.detect_features(boundary=True)
    assert fs.num_boundary == 4 * 5
    assert len(fs.corners) == 4 and len(fs.chains) == 4
    # Without a corner angle limit the boundary is one closed chain.
    fs = g.detect_features(boundary=True, corner_angle=180.0)
    assert len(fs.chains) == 1 and fs.chains[0]["closed"] and len(fs.corners) == 0


def test_marked_feature_edges_must_exist():
    mesh, g = geometry(*meshgen.grid(4, 4))
    with pytest.raises(ValueError, match=r"not edges of the mesh.*\(0, 15\)"):
        g.detect_features(boundary=False, edges=np.array([[0, 1], [0, 15]]))


@pytest.mark.parametrize("n, kept", [(4, True), (2, False), (1, False)])
def test_hard_corner_face_merging(n, kept):
    # grid(2, 2): two triangles; triangle (0, 2, 3) in the corner at vertex 3... every face has two boundary
    # edges meeting at 90 degrees (or 45 degrees with the diagonal), so each face gets two proposals.
    mesh, g = geometry(*meshgen.grid(2, 2))
    fs = g.detect_features(boundary=True, corner_angle=180.0)
    f, d, s = g.feature_hard(fs, n, 1)
    f, d, s = np.asarray(f), np.asarray(d), np.asarray(s)
    assert sorted(np.bincount(f).tolist()) == [2, 2]
    faces, dirs, dropped = native().merge_hard_directions(f, d, s, n, math.radians(1.0))
    if kept:
        assert sorted(np.asarray(faces).tolist()) == [0, 1] and dropped == []
        # the merged direction is the common one, unit length
        assert np.allclose(np.abs(np.asarray(dirs)), 1.0)
    else:
        assert len(faces) == 0 and sorted(x[0] for x in dropped) == [0, 1]
        # the two edges of a face are 90 degrees apart: modulo the n-symmetry that is 90 (n = 1 ... wrap to
        # 180/n at most) -> n = 2: 90 degrees, n = 1: 90 degrees
        assert all(abs(x[3] - 90.0) < 1e-9 for x in dropped)


def test_feature_band_weights_fall_off_by_ring():
    mesh, g = geometry(*meshgen.grid(12, 12))
    fs = g.detect_features(boundary=True, corner_angle=180.0)
    value, weight = (np.asarray(a) for a in g.feature_band(fs, 4, 3))
    # ring 1 (faces touching the boundary) weight 1, ring 2: 2/3, ring 3: 1/3, beyond: 0
    assert set(np.round(weight, 12).tolist()) <= {0.0, 1.0, round(2 / 3, 12), round(1 / 3, 12)}
    assert np.all(np.abs(value) <= weight + 1e-12)
    # along a straight boundary away from corners every contribution agrees: |value| = weight
    cent = mref.face_centroids(mesh.vertices, mesh.faces)
    mid = (np.abs(cent[:, 0] - 0.5) < 0.2) & (cent[:, 1] < 0.05)
    assert mid.any() and np.allclose(np.abs(value[mid]), weight[mid]) and np.all(weight[mid] == 1.0)
    # the field direction there is the boundary's (x axis) for n = 4: rep = e^{i 4 a} with a the x angle
    ops = native().FieldOperators(mesh.native, 4)
    frames = np.asarray(ops.frames)
    ang = np.arctan2(frames[mid, 1, 0], frames[mid, 0, 0])  # angle of the x axis in each face frame
    assert np.allclose(value[mid], np.exp(4j * ang), atol=1e-12)


# ---------------------------------------------------------------------------------------- curves
def test_curve_projection_reports_misses():
    mesh, g = geometry(*meshgen.grid(11, 11))
    x = np.linspace(0.1, 0.9, 20)
    on = np.stack([x, 0.5 + 0 * x, 0 * x], 1)
    c = g.project_curve(on, 0.02, 1e-9)
    assert c.num_missed == 0 and c.num_samples >= 40 and c.max_distance < 1e-15
    lifted = on.copy()
    lifted[10:, 2] = 0.05  # the second half floats 0.05 above the plane
    c = g.project_curve(lifted, 0.02, 0.01)
    assert 0 < c.num_missed < c.num_samples and abs(c.max_distance - 0.05) < 1e-12
    assert len(np.asarray(c.faces)) == c.num_samples - c.num_missed


def test_hard_curve_directions_are_the_tangent():
    mesh, g = geometry(*meshgen.grid(11, 11, random_diagonals=True))
    t = np.linspace(0, 1, 50)
    pts = np.stack([0.1 + 0.8 * t, 0.2 + 0.6 * t ** 2, 0 * t], 1)  # a parabola in the plane
    c = g.project_curve(pts, 0.01, 1e-9)
    n = 2
    f, d, s = (np.asarray(a) for a in g.curve_hard(c, n, 1, 7))
    assert len(f) > 10 and np.all(s == 7)
    ops = native().FieldOperators(mesh.native, n)
    dirs3 = np.asarray(ops.representation_to_directions(np.bincount(f, d.real, mesh.num_faces) + 1j * np.bincount(f, d.imag, mesh.num_faces)))
    faces = np.asarray(c.faces)
    tangents = np.asarray(c.tangents)
    for face in f:
        # mean tangent of the samples in that face, as a line
        tan = tangents[faces == face]
        ref = np.linalg.svd(tan.T @ tan)[0][:, 0]
        assert np.abs(dirs3[face, 0] @ ref) > math.cos(math.radians(2.0))
    every3 = np.asarray(g.curve_hard(c, n, 3, 0)[0])
    assert len(every3) == len(range(0, len(f), 3))


# ---------------------------------------------------------------------------------------- comb
def test_comb_blend_rule():
    mesh, g = geometry(*meshgen.grid(21, 21))
    F = mesh.num_faces
    dirs, w = np.zeros((F, 3)), np.zeros(F)
    p = np.array([[0.5, 0.5, 0.0]])
    x = np.array([[1.0, 0.0, 0.0]])
    y = np.array([[0.0, 1.0, 0.0]])
    d1, w1, ch = g.comb_stroke(dirs, w, 4, p, x, 0.1, "smooth", 0.5)
    ch = np.asarray(ch)
    d1, w1 = np.asarray(d1), np.asarray(w1)
    hit = int(np.argmax(w1))
    assert w1[hit] == 0.5 and np.allclose(d1[hit], [1, 0, 0])
    assert np.all(w1[ch] > 0) and np.all(w1[ch] <= 0.5) and np.count_nonzero(w1) == len(ch)
    # second stroke of strength 0.5 on the same spot: kappa = 0.5 + 0.5 * 0.5
    d2, w2, _ = g.comb_stroke(d1, w1, 4, p, x, 0.1, "smooth", 0.5)
    assert abs(np.asarray(w2)[hit] - 0.75) < 1e-15
    # a perpendicular stroke is the same cross for n = 4: the direction stays a cross direction
    d3, _, _ = g.comb_stroke(np.asarray(d2), np.asarray(w2), 4, p, y, 0.1, "constant", 1.0)
    assert abs(abs(np.asarray(d3)[hit] @ [1, 0, 0]) - 1) < 1e-12 or abs(np.asarray(d3)[hit] @ [0, 1, 0]) > 1 - 1e-12
    # for n = 1 a strength-1 stroke overwrites: the new direction is the stroke's
    d4, w4, _ = g.comb_stroke(np.asarray(d2), np.asarray(w2), 1, p, y, 0.1, "constant", 1.0)
    assert np.allclose(np.asarray(d4)[hit], [0, 1, 0]) and np.asarray(w4)[hit] == 1.0
    with pytest.raises(ValueError, match="strength"):
        g.comb_stroke(dirs, w, 4, p, x, 0.1, "smooth", 1.5)
    with pytest.raises(ValueError, match="falloff"):
        g.comb_stroke(dirs, w, 4, p, x, 0.1, "gaussian", 1.0)


# ---------------------------------------------------------------------------------------- mirror
def test_mirror_map_reflects_directions():
    V, F = meshgen.icosphere(3)
    mesh = Mesh(V, F)
    for axis in "xyz":
        mm = native().MirrorMap(mesh.native, axis, 0.0, 1e-9)
        # the icosahedron's vertices (0, +-1, +-t) and permutations are symmetric about every coordinate plane
        assert mm.num_matched == mesh.num_faces and len(mm.unmatched) == 0
        partner = np.asarray(mm.partner)
        assert np.array_equal(partner[partner], np.arange(mesh.num_faces))
        for n in (1, 2, 4):
            ops = native().FieldOperators(mesh.native, n)
            rng = np.random.default_rng(n)
            z = rng.normal(size=mesh.num_faces) + 1j * rng.normal(size=mesh.num_faces)
            p = np.asarray(mm.project(z, n))
            assert mm.asymmetry(p, n) < 1e-14 and mm.asymmetry(z, n) > 0.1
            d = np.asarray(ops.representation_to_directions(p))  # (F, n, 3)
            ax = "xyz".index(axis)
            refl = d[:, 0].copy()
            refl[:, ax] *= -1
            err = np.min(np.linalg.norm(d[partner] - refl[:, None, :], axis=2), axis=1)
            assert err.max() < 1e-12


def test_mirror_map_reports_unmatched():
    V, F = meshgen.icosphere(2)
    exact = np.asarray(native().MirrorMap(Mesh(V, F).native, "x", 0.0, 1e-9).partner)
    for v in (5, 0):  # vertex 5 = (0, 1, t) lies on the mirror plane, vertex 0 = (-1, t, 0) does not
        W = V.copy()
        W[v] += [0.01, 0.02, 0.0]  # breaks the symmetry of the faces around v and of their mirror images
        mm = native().MirrorMap(Mesh(W, F).native, "x", 0.0, 1e-6)
        ring = np.flatnonzero((F == v).any(axis=1))
        expected = set(ring.tolist()) | set(exact[ring].tolist())
        assert set(np.asarray(mm.unmatched).tolist()) == expected
        assert mm.num_matched == len(F) - len(expected)


# ---------------------------------------------------------------------------------------- cuts
def test_cut_mesh_keeps_faces_frames_and_opens_the_cut():
    V, F = meshgen.grid(8, 8, random_diagonals=True, seed=3)
    mesh = Mesh(V, F)
    idx = np.arange(64).reshape(8, 8)
    slit = [(int(idx[i, 4]), int(idx[i + 1, 4])) for i in range(2, 6)]  # along x at y = 4/7, inside
    cut, origin, opened, unopened, already = native().cut_mesh(mesh.native, np.array(slit))
    assert opened == 4 and len(unopened) == 0 and len(already) == 0
    # interior vertices of the slit are split once, the two tips not at all
    assert cut.num_vertices == mesh.num_vertices + 3
    assert np.array_equal(np.asarray(origin)[mesh.num_vertices:], idx[3:6, 4])
    assert cut.num_faces == mesh.num_faces and np.array_equal(cut.positions[: mesh.num_vertices], mesh.vertices)
    a = native().FieldOperators(mesh.native, 4)
    b = native().FieldOperators(cut, 4)
    assert np.array_equal(np.asarray(a.frames), np.asarray(b.frames))
    assert np.array_equal(np.asarray(a.mass), np.asarray(b.mass))
    assert len(cut.dual_edges()) == len(mesh.native.dual_edges()) - 4
    for i in (3, 4, 5):
        v = int(idx[i, 4])
        assert mesh.native.vertex_is_interior(v) and not cut.vertex_is_interior(v)
    # an isolated single edge inside cannot open
    _, _, opened, unopened, _ = native().cut_mesh(mesh.native, np.array([slit[1]]))
    assert opened == 0 and np.asarray(unopened).tolist() == [sorted(slit[1])]
    with pytest.raises(ValueError, match="not edges"):
        native().cut_mesh(mesh.native, np.array([[0, 63]]))


def test_cut_operator_is_the_energy_without_the_cut_edges():
    """The cut mesh's harmonic matrix equals the input mesh's with the terms of the cut edges removed."""
    mesh = core_mesh("fandisk.obj")
    g = native().GuideGeometry(mesh.native)
    fs = g.detect_features(boundary=False, sharp_angle=30.0)
    chain = max(fs.chains, key=lambda c: len(c["edges"]))
    verts = np.asarray(chain["vertices"])
    pairs = np.stack([verts[:-1], verts[1:]], 1)
    cut, _, opened, unopened, _ = native().cut_mesh(mesh.native, pairs)
    assert opened == len(pairs) - len(unopened)
    n = 4
    a, b = native().FieldOperators(mesh.native, n), native().FieldOperators(cut, n)
    def as_dict(ops):
        r, c, v = (np.asarray(x) for x in ops.energy_matrix(1))
        out: dict = {}
        for i, j, x in zip(r.tolist(), c.tolist(), v.tolist()):
            out[(i, j)] = out.get((i, j), 0) + x
        return out

    Sa, Sb = as_dict(a), as_dict(b)
    de = np.asarray(mesh.native.dual_edges())
    w = np.asarray(a.weights_per_edge)
    r = np.asarray(a.connection)
    cut_set = {tuple(sorted(p)) for p in pairs.tolist()} - {tuple(sorted(p)) for p in np.asarray(unopened).tolist()}
    removed = 0
    for e, (f0, f1, v0, v1) in enumerate(de.tolist()):
        if tuple(sorted((v0, v1))) in cut_set:
            # remove the edge's term w |r z0 - z1|^2 (S_00 += w, S_11 += w, S_10 -= w r, S_01 -= w conj r)
            Sa[(f0, f0)] -= w[e]
            Sa[(f1, f1)] -= w[e]
            Sa[(f1, f0)] += w[e] * r[e]
            Sa[(f0, f1)] += w[e] * np.conj(r[e])
            removed += 1
    assert removed == len(cut_set)
    scale = max(abs(x) for x in Sb.values())
    for key in set(Sa) | set(Sb):
        assert abs(Sa.get(key, 0) - Sb.get(key, 0)) < 1e-12 * scale, key


# ---------------------------------------------------------------------------------------- local energy rows
@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_energy_rows_match_the_energy_matrix(order):
    """energy_rows (for local solves) gives the rows of E_order that energy_matrix gives, to rounding (the
    full matrix is averaged with its adjoint, the rows are not: 1e-14 of the largest entry)."""
    mesh = core_mesh("fandisk.obj")
    ops = native().FieldOperators(mesh.native, 4)
    faces = np.random.default_rng(order).choice(mesh.num_faces, 400, replace=False)
    r, c, v = (np.asarray(x) for x in native().energy_rows(ops, order, faces))
    R, C, V = (np.asarray(x) for x in ops.energy_matrix(order))
    sel = np.isin(R, faces)
    full = dict(zip(zip(R[sel].tolist(), C[sel].tolist()), V[sel].tolist()))
    rows = dict(zip(zip(r.tolist(), c.tolist()), v.tolist()))
    scale = max(abs(x) for x in full.values())
    assert set(rows) <= set(full) | {k for k, x in rows.items() if abs(x) < 1e-14 * scale}
    assert max(abs(full.get(k, 0) - rows.get(k, 0)) for k in set(full) | set(rows)) < 1e-14 * scale
