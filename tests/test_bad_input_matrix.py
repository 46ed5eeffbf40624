"""Bad input through every layer: one table of cases (tests/bad_input_cases.py), run through nfield.core, the
CLI and the add-on.

Each :class:`Case` builds its own mesh (numpy arrays), parameters and constraints (the CLI's JSON form) and
states its documented outcome:

* ``error=<regex>``: the layer raises ValueError (core), exits with code 2 and one line
  ``nfield: error: ...`` (CLI), or the operator / scripting call fails with an ERROR report (add-on), and
  the message matches the regex, which names the problem (face / vertex index, parameter and its range).
  ``cli_error`` / ``blender_error`` override it where a layer words it differently (the CLI reads files,
  so it names the file and line; the add-on offers only n in {1, 2, 3, 4, 6} and orders 1..3).
* ``error=None``: the layer returns a field that is finite everywhere, a unit tangent vector on every face
  the mesh report keeps (zero on excluded ones), with every hard constraint holding (direction constraints
  along +d, vector constraints exactly, singularities with their index), on every connected component.
* ``blender_na=<reason>``: the input cannot exist in a Blender mesh (printed as the reason of the skip).

The core and CLI layers run here; the add-on layer runs in tests/test_blender_failures.py (it needs the
packaged extension in this process's only bpy) over the same ``CASES``. docs/hardening.md ("Bad input")
holds the table of outcomes; ``test_docs_list_every_case`` keeps it complete.
"""
from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from bad_input_cases import CASE_BY_NAME, CASES, check_field
from conftest import ROOT, TEST_INSTALLED, package_env
#: a CLI run on these tiny meshes takes about a second (interpreter start, numpy, the compiled module);
#: anything near this limit is a hang, not slowness (also under the shared machine's load)
CLI_TIMEOUT = 60.0

# ------------------------------------------------------------------------------------------ core layer
# The cases (bad_input_cases.py) need no nfield; the tests below need the compiled module.
try:
    import nfield._native as nat
    import nfield.core as core
except ImportError:
    if TEST_INSTALLED and "bpy" not in sys.modules:
        raise  # an installed nfield always has its compiled module
    nat = core = None
needs_native = pytest.mark.skipif(nat is None, reason="compiled module nfield._native is not built")


def _core_constraints(case):
    dirs = [core.DirectionConstraint(c["face"], tuple(c["direction"])) for c in case.constraints if "direction" in c]
    vecs = [core.VectorConstraint(c["face"], tuple(c["vector"])) for c in case.constraints if "vector" in c]
    sings = [core.SingularityConstraint(c["vertex"], c["index"]) for c in case.constraints if "vertex" in c]
    return dirs, vecs, sings


def run_core(case):
    V, F = case.mesh()
    mesh = core.Mesh(V, F)
    p = dict(case.params)
    if case.command == "eig":
        return mesh, core.eigenvalues(mesh, p.get("n", 4), p["k"])
    dirs, vecs, sings = _core_constraints(case)
    return mesh, core.solve(mesh, constraints=dirs, vector_constraints=vecs, singularities=sings, **p)


@needs_native
@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_core(case):
    if case.error is not None:
        with pytest.raises(ValueError) as info:
            run_core(case)
        assert re.search(case.error, str(info.value)), f"message {str(info.value)!r} !~ {case.error!r}"
        return
    mesh, result = run_core(case)
    if case.command == "eig":
        vals = np.asarray(result)
        assert vals.shape == (case.params["k"],) and np.isfinite(vals).all()
        assert np.all(np.diff(vals) >= -1e-9 * max(1.0, abs(vals).max()))  # ascending up to rounding
        assert vals.min() >= -1e-9 * max(1.0, abs(vals).max())  # S is positive semi-definite
        return
    n = result.n
    ops = nat.FieldOperators(mesh.native, n, "geometric")
    face_cons = [c for c in case.constraints if "face" in c]
    rep = []
    for c in face_cons:
        v = np.asarray(c.get("direction", c.get("vector")), float)
        if "direction" in c:
            v = v / np.abs(v).max()
        rep.append(complex(np.asarray(ops.tangent_to_representation(np.array([c["face"]]), v[None]))[0]))
    check_field(result.directions, np.asarray(mesh.native.face_normals), np.asarray(mesh.native.face_active), n,
                case.constraints, raw=np.asarray(result.raw_solution), rep=rep, report=result.mesh_report,
                case=case, singularities=result.singularities)
    assert np.isfinite(result.energy)


# ------------------------------------------------------------------------------------------ CLI layer
def write_off(path: Path, V, F) -> None:
    """OFF keeps 0-based indices as given (also out-of-range ones) and repr() writes nan / inf as such."""
    lines = ["OFF", f"{len(V)} {len(F)} 0"]
    lines += [" ".join(repr(float(x)) for x in v) for v in np.asarray(V, float)]
    lines += ["3 " + " ".join(str(int(i)) for i in f) for f in np.asarray(F)]
    path.write_text("\n".join(lines) + "\n")


