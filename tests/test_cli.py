"""Command line ``python -m nfield``: eig / solve / info, output files, JSON, and one-line errors (exit 2).

Every CLI call runs in a subprocess, exactly as a user would run it, with the nfield this session tests
(conftest.package_env: addon/, or the installed package).
Expected values:
  * eig on the icosphere (R ~ 1): the n = 1 spectrum of the complex connection Laplacian tends to
    2 (l (l + 1) - n^2) / R^2, l >= n, multiplicity 2 l + 1 (docs/conventions), i.e. 2, 2, 2, 10, 10, 10 ...
    On sphere.obj (1,280 faces) the first eigenvalue is within 1 % of 2 / R^2; 5 % is the tolerance.
  * a solved field: one unit, tangent row per input face; at a direction constraint one of the n
    directions is the projected constraint direction (to 1e-6 rad); on a closed surface the indices of a
    field without zeros sum to the Euler characteristic (2 on the sphere, 0 on the genus-1 rocker arm).
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import needs_native

from conftest import ADDON, ROOT, package_env

DATA = Path(__file__).parent / "data"
EXAMPLES = ROOT / "examples"




# ---------------------------------------------------------------------------------------- helpers
def run_cli(*args, pythonpath: Path | None = None, env_extra: dict | None = None, cwd: Path | None = None):
    """`python -m nfield ARGS` in a subprocess: the nfield this session tests, or the one in `pythonpath`."""
    env = package_env()
    if pythonpath is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(pythonpath)] + ([env["PYTHONPATH"]] if env.get("PYTHONPATH") else []))
    env.pop("NFIELD_DEBUG", None)
    if env_extra:
        env.update(env_extra)
    return subprocess.run([sys.executable, "-m", "nfield", *map(str, args)], capture_output=True, text=True,
                          env=env, cwd=str(cwd) if cwd else None, timeout=600)


def read_mesh_np(path: Path):
    """Tiny independent OBJ/OFF reader (triangles only): (V, F)."""
    text = Path(path).read_text()
    if str(path).lower().endswith(".off"):
        tok = text.split()
        assert tok[0] == "OFF"
        nv, nf = int(tok[1]), int(tok[2])
        i = 4
        V = np.array(tok[i:i + 3 * nv], dtype=float).reshape(nv, 3)
        i += 3 * nv
        F = []
        for _ in range(nf):
            k = int(tok[i])
            assert k == 3
            F.append([int(t) for t in tok[i + 1:i + 4]])
            i += 1 + k
        return V, np.array(F, dtype=np.int64)
    V, F = [], []
    for line in text.splitlines():
        s = line.split()
        if not s:
            continue
        if s[0] == "v":
            V.append([float(x) for x in s[1:4]])
        elif s[0] == "f":
            idx = [int(x.split("/")[0]) - 1 for x in s[1:]]
            assert len(idx) == 3
            F.append(idx)
    return np.array(V, dtype=float), np.array(F, dtype=np.int64)


def face_normals(V, F):
    N = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    return N / np.linalg.norm(N, axis=1, keepdims=True)


def symmetric_angle(r, d, normal, n):
    """Smallest angle between d (projected to the plane of `normal`) and any of the n directions r rotated by
    2 pi k / n about the normal."""
    d = d - normal * (d @ normal)
    d = d / np.linalg.norm(d)
    theta = math.atan2(float(np.cross(r, d) @ normal), float(r @ d))
    step = 2 * math.pi / n
    return abs((theta + step / 2) % step - step / 2)


def write_json(path: Path, obj) -> Path:
    path.write_text(json.dumps(obj))
    return path


def assert_one_line_error(proc, *needles):
    assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
    err = proc.stderr
    assert "Traceback" not in err and "Traceback" not in proc.stdout, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("nfield: error: "), err
    for needle in needles:
        assert needle.lower() in lines[0].lower(), (needle, lines[0])


SPHERE = DATA / "sphere.obj"
ROCKER = DATA / "rocker-arm.obj"
CAMEL = DATA / "camelhead.off"


def sphere_constraints():
    V, F = read_mesh_np(SPHERE)
    faces = [0, 333, 777, 1111]
    return V, F, [{"face": f, "direction": (V[F[f, 1]] - V[F[f, 0]]).tolist()} for f in faces]


# ---------------------------------------------------------------------------------------- help
def test_help_works_without_compiled_module(tmp_path):
    # a copy of the package without any compiled file
    shutil.copytree(ADDON / "nfield", tmp_path / "nfield",
                    ignore=shutil.ignore_patterns("_native*", "__pycache__", "*.so", "*.pyd"))
    proc = run_cli("--help", pythonpath=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for word in ("eig", "solve", "info"):
        assert word in proc.stdout
    proc = run_cli("solve", "--help", pythonpath=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for opt in ("--n", "--order", "--align", "--strength", "--constraints", "--vector-constraints",
                "--singularities", "--out", "--json"):
        assert opt in proc.stdout
    proc = run_cli("eig", "--help", pythonpath=tmp_path)
    assert proc.returncode == 0 and "--k" in proc.stdout
    # using it without the compiled module: one clear line naming the Python version and the fix
    tri = tmp_path / "tri.obj"
    tri.write_text(TRI_OBJ)
    proc = run_cli("eig", tri, "--n", "1", "--k", "1", pythonpath=tmp_path)
    here = f"{sys.version_info.major}.{sys.version_info.minor}"
    assert_one_line_error(proc, "compiled module", here, "build_addon.py")
    # a module built for another Python: the message names both versions and the file
    fake = "_native.cpython-39-x86_64-linux-gnu.so"
    (tmp_path / "nfield" / fake).write_bytes(b"")
    proc = run_cli("eig", tri, "--n", "1", "--k", "1", pythonpath=tmp_path)
    assert_one_line_error(proc, "built for Python 3.9", f"this is Python {here}", fake, "build_addon.py")


def test_help_in_place():
    proc = run_cli("--help")
    assert proc.returncode == 0 and "solve" in proc.stdout


def test_no_command_is_an_error():
    assert_one_line_error(run_cli(), "command")


# ---------------------------------------------------------------------------------------- eig
@needs_native
def test_eig_sphere_n1_matches_continuum_spectrum():
    proc = run_cli("eig", SPHERE, "--n", "1", "--k", "6")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert set(out) == {"eigenvalues"}
    vals = np.array(out["eigenvalues"], dtype=float)
    assert vals.shape == (6,)
    V, _ = read_mesh_np(SPHERE)
    R = float(np.linalg.norm(V - V.mean(axis=0), axis=1).mean())
    assert np.all(np.diff(vals) >= -1e-9 * abs(vals).max()), vals  # ascending
    # l = 1: 2 (1*2 - 1) / R^2 = 2 / R^2, three times (2l+1 = 3): each eigenvalue once, not doubled
    assert vals[0] == pytest.approx(2.0 / R**2, rel=0.05)
    assert np.allclose(vals[:3], vals[0], rtol=1e-3), vals
    # l = 2: 2 (2*3 - 1) / R^2 = 10 / R^2: the 4th value is the next distinct eigenvalue
    assert vals[3] == pytest.approx(10.0 / R**2, rel=0.05)
    assert vals[3] > 4 * vals[2]


@needs_native
def test_eig_sphere_n2_first_eigenvalue():
    # n = 2: 2 (l (l + 1) - 4) / R^2, l >= 2 -> 4 / R^2 (multiplicity 5)
    proc = run_cli("eig", SPHERE, "--n", "2", "--k", "6", "--weights", "geometric")
    assert proc.returncode == 0, proc.stderr
    vals = np.array(json.loads(proc.stdout)["eigenvalues"])
    V, _ = read_mesh_np(SPHERE)
    R = float(np.linalg.norm(V - V.mean(axis=0), axis=1).mean())
    assert vals[0] == pytest.approx(4.0 / R**2, rel=0.05)
    assert np.allclose(vals[:5], vals[0], rtol=1e-2), vals
    assert vals[5] > 1.5 * vals[4]  # l = 3: 2 (12 - 4) = 16


# ---------------------------------------------------------------------------------------- solve
def _check_field(rows, V, F, cons, n):
    N = face_normals(V, F)
    assert rows.shape == (F.shape[0], 3)
    assert rows.dtype == np.float64
    assert np.all(np.isfinite(rows))
    assert np.abs(np.linalg.norm(rows, axis=1) - 1.0).max() < 1e-9
    assert np.abs(np.einsum("ij,ij->i", rows, N)).max() < 1e-9
    for c in cons:
        f = c["face"]
        ang = symmetric_angle(rows[f], np.asarray(c["direction"], dtype=float), N[f], n)
        assert ang < 1e-6, (f, ang)


@needs_native
@pytest.mark.parametrize("n", [1, 4])
def test_solve_writes_npy(tmp_path, n):
    V, F, cons = sphere_constraints()
    cfile = write_json(tmp_path / "c.json", cons)
    out = tmp_path / "field.npy"
    proc = run_cli("solve", SPHERE, "--n", n, "--order", "2", "--constraints", cfile, "--out", out)
    assert proc.returncode == 0, proc.stderr
    rows = np.load(out)
    _check_field(rows, V, F, cons, n)
    if n == 1:  # a vector field: the direction itself, not just up to symmetry
        Nn = face_normals(V, F)
        for c in cons:
            d = np.asarray(c["direction"])
            d = d - Nn[c["face"]] * (d @ Nn[c["face"]])
            assert rows[c["face"]] @ (d / np.linalg.norm(d)) > 1 - 1e-12


@needs_native
def test_solve_writes_csv_equal_to_npy(tmp_path):
    V, F, cons = sphere_constraints()
    cfile = write_json(tmp_path / "c.json", cons)
    proc = run_cli("solve", SPHERE, "--n", "4", "--constraints", cfile, "--out", tmp_path / "f.csv")
    assert proc.returncode == 0, proc.stderr
    text = (tmp_path / "f.csv").read_text()
    assert not text.lstrip().startswith(("#", "x")), "csv must be header-less"
    rows = np.loadtxt(tmp_path / "f.csv", delimiter=",")
    assert rows.shape == (F.shape[0], 3)
    assert len(text.strip().splitlines()) == F.shape[0]
    proc = run_cli("solve", SPHERE, "--n", "4", "--constraints", cfile, "--out", tmp_path / "f.npy")
    assert proc.returncode == 0, proc.stderr
    ref = np.load(tmp_path / "f.npy")
    assert np.abs(rows - ref).max() < 1e-8  # %.9g
    _check_field(ref, V, F, cons, 4)


@needs_native
def test_solve_json_fields(tmp_path):
    V, F, cons = sphere_constraints()
    cfile = write_json(tmp_path / "c.json", cons)
    # an interior vertex far from the constrained faces
    centroids = V[F].mean(axis=1)
    dist = np.min([np.linalg.norm(V - centroids[c["face"]], axis=1) for c in cons], axis=0)
    vertex = int(np.argmax(dist))
    sfile = write_json(tmp_path / "s.json", [{"vertex": vertex, "index": 0.25}])
    proc = run_cli("solve", SPHERE, "--n", "4", "--order", "2", "--strength", "1.0", "--constraints", cfile,
                   "--singularities", sfile, "--json")
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)  # one JSON object, nothing else on stdout
    for key in ("faces", "n", "order", "align", "strength", "energy", "singularities", "sign_fixed_faces",
                "mesh_report", "seconds"):
        assert key in out, key
    assert out["faces"] == F.shape[0] == 1280
    assert (out["n"], out["order"], out["align"]) == (4, 2, "none")
    assert out["strength"] == pytest.approx(1.0)
    assert math.isfinite(out["energy"]) and out["energy"] > 0
    assert out["seconds"] >= 0
    assert isinstance(out["sign_fixed_faces"], list)
    assert all(0 <= f < 1280 for f in out["sign_fixed_faces"])
    assert out["mesh_report"]["num_input_faces"] == 1280
    sings = out["singularities"]
    assert sings and all(set(s) == {"vertex", "index"} for s in sings)
    for s in sings:
        assert abs(s["index"] * 4 - round(s["index"] * 4)) < 1e-9 and s["index"] != 0
    assert {s["vertex"]: s["index"] for s in sings}.get(vertex) == pytest.approx(0.25)
    assert sum(s["index"] for s in sings) == pytest.approx(2.0)  # Euler characteristic of the sphere


@needs_native
def test_solve_human_summary(tmp_path):
    proc = run_cli("solve", SPHERE, "--n", "4", "--align", "curvature-max")
    assert proc.returncode == 0, proc.stderr
    assert "faces: 1280" in proc.stdout
    assert "energy:" in proc.stdout and "singularities:" in proc.stdout and "time:" in proc.stdout
    assert proc.stderr == ""


@needs_native
@pytest.mark.slow
def test_solve_rocker_examples(tmp_path):
    cons = json.loads((EXAMPLES / "rocker_constraints.json").read_text())
    sing = json.loads((EXAMPLES / "rocker_singularities.json").read_text())
    # index 1/2: a multiple of 1/n for this n = 4 and for the demo's n = 2 (examples/demo/demo.py reads the same files)
    assert len(cons) == 4 and len(sing) == 1 and sing[0]["index"] == 0.5
    out = tmp_path / "rocker.npy"
    proc = run_cli("solve", ROCKER, "--n", "4", "--order", "2",
                   "--constraints", EXAMPLES / "rocker_constraints.json",
                   "--singularities", EXAMPLES / "rocker_singularities.json", "--out", out, "--json")
    assert proc.returncode == 0, proc.stderr
    V, F = read_mesh_np(ROCKER)
    assert F.shape[0] == 20088
    _check_field(np.load(out), V, F, cons, 4)
    res = json.loads(proc.stdout)
    got = {s["vertex"]: s["index"] for s in res["singularities"]}
    assert got.get(sing[0]["vertex"]) == pytest.approx(0.5)
    assert sum(got.values()) == pytest.approx(0.0, abs=1e-9)  # genus 1


@needs_native
def test_solve_polygon_obj_rows_per_polygon(tmp_path):
    # 3 x 2 quads on a bent sheet: 6 polygons, 12 triangles
    nx, ny = 4, 3
    verts = [(x, y, 0.2 * x * x - 0.1 * y * y + 0.05 * x * y) for y in range(ny) for x in range(nx)]
    quads = [(y * nx + x, y * nx + x + 1, (y + 1) * nx + x + 1, (y + 1) * nx + x)
             for y in range(ny - 1) for x in range(nx - 1)]
    obj = tmp_path / "quads.obj"
    obj.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in verts)
                   + "".join("f " + " ".join(str(i + 1) for i in q) + "\n" for q in quads))
    V = np.array(verts, dtype=float)
    q = quads[4]
    d = (V[q[1]] - V[q[0]]).tolist()
    cfile = write_json(tmp_path / "c.json", [{"face": 4, "direction": d}])
    out = tmp_path / "q.npy"
    proc = run_cli("solve", obj, "--n", "4", "--constraints", cfile, "--out", out)
    assert proc.returncode == 0, proc.stderr
    rows = np.load(out)
    assert rows.shape == (len(quads), 3)
    first_tris = np.array([[qq[0], qq[1], qq[2]] for qq in quads])
    _check_field(rows, V, first_tris, [{"face": 4, "direction": d}], 4)
    # face indices name polygons: 6 is out of range although the mesh has 12 triangles
    bad = write_json(tmp_path / "bad.json", [{"face": 6, "direction": d}])
    assert_one_line_error(run_cli("solve", obj, "--n", "4", "--constraints", bad), "face 6", "out of range")


# ---------------------------------------------------------------------------------------- info
@needs_native
def test_info_reports_boundary():
    proc = run_cli("info", CAMEL)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["faces"] == 22704
    assert out["num_input_faces"] == 22704
    assert out["num_boundary_loops"] == 1
    assert out["num_components"] == 1
    assert len(out["sliver_faces"]) == 73


@needs_native
def test_closed_pipe_exits_quietly():
    """`nfield info MESH | head -0`: the reader is gone before the output is written. The CLI stops with the
    SIGPIPE status (128 + 13) and says nothing: no 'Broken pipe' error, no traceback from the final flush."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        env = package_env()
        env.pop("NFIELD_DEBUG", None)
        proc = subprocess.run([sys.executable, "-m", "nfield", "info", str(CAMEL)], stdout=write_end,
                              stderr=subprocess.PIPE, text=True, env=env, timeout=600)
    finally:
        os.close(write_end)
    assert proc.returncode == 141, proc.stderr
    assert proc.stderr == ""


