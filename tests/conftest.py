"""Session-level fixtures for the nfield tests.

The location of the public test meshes (tests/data/, see tests/data/README.md) and which nfield the tests
import: the development tree's package (addon/, put first on sys.path), or with NFIELD_TEST_INSTALLED=1 the
installed one (a wheel in a virtual environment, or the extension a Blender test installs; addon/ is then
kept off sys.path, and the session stops if nfield still comes from a checkout). Files of the repository
(docs, examples, the layer table) are always read from this checkout. Helpers: ``mesh_path(name)``,
``core_mesh(name)``, ``package_env()`` (plain functions, ``from conftest import ...``) and the session
fixture ``data_dir``.
"""
from __future__ import annotations

import functools
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA_DIR = ROOT / "tests" / "data"
ADDON = ROOT / "addon"
TEST_INSTALLED = os.environ.get("NFIELD_TEST_INSTALLED", "") not in ("", "0")


def _is_checkout_addon(path: str) -> bool:
    """True for the addon/ folder of an nfield checkout (this one, or another one named by a .pth file)."""
    folder = Path(path or ".").resolve()
    return folder.name == "addon" and (folder / "nfield" / "__init__.py").is_file() \
        and (folder.parent / "build_addon.py").is_file()


if TEST_INSTALLED:
    sys.path[:] = [p for p in sys.path if not _is_checkout_addon(p)]
elif str(ADDON) not in sys.path:  # build_addon.py test sets PYTHONPATH; plain pytest runs need this
    sys.path.insert(0, str(ADDON))


def package_env(env: dict | None = None) -> dict:
    """Environment for a subprocess that imports nfield: the one this session tests (PYTHONPATH starts with
    addon/, or with NFIELD_TEST_INSTALLED no checkout's addon/ on it)."""
    env = dict(os.environ if env is None else env)
    paths = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p and not _is_checkout_addon(p)]
    env["PYTHONPATH"] = os.pathsep.join(paths if TEST_INSTALLED else [str(ADDON), *paths])
    return env


def pytest_sessionstart(session):
    """With NFIELD_TEST_INSTALLED: stop at once unless the nfield that imports is an installed one (the
    headless Blender suite installs its extension first, so there nfield need not import yet)."""
    if not TEST_INSTALLED:
        return
    import importlib.util

    spec = importlib.util.find_spec("nfield")
    if spec is None:
        return
    if spec.origin and _is_checkout_addon(str(Path(spec.origin).parent.parent)):
        pytest.exit(f"NFIELD_TEST_INSTALLED is set, but nfield imports from a checkout: {spec.origin}", returncode=3)
    import nfield.core  # the compiled module must load (tests that skip without it would pass quietly)

    try:
        print(f"\n[installed nfield] {nfield.core.native().__file__}", flush=True)
    except ImportError as exc:
        pytest.exit(f"NFIELD_TEST_INSTALLED: the installed nfield's compiled module does not load: {exc}", returncode=3)

# The eight meshes copied into tests/data/ (byte-for-byte, sha256 in tests/data/README.md).
MESH_NAMES = (
    "sphere.obj",
    "fertility.off",
    "eight.off",
    "fandisk.obj",
    "rocker-arm.obj",
    "camelhead.off",
    "stanford-bunny.obj",
    "armadillo.obj",
)


def face_cycle(face) -> list:
    """A polygon's vertex cycle started at its smallest index (same cycle, same orientation), to compare
    faces whose first vertex may differ."""
    k = list(face).index(min(face))
    return list(face[k:]) + list(face[:k])


def mesh_path(name: str) -> Path:
    """Absolute path of a test mesh in tests/data/, e.g. ``mesh_path("rocker-arm.obj")``.

    Raises FileNotFoundError naming the available meshes if it is not there.
    """
    path = DATA_DIR / name
    if not path.is_file():
        available = ", ".join(sorted(p.name for p in DATA_DIR.glob("*.o[bf][jf]")))
        raise FileNotFoundError(f"test mesh {name!r} not found in {DATA_DIR} (available: {available})")
    return path


