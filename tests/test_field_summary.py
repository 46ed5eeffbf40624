"""The native summary of a solution (field_summary.hpp), against its definitions computed here with numpy.

nfield.core builds every FieldResult from ``field_summary(ops, w, order, details)``: the unit field
u = w / |w|, the first of the n directions per face in 3D, the energy E_m(u) and the singularity indices of u.
Each is checked against the formula of docs/math.md on random fields (random magnitudes and phases, so that
the rings carry many singularities of both signs, with zeros, tiny and huge values), on a closed mesh, a mesh
with boundary and a mesh with excluded (degenerate) faces, for several n and every energy order.
"""
from __future__ import annotations

import numpy as np
import pytest

import meshgen as mg
from conftest import reference_indices

nat = pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")
core = pytest.importorskip("nfield.core", reason="nfield.core is not importable")


def _with_degenerate_faces():
    V, F = mg.grid(9, 9, 1.0, 1.0, random_diagonals=True, seed=3)
    V = V.copy()
    V[:, 2] = 0.2 * np.sin(3 * V[:, 0]) * np.cos(2 * V[:, 1])
    F = np.vstack([F, F[:2], [[0, 1, 1]]])  # two duplicate faces and one with a repeated vertex: excluded
    return V, F


MESHES = {
    "closed": lambda: mg.bumpy_sphere(2, amplitude=0.2, seed=4),
    "boundary": lambda: mg.grid(12, 10, 2.0, 1.5, random_diagonals=True, seed=5),
    "degenerate": _with_degenerate_faces,
}


def _random_field(num_faces, active, rng):
    w = rng.lognormal(sigma=3.0, size=num_faces) * np.exp(1j * rng.uniform(-np.pi, np.pi, num_faces))
    w[rng.random(num_faces) < 0.05] = 0.0                   # zeros: no direction, rings without an index
    w[rng.random(num_faces) < 0.02] *= 1e-310                # subnormal magnitudes: the unit field stays finite
    w[rng.random(num_faces) < 0.02] *= 1e300
    w[~active] = 0.0
    return w


@pytest.mark.parametrize("name", list(MESHES))
@pytest.mark.parametrize("n", [1, 2, 3, 4, 6])
def test_summary_matches_definitions(name, n):
    V, F = MESHES[name]()
    mesh = core.Mesh(np.asarray(V, float), np.asarray(F, np.int64))
    ops = nat.FieldOperators(mesh.native, n, "geometric")
    active = np.asarray(mesh.native.face_active, dtype=bool)
    frames = np.asarray(ops.frames)
    rng = np.random.default_rng(100 + n)
    for trial in range(3):
        w = _random_field(mesh.num_triangles, active, rng)
        for order in (1, 2, 3, 4):
            u, first, energy, sv, si = nat.field_summary(ops, w, order, True)
            # Unit field re / |w|, im / |w| (parts divided separately, so subnormal w stay finite), 0 where w = 0.
            # |w| is C's hypot natively and numpy's own complex absolute value here: they may differ by one
            # rounding, so u agrees to 2 ulp (4.5e-16), plus, for subnormal w, the spacing of subnormal numbers
            # (5e-324) relative to |w|.
            mag = np.abs(w)
            ref_u = np.zeros_like(w)
            nz = mag > 0
            ref_u.real[nz] = w.real[nz] / mag[nz]
            ref_u.imag[nz] = w.imag[nz] / mag[nz]
            assert np.array_equal(u == 0, ref_u == 0)
            assert np.all(np.abs(u - ref_u)[nz] <= 4.5e-16 + 2 * 5e-324 / mag[nz])
            normal = mag > 1e-290  # subnormal w carry fewer significant bits, and so does their u
            assert np.all(np.isfinite(u)) and np.allclose(np.abs(u[normal]), 1.0, rtol=0, atol=1e-15)
            # First direction cos(a) x + sin(a) y, a = arg(u) / n, zero rows where w = 0: within a few roundings of
            # numpy's trigonometric functions: 1e-15 per component of a unit vector.
            angle = np.angle(u) / n
            ref_first = np.cos(angle)[:, None] * frames[:, 0] + np.sin(angle)[:, None] * frames[:, 1]
            ref_first[~nz] = 0.0
            assert first.shape == (mesh.num_triangles, 3)
            assert np.abs(first - ref_first).max() < 1e-15
            # ... and one of the n directions the representation vector stands for (per_face.hpp).
            all_dirs = np.asarray(ops.representation_to_directions(u))
            assert np.abs(first[nz] - all_dirs[nz, 0]).max() < 1e-14
            # Energy u^H E_m u from the assembled E_m (COO triplets, face indices): the same sum in another order.
            rows, cols, vals = (np.asarray(a) for a in ops.energy_matrix(order))
            ref_energy = float(np.real(np.vdot(u[rows], vals * u[cols])))
            assert energy == pytest.approx(ref_energy, rel=1e-11, abs=1e-12 * np.abs(vals).sum())
            # Singularities: every vertex whose ring walk (step by step, conftest.reference_indices) gives a
            # non-zero index, with that index (exact multiples of 1/n up to ~1e-13 rounding of the angle sums).
            ref = reference_indices(mesh.native, ops, u)
            got = dict(zip(sv.tolist(), si.tolist()))
            assert set(got) == set(ref), (name, n, trial, order)
            for v, i in got.items():
                assert abs(i - ref[v]) < 1e-9 and round(i * n) == i * n
            assert dict(zip(*(a.tolist() for a in nat.singularity_indices(ops, u)))) == got
        assert len(got) > 0  # random phases: the rings do carry indices


