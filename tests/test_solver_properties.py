"""Property-based tests of the exact spline solver (hypothesis) over random small, dirty meshes and random
constraint sets.

Meshes: grids of 3..7 x 3..7 vertices, bent and jittered, with random diagonals, plus random holes (deleted
faces), duplicated faces, degenerate faces (a vertex moved onto another one, or an appended collinear
triangle) and flipped faces. Parameters: n in {1, 2, 3, 4, 6}, order 1..3, alignment none or (even n)
curvature. Constraints: direction and vector constraints on random faces (tangent directions, excluded faces
included on purpose), singularities at random interior vertices with indices inside the range the native
code reports admissible (singularity_numerator_range).

Property: ``nfield.core.solve`` either raises ValueError with one of the documented messages (a constraint on
an excluded face, contradictory constraints, a mesh without usable faces, a singularity index the solve
cannot impose because the rest of the design drives the ring's field to ~0 or the system is ill-conditioned)
or returns a field that is finite,
unit and tangent on every kept face and zero on excluded ones, whose direction constraints hold to 1e-8
(|sin| of the representation-space angle, as in test_splines.py) along +d, whose vector constraints hold to
1e-8 relative, and whose pinned singularities have their index. Nothing may raise anything else or hang.

Runs: the default profile "ci" is derandomized (the same examples every run, so a failure reproduces) and
bounded (max_examples below, a few seconds in all). ``NFIELD_HYPOTHESIS_PROFILE=long`` runs 2000 random
examples per test without derandomization (minutes; see docs/hardening.md); hypothesis prints the failing
example and its reproduction blob.
"""
from __future__ import annotations

import os
import re
from datetime import timedelta

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

import meshgen as mg  # noqa: E402

nat = pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")
core = pytest.importorskip("nfield.core")

# One example solves a mesh of at most ~70 faces: a few ms. The deadline (per example) is 100x that and more,
# so the shared machine's load cannot trip it, but a hang or a pathological slowdown does.
_COMMON = dict(deadline=timedelta(seconds=5), suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
               print_blob=True)
PROFILES = {
    "ci": settings(max_examples=60, derandomize=True, database=None, **_COMMON),
    "long": settings(max_examples=2000, derandomize=False, **_COMMON),
}
PROFILE_NAME = os.environ.get("NFIELD_HYPOTHESIS_PROFILE", "ci")
if PROFILE_NAME not in PROFILES:
    raise ValueError(f"NFIELD_HYPOTHESIS_PROFILE must be one of {sorted(PROFILES)}, got {PROFILE_NAME!r}")
PROFILE = PROFILES[PROFILE_NAME]

#: the ValueErrors a valid random design may legitimately meet (documented in docs/hardening.md)
DOCUMENTED = [
    r"face \d+: the face is excluded from the field",     # a constraint on a degenerate / duplicate face
    r"contradictory constraints: they cannot all hold at once",
    r"no usable face",                                    # every face deleted or degenerate
    # the ring's field nearly vanishes (the alignment overrides it) or the rows are ill-conditioned (order 3,
    # index near the end of its range): found by the long profile; the solver used to return a field without
    # the singularity
    r"singularity at vertex \d+: the solve could not impose index",
]
#: see test_splines.py: the constraint rows hold to rounding of the dense Schur solve (~1e-13 relative)
TOL = 1e-8


