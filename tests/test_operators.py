"""Discrete operators of paper sections 3, 4 and 6 (frames, transport, weights, energies) against
geometry and an independent numpy construction (tests/meshgen.py: ReferenceOperators).

Tolerances: every quantity here is a closed-form double-precision computation (atan2, sums of a few
dozen terms), so agreement is expected to ~1e-14 relative; 1e-10 leaves room for accumulated
rounding in sums over thousands of edges without letting any real mistake (a wrong weight, a missing
conjugate, a factor 2) through, since those change values by O(1).
"""
from __future__ import annotations

import numpy as np
import pytest

import meshgen as mg
import mesh_reference as mref

nat = pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")


# ----------------------------------------------------------------------------------------- meshes
def _meshes():
    return {
        "icosphere2": mg.icosphere(2),
        "bumpy": mg.bumpy_sphere(2, amplitude=0.2, seed=1),
        "torus_irregular": mg.torus(2.0, 0.7, 24, 10, perturb=0.35, random_diagonals=True, seed=2),
        "cylinder_irregular": mg.cylinder(1.0, 2.0, 16, 8, perturb=0.3, random_diagonals=True, seed=3),
        "ellipsoid_irregular": mg.irregular_ellipsoid(n_points=200, seed=4),
    }


MESHES = _meshes()


def _native_mesh(name):
    V, F = MESHES[name]
    return nat.Mesh(np.asarray(V, float), np.asarray(F, np.int32))


def _tangent_field(V, F, seed=0):
    """A fixed smooth-ish 3D vector field per face (projection onto the face is done by the API)."""
    c = mref.face_centroids(V, F)
    a = np.array([0.3, -0.5, 0.8])
    rng = np.random.default_rng(seed)
    return np.cross(a, c) + 0.5 * np.sin(3 * c) + 0.1 * rng.normal(size=c.shape)


def _ops(mesh, n, weights="geometric"):
    return nat.FieldOperators(mesh, n, weights)


def _edge_lookup(mesh):
    de = np.asarray(mesh.dual_edges())
    lut = {}
    for e, (f0, f1, _, _) in enumerate(de):
        lut[(int(f0), int(f1))] = (e, False)
        lut[(int(f1), int(f0))] = (e, True)
    return de, lut


# ----------------------------------------------------------------------------------------- frames
@pytest.mark.parametrize("name", list(MESHES))
def test_frames_orthonormal_tangent_positive(name):
    mesh = _native_mesh(name)
    ops = _ops(mesh, 1)
    fr = np.asarray(ops.frames)
    N = np.asarray(mesh.face_normals)
    x, y = fr[:, 0], fr[:, 1]
    # orthonormal, tangent, positively oriented: x . x = y . y = 1, x . y = x . N = 0, x cross y = N
    assert np.allclose((x * x).sum(1), 1, atol=1e-12)
    assert np.allclose((y * y).sum(1), 1, atol=1e-12)
    assert np.abs((x * y).sum(1)).max() < 1e-12
    assert np.abs((x * N).sum(1)).max() < 1e-12
    assert np.abs(np.cross(x, y) - N).max() < 1e-12
    # the mesh's normals are the (unit) right-hand-rule normals of the input winding (clean mesh)
    V, F = MESHES[name]
    Nref, Aref = mref.face_normals_areas(V, F)
    assert np.abs(N - Nref).max() < 1e-12
    assert np.allclose(np.asarray(mesh.face_areas), Aref, rtol=1e-12)
    assert np.allclose(np.asarray(ops.mass), Aref, rtol=1e-12)


