"""Regression tests for bugs the fuzzers found (native/fuzz, docs/hardening.md "Sanitizers and fuzzing").

Each test rebuilds the failing input through the public module and checks the property the fuzzer found
broken; the raw fuzzer input is also kept in native/fuzz/corpus/<target>/ so that every fuzz run replays it.

* Spline fill of empty components overflowed (fuzz_mesh_ingestion, corpus file
  regression-empty-component-fill-overflow): a component without constraints is filled with its smoothest
  field scaled by the RMS magnitude of the rest of the raw solution, which was computed as sqrt(sum |w|^2).
  The raw solution grows like length^(2 order), so from about 1e154 on (order 4 on a mesh of extent 1e20)
  |w|^2 overflowed and the returned field was NaN/inf instead of the scaled solution.
"""
from __future__ import annotations

import numpy as np
import pytest

nat = pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")


def _raw_solution(positions, faces, order, constrained_face, kind="direction"):
    mesh = nat.Mesh(np.asarray(positions, dtype=float), np.asarray(faces, dtype=np.int32))
    ops = nat.FieldOperators(mesh, 1, "geometric")
    solver = nat.ExactSolver(ops, order, 1.0, None, kind)
    if kind == "direction":
        solver.set_direction_constraint(constrained_face, 1.0 + 0.0j)
    else:
        solver.set_vector_constraint(constrained_face, 1.0 + 0.0j)
    return np.asarray(solver.solve()), np.asarray(mesh.face_component)


# Two disjoint quads (two triangles each, slightly bent): two components, only the first is constrained.
TWO_QUADS_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0.2], [0, 1, 0],
                        [3, 0, 0], [4, 0, 0.3], [4, 1, 0], [3, 1, 0]], dtype=float)
TWO_QUADS_F = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]]


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize("kind", ["direction", "vector"])
def test_empty_component_fill_is_scale_invariant(order, kind):
    """The raw solution scales exactly like length^(2 order) (lambda ~ length^-2m, M ~ length^2), fill
    included. At scale 1e20 the order-4 solution is ~1e160, representable, but its square is not."""
    scale = 1e20
    w1, component = _raw_solution(TWO_QUADS_V, TWO_QUADS_F, order, 0, kind)
    w2, _ = _raw_solution(TWO_QUADS_V * scale, TWO_QUADS_F, order, 0, kind)
    assert np.isfinite(w2).all(), w2
    unit = scale ** (2 * order) if kind == "direction" else 1.0  # a vector constraint fixes the magnitude
    constrained = component == component[0]
    np.testing.assert_allclose(w2[constrained] / unit, w1[constrained], rtol=1e-7)
    # The fill's phase is that of an eigenvector (arbitrary); its magnitudes scale like the rest.
    np.testing.assert_allclose(np.abs(w2[~constrained]) / unit, np.abs(w1[~constrained]), rtol=1e-7)
    assert (np.abs(w1[~constrained]) > 0).all()


def test_fuzzer_input_empty_component_fill_overflow():
    """The mesh the fuzzer decoded (coordinates in units of 1e58, order 2, combinatorial weights): face 3
    duplicates face 1 and is excluded, the other three faces are separate components, face 0 constrained."""
    positions = 1e58 * np.array([[1, -14, -12.25], [-14, -14, -14], [0, -1, -14], [-13.75, -13.5, -13.75],
                                 [-13.875, -13.5, -13.875], [-13.75, -7.375, -13.625]])
    faces = np.array([[0, 3, 4], [0, 5, 1], [2, 5, 3], [1, 5, 0]], dtype=np.int32)
    mesh = nat.Mesh(positions, faces)
    ops = nat.FieldOperators(mesh, 1, "combinatorial")
    solver = nat.ExactSolver(ops, 2, 1.0, None, "direction")
    solver.set_direction_constraint(0, complex(np.cos(3 * np.pi / 8), np.sin(3 * np.pi / 8)))
    w = np.asarray(solver.solve())
    assert np.isfinite(w).all(), w
    assert w[3] == 0  # excluded duplicate face
    assert (np.abs(w[:3]) > 0).all()