def test_summary_without_details_and_bad_input():
    V, F = mg.bumpy_sphere(1, amplitude=0.1, seed=1)
    mesh = core.Mesh(np.asarray(V, float), np.asarray(F, np.int64))
    ops = nat.FieldOperators(mesh.native, 4, "geometric")
    w = np.asarray(nat.smoothest_field(ops))
    u, first, energy, sv, si = nat.field_summary(ops, w, 2, False)
    u2, first2, _, _, _ = nat.field_summary(ops, w, 2, True)
    assert np.array_equal(u, u2) and np.array_equal(first, first2)
    assert np.isnan(energy) and len(sv) == 0 and len(si) == 0
    with pytest.raises(ValueError, match="one value per face"):
        nat.field_summary(ops, w[:-1], 1, True)
    with pytest.raises(ValueError, match="order"):
        nat.field_summary(ops, w, 5, True)


def test_result_uses_summary():
    """core.solve's FieldResult carries the summary of its raw solution: unit field, first directions, energy,
    singularities (a closed mesh: the indices sum to its Euler characteristic, 2)."""
    V, F = mg.bumpy_sphere(2, amplitude=0.2, seed=7)
    mesh = core.Mesh(np.asarray(V, float), np.asarray(F, np.int64))
    res = core.solve(mesh, n=4, order=2, constraints=[core.DirectionConstraint(3, (1.0, 0.0, 0.0))])
    ops = nat.FieldOperators(mesh.native, 4, "geometric")
    u, first, energy, sv, si = nat.field_summary(ops, res.raw_solution, 2, True)
    assert np.array_equal(res.representation, u) and np.array_equal(res.directions, first)
    assert res.energy == energy
    assert res.singularities == list(zip(sv.tolist(), si.tolist()))
    assert sum(i for _, i in res.singularities) == pytest.approx(2.0, abs=1e-9)


@pytest.mark.parametrize("name", list(MESHES))
def test_summary_of_a_region(name):
    """What a live result recomputes when only some faces changed: their unit field and first directions
    (field_summary_faces: the rows of field_summary, bit for bit), the singularities at their vertices
    (singularity_indices_near: those of the full search there) and the change of the energy (energy_change:
    the difference of the two full energies, to rounding)."""
    V, F = MESHES[name]()
    mesh = core.Mesh(np.asarray(V, float), np.asarray(F, np.int64))
    ops = nat.FieldOperators(mesh.native, 4, "geometric")
    active = np.asarray(mesh.native.face_active, dtype=bool)
    T = mesh.num_triangles
    rng = np.random.default_rng(7)
    w = _random_field(T, active, rng)
    faces = np.sort(rng.choice(T, T // 5, replace=False))
    w2 = w.copy()
    w2[faces] = _random_field(T, active, rng)[faces]
    u, first, _, _, _ = nat.field_summary(ops, w, 1, False)
    u2, first2, _, sv2, si2 = nat.field_summary(ops, w2, 1, True)
    uf, firstf = nat.field_summary_faces(ops, w2, faces)
    assert np.array_equal(uf, u2[faces]) and np.array_equal(firstf, first2[faces])
    near_vertices = set(np.asarray(mesh.native.faces)[faces].ravel().tolist())
    sv, si = nat.singularity_indices_near(ops, u2, faces)
    assert list(sv) == sorted(sv.tolist())
    want = {v: i for v, i in zip(sv2.tolist(), si2.tolist()) if v in near_vertices}
    assert dict(zip(sv.tolist(), si.tolist())) == want and want  # random phases: there are some
    for order in (1, 2, 3, 4):
        e1 = nat.field_summary(ops, u, order, True)[2]
        e2 = nat.field_summary(ops, u2, order, True)[2]
        rows, cols, vals = (np.asarray(a) for a in ops.energy_matrix(order))
        # the same sums in other orders: rounding of the full sums, ~1e-13 of the sum of |entries| (unit fields)
        assert nat.energy_change(ops, order, u, u2, faces) == pytest.approx(e2 - e1, abs=1e-12 * np.abs(vals).sum())
        assert nat.energy_change(ops, order, u, u, faces) == 0.0
    with pytest.raises(ValueError, match="one value per face"):
        nat.field_summary_faces(ops, w[:-1], faces)
    with pytest.raises(ValueError, match="out of range"):
        nat.field_summary_faces(ops, w, np.array([T]))
    with pytest.raises(ValueError, match="out of range"):
        nat.singularity_indices_near(ops, u, np.array([T + 3]))
    with pytest.raises(ValueError, match="one value per face"):
        nat.energy_change(ops, 2, u, u2[:-1], faces)
    with pytest.raises(ValueError, match="order"):
        nat.energy_change(ops, 5, u, u2, faces)