# -------------------------------------------------------------------------------------- transport
@pytest.mark.parametrize("name", list(MESHES))
@pytest.mark.parametrize("n", [1, 2, 4])
def test_connection_from_geometry_and_reverse(name, n):
    """r_ij = exp(i n (a_j - a_i)) with a_i the angle of the shared edge in frame i (eq. 1);
    |r| = 1; the reverse transport (same formula from j to i) r_ji satisfies r_ij r_ji = 1; and the
    Hermitian S holds -w conj(r) at (f0, f1) and -w r at (f1, f0)."""
    mesh = _native_mesh(name)
    ops = _ops(mesh, n)
    P = np.asarray(mesh.positions)
    fr = np.asarray(ops.frames)
    de = np.asarray(mesh.dual_edges())
    f0, f1, v0, v1 = de.T
    e = P[v1] - P[v0]
    ang = lambda f, vec: np.arctan2((vec * fr[f, 1]).sum(1), (vec * fr[f, 0]).sum(1))
    r_ij = np.exp(1j * n * (ang(f1, e) - ang(f0, e)))
    r_ji = np.exp(1j * n * (ang(f0, -e) - ang(f1, -e)))  # same edge, read from face1 towards face0
    r = np.asarray(ops.connection)
    assert r.shape == (len(de),)
    assert np.abs(np.abs(r) - 1).max() < 1e-12
    assert np.abs(r - r_ij).max() < 1e-10
    assert np.abs(r * r_ji - 1).max() < 1e-10
    # the energy matrix carries r and its reverse conj(r) = r_ji
    rows, cols, vals = ops.energy_matrix(1)
    S = mref.dense_from_coo(rows, cols, vals, mesh.num_faces)
    w = np.asarray(ops.weights_per_edge)
    assert np.abs(S[f0, f1] + w * np.conj(r)).max() < 1e-10 * w.max()
    assert np.abs(S[f1, f0] + w * np.conj(r_ji)).max() < 1e-10 * w.max()  # = -w r_ij
    diag = np.zeros(mesh.num_faces)
    np.add.at(diag, f0, w)
    np.add.at(diag, f1, w)
    assert np.allclose(np.diag(S).real, diag, rtol=1e-12, atol=0)
    assert np.abs(np.diag(S).imag).max() < 1e-12 * w.max()


@pytest.mark.parametrize("name", ["bumpy", "torus_irregular"])
@pytest.mark.parametrize("n", [1, 3])
def test_transport_is_unfolding_across_edge(name, n):
    """Geometric meaning of r (n = 1: discrete Levi-Civita): a tangent vector of face0 rotated about
    the shared edge onto face1's plane (hinge map: edge component kept, N0 x e -> N1 x e) has the
    representation r times the original one."""
    mesh = _native_mesh(name)
    ops = _ops(mesh, n)
    P = np.asarray(mesh.positions)
    N = np.asarray(mesh.face_normals)
    de = np.asarray(mesh.dual_edges())
    rng = np.random.default_rng(7)
    f0, f1, v0, v1 = de.T
    eh = P[v1] - P[v0]
    eh /= np.linalg.norm(eh, axis=1, keepdims=True)
    a, b = rng.normal(size=(2, len(de)))
    t0 = a[:, None] * eh + b[:, None] * np.cross(N[f0], eh)
    t1 = a[:, None] * eh + b[:, None] * np.cross(N[f1], eh)
    z0 = np.asarray(ops.tangent_to_representation(f0, t0))
    z1 = np.asarray(ops.tangent_to_representation(f1, t1))
    r = np.asarray(ops.connection)
    assert np.abs(z1 - r * z0).max() < 1e-10 * np.abs(z0).max()


# ---------------------------------------------------------------------------------------- weights
@pytest.mark.parametrize("name", list(MESHES))
def test_weights_geometric_and_combinatorial(name):
    """w_ij = 3 l^2 / (A_i + A_j) (eq. 2, appendix A), combinatorial w = 1 (Diamanti et al.)."""
    mesh = _native_mesh(name)
    P = np.asarray(mesh.positions)
    A = np.asarray(mesh.face_areas)
    de = np.asarray(mesh.dual_edges())
    f0, f1, v0, v1 = de.T
    w_ref = 3 * ((P[v1] - P[v0]) ** 2).sum(1) / (A[f0] + A[f1])
    assert np.allclose(np.asarray(_ops(mesh, 2).weights_per_edge), w_ref, rtol=1e-12, atol=0)
    assert np.array_equal(np.asarray(_ops(mesh, 2, "combinatorial").weights_per_edge), np.ones(len(de)))
    # on a clean closed mesh every edge is a dual edge; with a boundary the boundary edges are not
    s = mref.mesh_stats(*MESHES[name])
    assert len(de) == s["edges"] - s["boundary_edges"]


def test_weights_dimensionless_mass_scales():
    """w is dimensionless and M has units length^2 (conventions): scaling by 10 keeps w, multiplies
    M by 100 and S is unchanged."""
    V, F = MESHES["bumpy"]
    m1 = nat.Mesh(V, F.astype(np.int32))
    m2 = nat.Mesh(10.0 * V, F.astype(np.int32))
    o1, o2 = _ops(m1, 2), _ops(m2, 2)
    assert np.allclose(np.asarray(o1.weights_per_edge), np.asarray(o2.weights_per_edge), rtol=1e-12)
    assert np.allclose(np.asarray(o2.mass), 100 * np.asarray(o1.mass), rtol=1e-12)
    S1 = mref.dense_from_coo(*o1.energy_matrix(1), m1.num_faces)
    S2 = mref.dense_from_coo(*o2.energy_matrix(1), m2.num_faces)
    assert np.abs(S1 - S2).max() < 1e-10 * np.abs(S1).max()


