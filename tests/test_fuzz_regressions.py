"""Regression tests for what the fuzzers found (native/fuzz, docs/hardening.md "Sanitizers and fuzzing").

* NaN spline fields on meshes of large (or small) extent. fuzz_mesh_ingestion decoded a mesh of extent
  ~1e59 (inside the supported range [1e-60, 1e60] of the time) whose order-2 spline came back NaN/inf
  without an error: the fill of unconstrained components squares the raw solution, which grows like
  extent^(2 order). Following it up showed the whole class: order-4 splines on the unit sphere scaled to
  1e40 returned NaN, at 1e+-20 singularity-only solves failed, and lambda underflowed to 0 at 1e58.
  The supported extent is now [1e-12, 1e12] (native/src/mesh.cpp), where every order and kind solves;
  outside it the mesh is rejected with a ValueError asking to rescale. The fuzzer's mesh and the seeds
  components_fill_large/small (native/fuzz/corpus/mesh_ingestion/) are replayed on every fuzz run.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

nat = pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")

SPHERE = Path(__file__).resolve().parent / "data" / "sphere.obj"
MAX_EXTENT = 1e12  # kMaxExtent in native/src/mesh.cpp
MIN_EXTENT = 1e-12


def _unit_sphere():
    positions, triangles = nat.read_mesh(str(SPHERE))[:2]
    diagonal = np.linalg.norm(positions.max(axis=0) - positions.min(axis=0))
    return positions / diagonal, triangles  # bounding-box diagonal 1


def _solve(positions, triangles, order, kind, constraint):
    """The raw field and its Rayleigh quotient E_order(w) / |w|_M^2 (units length^-2 order)."""
    mesh = nat.Mesh(positions, triangles)
    ops = nat.FieldOperators(mesh, 4, "geometric")
    solver = nat.ExactSolver(ops, order, 1.0, None, kind)
    if constraint == "face":
        (solver.set_direction_constraint if kind == "direction" else solver.set_vector_constraint)(0, 1.0 + 0.0j)
    else:
        solver.set_singularity(next(v for v in range(len(positions)) if mesh.vertex_is_interior(v)), 1)
    w = np.asarray(solver.solve())
    rayleigh = ops.energy(w, order) / np.sum(np.abs(w) ** 2 * np.asarray(mesh.face_areas))
    return w, rayleigh


@pytest.mark.parametrize("extent", [0.99 * MAX_EXTENT, 1.01 * MIN_EXTENT])
@pytest.mark.parametrize("constraint", ["face", "singularity"])
@pytest.mark.parametrize("kind", ["direction", "vector"])
@pytest.mark.parametrize("order", [1, 2, pytest.param(3, marks=pytest.mark.slow), pytest.param(4, marks=pytest.mark.slow)])
def test_splines_are_finite_and_scale_covariant_at_the_extent_limits(extent, constraint, kind, order):
    """At both ends of the supported range every spline is finite and matches the unit-size solution:
    lambda ~ L^-2m and M ~ L^2, so direction splines scale like L^2m and vector splines (whose constraint
    fixes the magnitude) not at all. A singularity-only solve is the smoothest field under the constraint,
    which the sphere's symmetry leaves nearly non-unique, so there the Rayleigh quotient (~ L^-2m) is compared."""
    positions, triangles = _unit_sphere()
    w1, rayleigh1 = _solve(positions, triangles, order, kind, constraint)
    w, rayleigh = _solve(positions * extent, triangles, order, kind, constraint)
    assert np.isfinite(w).all() and np.abs(w).max() > 0
    if constraint == "face":
        unit = extent ** (2 * order) if kind == "direction" else 1.0
        # Order 3/4 solves are accurate to ~1e-6 of the largest value (kappa(V)^2 eps, spline_solver.hpp).
        np.testing.assert_allclose(w / unit, w1, rtol=1e-5, atol=1e-6 * np.abs(w1).max())
    else:
        # Inverse iteration (30 steps) between near-degenerate eigenvalues of the sphere: the iterate, and
        # so its quotient, depends on rounding at the 1e-3 level even between nearby unit-size solves.
        np.testing.assert_allclose(rayleigh * extent ** (2 * order), rayleigh1, rtol=1e-2)


@pytest.mark.parametrize("extent", [1.01 * MAX_EXTENT, 1e40, 0.99 * MIN_EXTENT, 1e-40])
def test_meshes_beyond_the_supported_extent_are_rejected(extent):
    """At 1e40 the order-4 spline used to come back NaN; now the mesh is refused up front."""
    positions, triangles = _unit_sphere()
    with pytest.raises(ValueError, match="outside the supported range.*rescale"):
        nat.Mesh(positions * extent, triangles)


def test_fuzzer_mesh_is_rejected_instead_of_solving_to_nan():
    """The mesh fuzz_mesh_ingestion decoded (coordinates in units of 1e58): face 3 duplicates face 1,
    the other three faces are separate components; its order-2 spline returned [nan, inf, inf, 0]."""
    positions = 1e58 * np.array([[1, -14, -12.25], [-14, -14, -14], [0, -1, -14], [-13.75, -13.5, -13.75],
                                 [-13.875, -13.5, -13.875], [-13.75, -7.375, -13.625]])
    faces = np.array([[0, 3, 4], [0, 5, 1], [2, 5, 3], [1, 5, 0]], dtype=np.int32)
    with pytest.raises(ValueError, match="outside the supported range"):
        nat.Mesh(positions, faces)
    # The same mesh at an extent inside the range solves to a finite field with every component filled.
    mesh = nat.Mesh(positions / 1e58 * 1e10, faces)
    solver = nat.ExactSolver(nat.FieldOperators(mesh, 1, "combinatorial"), 2, 1.0, None, "direction")
    solver.set_direction_constraint(0, complex(np.cos(3 * np.pi / 8), np.sin(3 * np.pi / 8)))
    w = np.asarray(solver.solve())
    assert np.isfinite(w).all() and w[3] == 0 and (np.abs(w[:3]) > 0).all()
