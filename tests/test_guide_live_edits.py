"""Guide edits in a DesignSession: weight 0 means no alignment term there, a live curve edit is solved exactly
in a region and defers the global solve, a target-only edit keeps the factorization, all-zero weights stay
well posed, guides in spectral mode, the live region's budget and the reuse of its factorization.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import meshgen
from conftest import core_mesh

nfield_core = pytest.importorskip("nfield.core")
from nfield.core import DesignSession, Mesh, native, solve  # noqa: E402
from nfield.core.guides import FeatureGuide, Symmetry  # noqa: E402


# ---------------------------------------------------------------------------------------- live edits
def spline_residual(mesh, session, result):
    """Per triangle: (E_m + |lambda| M_W) w - M (W g), the gradient of the spline's objective, with W and W g
    the session's guide field; zero wherever the face is free and unconstrained (first-order optimality)."""
    ops = session._operators()
    s = session.settings
    inputs = session._solve_inputs()
    r, c, v = (np.asarray(x) for x in ops.energy_matrix(s["order"]))
    w = np.asarray(result.raw_solution)
    Ew = np.zeros(len(w), dtype=complex)
    np.add.at(Ew, r, v * w[c])
    A = np.asarray(ops.mass)
    W = np.ones(len(w)) if inputs.matrix_weight is None else np.asarray(inputs.matrix_weight)
    value = np.zeros(len(w), dtype=complex) if inputs.alignment is None else np.asarray(inputs.alignment)
    grad = Ew - result.lambda_ * A * W * w - A * value
    scale = np.abs(Ew).max() + np.abs(result.lambda_ * A * W * w).max() + np.abs(A * value).max()
    return grad, scale


def test_zero_weight_faces_have_no_alignment_term():
    mesh = core_mesh("fandisk.obj")
    cent = mesh.vertices[mesh.faces].mean(axis=1)
    region = cent[:, 1] < np.percentile(cent[:, 1], 40)
    s = DesignSession(mesh, n=4, order=2, align="curvature-max")
    s.set_alignment_weight(np.where(region, 0.0, 1.0))
    r = s.solve()
    grad, scale = spline_residual(mesh, s, r)
    # optimality holds with the alignment term absent on the zero-weight faces (and present elsewhere):
    # rounding level of the largest term (the solver refines to ~1e-12)
    assert np.abs(grad).max() < 1e-9 * scale
    # the same field does NOT satisfy the equation with the alignment term restored on those faces
    ops = s._operators()
    A = np.asarray(ops.mass)
    w = np.asarray(r.raw_solution)
    base = np.asarray(native().alignment_field(ops, "curvature-max"))
    restored = grad - r.lambda_ * A * w - A * base
    assert np.abs(restored[region]).max() > 1e-4 * scale


def test_live_curve_edit_is_local_exact_and_defers_the_global_solve():
    mesh = core_mesh("fandisk.obj")
    V = mesh.vertices
    diag = mesh.native.bounding_box_diagonal
    s = DesignSession(mesh, n=4, order=2, align="curvature-max")
    rng = np.random.default_rng(3)
    normals = np.asarray(mesh.native.face_normals)
    for f in rng.choice(mesh.num_faces, 5, replace=False):
        d = rng.normal(size=3)
        s.set_direction(int(f), d - normals[f] * (d @ normals[f]))
    a, b = V[np.argmin(V[:, 0])], V[np.argmax(V[:, 0])]
    line = a + np.linspace(0.3, 0.5, 30)[:, None] * (b - a)
    s.set_curve("c", line, width=0.02, tolerance=0.2)
    before = s.solve()
    assert s.pending_work() is None
    s.set_curve("c", line + 0.005 * diag * np.array([0.0, 1.0, 0.0]), width=0.02, tolerance=0.2)
    live = s.solve(details=False, live=True)
    assert 0 < live.live_region < 0.25 * mesh.num_faces
    moved = np.flatnonzero(live.raw_solution != before.raw_solution)
    assert 0 < len(moved) <= live.live_region  # everything outside the region is held bit-identically
    assert s.pending_work() == "factorization"
    # inside the region the live field is the exact spline (with the outside held): optimality at the free faces
    grad, scale = spline_residual(mesh, s, live)
    constrained = {mesh.face_triangle(c.face) for c in s.constraints}
    free = np.setdiff1d(moved, list(constrained))
    assert np.abs(grad[free]).max() < 1e-9 * scale
    glob = s.solve(details=False)
    assert glob.live_region is None and s.pending_work() is None
    grad, scale = spline_residual(mesh, s, glob)
    assert np.abs(np.delete(grad, list(constrained))).max() < 1e-9 * scale