# --------------------------------------------------------------------------------------- energies
@pytest.mark.parametrize("name", list(MESHES))
def test_energy_matrices_are_powers(name):
    """E_m = S (M^-1 S)^(m-1) (section 6), Hermitian, positive semi-definite, and energy(z, m) = z^H E_m z."""
    mesh = _native_mesh(name)
    ops = _ops(mesh, 2)
    nF = mesh.num_faces
    S = mref.dense_from_coo(*ops.energy_matrix(1), nF)
    Minv = np.diag(1.0 / np.asarray(ops.mass))
    z = np.asarray(ops.tangent_to_representation(np.arange(nF), _tangent_field(*MESHES[name])))
    E = S
    for order in (1, 2, 3):
        Em = mref.dense_from_coo(*ops.energy_matrix(order), nF)
        scale = np.abs(E).max()
        assert np.abs(Em - E).max() < 1e-10 * scale, order
        assert np.abs(Em - Em.conj().T).max() < 1e-12 * scale
        ref = float(np.real(np.vdot(z, E @ z)))
        assert ref > 0
        assert abs(ops.energy(z, order) - ref) < 1e-10 * ref
        E = E @ Minv @ S
    with pytest.raises(ValueError):
        ops.energy_matrix(0)
    with pytest.raises(ValueError):
        ops.energy_matrix(5)


@pytest.mark.parametrize("name", list(MESHES))
@pytest.mark.parametrize("n", [1, 2, 4])
@pytest.mark.parametrize("weights", ["geometric", "combinatorial"])
def test_energy_matches_independent_reference(name, n, weights):
    """Energy of one fixed 3D field: native (its frames) vs the numpy reference (first-edge frames of
    the input winding, built independently). The energy of a 3D field does not depend on frames."""
    V, F = MESHES[name]
    mesh = _native_mesh(name)
    ops = _ops(mesh, n, weights)
    X = _tangent_field(V, F, seed=n)
    z = np.asarray(ops.tangent_to_representation(np.arange(len(F)), X))
    ref = mref.ReferenceOperators(V, F, n, weights)
    zr = ref.to_representation(X)
    assert np.allclose(np.abs(z), np.abs(zr), rtol=1e-12)
    e_ref = ref.energy(zr)
    assert abs(ops.energy(z, 1) - e_ref) < 1e-10 * e_ref


@pytest.mark.parametrize("name", ["bumpy", "torus_irregular", "ellipsoid_irregular"])
def test_frame_invariance_energy_indices_directions(name):
    """Re-choosing every face's frame (cyclic rotation of its vertex list changes the native first
    edge) changes no user-visible quantity: energies of a fixed 3D field (orders 1-3), the 3D
    directions, and the singularity indices of that field."""
    V, F = MESHES[name]
    Fr = mg.cyclic_rotate_faces(F, seed=11)
    assert np.any(Fr[:, 0] != F[:, 0])
    m1, m2 = nat.Mesh(V, F.astype(np.int32)), nat.Mesh(V, Fr.astype(np.int32))
    X = _tangent_field(V, F, seed=3)
    for n in (1, 2, 4):
        o1, o2 = _ops(m1, n), _ops(m2, n)
        fr1, fr2 = np.asarray(o1.frames), np.asarray(o2.frames)
        changed = np.linalg.norm(fr1[:, 0] - fr2[:, 0], axis=1) > 1e-3
        assert changed.mean() > 0.5  # the frames really were re-chosen
        z1 = np.asarray(o1.tangent_to_representation(np.arange(len(F)), X))
        z2 = np.asarray(o2.tangent_to_representation(np.arange(len(F)), X))
        for order in (1, 2, 3):
            e1, e2 = o1.energy(z1, order), o2.energy(z2, order)
            assert abs(e1 - e2) < 1e-10 * e1
        d1 = np.asarray(o1.representation_to_directions(z1))
        d2 = np.asarray(o2.representation_to_directions(z2))
        # same set of n unit directions per face (the order of the n directions may differ)
        dist = np.linalg.norm(d1[:, :, None, :] - d2[:, None, :, :], axis=3).min(axis=2)
        assert dist.max() < 1e-9
        v1, i1 = nat.singularity_indices(o1, z1)
        v2, i2 = nat.singularity_indices(o2, z2)
        assert np.array_equal(np.asarray(v1), np.asarray(v2))
        assert np.allclose(np.asarray(i1), np.asarray(i2), atol=1e-12)