# ---------------------------------------------------------------------------------------- errors
ARG_ERRORS = {
    "unknown_align": (["--align", "sideways"], ["align", "sideways"]),
    "n_zero": (["--n", "0"], ["n must be 1..64 (got 0)"]),
    "order_7": (["--order", "7"], ["order", "7"]),
    "strength_negative": (["--strength", "-1"], ["strength", "-1"]),
    "strength_nan": (["--strength", "nan"], ["strength"]),
    "out_extension": (["--out", "field.txt"], ["extension", ".txt"]),
    "n_not_int": (["--n", "four"], ["n must be an integer"]),
}


@pytest.mark.parametrize("name", sorted(ARG_ERRORS))
def test_bad_arguments_exit_2(name, tmp_path):
    extra, needles = ARG_ERRORS[name]
    args = ["solve", SPHERE, "--n", "4"] + extra
    proc = run_cli(*args, cwd=tmp_path)
    assert_one_line_error(proc, *needles)
    assert not (tmp_path / "field.txt").exists()


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _boundary_vertex(path: Path) -> int:
    _, F = read_mesh_np(path)
    e = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    return int(uniq[counts == 1][0, 0])


TRI_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0.5\nf 1 2 3\nf 2 4 3\n"


def _input_error_case(name: str, tmp_path: Path):
    """(args, needles) for each bad input."""
    cons = lambda obj: write_json(tmp_path / "c.json", obj)  # noqa: E731
    if name == "missing_mesh":
        return ["solve", tmp_path / "nope.obj", "--n", "4"], ["not found", "nope.obj"]
    if name == "malformed_obj":
        m = _write(tmp_path, "broken.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n")
        return ["solve", m, "--n", "4"], ["broken.obj"]
    if name == "obj_index_out_of_range":
        m = _write(tmp_path, "range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
        return ["solve", m, "--n", "4"], ["range.obj"]
    if name == "nan_vertex":
        m = _write(tmp_path, "nan.obj", TRI_OBJ.replace("v 1 0 0", "v nan 0 0"))
        return ["solve", m, "--n", "4"], ["nan"]
    if name == "unsupported_mesh_format":
        m = _write(tmp_path, "mesh.stl", "solid x\n")
        return ["info", m], [".stl"]
    if name == "constraints_not_list":
        c = cons({"face": 1, "direction": [1, 0, 0]})
        return ["solve", SPHERE, "--n", "4", "--constraints", c], ["list"]
    if name == "constraints_bad_json":
        c = _write(tmp_path, "c.json", '[{"face": 1, "direction": [1, 0, 0]')
        return ["solve", SPHERE, "--n", "4", "--constraints", c], ["json"]
    if name == "constraints_missing_file":
        return ["solve", SPHERE, "--n", "4", "--constraints", tmp_path / "none.json"], ["not found", "none.json"]
    if name == "constraints_wrong_schema":
        c = cons([{"face": 1, "dir": [1, 0, 0]}])
        return ["solve", SPHERE, "--n", "4", "--constraints", c], ["direction"]
    if name == "face_out_of_range":
        c = cons([{"face": 99999, "direction": [1, 0, 0]}])
        return ["solve", SPHERE, "--n", "4", "--constraints", c], ["99999", "out of range"]
    if name == "zero_direction":
        c = cons([{"face": 3, "direction": [0, 0, 0]}])
        return ["solve", SPHERE, "--n", "4", "--constraints", c], ["face 3", "zero"]
    if name == "direction_along_normal":
        V, F = read_mesh_np(SPHERE)
        c = cons([{"face": 3, "direction": face_normals(V, F)[3].tolist()}])
        return ["solve", SPHERE, "--n", "4", "--constraints", c], ["face 3", "normal"]
    if name == "duplicate_face":
        c = cons([{"face": 3, "direction": [1, 0, 0]}, {"face": 3, "direction": [0, 1, 0]}])
        return ["solve", SPHERE, "--n", "4", "--constraints", c], ["face 3", "more than one"]
    if name == "index_not_multiple":
        s = write_json(tmp_path / "s.json", [{"vertex": 5, "index": 0.3}])
        return ["solve", SPHERE, "--n", "4", "--singularities", s], ["0.3", "multiple of 1/4"]
    if name == "singularity_on_boundary":
        v = _boundary_vertex(CAMEL)
        s = write_json(tmp_path / "s.json", [{"vertex": v, "index": 0.25}])
        return ["solve", CAMEL, "--n", "4", "--singularities", s], [f"vertex {v}", "interior"]
    if name == "vertex_out_of_range":
        s = write_json(tmp_path / "s.json", [{"vertex": 642, "index": 0.25}])
        return ["solve", SPHERE, "--n", "4", "--singularities", s], ["642", "out of range"]
    if name == "vector_file_given_directions":
        c = cons([{"face": 1, "direction": [1, 0, 0]}])
        return ["solve", SPHERE, "--n", "4", "--vector-constraints", c], ["vector"]
    if name == "out_dir_missing":
        return ["solve", SPHERE, "--n", "4", "--out", tmp_path / "no" / "f.npy"], ["does not exist"]
    raise AssertionError(name)


INPUT_ERRORS = ["missing_mesh", "malformed_obj", "obj_index_out_of_range", "nan_vertex", "unsupported_mesh_format",
                "constraints_not_list", "constraints_bad_json", "constraints_missing_file",
                "constraints_wrong_schema", "face_out_of_range", "zero_direction", "direction_along_normal",
                "duplicate_face", "index_not_multiple", "singularity_on_boundary", "vertex_out_of_range",
                "vector_file_given_directions", "out_dir_missing"]


@needs_native
@pytest.mark.parametrize("name", INPUT_ERRORS)
def test_bad_inputs_exit_2(name, tmp_path):
    args, needles = _input_error_case(name, tmp_path)
    assert_one_line_error(run_cli(*args), *needles)


def test_unexpected_error_is_one_line_exit_1(monkeypatch, capsys):
    from nfield import cli

    def boom(path):
        raise ZeroDivisionError("synthetic failure")

    monkeypatch.setattr(cli, "_load_mesh", boom)
    monkeypatch.delenv("NFIELD_DEBUG", raising=False)
    assert cli.main(["info", "whatever.obj"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert err.strip().splitlines() == ["nfield: internal error: ZeroDivisionError: synthetic failure "
                                        "(set NFIELD_DEBUG=1 for the traceback)"]
    monkeypatch.setenv("NFIELD_DEBUG", "1")
    assert cli.main(["info", "whatever.obj"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_expected_error_in_process_is_exit_2(monkeypatch, capsys):
    from nfield import cli

    def bad(path):
        raise ValueError("mesh x.obj: line 3: expected 3 numbers\nsecond line")

    monkeypatch.setattr(cli, "_load_mesh", bad)
    assert cli.main(["info", "x.obj"]) == 2
    err = capsys.readouterr().err
    assert err == "nfield: error: mesh x.obj: line 3: expected 3 numbers second line\n"
