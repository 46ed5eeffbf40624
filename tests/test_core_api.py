"""nfield.core: Mesh (arrays and files, polygon numbering), constraint files, solve parameters and
validation, FieldResult, eigenvalues, smoothest_field, and the package's import behaviour.

Reference values:
  * a direction constraint must hold exactly: the unit representation u_t equals the normalized
    representation of the projected constraint direction (1e-9), and one of the n 3D directions is d;
  * an n-vector constraint (n-vector spline, eq. 11) holds exactly on the raw solution: w_t = d_t;
  * on a closed surface the indices of a field without zeros sum to the Euler characteristic.
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import has_native, needs_native

import nfield
from conftest import DATA_DIR as DATA
from conftest import package_env
from nfield.core import (
    DirectionConstraint,
    FieldResult,
    Mesh,
    SingularityConstraint,
    VectorConstraint,
    load_constraints,
)



SPHERE = DATA / "sphere.obj"


def symmetric_angle(r, d, normal, n):
    d = d - normal * (d @ normal)
    d = d / np.linalg.norm(d)
    theta = math.atan2(float(np.cross(r, d) @ normal), float(r @ d))
    step = 2 * math.pi / n
    return abs((theta + step / 2) % step - step / 2)


def quad_obj(tmp_path: Path, nx: int = 5, ny: int = 4) -> tuple[Path, np.ndarray, list]:
    """A (nx-1) x (ny-1) grid of non-planar quads on a saddle-ish sheet, written as an OBJ with quads."""
    verts = [(0.5 * x, 0.5 * y, 0.15 * math.sin(x) * math.cos(0.7 * y) + 0.05 * x * y)
             for y in range(ny) for x in range(nx)]
    quads = [(y * nx + x, y * nx + x + 1, (y + 1) * nx + x + 1, (y + 1) * nx + x)
             for y in range(ny - 1) for x in range(nx - 1)]
    path = tmp_path / "quads.obj"
    path.write_text("# quads\n" + "".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in verts)
                    + "".join("f " + " ".join(f"{i + 1}/{i + 1}" for i in q) + "\n" for q in quads))
    return path, np.array(verts, dtype=float), quads


# ---------------------------------------------------------------------------------------- package
def test_bl_info_and_lazy_imports():
    assert nfield.bl_info["name"] == "nfield"
    assert nfield.bl_info["blender"] == (3, 4, 0)
    assert nfield.bl_info["version"] == (0, 1, 0)
    assert nfield.bl_info["category"] == "Mesh"
    assert nfield.bl_info["description"]
    code = ("import sys, nfield, nfield.core, nfield.cli; "
            "assert 'nfield._native' not in sys.modules, 'native imported eagerly'; "
            "assert 'bpy' not in sys.modules, 'bpy imported'; print('ok')")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=package_env({"PATH": "/usr/bin:/bin"}))
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", proc.stderr


# ---------------------------------------------------------------------------------------- constraints
def test_constraint_dataclasses():
    c = DirectionConstraint(3, [1, 0, 0])
    assert c.face == 3 and c.direction == (1.0, 0.0, 0.0)
    with pytest.raises(Exception):
        c.face = 4  # frozen
    assert hash(c) == hash(DirectionConstraint(3, (1.0, 0.0, 0.0)))
    assert VectorConstraint(np.int64(2), np.array([0.0, 2.0, 0.0])).vector == (0.0, 2.0, 0.0)
    assert SingularityConstraint(7, 0.25).index == 0.25
    with pytest.raises(ValueError, match="non-negative integer"):
        DirectionConstraint(-1, (1, 0, 0))
    with pytest.raises(ValueError, match="3 components"):
        DirectionConstraint(1, (1, 0))
    with pytest.raises(ValueError, match="non-finite"):
        VectorConstraint(1, (1, float("nan"), 0))
    with pytest.raises(ValueError, match="must be a number"):
        SingularityConstraint(1, "a quarter")
    with pytest.raises(ValueError, match="non-negative integer"):
        SingularityConstraint(True, 0.25)


def test_load_constraints_roundtrip(tmp_path):
    p = tmp_path / "c.json"
    p.write_text(json.dumps([{"face": 1, "direction": [1, 0, 0]}, {"face": 2, "vector": [0, 1, 0]},
                             {"vertex": 3, "index": -0.5}]))
    got = load_constraints(p)
    assert got == [DirectionConstraint(1, (1, 0, 0)), VectorConstraint(2, (0, 1, 0)),
                   SingularityConstraint(3, -0.5)]
    p.write_text(json.dumps([{"face": 4, "direction": [0, 0, 1]}]))
    assert load_constraints(str(p), kind="direction") == [DirectionConstraint(4, (0, 0, 1))]
    p.write_text("[]")
    assert load_constraints(p, kind="singularity") == []


LOAD_ERRORS = {
    "not_a_list": ('{"face": 1, "direction": [1, 0, 0]}', None, "JSON list"),
    "bad_json": ("[{", None, "not valid JSON"),
    "entry_not_object": ("[[1, 2, 3]]", None, "entry 0"),
    "missing_key": ('[{"face": 1}]', None, "expected keys"),
    "unknown_key": ('[{"face": 1, "direction": [1, 0, 0], "weight": 2}]', None, "unknown key 'weight'"),
    "short_direction": ('[{"face": 1, "direction": [1, 0]}]', None, "3 components"),
    "string_component": ('[{"face": 1, "direction": [1, "0", 0]}]', None, "numbers"),
    "negative_face": ('[{"face": -2, "direction": [1, 0, 0]}]', None, "non-negative integer"),
    "float_face": ('[{"face": 1.5, "direction": [1, 0, 0]}]', None, "non-negative integer"),
    "bool_vertex": ('[{"vertex": true, "index": 0.25}]', None, "non-negative integer"),
    "string_index": ('[{"vertex": 1, "index": "1/4"}]', None, "number"),
    "wrong_kind": ('[{"vertex": 1, "index": 0.25}]', "direction", "singularity constraint"),
    "second_entry": ('[{"face": 1, "direction": [1, 0, 0]}, {"face": 2}]', None, "entry 1"),
}


@pytest.mark.parametrize("name", sorted(LOAD_ERRORS))
def test_load_constraints_errors(tmp_path, name):
    text, kind, needle = LOAD_ERRORS[name]
    p = tmp_path / f"{name}.json"
    p.write_text(text)
    with pytest.raises(ValueError) as info:
        load_constraints(p, kind=kind)
    assert needle in str(info.value)
    assert p.name in str(info.value)


def test_load_constraints_missing_file(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_constraints(tmp_path / "missing.json")


# ---------------------------------------------------------------------------------------- mesh
@needs_native
def test_mesh_from_arrays_and_validation():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.3]], dtype=float)
    F = np.array([[0, 1, 2], [1, 3, 2]])
    m = Mesh(V, F)
    assert (m.num_vertices, m.num_faces, m.num_triangles) == (4, 2, 2)
    assert m.face_to_polygon is None and not m.has_polygons
    assert m.report["num_input_faces"] == 2 and isinstance(m.report["summary"], list)
    json.dumps(m.report)
    bad = V.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="vertex 2 has a non-finite coordinate"):
        Mesh(bad, F)
    with pytest.raises(ValueError, match="out of range"):
        Mesh(V, [[0, 1, 4]])
    with pytest.raises(ValueError, match=r"shape \(F, 3\)"):
        Mesh(V, [[0, 1, 2, 3]])
    with pytest.raises(ValueError, match="no faces"):
        Mesh(V, np.zeros((0, 3), int))


@needs_native
def test_mesh_from_file_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="not found"):
        Mesh.from_file(tmp_path / "nope.obj")
    (tmp_path / "x.stl").write_text("solid\n")
    with pytest.raises(ValueError, match="unsupported mesh format"):
        Mesh.from_file(tmp_path / "x.stl")
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n")
    with pytest.raises(ValueError, match="bad.obj"):
        Mesh.from_file(tmp_path / "bad.obj")


@needs_native
def test_polygon_obj_rows_per_polygon(tmp_path):
    path, V, quads = quad_obj(tmp_path)
    mesh = Mesh.from_file(path)
    P = len(quads)
    assert mesh.num_faces == P and mesh.num_triangles == 2 * P and mesh.has_polygons
    assert mesh.face_to_polygon.tolist() == [p for p in range(P) for _ in range(2)]
    assert mesh.polygon_first_triangle.tolist() == [2 * p for p in range(P)]

    target = 5
    q = quads[target]
    d = V[q[1]] - V[q[0]]  # tangent to the polygon's first triangle (q0, q1, q2)
    res = nfield.core.solve(mesh, n=4, order=2, constraints=[DirectionConstraint(target, d)])
    assert res.directions.shape == (P, 3)
    assert res.all_directions().shape == (P, 4, 3)
    assert np.allclose(res.all_directions()[:, 0, :], res.directions)
    assert res.representation.shape == (2 * P,)
    normals = np.cross(V[[qq[1] for qq in quads]] - V[[qq[0] for qq in quads]],
                       V[[qq[2] for qq in quads]] - V[[qq[0] for qq in quads]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    assert np.abs(np.linalg.norm(res.directions, axis=1) - 1).max() < 1e-9
    assert np.abs(np.einsum("ij,ij->i", res.directions, normals)).max() < 1e-9
    assert symmetric_angle(res.directions[target], d, normals[target], 4) < 1e-6
    # the per-polygon rows are the first triangle's directions
    from nfield.core import native

    ops = native().FieldOperators(mesh.native, 4, "geometric")
    tri_dirs = ops.representation_to_directions(res.representation)  # (T, 4, 3)
    assert np.array_equal(res.all_directions(), tri_dirs[mesh.polygon_first_triangle])

    with pytest.raises(ValueError, match=rf"face {P} is out of range"):
        nfield.core.solve(mesh, n=4, constraints=[DirectionConstraint(P, d)])
    # align="field": one 3D vector per polygon
    field = np.tile([1.0, 0.2, 0.0], (P, 1))
    res2 = nfield.core.solve(mesh, n=4, align="field", alignment_field=field, strength=1.0)
    assert res2.directions.shape == (P, 3)
    with pytest.raises(ValueError, match=rf"shape \({P}, 3\)"):
        nfield.core.solve(mesh, n=4, align="field", alignment_field=np.ones((2 * P, 3)))


# ---------------------------------------------------------------------------------------- solve
@pytest.fixture(scope="module")
def sphere():
    if not has_native():
        pytest.skip("compiled module nfield._native is not built")
    return Mesh.from_file(SPHERE)


def _edge(mesh: Mesh, f: int) -> np.ndarray:
    a, b, _ = mesh.faces[f]
    return mesh.vertices[b] - mesh.vertices[a]


@needs_native
@pytest.mark.parametrize("n", [1, 2, 4])
def test_direction_constraints_hold_exactly(sphere, n):
    from nfield.core import native

    faces = [10, 400, 800, 1200]
    cons = [DirectionConstraint(f, _edge(sphere, f)) for f in faces]
    res = nfield.core.solve(sphere, n=n, order=2, constraints=cons)
    assert isinstance(res, FieldResult) and res.n == n
    ops = native().FieldOperators(sphere.native, n, "geometric")
    z = ops.tangent_to_representation(np.array(faces), np.array([c.direction for c in cons]))
    assert np.abs(res.representation[faces] - z / np.abs(z)).max() < 1e-9
    N = sphere.native.face_normals
    for c in cons:
        dirs = res.all_directions()[c.face]
        d = np.asarray(c.direction) / np.linalg.norm(c.direction)
        assert max(float(r @ d) for r in dirs) > 1 - 1e-12
        assert symmetric_angle(res.directions[c.face], d, N[c.face], n) < 1e-6
    assert np.abs(np.abs(res.representation) - 1).max() < 1e-12
    assert sum(i for _, i in res.singularities) == pytest.approx(2.0)
    assert all(0 <= f < sphere.num_faces for f in res.sign_fixed_faces)


@needs_native
def test_vector_constraints_hold_on_raw_solution(sphere):
    from nfield.core import native

    faces = [5, 600]
    vecs = [2.0 * _edge(sphere, 5), 0.5 * _edge(sphere, 600)]
    res = nfield.core.solve(sphere, n=2, order=2,
                            vector_constraints=[VectorConstraint(f, v) for f, v in zip(faces, vecs)])
    ops = native().FieldOperators(sphere.native, 2, "geometric")
    z = ops.tangent_to_representation(np.array(faces), np.array(vecs))
    assert np.abs(res.raw_solution[faces] - z).max() < 1e-9 * np.abs(z).max()


@needs_native
def test_singularity_constraint_is_met(sphere):
    v = 100
    res = nfield.core.solve(sphere, n=4, order=2, singularities=[SingularityConstraint(v, -0.25)])
    got = dict(res.singularities)
    assert got.get(v) == pytest.approx(-0.25)
    assert sum(got.values()) == pytest.approx(2.0)
    # also accepted through `constraints` and as dicts
    res2 = nfield.core.solve(sphere, n=4, order=2, constraints=[{"vertex": v, "index": -0.25}])
    assert dict(res2.singularities).get(v) == pytest.approx(-0.25)


@needs_native
def test_to_dict_is_json(sphere):
    res = nfield.core.solve(sphere, n=4, order=2, align="curvature-max", strength=2.0,
                            constraints=[DirectionConstraint(3, _edge(sphere, 3))])
    d = res.to_dict()
    text = json.dumps(d, allow_nan=False)
    back = json.loads(text)
    assert back["faces"] == 1280 and back["n"] == 4 and back["order"] == 2
    assert back["align"] == "curvature-max" and back["strength"] == 2.0
    assert back["energy"] == pytest.approx(res.energy)
    assert back["singularities"] == [{"vertex": v, "index": i} for v, i in res.singularities]
    assert back["mesh_report"]["num_input_faces"] == 1280
    assert back["seconds"] >= 0
    assert isinstance(back["sign_fixed_faces"], list)


@needs_native
def test_energy_is_energy_of_unit_field(sphere):
    from nfield.core import native

    res = nfield.core.solve(sphere, n=4, order=3, constraints=[DirectionConstraint(9, _edge(sphere, 9))])
    ops = native().FieldOperators(sphere.native, 4, "geometric")
    assert res.energy == pytest.approx(ops.energy(res.representation, 3), rel=1e-12)
    assert res.energy > 0


SOLVE_ERRORS = {
    "n_zero": (dict(n=0), "n (symmetry order) must be in 1..64 (got 0)"),
    "n_float": (dict(n=4.0), "must be an integer"),
    "order_5": (dict(order=5), "order (energy order) must be in 1..4"),
    "strength_zero": (dict(strength=0), "strength must be a finite number in [1e-06, 1e+06]"),
    "strength_inf": (dict(strength=float("inf")), "strength"),
    "align_unknown": (dict(align="diagonal"), "unknown align 'diagonal'"),
    "field_without_array": (dict(align="field"), "needs alignment_field"),
    "array_without_field": (dict(alignment_field=np.zeros((1280, 3))), 'only used with align="field"'),
    "weights_unknown": (dict(weights="cotan"), "unknown weights 'cotan'"),
    "face_out_of_range": (dict(constraints=[DirectionConstraint(1280, (1, 0, 0))]), "face 1280 is out of range"),
    "zero_direction": (dict(constraints=[DirectionConstraint(3, (0, 0, 0))]), "zero vector"),
    "duplicate_face": (dict(constraints=[DirectionConstraint(3, (1, 0, 0))],
                            vector_constraints=[VectorConstraint(3, (0, 1, 0))]), "face 3 has more than one"),
    "duplicate_vertex": (dict(singularities=[SingularityConstraint(4, 0.25), SingularityConstraint(4, 0.5)]),
                         "vertex 4 has more than one"),
    "index_not_multiple": (dict(n=3, singularities=[SingularityConstraint(4, 0.25)]), "not a multiple of 1/3"),
    "vertex_out_of_range": (dict(singularities=[SingularityConstraint(642, 0.25)]), "vertex 642 is out of range"),
    "wrong_list": (dict(vector_constraints=[DirectionConstraint(3, (1, 0, 0))]), "expected VectorConstraint"),
    "not_a_constraint": (dict(constraints=[(3, (1, 0, 0))]), "expected a DirectionConstraint"),
}


@needs_native
@pytest.mark.parametrize("name", sorted(SOLVE_ERRORS))
def test_solve_errors(sphere, name):
    kwargs, needle = SOLVE_ERRORS[name]
    with pytest.raises(ValueError) as info:
        nfield.core.solve(sphere, **kwargs)
    assert needle in str(info.value)


@needs_native
def test_direction_along_normal_and_excluded_face():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.3], [2, 2, 0.6]], dtype=float)
    # face 2 is degenerate (collinear vertices 0, 3, 4): excluded from the field
    F = np.array([[0, 1, 2], [1, 3, 2], [0, 3, 4]])
    mesh = Mesh(V, F)
    assert not mesh.native.face_active[2]
    with pytest.raises(ValueError, match="face 2: the face is excluded"):
        nfield.core.solve(mesh, n=4, constraints=[DirectionConstraint(2, (1, 0, 0))])
    with pytest.raises(ValueError, match="parallel to the face normal"):
        nfield.core.solve(mesh, n=4, constraints=[DirectionConstraint(0, (0, 0, 1))])
    # almost normal but with a clear tangent part is fine
    res = nfield.core.solve(mesh, n=4, constraints=[DirectionConstraint(0, (1e-3, 0, 1))])
    assert np.allclose(res.directions[2], 0)  # excluded face: zero row
    assert symmetric_angle(res.directions[0], np.array([1.0, 0, 0]), np.array([0, 0, 1.0]), 4) < 1e-6


# ---------------------------------------------------------------------------------------- spectra
@needs_native
def test_eigenvalues_and_smoothest_field(sphere):
    vals = nfield.core.eigenvalues(sphere, 1, 4)
    assert vals.shape == (4,) and np.all(np.diff(vals) >= -1e-9)
    R = float(np.linalg.norm(sphere.vertices - sphere.vertices.mean(0), axis=1).mean())
    assert vals[0] == pytest.approx(2 / R**2, rel=0.05)
    with pytest.raises(ValueError, match="k \\(number of eigenvalues\\) must be >= 1"):
        nfield.core.eigenvalues(sphere, 1, 0)
    with pytest.raises(ValueError, match="only 1280 usable faces"):
        nfield.core.eigenvalues(sphere, 1, 5000)
    res = nfield.core.smoothest_field(sphere, 1)
    assert res.order == 1 and res.directions.shape == (1280, 3)
    assert np.abs(np.linalg.norm(res.directions, axis=1) - 1).max() < 1e-9
    # Rayleigh quotient: E_1(u) >= lambda_1 u^H M u = lambda_1 * area for the unit field u (no zero faces)
    area = float(sphere.native.total_area)
    assert res.energy >= vals[0] * area * (1 - 1e-9)
    assert sum(i for _, i in res.singularities) == pytest.approx(2.0)
