"""Session-level fixtures for the nfield tests.

The location of the public test meshes (tests/data/, see tests/data/README.md) and the import path of
the development tree's package (addon/). Helpers: ``mesh_path(name)``, ``core_mesh(name)`` (plain
functions, ``from conftest import ...``) and the session fixture ``data_dir``.
"""
from __future__ import annotations

import functools
import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DATA_DIR = ROOT / "tests" / "data"
if str(ROOT / "addon") not in sys.path:  # build_addon.py test sets PYTHONPATH; plain pytest runs need this
    sys.path.insert(0, str(ROOT / "addon"))

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
