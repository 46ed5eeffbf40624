"""The paper's qualitative claims about n-field splines made quantitative: Fig. 10 (the biharmonic spline
continues the rate of change across a frozen region's boundary), Fig. 2 (point constraints converge under
refinement only with the biharmonic energy), and strength meaning the same on scaled and refined meshes.
Definitions of lambda and of the splines: tests/test_splines.py and native/include/nfield/spline_solver.hpp.
"""
from __future__ import annotations


import numpy as np
import pytest

import meshgen as mg
import mesh_reference as mref
from conftest import mesh_from_arrays

nat = pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")
core = pytest.importorskip("nfield.core", reason="nfield.core is not importable")

SPIKE = 100.0  # s_f = SPIKE * s_0 * mean area / A_f (spline_solver.hpp)
# Dense comparison (relative L2): the native result and the refined reference are both accurate far beyond
# kappa eps (n-vector splines measured 1e-16 to 1e-10 at orders 1-4, the worst on the flat grid at order 4,
# cond(E_ff) = 3e10); 1e-8 is the required accuracy and leaves orders of margin.
DENSE_TOL = 1e-8


# ========================================================================= Fig. 10 (frozen region)
def _sphere_frame(P):
    th = np.arccos(np.clip(P[:, 2] / np.linalg.norm(P, axis=1), -1, 1))
    ph = np.arctan2(P[:, 1], P[:, 0])
    e_th = np.stack([np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), -np.sin(th)], 1)
    e_ph = np.stack([-np.sin(ph), np.cos(ph), 0 * ph], 1)
    return th, e_th, e_ph


def _coords_in_frame(ops, w, e1, e2):
    """Representation of the field w (native frames) in the frame (e1, e2) (projected per face)."""
    n = ops.n
    fr = np.asarray(ops.frames)
    alpha = np.angle(w) / n
    d = np.cos(alpha)[:, None] * fr[:, 0] + np.sin(alpha)[:, None] * fr[:, 1]
    beta = np.arctan2((d * e2).sum(1), (d * e1).sum(1))
    return np.abs(w) * np.exp(1j * n * beta)


