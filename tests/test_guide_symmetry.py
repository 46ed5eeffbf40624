"""Mirror symmetry of guided fields in nfield.core: u(mirror f) = reflect(u(f)) holds to 1e-8 on a symmetric
mesh (it is imposed exactly: rounding only), also with constraints and guides on one side only; a face without
a partner is reported; the symmetric solve is the minimiser over symmetric fields (against a dense solve).
"""
from __future__ import annotations

import numpy as np
import pytest

import meshgen

nfield_core = pytest.importorskip("nfield.core")
from nfield.core import DesignSession, Mesh, native  # noqa: E402
from nfield.core.guides import Symmetry  # noqa: E402


# ---------------------------------------------------------------------------------------- symmetry
def symmetric_mesh():
    V, F = meshgen.icosphere(3)
    V = V * [1.0, 0.8, 0.6]  # an ellipsoid: still symmetric about every coordinate plane, curvature varies
    return Mesh(V, F)


@pytest.mark.parametrize("n", [1, 2, 4])
def test_mirror_symmetry_holds_exactly(n):
    mesh = symmetric_mesh()
    s = DesignSession(mesh, n=n, order=2, align="curvature-max" if n % 2 == 0 else "none")
    info = s.set_symmetry("x")
    assert info["matched"] == mesh.num_faces and info["unmatched"] == []
    # constraints on one side only: the other side follows through the symmetry
    cent = mesh.vertices[mesh.faces].mean(axis=1)
    rng = np.random.default_rng(n)
    normals = np.asarray(mesh.native.face_normals)
    for f in rng.choice(np.flatnonzero(cent[:, 0] > 0.2), 3, replace=False):
        d = rng.normal(size=3)
        s.set_direction(int(f), d - normals[f] * (d @ normals[f]))
    r = s.solve()
    mm = native().MirrorMap(mesh.native, "x", 0.0, 1e-9)
    assert mm.asymmetry(r.representation, n) < 1e-8
    assert mm.asymmetry(r.raw_solution, n) < 1e-8


def test_mirror_symmetry_reports_unmatched_faces():
    V, F = meshgen.icosphere(3)
    V = V.copy()
    V[0] += [0.0, 0.0, 0.01]
    mesh = Mesh(V, F)
    s = DesignSession(mesh, n=4, align="curvature-max")
    with pytest.raises(ValueError, match=r"no mirror partner \(") as err:
        s.set_symmetry("x")
    ring = np.flatnonzero((F == 0).any(axis=1))
    for f in ring[:3]:
        assert str(int(f)) in str(err.value)
    info = s.set_symmetry(Symmetry("x", partial=True))
    assert set(ring.tolist()) <= set(info["unmatched"]) and info["matched"] == mesh.num_faces - len(info["unmatched"])
    r = s.solve()
    assert r.guides.symmetry["unmatched"] == info["unmatched"]


def dense_symmetric_minimiser(ops, mm, n, Vc, b, faces=(), dirs=()):
    """Independent reference: the minimiser of z^H Vc z - 2 Re(z^H b) over symmetric fields (z_p = T_f z_f for
    every matched pair) with the direction rows <z_f, J d> = 0, by the null-space method on the real form."""
    T = len(b)
    H = np.block([[Vc.real, -Vc.imag], [Vc.imag, Vc.real]])
    g = np.concatenate([b.real, b.imag])
    rows = []
    for f, d in zip(faces, dirs):  # <z_f, J d> = Re(conj(i d) z_f) = 0
        row = np.zeros(2 * T)
        cc = 1j * d
        row[f], row[T + f] = cc.real, cc.imag
        rows.append(row)
    partner = np.asarray(mm.partner)
    for f in range(T):
        p = int(partner[f])
        if p < f:
            continue
        t1 = complex(np.asarray(mm.map(np.array([f]), np.array([1.0 + 0j]), n))[0])
        ti = complex(np.asarray(mm.map(np.array([f]), np.array([1j]), n))[0])
        for part in (np.real, np.imag):  # z_p - T_f(z_f) = 0, real and imaginary parts (T_f is real-linear)
            row = np.zeros(2 * T)
            row[p] += part(1.0 + 0j)
            row[T + p] += part(1j)
            row[f] -= part(t1)
            row[T + f] -= part(ti)
            rows.append(row)
    C = np.array(rows)
    _, sv, vt = np.linalg.svd(C)
    null = vt[np.sum(sv > 1e-10 * sv[0]):].T
    x = null @ np.linalg.solve(null.T @ H @ null, null.T @ g)
    return x[:T] + 1j * x[T:]