def cli_args(case, tmp_path: Path):
    V, F = case.mesh()
    mesh = tmp_path / f"{case.name}.off"
    write_off(mesh, V, F)
    p = dict(case.params)
    args = [case.command, str(mesh), "--n", str(p.pop("n", 4))]
    if case.command == "eig":
        args += ["--k", str(p.pop("k"))]
    for key in ("order", "strength", "align"):
        if key in p:
            args += [f"--{key}", repr(p.pop(key)) if key == "strength" else str(p.pop(key))]
    assert not p, f"parameters the CLI cannot take: {p}"
    for kind, opt, key in (("direction", "--constraints", "direction"), ("vector", "--vector-constraints", "vector"),
                           ("singularity", "--singularities", "index")):
        items = [c for c in case.constraints if key in c]
        if items:
            f = tmp_path / f"{kind}.json"
            f.write_text(json.dumps(items))
            args += [opt, str(f)]
    out = tmp_path / "field.npy"
    if case.command == "solve":
        args += ["--out", str(out), "--json"]
    return args, out, mesh


def run_cli(args):
    env = package_env()
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "nfield", *args], capture_output=True, text=True, env=env,
                              timeout=CLI_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"CLI did not finish within {CLI_TIMEOUT} s (hang): nfield {' '.join(args)}")
    return proc, time.perf_counter() - t0


@needs_native
@pytest.mark.slow  # one CLI process per case; the in-process test above covers the same cases quickly
@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_cli(case, tmp_path):
    args, out, mesh_file = cli_args(case, tmp_path)
    proc, _ = run_cli(args)
    assert "Traceback" not in proc.stderr, proc.stderr
    expected = case.cli_error or case.error
    if expected is not None:
        assert proc.returncode == 2, (proc.returncode, proc.stdout, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("nfield: error: "), proc.stderr
        assert re.search(expected, lines[0]), f"{lines[0]!r} !~ {expected!r}"
        return
    assert proc.returncode == 0, proc.stderr
    if case.command == "eig":
        vals = np.asarray(json.loads(proc.stdout)["eigenvalues"])
        assert vals.shape == (case.params["k"],) and np.isfinite(vals).all()
        return
    summary = json.loads(proc.stdout)
    directions = np.load(out)
    mesh = core.Mesh.from_file(mesh_file)
    check_field(directions, np.asarray(mesh.native.face_normals), np.asarray(mesh.native.face_active),
                summary["n"], case.constraints, report=summary["mesh_report"], case=case,
                singularities=[(s["vertex"], s["index"]) for s in summary["singularities"]])


# ------------------------------------------------------------------------------------------ out of memory
_OOM_SCRIPT = r"""
import resource, sys
sys.path.insert(0, sys.argv[1])
import meshgen as mg
from nfield import core
from nfield.cli import main
V, F = mg.icosphere(5)  # 20480 faces: the order-4 factorization needs far more than 64 MB
mesh = core.Mesh(V, F)
core.native()
path = sys.argv[2]
with open(path, "w") as fh:
    fh.write("OFF\n%d %d 0\n" % (len(V), len(F)))
    fh.writelines("%r %r %r\n" % tuple(map(float, v)) for v in V)  # float: numpy 2's repr is np.float64(...)
    fh.writelines("3 %d %d %d\n" % tuple(f) for f in F)
used = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
resource.setrlimit(resource.RLIMIT_AS, (used + 64 * 2**20, resource.getrlimit(resource.RLIMIT_AS)[1]))
try:
    core.solve(mesh, n=4, order=4)
    print("CORE no error")
except MemoryError as exc:
    print("CORE MemoryError", exc)
print("CLI exit", main(["solve", path, "--n", "4", "--order", "4"]))
"""


@needs_native
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="needs RLIMIT_AS and /proc (Linux)")
@pytest.mark.no_sanitizer  # ASan reserves terabytes of address space: RLIMIT_AS cannot be lowered under it
def test_out_of_memory_is_memory_error_and_cli_exit_2(tmp_path):
    """A real std::bad_alloc (address space limited to 64 MB above what the process uses, in a subprocess):
    the core raises MemoryError, the CLI exits 2 with one line (not exit 1, not a traceback)."""
    env = dict(package_env(), OPENBLAS_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-c", _OOM_SCRIPT, str(Path(__file__).parent), str(tmp_path / "big.off")],
                          capture_output=True, text=True, env=env, timeout=CLI_TIMEOUT * 2)
    assert "CORE MemoryError" in proc.stdout, proc.stdout + proc.stderr
    assert "CLI exit 2" in proc.stdout, proc.stdout + proc.stderr
    err = [l for l in proc.stderr.splitlines() if l.startswith("nfield:")]
    assert err == [l for l in proc.stderr.splitlines() if l.strip()] and len(err) == 1, proc.stderr
    assert err[0].startswith("nfield: error: out of memory"), err


# ------------------------------------------------------------------------------------------ docs
@pytest.mark.no_sanitizer  # reads docs/, no native code
def test_docs_list_every_case():
    """docs/hardening.md's "Bad input" section names every case of the table (and no unknown one)."""
    text = (ROOT / "docs" / "hardening.md").read_text()
    m = re.search(r"^# Bad input\n(.*?)(?=^# |\Z)", text, re.S | re.M)
    assert m, "docs/hardening.md has no top-level section '# Bad input'"
    named = set(re.findall(r"^\| `([a-z0-9_]+)` \|", m.group(1), re.M))
    assert named == set(CASE_BY_NAME), (sorted(set(CASE_BY_NAME) - named), sorted(named - set(CASE_BY_NAME)))