@pytest.mark.slow
def test_fig10_biharmonic_continues_rate_of_change():
    """Paper Fig. 10 (4-vector field). Unit sphere icosphere(4); a band of faces south of the equator
    (0 < s < 0.32, s = theta - pi/2) is frozen by n-vector constraints to a rotationally symmetric
    field that grows and rotates along the meridians: C(s) = exp(a s) exp(i beta s), C the
    representation in the meridian frame (e_theta, e_phi), which is parallel along the meridians (great
    circles), so dC/ds is the covariant rate of change. The free northern hemisphere is solved with
    the harmonic (order 1) and biharmonic (order 2) energy; C'(0) is measured by cubic least-squares
    fits of C(s) over 0.25 on each side of the equator.
      Locality (exact): changing the frozen field on faces that do not touch the free region leaves
        the harmonic solution unchanged (to rounding) - the paper's "changing the blue part has no
        effect as long as the boundary triangles remain" - and changes the biharmonic one.
      Continuation: frozen rates r = +(a + i beta) (field A) and -(a + i beta) (field B), both with
        C(0) = 1. Transfer T = |s_out(A) - s_out(B)| / |s_in(A) - s_in(B)|: how much of the change of
        the inside slope shows up outside. Measured: biharmonic 0.94, harmonic 0.17. Required:
        biharmonic T > 0.75 and each |s_out - s_in| < 0.25 |r| (measured 0.02 and 0.13 |r|);
        harmonic T < 0.35 and max |s_out - s_in| > 0.5 |r| (measured 0.69 and 1.24 |r|).
    """
    n = 4
    V, F = mg.icosphere(4)
    mesh = mesh_from_arrays((V, F))
    ops = nat.FieldOperators(mesh.native, n, "geometric")
    c = mref.face_centroids(V, F)
    th, e_th, e_ph = _sphere_frame(c)
    s = th - np.pi / 2
    band = (s > 0) & (s < 0.32)
    north = s <= 0
    de = np.asarray(mesh.native.dual_edges())
    touch = np.zeros(len(F), bool)
    for f0, f1 in de[:, :2]:
        if band[f0] and north[f1]:
            touch[f0] = True
        if band[f1] and north[f0]:
            touch[f1] = True
    faces = np.nonzero(band)[0]
    a, beta = 1.0, 1.5
    rate = a + 1j * beta

    def frozen(sign, wiggle=False):
        ss = sign * s[faces]
        rho, psi = np.exp(a * ss), beta / n * ss  # representation angle n psi = beta ss
        if wiggle:  # change the frozen field away from the free region only
            far = ~touch[faces]
            rho = np.where(far, rho * (1 + 0.5 * np.sin(20 * ss)), rho)
            psi = np.where(far, psi + 0.7 * np.sin(13 * ss), psi)
        vec = rho[:, None] * (np.cos(psi)[:, None] * e_th[faces] + np.sin(psi)[:, None] * e_ph[faces])
        return np.asarray(ops.tangent_to_representation(faces, vec))

    def cubic_slope(C, sel):
        A = np.stack([s[sel] ** k for k in range(4)], 1)
        return np.linalg.lstsq(A, C[sel], rcond=None)[0][1]

    inside, outside = band & (s < 0.25), north & (s > -0.25)
    slopes, locality = {}, {}
    for order in (1, 2):
        solver = nat.ExactSolver(ops, order, 1.0, None, "vector")  # one factorization, cached columns
        sol = {}
        for key, vals in (("A", frozen(1)), ("B", frozen(-1)), ("A'", frozen(1, wiggle=True))):
            for f, z in zip(faces, vals):
                solver.set_vector_constraint(int(f), complex(z))
            sol[key] = np.asarray(solver.solve())
        for key in ("A", "B"):
            C = _coords_in_frame(ops, sol[key], e_th, e_ph)
            slopes[(order, key)] = (cubic_slope(C, inside), cubic_slope(C, outside))
        ref = np.abs(sol["A"][north]).max()
        locality[order] = np.abs(sol["A"][north] - sol["A'"][north]).max() / ref
    # the measurement recovers the imposed rates on the frozen side (5%: cubic fit of exp over 0.25)
    for order in (1, 2):
        assert abs(slopes[(order, "A")][0] - rate) < 0.05 * abs(rate)
        assert abs(slopes[(order, "B")][0] + rate) < 0.05 * abs(rate)
    assert locality[1] < 1e-9, locality
    assert locality[2] > 1e-3, locality

    def transfer(order):
        (ia, oa), (ib, ob) = slopes[(order, "A")], slopes[(order, "B")]
        return abs(oa - ob) / abs(ia - ib)

    mis = {o: [abs(slopes[(o, k)][1] - slopes[(o, k)][0]) / abs(rate) for k in ("A", "B")] for o in (1, 2)}
    print(f"transfer harmonic {transfer(1):.3f} biharmonic {transfer(2):.3f}; mismatch/|r| {mis}; "
          f"locality {locality}")
    assert transfer(2) > 0.75 and max(mis[2]) < 0.25
    assert transfer(1) < 0.35 and max(mis[1]) > 0.5


# ========================================================================= Fig. 2 (refinement)
def _levels(base, levels):
    V, F = base
    out = [(V, F)]
    proj = mg.project_to_sphere(1.0)
    for _ in range(levels):
        V, F = mg.midpoint_subdivide(V, F, project=proj)
        out.append((V, F))
    return out