def dense_energy(ops, order, T):
    r, c, v = (np.asarray(x) for x in ops.energy_matrix(order))
    E = np.zeros((T, T), dtype=complex)
    np.add.at(E, (r, c), v)
    return E


def test_symmetric_solve_is_the_minimiser_over_symmetric_fields():
    """On a mesh symmetric only up to the matching tolerance the solver's defect correction must reach the
    exact minimiser over symmetric fields: compared with an independent dense solve (real form, symmetry and
    direction constraints as rows, null-space method) on a small mesh, to 1e-8 relative. The asymmetry is
    1e-3 of the diagonal: the uncorrected projected solve is off by about 2e-3 there."""
    V, F = meshgen.icosphere(2)
    V = V * [1.0, 0.8, 0.6]
    rng = np.random.default_rng(4)
    V = V + 1e-3 * rng.normal(size=V.shape)
    mesh = Mesh(V, F)
    n, order = 2, 2
    nat = native()
    ops = nat.FieldOperators(mesh.native, n)
    mm = nat.MirrorMap(mesh.native, "x", 0.0, 1e-2 * mesh.native.bounding_box_diagonal)
    assert mm.num_matched == len(F) and mm.max_mismatch > 0
    align = np.asarray(nat.alignment_field(ops, "curvature-max"))
    cent = V[F].mean(axis=1)
    faces = [int(f) for f in rng.choice(np.flatnonzero(cent[:, 0] > 0.3), 3, replace=False)]
    dirs = np.exp(1j * rng.uniform(0, 2 * np.pi, 3))
    solver = nat.ExactSolver(ops, order, 1.0, align, "direction")
    solver.set_symmetry(mm)
    for f, d in zip(faces, dirs):
        solver.set_direction_constraint(f, complex(d))
    w = np.asarray(solver.solve())
    assert list(solver.sign_fixed_faces) == [] and solver.symmetry_corrections >= 1
    assert mm.asymmetry(w, n) < 1e-12
    # V = E + |lambda| M, b = M u' with the +d safeguard at the constrained faces
    T = len(F)
    A = np.asarray(ops.mass)
    Vc = dense_energy(ops, order, T) + np.diag(-solver.lambda_ * A)
    b = A * align
    spike = 100 * np.sqrt(np.mean(np.abs(align[np.abs(align) > 0]) ** 2))
    for f, d in zip(faces, dirs):
        b[f] = spike * (A.sum() / T) * d  # A_f s_f d_f with s_f = spike * mean_area / A_f
    ref = dense_symmetric_minimiser(ops, mm, n, Vc, b, faces, dirs)
    assert np.abs(w - ref).max() < 1e-8 * np.abs(ref).max(), np.abs(w - ref).max() / np.abs(ref).max()


def test_one_sided_guides_with_symmetry():
    """A soft curve on one side only, on an exactly symmetric mesh: the guide weights are not symmetric, so V is
    not either; on symmetric fields only the symmetrized weights matter, and the session's solve must be the
    exact minimiser over symmetric fields of the spline with the curve's weights (dense reference, 1e-8)."""
    V, F = meshgen.icosphere(2)
    V = V * [1.0, 0.8, 0.6]
    mesh = Mesh(V, F)
    n, order = 4, 2
    s = DesignSession(mesh, n=n, order=order, align="curvature-max")
    s.set_curve("c", np.array([[0.5, -0.6, 0.3], [0.7, 0.0, 0.45], [0.5, 0.6, 0.3]]), width=0.1, tolerance=0.3)
    s.set_symmetry("x", tolerance=1e-9)
    r = s.solve()
    inputs = s._solve_inputs()
    W = np.asarray(inputs.matrix_weight)
    assert np.ptp(W) > 1.0  # the curve really weighs (and only on one side, before symmetrization)
    ops = s._operators()
    mm = s._mirror
    A = np.asarray(ops.mass)
    Vc = dense_energy(ops, order, len(F)) + np.diag(-r.lambda_ * A * W)
    ref = dense_symmetric_minimiser(ops, mm, n, Vc, A * np.asarray(inputs.alignment))
    assert np.abs(r.raw_solution - ref).max() < 1e-8 * np.abs(ref).max()
    assert mm.asymmetry(r.raw_solution, n) < 1e-12