# ----------------------------------------------------------------------------- representation maps
@pytest.mark.parametrize("n", [1, 2, 3, 4, 6])
def test_representation_roundtrip(n):
    """tangent_to_representation: |z| = |projection|, arg z = n * angle; representation_to_directions
    gives n unit tangent directions 2 pi / n apart, each of which maps back to z / |z|."""
    mesh = _native_mesh("bumpy")
    ops = _ops(mesh, n)
    V, F = MESHES["bumpy"]
    N = np.asarray(mesh.face_normals)
    rng = np.random.default_rng(n)
    X = rng.normal(size=(len(F), 3))
    Xt = X - (X * N).sum(1, keepdims=True) * N
    z = np.asarray(ops.tangent_to_representation(np.arange(len(F)), X))
    assert np.allclose(np.abs(z), np.linalg.norm(Xt, axis=1), rtol=1e-12)
    # the 3D input and its tangent projection give the same representation
    zt = np.asarray(ops.tangent_to_representation(np.arange(len(F)), Xt))
    assert np.abs(z - zt).max() < 1e-12 * np.abs(z).max()
    D = np.asarray(ops.representation_to_directions(z))
    assert D.shape == (len(F), n, 3)
    assert np.allclose(np.linalg.norm(D, axis=2), 1, atol=1e-12)
    assert np.abs(np.einsum("fkd,fd->fk", D, N)).max() < 1e-12
    xh = Xt / np.linalg.norm(Xt, axis=1, keepdims=True)
    # the input direction is one of the n directions
    assert np.max(np.einsum("fkd,fd->fk", D, xh), axis=1).min() > 1 - 1e-12
    for k in range(n):
        zk = np.asarray(ops.tangent_to_representation(np.arange(len(F)), D[:, k]))
        assert np.abs(zk - z / np.abs(z)).max() < 1e-10
    if n > 1:  # consecutive directions are 2 pi / n apart
        c = np.einsum("fkd,fjd->fkj", D, D)
        off = c[:, ~np.eye(n, dtype=bool)].reshape(len(F), n, n - 1)
        assert np.allclose(off.max(axis=2), np.cos(2 * np.pi / n), atol=1e-10)
    # zero stays zero
    Z = np.asarray(ops.representation_to_directions(np.zeros(len(F), complex)))
    assert np.all(Z == 0)


# ------------------------------------------------------------------------------------- holonomy
def _ring_product(ops, mesh, lut, v):
    r = np.asarray(ops.connection)
    ring = list(mesh.vertex_ring_faces(v))
    prod = 1.0 + 0j
    for a, b in zip(ring, ring[1:] + ring[:1]):
        e, rev = lut[(a, b)]
        prod *= np.conj(r[e]) if rev else r[e]
    return prod


@pytest.mark.parametrize("name", ["icosphere2", "bumpy", "torus_irregular", "ellipsoid_irregular",
                                  "cylinder_irregular"])
@pytest.mark.parametrize("n", [1, 2, 4])
def test_ring_holonomy_is_n_times_angle_defect(name, n):
    """Around every interior vertex the product of transports is exp(i n K_v) (discrete Gauss-Bonnet
    for the Levi-Civita connection), with K_v = 2 pi - sum of corner angles; ring_holonomy(v) is its
    angle in (-pi, pi]. The ring product is also recomputed here from `connection` and the ring order.
    Counter-clockwise rings give +n K_v, so this also checks the ring orientation."""
    V, F = MESHES[name]
    mesh = _native_mesh(name)
    ops = _ops(mesh, n)
    _, lut = _edge_lookup(mesh)
    K = mref.angle_defects(V, F)
    n_interior = 0
    for v in range(len(V)):
        if not mesh.vertex_is_interior(v):
            assert mesh.angle_defect(v) == 0.0
            continue
        n_interior += 1
        assert abs(mesh.angle_defect(v) - K[v]) < 1e-12
        h = ops.ring_holonomy(v)
        assert -np.pi < h <= np.pi
        assert abs(mref.wrap_angle(h - n * K[v])) < 1e-9, (v, h, n * K[v])
        prod = _ring_product(ops, mesh, lut, v)
        assert abs(mref.wrap_angle(np.angle(prod) - h)) < 1e-9
    s = mref.mesh_stats(V, F)
    expected_interior = s["vertices_used"] - s["boundary_edges"]  # one boundary vertex per boundary edge
    assert n_interior == expected_interior