@st.composite
def dirty_meshes(draw):
    nx, ny = draw(st.integers(3, 7)), draw(st.integers(3, 7))
    seed = draw(st.integers(0, 2**31 - 1))
    V, F = mg.grid(nx, ny, random_diagonals=draw(st.booleans()), seed=seed)
    rng = np.random.default_rng(seed)
    V = V.copy()
    bend = draw(st.floats(0.0, 1.5))
    V[:, 2] = bend * np.sin(2.0 * V[:, 0]) * np.cos(1.5 * V[:, 1])
    jitter = draw(st.floats(0.0, 0.3)) / max(nx, ny)
    V[:, :2] += rng.uniform(-jitter, jitter, (len(V), 2))
    F = [list(f) for f in F]
    holes = draw(st.integers(0, len(F) // 3))
    for i in sorted(rng.choice(len(F), size=holes, replace=False), reverse=True):
        del F[i]
    for _ in range(draw(st.integers(0, 2))):  # duplicates (also with another winding)
        if F:
            f = F[int(rng.integers(len(F)))]
            F.append(f[::-1] if rng.random() < 0.5 else list(f))
    if draw(st.booleans()) and len(V) > 4:  # collapse a vertex onto a neighbour: zero-area faces
        a = int(rng.integers(len(V)))
        b = int(np.argsort(np.linalg.norm(V - V[a], axis=1))[1])
        V[a] = V[b]
    if draw(st.booleans()):  # a collinear triangle
        k = len(V)
        V = np.vstack([V, [[5, 5, 0], [6, 5, 0], [7, 5, 0]]])
        F.append([k, k + 1, k + 2])
    for _ in range(draw(st.integers(0, 3))):  # flipped faces
        if F:
            i = int(rng.integers(len(F)))
            F[i] = F[i][::-1]
    if not F:
        F = [[0, 1, nx]]
    return V, np.asarray(F, dtype=np.int64)


@st.composite
def designs(draw):
    V, F = draw(dirty_meshes())
    mesh = core.Mesh(V, F)  # dirty but valid arrays: never raises
    n = draw(st.sampled_from([1, 2, 3, 4, 6]))
    order = draw(st.integers(1, 3))
    align = draw(st.sampled_from(["none", "curvature-max", "curvature-min"] if n % 2 == 0 else ["none"]))
    strength = draw(st.sampled_from([1e-3, 1.0, 100.0]))
    normals = np.asarray(mesh.native.face_normals)
    faces = draw(st.lists(st.integers(0, len(F) - 1), unique=True, max_size=min(8, len(F))))
    dirs, vecs = [], []
    for f in faces:
        a = draw(st.floats(0, 2 * np.pi))
        nrm = normals[f]
        if not np.any(nrm):  # an excluded face: any direction (the solve must name the face)
            d = np.array([np.cos(a), np.sin(a), 0.3])
        else:
            t = np.cross(nrm, [0.3, 0.5, 0.7]) if abs(nrm @ [0.3, 0.5, 0.7]) < 0.99 * np.linalg.norm([0.3, 0.5, 0.7]) \
                else np.cross(nrm, [1.0, 0.0, 0.0])
            t /= np.linalg.norm(t)
            d = np.cos(a) * t + np.sin(a) * np.cross(nrm, t)
        if draw(st.integers(0, 3)) == 0:
            vecs.append(core.VectorConstraint(f, tuple(d * draw(st.floats(0.1, 3.0)))))
        else:
            dirs.append(core.DirectionConstraint(f, tuple(d)))
    sings = []
    ops = nat.FieldOperators(mesh.native, n, "geometric")
    interior = [v for v in range(mesh.num_vertices) if mesh.native.vertex_is_interior(v)]
    for v in draw(st.lists(st.sampled_from(interior), unique=True, max_size=2)) if interior else []:
        lo, hi = nat.singularity_numerator_range(ops, v)
        num = draw(st.integers(lo, hi).filter(lambda k: k != 0)) if hi > lo or lo != 0 else 0
        if num:
            sings.append(core.SingularityConstraint(v, num / n))
    return mesh, dict(n=n, order=order, align=align, strength=strength), dirs, vecs, sings


def _check(mesh, params, dirs, vecs, sings, result):
    n = params["n"]
    active = np.asarray(mesh.native.face_active)
    normals = np.asarray(mesh.native.face_normals)
    d = result.directions
    assert np.isfinite(d).all() and np.isfinite(result.raw_solution).all()
    length = np.linalg.norm(d, axis=1)
    # the solver can leave a face at exactly zero (a zero of the spline): then its row is zero, nothing else
    nonzero = np.abs(result.raw_solution) > 0
    assert np.abs(length[active & nonzero] - 1).max(initial=0) < 1e-9
    assert np.all(length[~active] == 0)
    assert np.abs(np.einsum("ij,ij->i", d, normals)).max() < 1e-9
    ops = nat.FieldOperators(mesh.native, n, "geometric")
    w = np.asarray(result.raw_solution)
    for c in dirs:
        z = complex(np.asarray(ops.tangent_to_representation(np.array([c.face]), np.array([c.direction])))[0])
        z /= abs(z)
        wf = w[c.face]
        assert abs(wf) > 0, f"constrained face {c.face} vanished"
        assert abs((np.conj(z) * wf).imag) / abs(wf) < TOL, (c, wf, z)
        assert (np.conj(z) * wf).real > 0, f"face {c.face} points along -d"
    for c in vecs:
        z = complex(np.asarray(ops.tangent_to_representation(np.array([c.face]), np.array([c.vector])))[0])
        assert abs(w[c.face] - z) <= TOL * abs(z), (c, w[c.face], z)
    got = dict(result.singularities)
    scale = np.abs(w).max()
    for s in sings:
        ring = mesh.native.vertex_ring_faces(s.vertex)
        if np.abs(w[ring]).max() <= 1e-9 * scale:
            # The singularity rows are homogeneous: when nothing pulls the field onto the ring (a tiny mesh
            # whose ring is most of it, no alignment), the spline may vanish there (rounding noise, ~1e-14
            # relative). A zero has no index; documented in docs/hardening.md.
            continue
        assert got.get(s.vertex) == pytest.approx(s.index), (s, got.get(s.vertex))


@PROFILE
@given(designs())
def test_random_designs_solve_or_fail_documented(design):
    mesh, params, dirs, vecs, sings = design
    try:
        result = core.solve(mesh, constraints=dirs, vector_constraints=vecs, singularities=sings, **params)
    except ValueError as exc:
        assert any(re.search(p, str(exc)) for p in DOCUMENTED), f"undocumented ValueError: {exc}"
        return
    _check(mesh, params, dirs, vecs, sings, result)


@PROFILE
@given(designs())
def test_random_designs_without_excluded_faces_solve(design):
    """Constraints only on kept faces and singularities only where admissible: no 'excluded face' error may
    occur, and contradictions are only possible between singularities and constraints sharing a ring."""
    mesh, params, dirs, vecs, sings = design
    active = np.asarray(mesh.native.face_active)
    dirs = [c for c in dirs if active[c.face]]
    vecs = [c for c in vecs if active[c.face]]
    try:
        result = core.solve(mesh, constraints=dirs, vector_constraints=vecs, singularities=sings, **params)
    except ValueError as exc:
        ring_faces = {f for s in sings for f in mesh.native.vertex_ring_faces(s.vertex)}
        constrained = {c.face for c in dirs + vecs}
        shared = ring_faces & constrained or len(sings) > 1
        not_imposed = re.search(DOCUMENTED[-1], str(exc))
        assert ("contradictory constraints" in str(exc) and shared) or not_imposed, \
            f"unexpected ValueError: {exc}"
        return
    _check(mesh, params, dirs, vecs, sings, result)


# ============================================================ first-order optimality of random clean designs
@st.composite
def clean_designs(draw):
    """A mesh without excluded faces (so unknown = face): a bent or flat grid (boundary), a cylinder
    (developable, open) or a bumpy sphere (closed); n, order 1..4, alignment, and 1..6 hard constraints of one
    kind (n-vector spline) or mixed (n-direction spline), at distinct random faces."""
    family = draw(st.sampled_from(["bent", "flat", "cylinder", "sphere"]))
    seed = draw(st.integers(0, 2**31 - 1))
    if family in ("bent", "flat"):
        V, F = mg.grid(draw(st.integers(3, 8)), draw(st.integers(3, 8)), random_diagonals=True, seed=seed)
        V = V.copy()
        if family == "bent":
            V[:, 2] = draw(st.floats(0.2, 1.5)) * np.sin(2.0 * V[:, 0]) * np.cos(1.5 * V[:, 1])
    elif family == "cylinder":
        V, F = mg.cylinder(1.0, 2.0, draw(st.integers(5, 10)), draw(st.integers(3, 6)), random_diagonals=True,
                           seed=seed)
    else:
        V, F = mg.bumpy_sphere(1, amplitude=draw(st.floats(0.0, 0.3)), seed=seed)
    mesh = core.Mesh(V, F)
    n = draw(st.sampled_from([1, 2, 4]))
    order = draw(st.integers(1, 4))
    align = draw(st.sampled_from(["none", "curvature-max"] if n % 2 == 0 and family in ("bent", "sphere")
                                 else ["none"]))
    strength = draw(st.sampled_from([0.1, 1.0, 30.0]))
    k = draw(st.integers(1, min(6, len(F))))
    faces = draw(st.lists(st.integers(0, len(F) - 1), unique=True, min_size=k, max_size=k))
    normals = np.asarray(mesh.native.face_normals)
    vector_kind = draw(st.booleans())
    dirs, vecs = [], []
    for f in faces:
        a = draw(st.floats(0, 2 * np.pi))
        nrm = normals[f]
        t = np.cross(nrm, [0.3, 0.5, 0.7]) if abs(nrm @ [0.3, 0.5, 0.7]) < 0.99 * np.linalg.norm([0.3, 0.5, 0.7]) \
            else np.cross(nrm, [1.0, 0.0, 0.0])
        t /= np.linalg.norm(t)
        d = np.cos(a) * t + np.sin(a) * np.cross(nrm, t)
        if vector_kind or draw(st.integers(0, 3)) == 0:
            vecs.append(core.VectorConstraint(f, tuple(d * draw(st.floats(0.2, 3.0)))))
        else:
            dirs.append(core.DirectionConstraint(f, tuple(d)))
    return mesh, dict(n=n, order=order, align=align, strength=strength), dirs, vecs


# conftest.stationarity_residual is a normwise backward error: ~1e-16 for these solves; the required bounds.
OPTIMALITY_TOL = {1: 1e-10, 2: 1e-10, 3: 1e-8, 4: 1e-8}


@PROFILE
@given(clean_designs())
def test_random_splines_are_optimal_and_live_agrees(design):
    """nfield.core.solve (one-shot: vector constraints substituted) returns a field that meets its vector
    constraints exactly and its direction constraints along +d, and satisfies the first-order conditions of
    eq. 8 / eq. 12 at every free face (conftest.stationarity_residual within OPTIMALITY_TOL). A DesignSession
    (live solver: Schur rows, cached columns, anchors for lambda = 0) gives the same field: to 1e-8 relative
    at orders 1-2, 1e-6 at orders 3-4 (cond(V) reaches 1e10-1e12 on these meshes at order 4, and the live
    column route carries ~1e-2 cond(V) eps, test_splines.py)."""
    from conftest import stationarity_residual

    mesh, params, dirs, vecs = design
    res = core.solve(mesh, constraints=dirs, vector_constraints=vecs, **params)
    n, order = params["n"], params["order"]
    ops = nat.FieldOperators(mesh.native, n, "geometric")
    w = np.asarray(res.raw_solution)
    assert np.isfinite(w).all()
    for c in vecs:
        z = complex(np.asarray(ops.tangent_to_representation(np.array([c.face]), np.array([c.vector])))[0])
        assert w[c.face] == z
    for c in dirs:
        z = complex(np.asarray(ops.tangent_to_representation(np.array([c.face]), np.array([c.direction])))[0])
        assert abs((np.conj(z) * w[c.face]).imag) <= TOL * abs(z * w[c.face]) and (np.conj(z) * w[c.face]).real > 0
    kind = "vector" if vecs and not dirs else "direction"
    u = np.zeros(len(w), complex)
    if params["align"] != "none":
        u = np.asarray(nat.alignment_field(ops, params["align"]), dtype=np.complex128)
    mass = np.asarray(ops.mass)
    rhs = (-res.lambda_ if kind == "vector" else 1.0) * mass * u
    free = np.setdiff1d(np.arange(len(w)), [c.face for c in dirs + vecs])
    if free.size:
        resid = stationarity_residual(ops, order, res.lambda_, w, rhs, free)
        assert resid < OPTIMALITY_TOL[order], resid
    s = core.DesignSession(mesh, **params)
    for c in dirs:
        s.set_direction(c.face, c.direction)
    for c in vecs:
        s.set_vector(c.face, c.vector)
    live = np.asarray(s.solve(details=False).raw_solution)
    tol = 1e-8 if order <= 2 else 1e-6
    assert np.abs(live - w).max() <= tol * np.abs(w).max(), (np.abs(live - w).max() / np.abs(w).max(), kind)
