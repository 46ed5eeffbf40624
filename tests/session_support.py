"""What the DesignSession tests share (test_session.py, test_session_regions.py): the accuracy bounds, the test
meshes, a from-scratch reference solve and checks of hard constraints on a raw solution."""
from __future__ import annotations

import functools

import numpy as np

import meshgen as mg
import mesh_reference as mref
import nfield.core as core
from conftest import core_mesh
from nfield.core import DesignSession, DirectionConstraint, VectorConstraint

# The accuracy required of incremental vs from-scratch results ("to 1e-8 relative"). The
# two computations factor the same matrix; they differ only in the order in which the cached columns
# were computed (batched back-substitutions vs one batch), so the observed difference is ~1e-15 or 0.
REL_TOL = 1e-8
# Hard constraints on the raw solution: the native solver keeps constraint rows exact to ~1e-12 after
# one step of iterative refinement (spline_solver.hpp, "Accuracy"). 1e-8 leaves four orders of margin
# for ill-conditioned faces (the rocker arm has 2.6 degree slivers) while any real violation (a wrong
# direction, a missing row) is O(1).
CONSTRAINT_TOL = 1e-8


# ============================================================================== helpers
data_mesh = core_mesh


@functools.lru_cache(maxsize=None)
def procedural_mesh(kind: str):
    if kind == "bumpy":  # 1,280 faces, irregular (jittered) triangulation, closed, chi = 2
        V, F = mg.bumpy_sphere(3)
    elif kind == "ico4":
        V, F = mg.icosphere(4)
    elif kind == "ico5":
        V, F = mg.icosphere(5)
    else:
        raise KeyError(kind)
    return core.Mesh(np.asarray(V, float), np.asarray(F, np.int64))


def get_mesh(name: str):
    return procedural_mesh(name) if name in ("bumpy", "ico4", "ico5") else data_mesh(name)


def rel(a, b) -> float:
    a, b = np.asarray(a), np.asarray(b)
    return float(np.abs(a - b).max() / np.abs(b).max())


def scratch(session: DesignSession, **overrides):
    """The from-scratch solve (core API, fresh operators and factorization) of the session's state."""
    s = dict(session.settings)
    s.update(overrides)
    return core.solve(session.mesh, n=s["n"], order=s["order"], align=s["align"], strength=s["strength"],
                      weights=s["weights"], constraints=session.constraints)


def tangent(mesh, face: int, rng) -> np.ndarray:
    """A random unit 3D vector in the plane of `face`."""
    nrm = np.asarray(mesh.native.face_normals)[face]
    d = rng.normal(size=3)
    d -= nrm * (d @ nrm)
    return d / np.linalg.norm(d)


def representation(session: DesignSession, face: int, vec) -> complex:
    ops = session._operators()
    tri = session.mesh.face_triangle(face)
    return complex(np.asarray(ops.tangent_to_representation(np.array([tri]), np.asarray([vec], float)))[0])


def check_constraints(session: DesignSession, w: np.ndarray) -> None:
    """Every direction constraint points along +d on the raw solution w (n-symmetry aware, because the
    representation vector d encodes all n directions at once: w_f along +d means Re(conj(d) w_f) > 0 and
    Im(conj(d) w_f) = 0); every vector constraint's value is met."""
    for c in session.constraints:
        if isinstance(c, DirectionConstraint):
            d = representation(session, c.face, c.direction)
            z = np.conj(d / abs(d)) * w[session.mesh.face_triangle(c.face)]
            assert z.real > 0, f"face {c.face}: field points along -d (conj(d) w = {z})"
            assert abs(z.imag) <= CONSTRAINT_TOL * abs(z), f"face {c.face}: direction off by {z}"
        elif isinstance(c, VectorConstraint):
            v = representation(session, c.face, c.vector)
            got = w[session.mesh.face_triangle(c.face)]
            assert abs(got - v) <= CONSTRAINT_TOL * abs(v), f"face {c.face}: vector {got} != {v}"


def face_centroids(mesh) -> np.ndarray:
    return mref.face_centroids(np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64))


def patch(mesh, center_face: int, radius: float) -> np.ndarray:
    """Faces whose centroid lies within `radius` of the centroid of `center_face` (a triangle mesh)."""
    C = face_centroids(mesh)
    return np.flatnonzero(np.linalg.norm(C - C[center_face], axis=1) < radius)


def interior_vertex_in(mesh, faces, rng, avoid=()) -> int:
    """A random interior vertex whose whole ring lies in `faces` and touches none of `avoid`."""
    inside = set(np.asarray(faces).tolist())
    avoid = set(avoid)
    for v in rng.permutation(np.unique(np.asarray(mesh.faces)[np.asarray(faces)])):
        v = int(v)
        ring = set(mesh.native.vertex_ring_faces(v))
        if mesh.native.vertex_is_interior(v) and ring <= inside and not ring & avoid:
            return v
    raise AssertionError("no interior vertex found in the patch")


# ============================================================================== 1. random edits