def _probe(ops, w, Vd, Fd, P):
    f = mref.closest_faces(Vd, Fd, P)
    fr = np.asarray(ops.frames)[f]
    n = ops.n
    alpha = np.angle(w[f]) / n
    d = np.cos(alpha)[:, None] * fr[:, 0] + np.sin(alpha)[:, None] * fr[:, 1]
    _, e1, e2 = _sphere_frame(P)
    beta = np.arctan2((d * e2).sum(1), (d * e1).sum(1))
    return np.abs(w[f]) * np.exp(1j * n * beta)


def test_fig2_point_constraints_converge_only_biharmonic():
    """Paper Fig. 2 / section 5: point (single-face) vector constraints are well posed for the
    biharmonic energy, not for the harmonic one (a point has zero H^1 capacity in 2D). Unit sphere,
    levels 0..3 of 1-to-4 refinement of icosphere(2) (320 .. 20480 faces), 3 vector constraints at
    fixed 3D points, n = 1, no alignment. Probes at fixed points away from the constraints.
      biharmonic: the probe values converge (successive differences shrink, magnitude settles);
      harmonic: the constraints' influence decays ~ 1/log(1/h) under refinement, so the values keep
        drifting towards zero level after level and the relative change does not shrink.
    """
    levels = _levels(mg.icosphere(2), 3)
    cpts = np.array([[1.0, 0.2, 0.1], [-0.3, 1.0, 0.4], [0.1, -0.4, -1.0]])
    cpts /= np.linalg.norm(cpts, axis=1, keepdims=True)
    cvec = np.array([[0, 0, 1.0], [1.0, 0, 0], [0, 1.0, 0]])
    rng = np.random.default_rng(0)
    probes = rng.normal(size=(200, 3))
    probes /= np.linalg.norm(probes, axis=1, keepdims=True)
    far = np.min(np.linalg.norm(probes[:, None] - cpts[None], axis=2), axis=1) > 0.5
    probes = probes[far][:40]
    vals = {1: [], 2: []}
    for V, F in levels:
        mesh = mesh_from_arrays((V, F))
        ops = nat.FieldOperators(mesh.native, 1, "geometric")
        cf = mref.closest_faces(V, F, cpts)
        for order in (1, 2):
            res = core.solve(mesh, n=1, order=order, vector_constraints=[
                core.VectorConstraint(int(f), tuple(v)) for f, v in zip(cf, cvec)])
            vals[order].append(_probe(ops, np.asarray(res.raw_solution), V, F, probes))
    diffs = {o: [np.linalg.norm(vals[o][k + 1] - vals[o][k]) / np.sqrt(len(probes))
                 for k in range(len(levels) - 1)] for o in (1, 2)}
    mags = {o: [np.sqrt(np.mean(np.abs(v) ** 2)) for v in vals[o]] for o in (1, 2)}
    print("successive differences", diffs, "rms magnitudes", mags)
    rel = {o: [diffs[o][k] / mags[o][k + 1] for k in range(len(diffs[o]))] for o in (1, 2)}
    # biharmonic: converges - differences shrink (0.064, 0.035, 0.012 measured), the last one is
    # below 2% of the field, and the magnitude at the probes has settled (1.031 vs 1.030)
    assert diffs[2][-1] < 0.5 * diffs[2][0] and rel[2][-1] < 0.02, rel[2]
    assert abs(mags[2][-1] / mags[2][-2] - 1) < 0.02, mags[2]
    # harmonic: the constraints' influence keeps vanishing (rms magnitude ratios 0.87, 0.85, 0.88
    # measured, ~ log(1/h) / log(2/h)), and the last change is still > 5% of the field
    assert all(mags[1][k + 1] < 0.95 * mags[1][k] for k in range(len(levels) - 1)), mags[1]
    assert rel[1][-1] > 0.05 and rel[1][-1] > 4 * rel[2][-1], rel


# ================================================================= strength: scale and refinement
def _ellipsoid_level(k):
    V, F = mg.icosphere(k)
    return V * np.array([1.6, 1.0, 0.6]), F


def _first_dirs_at(res, V, F, P):
    f = mref.closest_faces(V, F, P)
    return res.all_directions()[f]


