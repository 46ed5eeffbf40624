"""Guide authoring in nfield.core (DesignSession and solve): features, weights, curves, comb, cuts, symmetry.

The issue's core tests, with what each one checks and why the tolerance:
  * hard features on fandisk and the rocker arm: the field is within 1 degree of the sharp edge direction
    on every face next to a sharp edge (the direction constraints hold to rounding; faces next to two
    feature edges get their mean direction when the two agree to 1 degree, hence "within 1 degree"), except
    the faces the corner rule dropped, which are listed with the features involved;
  * soft features: the mean deviation from the edge directions on those faces falls strictly as the
    feature weight grows (the weighted alignment term pulls harder; at weight -> infinity it becomes the
    hard constraint);
  * a weight of 0: the base alignment's values on those faces have no influence at all (the solutions agree
    to rounding), and there the solution satisfies the spline's optimality condition without any
    alignment term;
  * mirror symmetry: u(mirror f) = reflect(u(f)) holds to 1e-8 on a symmetric mesh (it is imposed exactly:
    rounding only), also with constraints on one side; a face without partner is reported;
  * a cut lets the field jump: across a slit the field turns by far more than across the same edges
    without the cut.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import meshgen
from conftest import core_mesh

nfield_core = pytest.importorskip("nfield.core")
from nfield.core import DesignSession, Mesh, native, solve  # noqa: E402
from nfield.core.guides import CurveGuide, FeatureGuide, Symmetry, parse_features  # noqa: E402


def feature_faces(mesh, fg: FeatureGuide):
    """(face, unit edge vector) for every face next to a feature edge, from an independent walk over the
    edge table (not from the guide code's chains)."""
    g = native().GuideGeometry(mesh.native)
    fs = g.detect_features(boundary=fg.boundary, sharp_angle=-1 if fg.sharp_angle is None else fg.sharp_angle)
    E = np.asarray(g.edges())
    V = mesh.vertices
    out = []
    for e in np.asarray(fs.edge_ids).tolist():
        a, b = E[e]
        ev = (V[b] - V[a]) / np.linalg.norm(V[b] - V[a])
        for f in g.edge_faces(e):
            out.append((f, ev))
    return out


def deviation_degrees(result, pairs, skip=()):
    """Per (face, edge vector): the angle between the edge line and the nearest of the face's n directions."""
    alld = result.all_directions()
    return np.array([math.degrees(math.acos(min(1.0, float(np.abs(alld[f] @ ev).max()))))
                     for f, ev in pairs if f not in skip])


# ---------------------------------------------------------------------------------------- features
@pytest.mark.parametrize("name", ["fandisk.obj", pytest.param("rocker-arm.obj", marks=pytest.mark.slow)])
def test_hard_features_follow_every_sharp_edge(name):
    mesh = core_mesh(name)
    s = DesignSession(mesh, n=4, order=2, align="curvature-max")
    fg = s.set_features("sharp:30", mode="hard")
    r = s.solve()
    rep = r.guides
    assert rep.feature_edges > 100 and rep.hard_constraints > 0
    dropped = {d["face"] for d in rep.dropped}
    # every dropped face is explained by two named guides and an angle the 4-symmetry cannot absorb
    for d in rep.dropped:
        assert "feature chain" in d["reason"] and "degrees apart" in d["reason"]
    pairs = feature_faces(mesh, fg)
    dev = deviation_degrees(r, pairs, skip=dropped)
    assert len(dev) > 0.8 * len(pairs)
    assert dev.max() < 1.0, dev.max()
    # the +d rule: the field points along each constraint, not against it (n = 4: the cross contains both
    # d and -d, so this is the plain direction check above); every constrained face is unit length
    assert np.allclose(np.linalg.norm(r.directions[[f for f, _ in pairs if f not in dropped]], axis=1), 1.0)


def test_soft_feature_deviation_falls_with_weight():
    mesh = core_mesh("fandisk.obj")
    s = DesignSession(mesh, n=4, order=2, align="curvature-max")
    pairs = feature_faces(mesh, parse_features("sharp:30"))
    without = float(deviation_degrees(s.solve(details=False), pairs).mean())
    means = []
    for w in (1e-4, 1e-3, 1e-2, 1e-1, 1.0):
        s.set_features("sharp:30", mode="soft", weight=w, width=2)
        means.append(float(deviation_degrees(s.solve(details=False), pairs).mean()))
    assert all(b < a for a, b in zip(means, means[1:])), means
    # already the weakest weight improves on no feature alignment, and weight 1 (as stiff as the smoothness
    # itself, docs/guides.md) comes close to the hard mode: what remains is mostly the faces next to two
    # feature edges, which take the mean of the two directions (measured: 7.7 -> 2.1 ... 0.15 degrees)
    assert means[0] < without and means[-1] < 0.05 * without, (without, means)


def test_feature_spec_parsing():
    fg = parse_features("boundary,sharp:30", mode="hard", every=2)
    assert fg.boundary and fg.sharp_angle == 30.0 and fg.mode == "hard" and fg.every == 2
    assert parse_features("sharp").sharp_angle == 30.0 and not parse_features("sharp").boundary
    for bad in ("", "edges", "sharp:abc", "sharp:200", "boundary:3"):
        with pytest.raises(ValueError):
            parse_features(bad)
    with pytest.raises(ValueError, match="mode"):
        FeatureGuide(mode="firm")


# ---------------------------------------------------------------------------------------- weights
def test_zero_weight_means_no_alignment_there():
    mesh = core_mesh("rocker-arm.obj")
    F = mesh.num_faces
    cent = mesh.vertices[mesh.faces].mean(axis=1)
    region = cent[:, 0] < np.percentile(cent[:, 0], 30)
    weight = np.where(region, 0.0, 1.0)
    rng = np.random.default_rng(1)
    field_a = rng.normal(size=(F, 3))
    field_b = field_a.copy()
    field_b[region] = rng.normal(size=(int(region.sum()), 3))  # other guide values where the weight is 0
    ra = solve(mesh, n=2, order=2, align="field", alignment_field=field_a, alignment_weight=weight)
    rb = solve(mesh, n=2, order=2, align="field", alignment_field=field_b, alignment_weight=weight)
    scale = np.abs(ra.raw_solution).max()
    assert np.abs(ra.raw_solution - rb.raw_solution).max() < 1e-12 * scale
    # with the values changed where the weight is 1 the solution does change (the test can fail)
    field_c = field_a.copy()
    field_c[~region] = rng.normal(size=(int((~region).sum()), 3))
    rc = solve(mesh, n=2, order=2, align="field", alignment_field=field_c, alignment_weight=weight)
    assert np.abs(ra.raw_solution - rc.raw_solution).max() > 1e-3 * scale


def test_weight_and_rotation_validation():
    mesh = core_mesh("sphere.obj")
    s = DesignSession(mesh, n=4, align="curvature-max")
    with pytest.raises(ValueError, match="one value per face"):
        s.set_alignment_weight(np.ones(3))
    w = np.ones(mesh.num_faces)
    w[7] = -1
    with pytest.raises(ValueError, match="face 7"):
        s.set_alignment_weight(w)
    w[7] = np.nan
    with pytest.raises(ValueError, match="face 7"):
        s.set_alignment_rotation(w)


def test_rotation_turns_the_guide():
    """A rotation of pi/(2n)... for n = 2 a quarter turn (pi/2) of the guide turns the solution by pi/2 where
    only the rotated guide acts (uniform rotation, no constraints: the spline is equivariant)."""
    mesh = core_mesh("rocker-arm.obj")
    r0 = solve(mesh, n=2, order=2, align="curvature-max")
    r1 = solve(mesh, n=2, order=2, align="curvature-max", alignment_rotation=np.full(mesh.num_faces, math.pi / 2))
    # rotating every guide vector by pi/2 multiplies the representation by e^{i n pi/2} = -1 for n = 2, so
    # the linear spline's solution is multiplied by -1 as well: directions turn by exactly 90 degrees
    assert np.abs(r1.raw_solution + r0.raw_solution).max() < 1e-9 * np.abs(r0.raw_solution).max()


# ---------------------------------------------------------------------------------------- curves and comb
def test_hard_curve_constrains_the_faces_it_crosses():
    mesh = core_mesh("stanford-bunny.obj")
    V = mesh.vertices
    c = V.mean(axis=0)
    diag = mesh.native.bounding_box_diagonal
    t = np.linspace(0, 2 * np.pi, 100)
    pts = c + 0.3 * diag * np.stack([np.cos(t), 0 * t, np.sin(t)], 1)  # a ring around the bunny, off the surface
    s = DesignSession(mesh, n=4, order=1, align="none")
    s.set_curve("ring", pts, mode="hard", tolerance=0.05, every=4)
    r = s.solve()
    info = r.guides.curves["ring"]
    assert info["missed"] > 0 and "ring" in r.guides.missed_curves  # parts of the ring float off the bunny
    assert r.guides.hard_constraints > 5
    s.set_curve("ring", pts, mode="hard", tolerance=1.0, every=4)  # generous tolerance: nothing missed
    r = s.solve()
    assert r.guides.curves["ring"]["missed"] == 0 and not r.guides.missed_curves


def test_curve_guide_validation():
    with pytest.raises(ValueError, match="shape"):
        CurveGuide(np.zeros((1, 3)))
    with pytest.raises(ValueError, match="not finite"):
        CurveGuide(np.array([[0, 0, 0], [np.nan, 0, 0]]))
    with pytest.raises(ValueError, match="mode"):
        CurveGuide(np.zeros((2, 3)), mode="loose")
    s = DesignSession(core_mesh("sphere.obj"), n=4)
    with pytest.raises(ValueError, match="no curve guide"):
        s.remove_curve("nope")


def test_comb_strokes_accumulate_and_guide():
    mesh = core_mesh("sphere.obj")
    s = DesignSession(mesh, n=1, order=2, align="none")
    d, w = s.comb_field
    assert not w.any()
    hit = 17
    p = mesh.vertices[mesh.faces[hit]].mean(axis=0)
    n = np.asarray(mesh.native.face_normals)[hit]
    along = np.cross(n, [0.0, 0.0, 1.0])
    along /= np.linalg.norm(along)
    changed = s.comb([p], [along], radius=0.05, strength=0.5)
    d, w = s.comb_field
    assert hit in changed and w[hit] == 0.5 and np.allclose(d[hit], along, atol=1e-12)
    s.comb([p], [along], radius=0.05, strength=0.5)
    assert s.comb_field[1][hit] == 0.75
    r = s.solve()
    # with the comb as the only guide, the field at the stroke's centre follows it (n = 1: the vector itself)
    assert r.directions[hit] @ along > math.cos(math.radians(10))
    s.clear_comb()
    assert not s.comb_field[1].any()
    with pytest.raises(ValueError, match="radius"):
        s.comb([p], [along], radius=0)


def test_comb_stroke_in_batches_is_one_stroke():
    """A brush stroke fed sample by sample (begin / extend / end, as the comb tool does while the mouse moves)
    gives exactly the comb field of one stroke of all its samples: what a face feels is a sum and a maximum
    over the samples, both independent of order and grouping (bit-identical here: the same additions in the
    same order). Cancelling puts the comb field back."""
    V, F = meshgen.icosphere(4)
    mesh = Mesh(V, F)
    rng = np.random.default_rng(5)
    points = V[rng.choice(len(V), 30)]
    dirs = rng.normal(size=(30, 3))
    a = DesignSession(mesh, n=4, order=2, align="none")
    a.comb(points[:5], dirs[:5], radius=0.1, strength=0.7)  # an earlier stroke the new one blends with
    before = a.comb_field
    changed = a.comb(points, dirs, radius=0.08, falloff="linear", strength=0.6)
    b = DesignSession(mesh, n=4, order=2, align="none")
    b.set_comb(*before)
    b.begin_comb_stroke(radius=0.08, falloff="linear", strength=0.6)
    for i in range(0, 30, 4):
        touched = b.extend_comb_stroke(points[i:i + 4], dirs[i:i + 4])
        assert len(touched) > 0
    assert b.comb_stroke_active
    assert np.array_equal(b.end_comb_stroke(), changed)
    assert np.array_equal(a.comb_field[0], b.comb_field[0]) and np.array_equal(a.comb_field[1], b.comb_field[1])
    b.begin_comb_stroke(radius=0.08)
    b.extend_comb_stroke(points[:3], dirs[:3])
    b.cancel_comb_stroke()
    assert not b.comb_stroke_active and np.array_equal(b.comb_field[1], a.comb_field[1])
    with pytest.raises(ValueError, match="no comb stroke in progress"):
        b.extend_comb_stroke(points[:1], dirs[:1])


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


def test_mirrored_comb_samples():
    """The mirror images of comb samples: points and directions reflected about the plane; a sample on a
    face without a partner (partial symmetry) has no image and is listed."""
    V, F = meshgen.icosphere(3)
    V = V.copy()
    V[0] += [0.0, 0.0, 0.01]  # one vertex off: its faces have no partner
    mesh = Mesh(V, F)
    s = DesignSession(mesh, n=4, align="none")
    s.set_symmetry(Symmetry("x", partial=True))
    ring = np.flatnonzero((F == 0).any(axis=1))
    cent = V[F].mean(axis=1)
    good = int(np.argmax(cent[:, 1]))
    p = np.stack([cent[good], cent[ring[0]]])
    d = np.array([[1.0, 2.0, 3.0], [1.0, 0.0, 0.0]])
    mp, md, unmatched = s.mirrored_samples(p, d)
    assert unmatched == [1]
    assert np.allclose(mp, [[-p[0, 0], p[0, 1], p[0, 2]]]) and np.allclose(md, [[-1.0, 2.0, 3.0]])


# ---------------------------------------------------------------------------------------- cuts
def test_cut_lets_the_field_jump():
    V, F = meshgen.grid(21, 21)
    mesh = Mesh(V, F)
    idx = np.arange(21 * 21).reshape(21, 21)
    # a slit along x = 0.5 from the bottom edge to y = 0.8 (the two halves stay connected above it)
    slit = np.array([(idx[10, j], idx[10, j + 1]) for j in range(0, 16)])
    cent = V[F].mean(axis=1)
    left = int(np.argmin(np.linalg.norm(cent - [0.25, 0.4, 0], axis=1)))
    right = int(np.argmin(np.linalg.norm(cent - [0.75, 0.4, 0], axis=1)))
    across = []  # pairs of faces on the two sides of the slit's middle edges
    for j in range(5, 11):
        a, b = idx[10, j], idx[10, j + 1]
        both = np.flatnonzero((F == a).any(axis=1) & (F == b).any(axis=1))
        across.append(both)

    def jump(cuts):
        r = solve(mesh, n=1, order=1, align="none", constraints=[], vector_constraints=[
            nfield_core.VectorConstraint(left, (1.0, 0.0, 0.0)), nfield_core.VectorConstraint(right, (0.0, 1.0, 0.0))],
            cuts=cuts)
        d = r.directions
        return max(math.degrees(math.acos(np.clip(d[a] @ d[b], -1, 1))) for a, b in across), r

    with_cut, r = jump(slit)
    without, _ = jump(np.zeros((0, 2), dtype=int))
    assert r.guides.cuts["opened"] == len(slit)
    # without the cut the harmonic field turns smoothly from 0 to 90 degrees over ~10 faces: a few degrees per
    # edge; with it each side keeps its own constraint's direction up to the slit
    assert without < 15 and with_cut > 45, (without, with_cut)


def test_singularity_on_a_cut_is_refused():
    V, F = meshgen.grid(9, 9)
    mesh = Mesh(V, F)
    idx = np.arange(81).reshape(9, 9)
    s = DesignSession(mesh, n=4)
    s.set_cuts([(idx[4, j], idx[4, j + 1]) for j in range(0, 5)])
    with pytest.raises(ValueError, match="cut"):
        s.set_singularity(int(idx[4, 2]), 0.25)


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
