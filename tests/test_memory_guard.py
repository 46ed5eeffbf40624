"""Memory guard (native/include/nfield/memory_guard.hpp): a factorization or an eigenbasis run that would
not fit is refused before it starts, with a message saying what would fit.

The available memory is capped with NFIELD_MEMORY_LIMIT_MB (read by the native code at every check), so the
refusals are deterministic whatever the machine has. Checked:
  * the estimate of a basis run is realistic: within [0.5, 3] of the measured peak RSS growth of a fresh
    process (measured 0.94-1.6 on fandisk and the rocker arm; an estimate far below the truth would let
    a run swap, far above it would refuse runs that fit);
  * an exact factorization and a basis beyond the cap raise nfield._native.InsufficientMemory (a
    MemoryError) naming the need, the budget and the advice; the advised k really fits and computes;
  * a session keeps its state after a refusal.
"""
from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

from conftest import DATA_DIR as DATA
from conftest import core_mesh, package_env

nat = pytest.importorskip("nfield._native", reason="compiled module nfield._native is not built")
core = pytest.importorskip("nfield.core", reason="nfield.core is not importable")


@pytest.fixture(scope="module")
def fandisk():
    mesh = core_mesh("fandisk.obj")
    return mesh, nat.FieldOperators(mesh.native, 4)


def test_available_memory_and_user_cap(monkeypatch):
    monkeypatch.delenv("NFIELD_MEMORY_LIMIT_MB", raising=False)
    free = nat.available_memory_bytes()
    assert free > 0, "MemAvailable should be readable on Linux"
    monkeypatch.setenv("NFIELD_MEMORY_LIMIT_MB", "64")
    assert nat.available_memory_bytes() <= 64 * 2**20  # the cap wins over a larger MemAvailable
    monkeypatch.setenv("NFIELD_MEMORY_LIMIT_MB", "not a number")  # ignored, not a crash
    capped = nat.available_memory_bytes()
    assert capped > 64 * 2**20 and abs(capped - free) < 0.5 * free  # MemAvailable again (it fluctuates)


# Peak RSS from VmHWM (this process's address space): ru_maxrss would start at the forking parent's peak,
# which Linux carries over exec.
PROBE = """
from nfield.core import Mesh, native
nat = native()
mesh = Mesh.from_file({path!r})
ops = nat.FieldOperators(mesh.native, 4)
est = nat.estimate_basis_bytes(ops, {k}, "double")
def peak():
    line = next(l for l in open("/proc/self/status") if l.startswith("VmHWM:"))
    return int(line.split()[1]) * 1024
before = peak()
nat.SpectralBasis.compute(ops, {k})
after = peak()
print(est, after - before)
"""


@pytest.mark.slow
@pytest.mark.no_sanitizer  # ASan's allocator changes the peak RSS this compares with
def test_basis_estimate_matches_measured_peak():
    code = PROBE.format(path=str(DATA / "fandisk.obj"), k=250)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600, check=True,
                         env=package_env())
    est, measured = (int(x) for x in out.stdout.split())
    print(f"fandisk k=250: estimate {est / 2**20:.0f} MB, measured peak growth {measured / 2**20:.0f} MB")
    assert 0.5 <= est / measured <= 3.0


def test_exact_factorization_refused_with_advice(monkeypatch):
    mesh = core_mesh("rocker-arm.obj")
    ops = nat.FieldOperators(mesh.native, 4)
    monkeypatch.setenv("NFIELD_MEMORY_LIMIT_MB", "5")
    with pytest.raises(nat.InsufficientMemory) as info:
        nat.ExactSolver(ops, 2, 1.0, None, "direction")
    msg = str(info.value)
    assert isinstance(info.value, MemoryError)
    assert re.search(r"order-2 system \(20088 faces\) needs about \d+ MB of memory but only [45] MB", msg), msg
    assert "lower energy order" in msg
    with pytest.raises(MemoryError, match="needs about"):  # through the core API too
        core.solve(mesh, n=4, order=2)
    monkeypatch.delenv("NFIELD_MEMORY_LIMIT_MB")
    assert np.isfinite(core.solve(mesh, n=4, order=2).raw_solution).all()


@pytest.mark.slow
def test_basis_refused_and_the_advised_k_fits(monkeypatch, fandisk):
    mesh, ops = fandisk
    need = nat.estimate_basis_bytes(ops, 300)
    cap_mb = 0.6 * need / 2**20 / 0.85  # the guard allows 85% of the available memory
    monkeypatch.setenv("NFIELD_MEMORY_LIMIT_MB", f"{cap_mb:.3f}")
    with pytest.raises(nat.InsufficientMemory) as info:
        nat.SpectralBasis.compute(ops, 300)
    msg = str(info.value)
    m = re.search(r"k <= (\d+) fits", msg)
    assert m and "spectral basis of k=300 eigenfields" in msg and "exact mode needs no basis" in msg, msg
    k_fit = int(m.group(1))
    assert 0 < k_fit < 300
    assert nat.estimate_basis_bytes(ops, k_fit) <= 0.85 * cap_mb * 2**20 < nat.estimate_basis_bytes(ops, k_fit + 1)
    assert nat.SpectralBasis.compute(ops, k_fit).size == k_fit  # the advice is true


def test_session_keeps_its_state_after_a_refusal(monkeypatch, tmp_path, fandisk):
    mesh, _ops = fandisk
    s = core.DesignSession(mesh, n=4, order=2, mode="spectral", k=40, cache_dir=tmp_path)
    normal = np.asarray(mesh.native.face_normals)[5]
    s.set_direction(5, np.cross(normal, [0.3, 0.5, 0.8]))  # a tangent direction
    first = s.solve()
    monkeypatch.setenv("NFIELD_MEMORY_LIMIT_MB", "1")
    s.configure(k=200)
    with pytest.raises(MemoryError, match="k=200"):
        s.solve()
    assert s.field is first and s.has_basis is False
    monkeypatch.delenv("NFIELD_MEMORY_LIMIT_MB")
    s.configure(k=40)
    assert np.array_equal(s.solve().raw_solution, first.raw_solution)
