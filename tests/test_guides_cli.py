"""Command line guide options of ``python -m nfield solve`` (subprocesses, as a user runs them).

  * --align-features boundary,sharp:30 with --feature-mode hard: on fandisk every face next to a sharp edge
    that the corner rule kept has a direction within 1 degree of the edge (the CLI writes the field); the text
    output reports the features and the dropped faces;
  * --alignment-weight / --alignment-rotation / --cuts / --curves files are read and checked (wrong sizes,
    bad JSON, unknown keys, edges that do not exist: exit 2 with one line);
  * --symmetry on a mirror-symmetric mesh gives a symmetric field (to 1e-8), and on a non-symmetric one
    refuses with the unmatched faces unless --symmetry-partial.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

import meshgen
from test_cli import DATA, assert_one_line_error, needs_native, run_cli, write_json

FANDISK = DATA / "fandisk.obj"


def write_obj(path, V, F):
    lines = [f"v {x:.17g} {y:.17g} {z:.17g}" for x, y, z in V] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in F]
    path.write_text("\n".join(lines) + "\n")
    return path


@needs_native
def test_hard_features_on_fandisk(tmp_path):
    out = tmp_path / "field.npy"
    proc = run_cli("solve", FANDISK, "--n", "4", "--align", "curvature-max", "--align-features", "sharp:30",
                   "--feature-mode", "hard", "--out", out, "--json")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    g = summary["guides"]
    assert g["feature_edges"] > 100 and g["hard_constraints"] > 0
    dropped = {d["face"] for d in g["dropped"]}
    field = np.load(out)
    from nfield.core import Mesh, native

    mesh = Mesh.from_file(FANDISK)
    geo = native().GuideGeometry(mesh.native)
    fs = geo.detect_features(boundary=False, sharp_angle=30.0)
    E = np.asarray(geo.edges())
    normals = np.asarray(mesh.native.face_normals)
    worst = 0.0
    for e in np.asarray(fs.edge_ids).tolist():
        ev = mesh.vertices[E[e][1]] - mesh.vertices[E[e][0]]
        ev /= np.linalg.norm(ev)
        for f in geo.edge_faces(e):
            if f in dropped:
                continue
            # n = 4: the field's first direction or its perpendicular in the face plane lies along the edge
            d = field[f]
            perp = np.cross(normals[f], d)
            c = max(abs(d @ ev), abs(perp @ ev))
            worst = max(worst, math.degrees(math.acos(min(1.0, c))))
    assert worst < 1.0
    text = run_cli("solve", FANDISK, "--n", "4", "--align-features", "sharp:30", "--feature-mode", "hard")
    assert text.returncode == 0 and "guides: features:" in text.stdout and "dropped" in text.stdout


@needs_native
def test_guide_file_errors(tmp_path):
    F = 12946  # fandisk faces
    w = tmp_path / "w.csv"
    np.savetxt(w, np.ones(10), delimiter=",")
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--align", "curvature-max", "--alignment-weight", w),
                          "10 numbers", f"{F} faces")
    neg = tmp_path / "neg.npy"
    arr = np.ones(F)
    arr[3] = -2
    np.save(neg, arr)
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--alignment-weight", neg), "face 3")
    bad = tmp_path / "bad.json"
    bad.write_text("[[1, 2], [3")
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--cuts", bad), "not valid JSON")
    cuts = write_json(tmp_path / "cuts.json", [[0, 5000]])
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--cuts", cuts), "not edges")
    curves = write_json(tmp_path / "curves.json", [{"points": [[0, 0, 0], [1, 0, 0]], "colour": "red"}])
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--curves", curves), "unknown key", "colour")
    curves = write_json(tmp_path / "curves.json", [{"points": [[0, 0, 0]]}])
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--curves", curves), "curve 0", "k >= 2")
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--align-features", "sharp:x"), "sharp angle")
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--symmetry", "w"), "axis")
    assert_one_line_error(run_cli("solve", FANDISK, "--n", "4", "--feature-width", "0"), "feature width")


@needs_native
def test_cuts_weights_rotation_and_curves(tmp_path):
    V, F = meshgen.grid(15, 15)
    obj = write_obj(tmp_path / "grid.obj", V, F)
    idx = np.arange(225).reshape(15, 15)
    cuts = write_json(tmp_path / "cuts.json", [[int(idx[7, j]), int(idx[7, j + 1])] for j in range(10)])
    np.save(tmp_path / "rot.npy", np.full(len(F), 0.3))
    np.save(tmp_path / "w.npy", np.linspace(0, 1, len(F)))
    curves = write_json(tmp_path / "curves.json", [
        {"name": "diag", "points": [[0.1, 0.1, 0.0], [0.9, 0.9, 0.0]], "mode": "hard", "every": 2},
        {"points": [[0.1, 0.9, 0.0], [0.9, 0.1, 0.3]], "tolerance": 0.01}])
    proc = run_cli("solve", obj, "--n", "2", "--cuts", cuts, "--alignment-rotation", tmp_path / "rot.npy",
                   "--alignment-weight", tmp_path / "w.npy", "--curves", curves, "--json")
    assert proc.returncode == 0, proc.stderr
    g = json.loads(proc.stdout)["guides"]
    assert g["cuts"]["opened"] == 10
    assert g["curves"]["diag"]["missed"] == 0 and g["hard_constraints"] > 0
    assert g["missed_curves"] == ["1"]  # the second curve rises off the plane


@needs_native
def test_symmetry_option(tmp_path):
    V, F = meshgen.icosphere(3)
    obj = write_obj(tmp_path / "sym.obj", V * [1.0, 0.8, 0.6], F)
    out = tmp_path / "f.npy"
    proc = run_cli("solve", obj, "--n", "4", "--align", "curvature-max", "--symmetry", "x", "--out", out, "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["guides"]["symmetry"]["unmatched"] == []
    d = np.load(out)
    from nfield.core import Mesh, native

    mesh = Mesh.from_file(obj)
    partner = np.asarray(native().MirrorMap(mesh.native, "x", 0.0, 1e-9).partner)
    refl = d.copy()
    refl[:, 0] *= -1
    normals = np.asarray(mesh.native.face_normals)
    # the mirror face's cross contains the reflected direction: its first direction or its perpendicular
    q = d[partner]
    qp = np.cross(normals[partner], q)
    err = np.minimum(np.minimum(np.linalg.norm(q - refl, axis=1), np.linalg.norm(q + refl, axis=1)),
                     np.minimum(np.linalg.norm(qp - refl, axis=1), np.linalg.norm(qp + refl, axis=1)))
    assert err.max() < 1e-8
    W = V.copy()
    W[0] += [0, 0, 0.02]
    bent = write_obj(tmp_path / "bent.obj", W, F)
    assert_one_line_error(run_cli("solve", bent, "--n", "4", "--symmetry", "x"), "no mirror partner",
                          "--symmetry-partial")
    proc = run_cli("solve", bent, "--n", "4", "--symmetry", "x", "--symmetry-partial", "--json")
    assert proc.returncode == 0, proc.stderr
    assert len(json.loads(proc.stdout)["guides"]["symmetry"]["unmatched"]) > 0