def test_target_only_edit_reuses_the_factorization():
    mesh = core_mesh("rocker-arm.obj")
    s = DesignSession(mesh, n=2, order=2, align="curvature-max")
    s.solve()
    theta = np.zeros(mesh.num_faces)
    theta[: mesh.num_faces // 3] = 0.4
    s.set_alignment_rotation(theta)
    assert s.pending_work() is None  # only the right-hand side changes
    r = s.solve()
    fresh = solve(mesh, n=2, order=2, align="curvature-max", alignment_rotation=theta)
    assert np.abs(r.raw_solution - fresh.raw_solution).max() < 1e-10 * np.abs(fresh.raw_solution).max()
    s.set_alignment_weight(np.where(theta > 0, 2.0, 1.0))
    assert s.pending_work() == "factorization"  # the weights are part of V


def test_all_zero_weights_on_a_flat_piece_stay_well_posed():
    """A flat square has a parallel field in the kernel of E_m: with every alignment weight 0 the system would
    be singular. Such a component is solved as the unaligned spline (weight 1, target 0) and reported; the
    result is then exactly the plain solve without weights."""
    V, F = meshgen.grid(12, 12, random_diagonals=True, seed=2)
    mesh = Mesh(V, F)
    cons = [nfield_core.DirectionConstraint(5, (1.0, 0.2, 0.0)), nfield_core.DirectionConstraint(140, (0.3, 1.0, 0.0))]
    r0 = solve(mesh, n=4, order=2, align="none", constraints=cons)
    r1 = solve(mesh, n=4, order=2, align="none", constraints=cons, alignment_weight=np.zeros(len(F)))
    assert r1.guides.unweighted_components == 1
    assert np.abs(r1.raw_solution - r0.raw_solution).max() < 1e-12 * np.abs(r0.raw_solution).max()


def test_spectral_mode_with_guides():
    """Spectral mode keeps targets-only guides in the basis (the alignment's projection changes, Lambda stays
    diagonal); non-uniform weights and mirror symmetry fall back to the exact solver; cuts get the basis of the
    cut mesh."""
    mesh = core_mesh("sphere.obj")
    s = DesignSession(mesh, n=2, order=2, align="curvature-max", mode="spectral", k=40, cache_dir=False)
    r0 = s.solve()
    assert r0.mode == "spectral"
    s.set_alignment_rotation(np.full(mesh.num_faces, math.pi / 2))  # e^{i n pi/2} = -1 for n = 2
    r1 = s.solve()
    assert r1.mode == "spectral"
    assert np.abs(r1.raw_solution + r0.raw_solution).max() < 1e-12 * np.abs(r0.raw_solution).max()
    s.set_features(FeatureGuide(boundary=False, sharp_angle=4.5))  # the sphere's edges bend by 3.2-5.4 degrees
    r2 = s.solve()
    assert r2.guides.feature_edges > 0 and r2.mode == "exact"  # soft features: non-uniform weights
    s.set_features(None)
    s.set_alignment_weight(np.linspace(0.5, 1.5, mesh.num_faces))
    assert s.solve().mode == "exact"
    s.set_alignment_weight(None)
    s.set_symmetry(Symmetry("x", tolerance=1e-3, partial=True))
    assert s.solve().mode == "exact"
    s.set_symmetry(None)
    V = mesh.vertices
    E = np.asarray(native().GuideGeometry(mesh.native).edges())
    s.set_cuts(E[np.abs(V[E[:, 0], 2]) + np.abs(V[E[:, 1], 2]) < 0.15][:20])
    r3 = s.solve()
    assert r3.mode == "spectral" and s._basis.mesh_hash == s._solve_native_mesh().content_hash
    assert s._basis.mesh_hash != mesh.native.content_hash


def test_live_region_budget_and_factorization_reuse():
    """A live edit whose full margin would exceed LIVE_REGION_BUDGET grows fewer rings (the changed faces are
    always in); a later live edit of the same region with the same weights there (a target-only change: two
    rotations of the same faces) reuses the region's factorization and is still the exact spline of the
    region (optimality at its free faces)."""
    from nfield.core import session_live

    mesh = core_mesh("fandisk.obj")
    V = mesh.vertices
    s = DesignSession(mesh, n=4, order=2, align="curvature-max")
    s.solve()
    a, b = V[np.argmin(V[:, 0])], V[np.argmax(V[:, 0])]
    line = a + np.linspace(0.3, 0.6, 30)[:, None] * (b - a)
    s.set_curve("c", line, width=0.03, tolerance=0.2)
    inputs = s._solve_inputs()
    full = s._live_region(inputs)
    budget = session_live.LIVE_REGION_BUDGET
    try:
        session_live.LIVE_REGION_BUDGET = len(full) - 1
        narrow = s._live_region(inputs)
        assert len(narrow) < len(full) and set(narrow.tolist()) < set(full.tolist())
        changed = np.flatnonzero((np.asarray(inputs.matrix_weight) != s._base_record.weight)
                                 | (np.asarray(inputs.alignment) != s._base_record.value))
        assert set(changed.tolist()) <= set(narrow.tolist())  # the changed faces are always solved
        # the widest margin within the budget: changed faces grown by k rings, and k + 1 rings would not fit
        grown, steps = native().grow_faces(s._solve_native_mesh(), changed, 9)
        k = int(steps[np.isin(grown, narrow)].max())
        assert np.array_equal(narrow, grown[steps <= k]) and np.count_nonzero(steps <= k + 1) > len(full) - 1
        # a walk with a limit ends with the first complete step past it
        cut, cut_steps = native().grow_faces(s._solve_native_mesh(), changed, 9, len(full) - 1)
        last = int(cut_steps.max())
        assert np.array_equal(cut, grown[steps <= last]) and np.array_equal(cut_steps, steps[steps <= last])
        assert np.count_nonzero(steps < last) <= len(full) - 1 < len(cut)
    finally:
        session_live.LIVE_REGION_BUDGET = budget
    s.solve(details=False, live=True)  # the curve's live solve: the global solve is now due
    # two rotations of the same faces: the second edit's region and weights are those of the first
    cent = V[mesh.faces].mean(axis=1)
    turned = np.linalg.norm(cent - cent[0], axis=1) < 0.1 * mesh.native.bounding_box_diagonal
    theta = np.where(turned, 0.3, 0.0)
    s.set_alignment_rotation(theta)
    first = s.solve(details=False, live=True)
    built, region = s._live_solver, s._live_key[1]
    s.set_alignment_rotation(2 * theta)
    second = s.solve(details=False, live=True)
    assert s._live_solver is built and np.array_equal(s._live_key[1], region)  # the factorization was reused
    assert np.abs(second.raw_solution - first.raw_solution).max() > 1e-6  # the targets did change the field
    grad, scale = spline_residual(mesh, s, second)
    constrained = {mesh.face_triangle(c.face) for c in s.constraints}
    free = np.setdiff1d(region, list(constrained))
    assert np.abs(grad[free]).max() < 1e-9 * scale


def test_live_edits_chain_from_the_last_live_solve():
    """Successive live edits of one interaction (a brush stroke's ticks) start from the last solve, live or
    global: the second edit's region covers only what changed since the first live solve, the faces outside
    it keep the first live solution bit-identically, and it is the exact spline there (optimality at its free
    faces). A live solve needs no global factorization (pending_work(live=True) is None) while the global
    solve stays due (pending_work() says "factorization")."""
    mesh = core_mesh("fandisk.obj")
    s = DesignSession(mesh, n=4, order=2, align="curvature-max")
    s.solve()
    cent = mesh.vertices[mesh.faces].mean(axis=1)
    normals = np.asarray(mesh.native.face_normals)
    diag = mesh.native.bounding_box_diagonal

    def dab(face):
        d = np.cross(normals[face], [0.3, 0.5, 0.8])
        s.comb([cent[face]], [d], radius=0.03)

    dab(100)
    first = s.solve(details=False, live=True)
    assert s.pending_work() == "factorization" and s.pending_work(live=True) is None
    far = int(np.argmax(np.linalg.norm(cent - cent[100], axis=1)))  # a dab far from the first one
    assert np.linalg.norm(cent[far] - cent[100]) > 0.3 * diag
    dab(far)
    second = s.solve(details=False, live=True)
    moved = np.flatnonzero(second.raw_solution != first.raw_solution)
    assert 0 < len(moved) <= second.live_region
    # the region of the second edit lies around the second dab only: nothing near the first dab moved
    assert np.linalg.norm(cent[mesh.triangle_face[moved]] - cent[100], axis=1).min() > 0.1 * diag
    grad, scale = spline_residual(mesh, s, second)
    assert np.abs(grad[moved]).max() < 1e-9 * scale
    glob = s.solve(details=False)
    assert glob.live_region is None and s.pending_work() is None


# ---------------------------------------------------------------------------------------- live results
def full_rebuild(session, result):
    """The FieldResult of `result`'s raw solution computed from scratch over the whole mesh (with details)."""
    from nfield.core.solve import _result

    st = session.settings
    return _result(session.mesh, session._operators(), result.raw_solution, n=st["n"], order=st["order"],
                   align=st["align"], strength=st["strength"], weights=st["weights"], lam=result.lambda_,
                   sign_fixed=[], t0=0.0, details=True)


def assert_same_result(live, full, details=True):
    """The live result updated on its region equals the full rebuild: the per-face arrays and the singularities
    exactly (the same per-face arithmetic), the energy to rounding (the previous energy plus the change on the
    region, summed in another order: relative 1e-10 leaves room for a few chained edits at ~1e-15 each)."""
    assert np.array_equal(live.representation, full.representation)
    assert np.array_equal(live.directions, full.directions)
    assert np.array_equal(live.all_directions(), full.all_directions())
    if details:
        assert live.singularities == full.singularities
        assert abs(live.energy - full.energy) <= 1e-10 * abs(full.energy)
    else:
        assert live.singularities is None and math.isnan(live.energy)


@pytest.mark.parametrize("order", [1, 2])
def test_live_result_is_updated_on_its_region_and_equals_a_full_rebuild(order):
    """A live solve changes the raw field only on its region, so its FieldResult is the previous one with the
    region's faces recomputed, the energy changed by its change there and the singularities searched again at
    the region's vertices: equal to a full rebuild, through chained edits with and without details, and with
    singularities that the edits create or remove."""
    mesh = core_mesh("fandisk.obj")
    V = mesh.vertices
    diag = mesh.native.bounding_box_diagonal
    cent = V[mesh.faces].mean(axis=1)
    normals = np.asarray(mesh.native.face_normals)
    s = DesignSession(mesh, n=4, order=order, align="curvature-max")
    a, b = V[np.argmin(V[:, 0])], V[np.argmax(V[:, 0])]
    line = a + np.linspace(0.3, 0.5, 30)[:, None] * (b - a)
    s.set_curve("c", line, width=0.02, tolerance=0.2)
    base = s.solve()
    changed_singularities = 0
    previous = base
    for step in range(4):
        if step % 2 == 0:
            s.set_curve("c", line + (step + 1) * 0.004 * diag * np.array([0.0, 1.0, 0.2]), width=0.02, tolerance=0.2)
        else:  # a comb stroke across the field, to make and unmake singularities
            f = int(np.argmin(np.linalg.norm(cent - cent.mean(axis=0), axis=1))) if step == 1 else 200
            path = cent[f] + np.outer(np.linspace(0, 0.1 * diag, 8), np.cross(normals[f], [0.2, 0.3, 1.0]))
            s.comb(path, -np.gradient(path, axis=0), radius=0.04)
        details = step != 2  # the edit after one without details falls back to a full pass for the details
        live = s.solve(details=details, live=True)
        assert live.live_region is not None
        assert_same_result(live, full_rebuild(s, live), details)
        if details and previous.singularities is not None:
            changed_singularities += previous.singularities != live.singularities
        previous = live
    assert changed_singularities > 0  # the singularity update was exercised, not only carried over


def test_live_result_of_a_polygon_mesh_shows_each_polygons_first_triangle():
    """With polygons, a face's direction is that of its first triangle: the live result updates the polygons
    whose first triangle lies in the region, and equals the full rebuild."""
    V, F = meshgen.torus(R=2.0, r=0.7, nu=40, nv=14)
    mesh = Mesh(V, F, face_to_polygon=np.arange(len(F)) // 2, num_polygons=len(F) // 2)
    assert mesh.has_polygons
    s = DesignSession(mesh, n=4, order=2, align="curvature-max")
    s.solve()
    tri_cent = V[F].mean(axis=1)
    tri_normals = np.asarray(mesh.native.face_normals)
    t = 301
    path = tri_cent[t] + np.outer(np.linspace(0, 0.6, 6), np.cross(tri_normals[t], [0.0, 0.0, 1.0]))
    s.comb(path, np.gradient(path, axis=0), radius=0.05)
    live = s.solve(live=True)
    assert 0 < live.live_region < len(F)
    assert_same_result(live, full_rebuild(s, live))


def test_live_edit_keeps_committed_layers():
    """A committed layer is held by every later solve: a live edit whose region reaches its faces leaves them
    bit-identical (they are not free faces of the region)."""
    mesh = core_mesh("fandisk.obj")
    cent = mesh.vertices[mesh.faces].mean(axis=1)
    diag = mesh.native.bounding_box_diagonal
    s = DesignSession(mesh, n=4, order=2, align="curvature-max")
    s.solve()
    near = np.flatnonzero(np.linalg.norm(cent - cent[100], axis=1) < 0.08 * diag)
    s.begin_region(near)
    s.set_direction(int(near[0]), np.cross(np.asarray(mesh.native.face_normals)[near[0]], [1.0, 0.0, 0.0]))
    s.solve()
    layer = s.commit_region()
    s.solve()
    s.set_alignment_weight(np.where(np.linalg.norm(cent - cent[100], axis=1) < 0.1 * diag, 0.0, 1.0))
    live = s.solve(details=False, live=True)
    assert live.live_region is not None and live.live_region > 0  # solved live around the layer
    assert np.array_equal(live.raw_solution[layer.triangles], layer.values)


def test_region_solver_holds_every_other_face():
    """ExactSolver(free_faces, held_field): every active face but the free ones is held at its value in the field
    (a live region), the same solver as one given those faces as frozen_faces, bit for bit, whose unknowns are
    the free faces only. Bad input is refused with the problem named."""
    mesh = core_mesh("fandisk.obj")
    ops = native().FieldOperators(mesh.native, 4)
    align = np.asarray(native().alignment_field(ops, "curvature-max"))
    held = np.asarray(solve(mesh, n=4, order=2, align="curvature-max").raw_solution)
    cent = mesh.vertices[mesh.faces].mean(axis=1)
    region = np.flatnonzero(np.linalg.norm(cent - cent[50], axis=1) < 0.1 * mesh.native.bounding_box_diagonal)
    outside = np.setdiff1d(np.flatnonzero(np.asarray(mesh.native.face_active)), region)
    a = native().ExactSolver(ops, 2, 1.0, align, "direction", free_faces=region, held_field=held)
    b = native().ExactSolver(ops, 2, 1.0, align, "direction", frozen_faces=outside, frozen_values=held[outside])
    assert a.num_unknowns == b.num_unknowns == len(region)
    for solver in (a, b):
        solver.set_direction_constraint(int(region[3]), 1j)
    wa, wb = np.asarray(a.solve()), np.asarray(b.solve())
    assert np.array_equal(wa, wb)
    assert np.array_equal(wa[outside], held[outside]) and not np.array_equal(wa[region], held[region])
    assert a.face_frozen(int(outside[0])) and not a.face_frozen(int(region[0]))
    with pytest.raises(ValueError, match="frozen"):
        a.set_direction_constraint(int(outside[0]), 1.0)
    make = lambda **kw: native().ExactSolver(ops, 2, 1.0, align, "direction", **kw)  # noqa: E731
    with pytest.raises(ValueError, match="go together"):
        make(free_faces=region)
    with pytest.raises(ValueError, match="not both"):
        make(free_faces=region, held_field=held, frozen_faces=outside, frozen_values=held[outside])
    with pytest.raises(ValueError, match="given twice"):
        make(free_faces=np.r_[region, region[:1]], held_field=held)
    with pytest.raises(ValueError, match="one value per face"):
        make(free_faces=region, held_field=held[:-1])
    with pytest.raises(ValueError, match="out of range"):
        make(free_faces=np.r_[region, mesh.num_faces], held_field=held)
    bad = held.copy()
    bad[region[0]] = np.nan  # a free face's held value is not used
    make(free_faces=region, held_field=bad)
    bad[outside[0]] = np.nan
    with pytest.raises(ValueError, match=f"held value on face {outside[0]} is not finite"):
        make(free_faces=region, held_field=bad)
