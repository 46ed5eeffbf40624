"""Mesh ingestion (native Mesh, read_mesh; mesh.hpp / mesh_io.hpp): validation errors, the mesh
report on the shared data meshes and on constructed defects, and the file readers.

Counts are exact integers. Reader round trips are exact: ASCII files are written with repr() (17
significant digits, which round-trips binary64 exactly) and binary PLY files store float64.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

import meshgen as mg
import mesh_reference as mref

nat = pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")
core = pytest.importorskip("nfield.core", reason="nfield.core is not importable")

DATA = Path(__file__).parent / "data"


def _mesh(V, F):
    return nat.Mesh(np.asarray(V, np.float64), np.asarray(F, np.int32))


def _data(name):
    p = DATA / name
    if not p.exists():
        pytest.skip(f"test mesh {p} is missing (tests/data not populated)")
    return p


# ------------------------------------------------------------------------------ invalid input
def test_nan_and_inf_coordinates_rejected():
    V, F = mg.icosphere(1)
    for bad, word in ((np.nan, "nan"), (np.inf, "inf"), (-np.inf, "inf")):
        W = V.copy()
        W[17, 1] = bad
        with pytest.raises(ValueError) as ei:
            _mesh(W, F)
        msg = str(ei.value).lower()
        assert word in msg and "17" in msg, msg
        with pytest.raises(ValueError) as ei:
            core.Mesh(W, F)
        assert "17" in str(ei.value)


def test_out_of_range_indices_rejected():
    V, F = mg.icosphere(1)
    for bad in (len(V), -1, 10 ** 6):
        G = F.copy()
        G[33, 2] = bad
        with pytest.raises(ValueError) as ei:
            _mesh(V, G)
        msg = str(ei.value).lower()
        # names the face, the offending value and that it is an index / out of range
        assert "face 33" in msg and str(bad) in msg and ("index" in msg or "range" in msg), msg


def test_empty_and_malformed_arrays_rejected():
    """Empty or wrongly shaped arrays: ValueError saying what is missing / wrong."""
    V, F = mg.icosphere(1)
    cases = [
        ((np.zeros((0, 3)), F[:0]), ("no vertices", "empty")),
        ((V, np.zeros((0, 3), np.int32)), ("no faces", "empty")),
        ((np.zeros((0, 3)), F), ("no vertices", "empty", "range")),
        ((V[:, :2], F), ("shape", "3")),
        ((V, F[:, :2]), ("shape", "3")),
    ]
    for (A, B), words in cases:
        with pytest.raises((ValueError, TypeError)) as ei:
            _mesh(A, B)
        msg = str(ei.value).lower()
        assert any(w in msg for w in words), msg


# ------------------------------------------------------------------------------ data meshes
# name: (faces, chi, boundary loops, unused vertices, slivers) from tests/data/README.md
DATA_MESHES = {
    "sphere.obj": (1280, 2, 0, 0, None),
    "fertility.off": (9000, -6, 0, 0, None),
    "eight.off": (11092, -2, 0, 0, None),
    "fandisk.obj": (12946, 2, 0, 0, None),
    "rocker-arm.obj": (20088, 0, 0, 0, None),
    "camelhead.off": (22704, 1, 1, 0, 73),
    "stanford-bunny.obj": (69451, -3, 5, 1113, 1),
    "armadillo.obj": (86482, 2, 0, 0, None),
}


@pytest.mark.parametrize("name", list(DATA_MESHES))
def test_data_mesh_reports(name):
    faces, chi, loops, unused, slivers = DATA_MESHES[name]
    P, T, tp, npoly = nat.read_mesh(str(_data(name)))
    assert np.asarray(T).shape == (faces, 3) and npoly == faces
    assert np.array_equal(np.asarray(tp), np.arange(faces))
    mesh = _mesh(P, T)
    rep = mesh.report()
    assert rep["euler_characteristic"] == chi
    assert rep["num_boundary_loops"] == loops
    assert len(rep["unused_vertices"]) == unused
    if slivers is not None:
        assert len(rep["sliver_faces"]) == slivers
    assert rep["num_components"] == 1
    assert len(rep["flipped_faces"]) == 0 and rep["num_orientation_cuts"] == 0
    assert len(rep["nonmanifold_edges"]) == 0 and len(rep["degenerate_faces"]) == 0
    assert len(rep["duplicate_faces"]) == 0
    assert mesh.num_active_faces == faces
    # the report's chi agrees with a numpy count over the faces
    assert mref.mesh_stats(np.asarray(P), np.asarray(T))["chi"] == chi
    if unused:
        used = np.zeros(len(np.asarray(P)), bool)
        used[np.asarray(T).reshape(-1)] = True
        assert sorted(rep["unused_vertices"]) == sorted(np.nonzero(~used)[0].tolist())
    assert isinstance(rep["summary"], list)


def test_bunny_boundary_edges_and_core_mesh():
    p = _data("stanford-bunny.obj")
    mesh = core.Mesh.from_file(p)
    rep = mesh.report
    assert rep["num_boundary_edges"] == 223 and rep["num_boundary_loops"] == 5
    assert len(rep["unused_vertices"]) == 1113
    # boundary vertices are not interior; a vertex used by no face is not interior either
    assert not mesh.native.vertex_is_interior(rep["unused_vertices"][0])


# ------------------------------------------------------------------------------ synthetic defects
def test_procedural_meshes_report_matches_numpy():
    cases = {
        "icosphere": mg.icosphere(2), "torus": mg.torus(2, 0.7, 20, 8, perturb=0.3, random_diagonals=True),
        "cylinder": mg.cylinder(1, 2, 16, 6), "disk": mg.disk(5), "ellipse": mg.irregular_ellipse(),
        "ellipsoid": mg.irregular_ellipsoid(n_points=150, seed=2),
    }
    for name, (V, F) in cases.items():
        s = mref.mesh_stats(V, F)
        rep = _mesh(V, F).report()
        assert rep["euler_characteristic"] == s["chi"], name
        assert rep["num_boundary_edges"] == s["boundary_edges"], name
        assert rep["num_components"] == 1 and len(rep["flipped_faces"]) == 0, name
        m = _mesh(V, F)
        assert np.array_equal(np.asarray(m.faces), F), name  # clean input keeps its winding


def _solve_dirs(mesh, n=2, order=2):
    return core.solve(mesh, n=n, order=order)


def test_degenerate_faces_excluded_with_zero_output():
    V, F = mg.icosphere(2)
    V = np.concatenate([V, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]])  # collinear triple
    nv = len(V)
    F = np.concatenate([F, [[0, 0, 5], [nv - 3, nv - 2, nv - 1]]])  # repeated vertex; zero area
    mesh = _mesh(V, F)
    rep = mesh.report()
    bad = [len(F) - 2, len(F) - 1]
    assert sorted(rep["degenerate_faces"]) == bad
    active = np.asarray(mesh.face_active)
    assert not active[bad].any() and active[:-2].all()
    assert mesh.num_active_faces == len(F) - 2
    assert np.all(np.asarray(mesh.face_component)[bad] == -1)
    assert np.all(np.asarray(mesh.face_areas)[bad] == 0)
    # the sphere part is unaffected: chi of the active part is still 2, and the field is zero there
    assert rep["euler_characteristic"] == 2
    ops = nat.FieldOperators(mesh, 2, "geometric")
    z = np.asarray(nat.smoothest_field(ops))
    assert np.all(z[bad] == 0) and np.all(z[:-2] != 0)
    res = _solve_dirs(core.Mesh(V, F))
    assert np.all(res.directions[bad] == 0)
    assert np.allclose(np.linalg.norm(res.directions[:-2], axis=1), 1)
    with pytest.raises(ValueError, match=str(bad[0])):
        core.solve(core.Mesh(V, F), n=2, constraints=[core.DirectionConstraint(bad[0], (1, 0, 0))])


def test_needle_face_excluded():
    """A needle (height < 1e-7 of its longest edge) is degenerate even with nonzero area."""
    V, F = mg.icosphere(2)
    nv = len(V)
    V = np.concatenate([V, [[3, 0, 0], [4, 0, 0], [3.5, 1e-9, 0]]])
    F = np.concatenate([F, [[nv, nv + 1, nv + 2]]])
    rep = _mesh(V, F).report()
    assert rep["degenerate_faces"] == [len(F) - 1]


def test_duplicate_faces_excluded():
    V, F = mg.icosphere(2)
    F2 = np.concatenate([F, F[[10]], F[[20]][:, [1, 2, 0]]])  # exact copy and a rotated copy
    mesh = _mesh(V, F2)
    rep = mesh.report()
    assert sorted(rep["duplicate_faces"]) == [len(F), len(F) + 1]
    assert not np.asarray(mesh.face_active)[len(F):].any()
    assert rep["euler_characteristic"] == 2 and len(rep["nonmanifold_edges"]) == 0
    ops = nat.FieldOperators(mesh, 4, "geometric")
    ref = nat.FieldOperators(_mesh(V, F), 4, "geometric")
    assert np.allclose(np.asarray(nat.eigen(ops, 8)[0]), np.asarray(nat.eigen(ref, 8)[0]), rtol=1e-9)


def test_nonmanifold_edge_is_a_cut():
    """Three triangles on one edge (a fin on a flat sheet): the edge is listed, no dual edge crosses
    it, and a field can still be computed."""
    V, F = mg.grid(6, 6, 1.0, 1.0)
    # an edge of the grid interior: find an interior edge (two faces) and add a fin triangle on it
    a, b = int(F[12, 0]), int(F[12, 1])
    fin_apex = len(V)
    V = np.concatenate([V, [[0.5 * (V[a, 0] + V[b, 0]), 0.5 * (V[a, 1] + V[b, 1]), 0.5]]])
    F2 = np.concatenate([F, [[a, b, fin_apex]]])
    cnt = sum(1 for f in F2 if a in f and b in f)
    assert cnt == 3
    mesh = _mesh(V, F2)
    rep = mesh.report()
    assert [tuple(e) for e in rep["nonmanifold_edges"]] == [tuple(sorted((a, b)))]
    de = np.asarray(mesh.dual_edges())
    for f0, f1, v0, v1 in de:
        assert {int(v0), int(v1)} != {a, b}
    res = core.solve(core.Mesh(V, F2), n=4, order=2)
    assert np.all(np.isfinite(res.representation))
    assert np.allclose(np.abs(res.representation), 1)


def test_inconsistent_orientation_flipped_and_listed():
    V, F = mg.icosphere(2)
    G = F.copy()
    flip = [7, 100, 201]
    G[flip] = G[flip][:, [0, 2, 1]]
    mesh = _mesh(V, G)
    rep = mesh.report()
    assert sorted(rep["flipped_faces"]) == flip
    assert rep["num_orientation_cuts"] == 0
    # internal orientation equals the consistent one (outward), so normals are outward
    N = np.asarray(mesh.face_normals)
    assert np.all((N * mref.face_centroids(V, F)).sum(1) > 0)
    # spectrum equals the one of the consistently oriented mesh
    for n in (1, 2, 4):
        a = np.asarray(nat.eigen(nat.FieldOperators(mesh, n, "geometric"), 10)[0])
        b = np.asarray(nat.eigen(nat.FieldOperators(_mesh(V, F), n, "geometric"), 10)[0])
        assert np.allclose(a, b, rtol=1e-9)


def test_majority_orientation_wins():
    """A whole mesh given inward (all faces reversed) is kept as is (no face flipped): the majority
    of its one component is consistent."""
    V, F = mg.icosphere(2)
    mesh = _mesh(V, F[:, [0, 2, 1]])
    assert len(mesh.report()["flipped_faces"]) == 0


def test_moebius_strip():
    V, F = mg.mobius(40, 6)
    s = mref.mesh_stats(V, F)
    assert s["inconsistent_edges"] > 0
    mesh = _mesh(V, F)
    rep = mesh.report()
    assert rep["num_orientation_cuts"] >= 1
    assert rep["euler_characteristic"] == 0
    assert rep["num_components"] == 1
    # the cut edges are not dual edges: (#dual edges) = interior edges - cuts
    assert len(np.asarray(mesh.dual_edges())) == s["edges"] - s["boundary_edges"] - rep["num_orientation_cuts"]
    cm = core.Mesh(V, F)
    Nn = np.asarray(mesh.face_normals)
    for n, order in ((1, 2), (2, 1), (4, 2)):
        res = core.solve(cm, n=n, order=order)
        assert np.all(np.isfinite(res.representation))
        assert np.allclose(np.abs(res.representation), 1)
        d = res.directions
        assert np.allclose(np.linalg.norm(d, axis=1), 1)
        assert np.abs((d * Nn).sum(1)).max() < 1e-9


def test_several_components():
    V1, F1 = mg.icosphere(2)
    V2, F2 = mg.torus(2, 0.5, 16, 8)
    V = np.concatenate([V1, V2 + [6, 0, 0]])
    F = np.concatenate([F1, F2 + len(V1)])
    mesh = _mesh(V, F)
    rep = mesh.report()
    assert rep["num_components"] == 2 and mesh.num_components == 2
    comp = np.asarray(mesh.face_component)
    assert len(set(comp[: len(F1)])) == 1 and len(set(comp[len(F1):])) == 1 and comp[0] != comp[-1]
    assert rep["euler_characteristic"] == 2 + 0
    res = core.solve(core.Mesh(V, F), n=2, order=2)
    assert np.allclose(np.abs(res.representation), 1)
    # singularities: the sphere part carries index sum 2, the torus part 0
    sph = [i for v, i in res.singularities if v < len(V1)]
    tor = [i for v, i in res.singularities if v >= len(V1)]
    assert abs(sum(sph) - 2) < 1e-9 and abs(sum(tor)) < 1e-9


# ------------------------------------------------------------------------------ readers
def _write_obj_polygons(path):
    """A 3x2 grid of quads, one triangle and one pentagon (fan triangulated by the reader)."""
    V, F = mg.grid(4, 3, 3.0, 2.0)
    quads = []
    for i in range(3):
        for j in range(2):
            a = i * 3 + j
            quads.append([a, a + 3, a + 4, a + 1])
    extra_v = np.array([[0, 3, 0], [1, 3, 0], [0.5, 4, 0], [4, 0, 0], [5, 0, 0], [5.5, 1, 0], [4.5, 2, 0],
                        [3.8, 1, 0]], float)
    V = np.concatenate([V, extra_v])
    tri = [12, 13, 14]
    penta = [15, 16, 17, 18, 19]
    polys = quads + [tri, penta]
    with open(path, "w") as fh:
        fh.write("# test\n")
        for p in V:
            fh.write("v %r %r %r\n" % tuple(map(float, p)))
        fh.write("vn 0 0 1\nvt 0 0\n")
        for k, poly in enumerate(polys):
            if k % 2:
                fh.write("f " + " ".join(f"{i + 1}/1/1" for i in poly) + "\n")
            else:
                fh.write("f " + " ".join(str(i + 1) for i in poly) + "\n")
    return V, polys


def test_obj_polygons_triangle_to_polygon_map(tmp_path):
    p = tmp_path / "poly.obj"
    V, polys = _write_obj_polygons(p)
    P, T, tp, npoly = nat.read_mesh(str(p))
    P, T, tp = np.asarray(P), np.asarray(T), np.asarray(tp)
    assert np.array_equal(P, V)
    assert npoly == len(polys)
    exp_T, exp_tp = [], []
    for k, poly in enumerate(polys):  # fan triangulation keeps the polygon order
        for j in range(1, len(poly) - 1):
            exp_T.append([poly[0], poly[j], poly[j + 1]])
            exp_tp.append(k)
    assert np.array_equal(T, np.array(exp_T)) and np.array_equal(tp, np.array(exp_tp))
    mesh = core.Mesh.from_file(p)
    assert mesh.num_faces == len(polys) and mesh.num_triangles == len(exp_T)
    res = core.solve(mesh, n=4, order=2)
    assert res.directions.shape == (len(polys), 3)
    # one row per polygon, taken from the polygon's first triangle
    first = [exp_tp.index(k) for k in range(len(polys))]
    ops = nat.FieldOperators(mesh.native, 4, "geometric")
    tri_dirs = np.asarray(ops.representation_to_directions(res.representation))[:, 0]
    assert np.allclose(res.directions, tri_dirs[first], atol=1e-12)
    assert np.allclose(np.linalg.norm(res.directions, axis=1), 1)


def _write_off(path, V, F):
    with open(path, "w") as fh:
        fh.write("OFF\n# comment\n")
        fh.write(f"{len(V)} {len(F)} 0\n")
        for p in V:
            fh.write("%r %r %r\n" % tuple(map(float, p)))
        for f in F:
            fh.write(f"3 {f[0]} {f[1]} {f[2]}\n")


def _write_ply_ascii(path, V, F):
    with open(path, "w") as fh:
        fh.write("ply\nformat ascii 1.0\ncomment made by nfield tests\n")
        fh.write(f"element vertex {len(V)}\nproperty double x\nproperty double y\nproperty double z\n")
        fh.write(f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n")
        for p in V:
            fh.write("%r %r %r\n" % tuple(map(float, p)))
        for f in F:
            fh.write(f"3 {f[0]} {f[1]} {f[2]}\n")


def _write_ply_binary(path, V, F, float_type="double"):
    with open(path, "wb") as fh:
        hdr = ("ply\nformat binary_little_endian 1.0\n"
               f"element vertex {len(V)}\nproperty {float_type} x\nproperty {float_type} y\n"
               f"property {float_type} z\nproperty uchar red\n"
               f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n")
        fh.write(hdr.encode("ascii"))
        code = "<d" if float_type == "double" else "<f"
        for p in V:
            fh.write(struct.pack("<" + code[1] * 3, *p) + struct.pack("<B", 200))
        for f in F:
            fh.write(struct.pack("<Biii", 3, *(int(x) for x in f)))


def test_off_ply_ascii_binary_same_arrays(tmp_path):
    V, F = mg.torus(2, 0.7, 12, 6, perturb=0.3, random_diagonals=True, seed=4)
    files = {"m.off": _write_off, "m_ascii.ply": _write_ply_ascii, "m_bin.ply": _write_ply_binary}
    for name, writer in files.items():
        writer(tmp_path / name, V, F)
        P, T, tp, npoly = nat.read_mesh(str(tmp_path / name))
        assert np.array_equal(np.asarray(P), V), name
        assert np.array_equal(np.asarray(T), F), name
        assert np.array_equal(np.asarray(tp), np.arange(len(F))) and npoly == len(F), name
    # binary float32 positions read as the float32 values
    _write_ply_binary(tmp_path / "m_f32.ply", V, F, "float")
    P, T, _, _ = nat.read_mesh(str(tmp_path / "m_f32.ply"))
    assert np.array_equal(np.asarray(P), V.astype(np.float32).astype(np.float64))
    assert np.array_equal(np.asarray(T), F)


def test_malformed_files_raise_value_error(tmp_path):
    V, F = mg.icosphere(1)
    bad_off = tmp_path / "bad.off"
    bad_off.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")  # truncated
    bad_obj = tmp_path / "bad.obj"
    bad_obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")  # index out of range
    bad_ply = tmp_path / "bad.ply"
    bad_ply.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n0\n")
    for p in (bad_off, bad_ply):
        with pytest.raises(ValueError) as ei:
            nat.read_mesh(str(p))
        assert p.name in str(ei.value), str(ei.value)
    for p in (bad_off, bad_obj, bad_ply):  # an out-of-range OBJ index is caught by the reader or Mesh
        with pytest.raises(ValueError) as ei:
            core.Mesh.from_file(p)
        assert p.name in str(ei.value), str(ei.value)
    with pytest.raises(ValueError):
        nat.read_mesh(str(tmp_path / "x.stl"))