@functools.lru_cache(maxsize=None)
def core_mesh(name: str):
    """nfield.core.Mesh of a test mesh, loaded once per session (skips the test if the mesh is missing)."""
    path = DATA_DIR / name
    if not path.is_file():
        pytest.skip(f"test mesh {path} is missing")
    from nfield.core import Mesh

    return Mesh.from_file(path)


def mesh_from_arrays(VF):
    """nfield.core.Mesh of a generated mesh given as (V, F) arrays (tests/meshgen.py)."""
    import numpy as np
    from nfield.core import Mesh

    V, F = VF
    return Mesh(np.asarray(V, float), np.asarray(F, np.int64))


def has_native() -> bool:
    """True when the compiled module nfield._native imports."""
    try:
        import nfield._native  # noqa: F401
    except ImportError:
        return False
    return True


needs_native = pytest.mark.skipif(not has_native(), reason="compiled module nfield._native is not built")


def run_beside_main_loop(work) -> dict:
    """Runs work() in a thread named "solver" while this thread loops, sleeping 1 ms per iteration (each
    wake-up needs the GIL). Returns {"result" or "error", "seconds" (of work), "count" (iterations),
    "gap" (longest time between iterations)}: a computation holding the GIL shows as a gap about as long
    as the computation. The loop sleeps instead of spinning: a spinning Python thread slows a 2-thread
    OpenBLAS factorization ~10x on a 2-core machine."""
    import threading
    import time

    box: dict = {}

    def run():
        t0 = time.perf_counter()
        try:
            box["result"] = work()
        except BaseException as exc:  # noqa: BLE001 - reported by the caller
            box["error"] = exc
        box["seconds"] = time.perf_counter() - t0

    worker = threading.Thread(target=run, name="solver")
    count, gap, last = 0, 0.0, time.perf_counter()
    worker.start()
    while worker.is_alive():
        time.sleep(0.001)
        now = time.perf_counter()
        count, gap, last = count + 1, max(gap, now - last), now
    worker.join()
    box.update(count=count, gap=gap)
    return box


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The directory holding the test meshes (tests/data/)."""
    return DATA_DIR


def system_blender_env() -> dict:
    """Environment for Debian's Blender (3.4, embedded system Python 3.11).

    Its embedded interpreter finds its home through PATH: with pyenv's or the venv's bin first (as under
    `build_addon.py`, started by pyenv's python3), it would load pyenv's standard library and no NumPy.
    So drop those PATH entries and every variable that redirects Python."""
    env = dict(os.environ)
    for key in ("PYTHONHOME", "PYTHONPATH", "VIRTUAL_ENV", "PYENV_VERSION"):
        env.pop(key, None)
    keep = [p for p in env.get("PATH", "").split(os.pathsep) if p and ".pyenv" not in p and ".venv" not in p]
    env["PATH"] = os.pathsep.join(keep or ["/usr/bin", "/bin"])
    return env


# ------------------------------------------------------------------------------------------ markers
# `build_addon.py test` runs the suite in legs selected by these markers: the core suite (neither) under
# every Python, `blender` under every PyPI bpy release of the matrix, `gui` once with Debian's Blender 3.4.
MARKERS = {
    "blender": "the headless Blender suite: needs PyPI bpy (run under every bpy release of the matrix)",
    "gui": "Debian's Blender 3.4: a real window under Xvfb, or the legacy (bl_info) install",
    "slow": "a long run of code the quicker tests also cover (large meshes); left out of `test --quick` and "
            "of the sanitizer job",
    "no_sanitizer": "left out of the ASan/UBSan job: runs no native code, or measures memory, which ASan changes",
}


def pytest_configure(config):
    for name, text in MARKERS.items():
        config.addinivalue_line("markers", f"{name}: {text}")


# ------------------------------------------------------------------------------------------ the packaged add-on
PACKAGE_SOURCES = [ROOT / "addon", ROOT / "native", ROOT / "CMakeLists.txt", ROOT / "pyproject.toml",
                   ROOT / "build_addon.py"]


def _newest_source_mtime() -> float:
    newest = 0.0
    for src in PACKAGE_SOURCES:
        paths = [src] if src.is_file() else [p for p in src.rglob("*") if p.is_file() and "__pycache__" not in p.parts
                                             and not p.name.startswith("_native")]
        for p in paths:
            newest = max(newest, p.stat().st_mtime)
    return newest


def package_version() -> str:
    for line in (ROOT / "addon" / "nfield" / "__init__.py").read_text().splitlines():
        if line.startswith("__version__"):
            return line.split("=")[1].strip().strip('"')
    raise AssertionError("addon/nfield/__init__.py has no __version__")


def _packaged(name: str) -> Path:
    """dist/<name>, rebuilt with `build_addon.py package` (the wheels, then both zips) when older than a
    source. `build_addon.py test` packages before the Blender legs, so each leg reuses it. Runs build_addon.py
    with the system python3 (standard library only), so packaging never depends on the interpreter running
    the tests."""
    import shutil
    import subprocess

    z = ROOT / "dist" / name
    if not z.exists() or z.stat().st_mtime < _newest_source_mtime():
        python = shutil.which("python3") or sys.executable
        proc = subprocess.run([python, str(ROOT / "build_addon.py"), "package"], cwd=ROOT,
                              capture_output=True, text=True, timeout=3600)
        assert proc.returncode == 0, f"build_addon.py package failed:\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    assert z.is_file(), z
    return z


@pytest.fixture(scope="session")
def extension_zip() -> Path:
    """dist/nfield-<version>-linux-x64.zip: the Blender extension (4.2 and later) made from the wheels."""
    return _packaged(f"nfield-{package_version()}-linux-x64.zip")


@pytest.fixture(scope="session")
def legacy_zip() -> Path:
    """dist/nfield-<version>-blender34-legacy.zip: the legacy add-on for Blender 3.4, from the 3.11 wheel."""
    return _packaged(f"nfield-{package_version()}-blender34-legacy.zip")


# Files that need PyPI bpy at import time: not even imported when the marker expression deselects
# `blender` (the core legs then never load bpy, and under a Python without bpy nothing is skipped either).
BLENDER_ONLY_FILES = {"test_blender_headless.py", "test_blender_design.py", "test_blender_failures.py",
                      "test_blender_guides.py", "test_blender_guide_tools.py", "test_blender_mesh_read.py", "test_blender_artist.py",
                      "test_blender_remesh.py", "test_hatching_blender.py", "test_rendering.py", "test_demo.py"}


def _marks_blender_or_gui(path: Path) -> bool:
    """Whether a test file marks tests `blender` or `gui` (read from its text: the files without such marks
    are core only and are not imported when the marker expression selects only `blender`/`gui` tests, as in
    the Blender legs, where nfield is the extension's and imports only once a test has installed it)."""
    text = path.read_text(errors="replace")
    return "mark.blender" in text or "mark.gui" in text


def _selects(markexpr: str, blender: bool, gui: bool) -> bool:
    """Whether -m markexpr selects some test with these `blender`/`gui` marks (any other marks)."""
    import itertools
    import re

    from _pytest.mark.expression import Expression  # pytest's own -m evaluator

    expr = Expression.compile(markexpr)
    others = sorted(set(re.findall(r"[A-Za-z_]\w*", markexpr)) - {"and", "or", "not", "blender", "gui"})
    for values in itertools.product((False, True), repeat=len(others)):
        marks = dict(zip(others, values), blender=blender, gui=gui)
        if expr.evaluate(lambda name, **_kw: marks.get(name, False)):
            return True
    return False


def pytest_ignore_collect(collection_path, config):
    markexpr = config.getoption("markexpr", "") or ""
    if not markexpr or not collection_path.name.startswith("test_"):
        return None
    if collection_path.name in BLENDER_ONLY_FILES:
        return True if not _selects(markexpr, blender=True, gui=False) else None
    if collection_path.suffix != ".py" or _marks_blender_or_gui(Path(collection_path)):
        return None
    return True if not _selects(markexpr, blender=False, gui=False) else None


# ------------------------------------------------------------------------------------------ PyPI bpy processes
def bpy_exit_crashes() -> bool:
    """True in a process that imported PyPI bpy older than 4.3. That module crashes (SIGSEGV in
    bpy_class_free, called from SpaceType's static destructor after Python was finalized) at interpreter exit
    once any add-on has registered a property with an update callback, even after unregistering it: a Blender
    bug, reproduced without nfield by six lines (a PropertyGroup with `IntProperty(update=f)`, registered,
    then exit) in bpy 4.2.23 and absent from 4.5, 5.0 and 5.2."""
    bpy = sys.modules.get("bpy")
    return bpy is not None and tuple(bpy.app.version[:2]) < (4, 3)


def end_bpy_process(code: int = 0) -> None:
    """Ends a test process (pytest or a bpy script it started) with `code`. Where bpy's exit crashes (see
    bpy_exit_crashes) it skips the static destructors with os._exit after flushing the output; everything
    the process had to do is done by then. Elsewhere a normal exit."""
    if bpy_exit_crashes():
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


def bpy_script_main(work) -> None:
    """The script side of blender_support.run_script: `work(out_dir)` with the directory given as the first argument
    (created), its result printed as the last line of JSON, then the process ended (end_bpy_process)."""
    import json

    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    result = work(out)
    sys.stdout.flush()
    print(json.dumps(result))
    end_bpy_process(0)


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session, exitstatus):
    session.config._nfield_exitstatus = int(exitstatus)


@pytest.hookimpl(trylast=True)
def pytest_unconfigure(config):
    if bpy_exit_crashes():  # see there: pytest's own exit would end in SIGSEGV after a complete, reported run
        end_bpy_process(getattr(config, "_nfield_exitstatus", 0))
def stationarity_residual(ops, order: int, lam: float, w, rhs, free) -> float:
    """First-order optimality of a spline w (complex, one value per unknown = per face on meshes without
    excluded faces): the largest |((E_order - lam M) w - rhs)_f| over the faces `free` (those in no constraint
    row and not substituted), relative to the largest sum_j |E_fj| |w_j| + |lam| A_f |w_f| + |rhs_f| there (the
    normwise backward-error scale: a backward-stable solve gives ~1e-16 whatever the condition number).
    n-vector spline (eq. 8): rhs = -lam M u'; n-direction spline (eq. 12): rhs = M u' (the safeguard only
    changes u' at constrained faces)."""
    import numpy as np

    rows, cols, vals = (np.asarray(a) for a in ops.energy_matrix(order))
    w = np.asarray(w, dtype=np.complex128)
    mass = np.asarray(ops.mass)
    Ew = np.zeros(len(w), dtype=np.complex128)
    np.add.at(Ew, rows, vals * w[cols])
    size = np.zeros(len(w))
    np.add.at(size, rows, np.abs(vals) * np.abs(w[cols]))
    r = Ew - lam * mass * w - np.asarray(rhs)
    size += abs(lam) * mass * np.abs(w) + np.abs(rhs)
    free = np.asarray(free)
    return float(np.abs(r[free]).max() / size[free].max())


def reference_indices(mesh_native, ops, z) -> dict:
    """Independent index computation from the ring order, `connection` and angle_defect: for every
    interior vertex with nonzero ring vectors, (sum psi_j + n K_v) / (2 pi n), psi_j in (-pi, pi], walking each
    ring step by step (docs/math.md section 7). Returns {vertex: index} for the non-zero indices."""
    import numpy as np

    import mesh_reference as mref

    n = ops.n
    r = np.asarray(ops.connection)
    de = np.asarray(mesh_native.dual_edges())
    lut = {}
    for e, (f0, f1, _, _) in enumerate(de):
        lut[(int(f0), int(f1))] = r[e]
        lut[(int(f1), int(f0))] = np.conj(r[e])
    out = {}
    for v in range(mesh_native.num_vertices):
        if not mesh_native.vertex_is_interior(v):
            continue
        ring = list(mesh_native.vertex_ring_faces(v))
        zr = z[ring]
        if np.any(zr == 0):
            continue
        total = 0.0
        for a, b, za, zb in zip(ring, ring[1:] + ring[:1], zr, np.roll(zr, -1)):
            total += float(mref.wrap_angle(np.angle(zb / (lut[(a, b)] * za))))
        idx = (total + n * mesh_native.angle_defect(v)) / (2 * np.pi * n)
        if abs(idx) > 0.5 / n:
            out[v] = idx
    return out
