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