def _nsym_angle_deg(D1, D2, n):
    """Angle (deg) between two n-direction sets given by (k, n, 3) arrays of unit directions."""
    best = np.max(np.einsum("kd,kjd->kj", D1[:, 0], D2), axis=1)
    return np.degrees(np.arccos(np.clip(best, -1, 1)))


def test_strength_same_on_scaled_mesh():
    """Scaling the mesh by 1000 maps lambda to lambda/1000^(2m) exactly like the spectrum and the
    alignment field magnitude is dimensionless: the curvature-aligned direction field (n = 2, 4,
    order 1, 2, with two direction constraints) is identical (1e-6 rad: rounding amplified by the
    conditioning of V)."""
    V, F = _ellipsoid_level(3)
    m1, m2 = mesh_from_arrays((V, F)), mesh_from_arrays((1000 * V, F))
    cons = [core.DirectionConstraint(5, (1, 0, 0)), core.DirectionConstraint(700, (0, 1, 0))]
    for n in (2, 4):
        for order in (1, 2):
            for strength in (0.05, 5.0):
                a = core.solve(m1, n=n, order=order, align="curvature-max", strength=strength, constraints=cons)
                b = core.solve(m2, n=n, order=order, align="curvature-max", strength=strength, constraints=cons)
                assert abs(b.lambda_ * 1000 ** (2 * order) - a.lambda_) < 1e-9 * abs(a.lambda_)
                ang = np.abs(mref.wrap_angle(np.angle(b.representation) - np.angle(a.representation)))
                assert ang.max() < 1e-6, (n, order, strength, ang.max())


def _rough_user_field(V, F, freq=3.0):
    """A unit tangent-ish 3D field turning quickly along x (angle 3x + 2y in a frame built from the
    z axis): far from the smoothest field, so the strength really trades smoothness for alignment."""
    c = mref.face_centroids(V, F)
    e1 = np.cross([0.0, 0.0, 1.0], c) + 1e-3
    e2 = np.cross(c, e1)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
    a = freq * c[:, 0] + 2 * c[:, 1]
    return np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2


def test_strength_same_under_refinement():
    """The same strength means the same on a mesh and on its 1-to-4 refinement (vertices on the same
    ellipsoid, 1280 -> 5120 faces): n = 2, order 2, aligned with a rough user field. At 60 probe points
    the coarse solution at strength s is closer to the fine solution at the *same* s than to the fine
    solutions at s/4 and 4s (median angle), for s = 16 and 64 where the field depends on s. Measured
    (s = 16): 1.4 deg vs 3.3 and 5.0 deg; the 1.4 deg is the discretisation floor (probe sampling on
    the coarse faces), the same at every strength. A strength mapping that depended on the resolution
    (e.g. on the face count, a factor 4 here) would move the best match to s/4 or 4s."""
    rng = np.random.default_rng(1)
    P = rng.normal(size=(60, 3))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    P *= np.array([1.6, 1.0, 0.6])
    n = 2
    dirs = {}
    for k, strengths in ((3, (16.0, 64.0)), (4, (4.0, 16.0, 64.0, 256.0))):
        V, F = _ellipsoid_level(k)
        mesh = mesh_from_arrays((V, F))
        X = _rough_user_field(V, F)
        for strength in strengths:
            res = core.solve(mesh, n=n, order=2, align="field", alignment_field=X, strength=strength)
            dirs[(k, strength)] = _first_dirs_at(res, V, F, P)
    for s in (16.0, 64.0):
        d = {r: float(np.median(_nsym_angle_deg(dirs[(3, s)], dirs[(4, r * s)], n))) for r in (0.25, 1.0, 4.0)}
        print(f"strength {s}: median angle coarse vs fine at s/4, s, 4s: {d}")
        assert d[1.0] < 3.0 and d[1.0] < 0.75 * min(d[0.25], d[4.0]), d
