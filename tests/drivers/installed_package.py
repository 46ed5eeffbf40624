"""The test legs of `build_addon.py test` that use nfield as a user installs it: `pip install .` into a fresh
virtual environment, and the core suite run against a repaired wheel with the system's copies of the libraries
it bundles hidden from the loader.

Not a test module: build_addon.py imports it (driver()) and passes itself as `driver`, for its run, say,
Failure and helpers; this file holds only what is particular to these legs.
"""
from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest_runs

# Shared libraries of the manylinux policy (every Linux system has them): never hidden.
SYSTEM_LIBRARIES = ("linux-vdso", "ld-linux", "libc.so", "libm.so", "libdl.so", "libpthread.so", "librt.so",
                    "libstdc++.so", "libgcc_s.so", "libutil.so")

# Runs in the fresh virtual environment after `pip install .`: nfield comes from there and solves.
_PIP_CHECK = r"""
import sys, nfield, nfield.core as core
assert "site-packages" in nfield.__file__, nfield.__file__
mesh = core.Mesh.from_file(sys.argv[1])
field = core.solve(mesh, n=4)
print("solved", field.directions.shape, "from", nfield.__file__)
"""


def fresh_venv(driver, name: str, version: tuple[int, int]) -> Path:
    """An empty virtual environment build/venvs/<name> of that Python (made anew); returns its python."""
    base = driver.find_interpreter(version)
    if base is None:
        raise driver.Failure(f"no CPython {'%d.%d' % version} on this machine")
    folder = driver.BUILD_ROOT / "venvs" / name
    shutil.rmtree(folder, ignore_errors=True)
    driver.run([base, "-m", "venv", folder])
    return folder / "bin" / "python"


def pip_install(driver, python: Path, *requirements) -> None:
    driver.run([python, "-m", "pip", "install", "--disable-pip-version-check", "--progress-bar", "off",
                "--no-input", *requirements], cwd=python.parent)


def pip_install_check(driver, env) -> tuple[bool, str]:
    """`pip install .` into a fresh virtual environment (pip's own build: an isolated build environment and
    the build directory of pyproject.toml), then the command line, `python -m nfield` and a solve there."""
    python = fresh_venv(driver, f"pip-cp{env.version.replace('.', '')}", env.python)
    start = time.monotonic()
    pip_install(driver, python, str(driver.ROOT))
    seconds = time.monotonic() - start
    sphere = driver.ROOT / "tests" / "data" / "sphere.obj"
    clean = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    driver.run([python.parent / "nfield", "--help"], env=clean, cwd=python.parent, capture=True)
    driver.run([python, "-m", "nfield", "info", sphere], env=clean, cwd=python.parent, capture=True)
    driver.run([python, "-c", _PIP_CHECK, sphere], env=clean, cwd=python.parent)
    return True, f"pip install . {seconds:.0f} s; nfield --help, python -m nfield info, nfield.core.solve"


def hide_system_libraries(driver, module: Path) -> list[str]:
    """A command prefix that runs a command with the shared libraries `module` links from the system (those
    auditwheel bundles) hidden from the loader: in a private mount namespace (`unshare --mount` as root;
    `--map-root-user` otherwise) an empty file is bind-mounted over each of them. Before the command it
    checks that the hiding works: loading `module` itself must fail there (NFIELD_HIDING_PROBE)."""
    libs = []
    for line in driver.run(["ldd", module], capture=True, quiet=True).stdout.splitlines():
        parts = line.split()
        if len(parts) >= 3 and parts[1] == "=>" and not parts[0].startswith(SYSTEM_LIBRARIES):
            libs.append(str(Path(parts[2]).resolve()))
    if not any("cholmod" in lib for lib in libs):
        raise driver.Failure(f"ldd {module} lists no CHOLMOD: {libs}")
    empty = driver.BUILD_ROOT / "hidden-library"
    empty.write_bytes(b"")
    script = ('set -e; empty=$0; while [ "$1" != -- ]; do mount --bind "$empty" "$1"; shift; done; shift; '
              'if "$1" -c "import ctypes, sys; ctypes.CDLL(sys.argv[1])" "$NFIELD_HIDING_PROBE" 2>/dev/null; '
              'then echo "the system libraries are not hidden: $NFIELD_HIDING_PROBE loads"; exit 97; fi; '
              'echo "hidden from the loader in this mount namespace: the system copies of the bundled libraries"; '
              'exec "$@"')
    unshare = ["unshare", "--mount"] + ([] if os.geteuid() == 0 else ["--map-root-user"])
    return [*unshare, "sh", "-c", script, str(empty), *libs, "--"]


def core_suite_from_wheel(driver, env, wheel: Path, dev_module: Path) -> tuple[bool, str]:
    """The core suite under env's Python against `wheel` installed into a fresh virtual environment (with
    NumPy and the test requirements only), the system's copies of the libraries the wheel bundles hidden
    (dev_module, the development build linked against them, must then fail to load)."""
    python = fresh_venv(driver, f"wheel-cp{env.version.replace('.', '')}", env.python)
    numpy = [r for r in env.requirements if r.startswith("numpy")]
    pip_install(driver, python, str(wheel), *numpy, *driver.TEST_REQUIREMENTS)
    run_env = dict(pytest_runs.installed_env(), NFIELD_HIDING_PROBE=str(dev_module))
    args = ["tests", *pytest_runs.PYTEST_WORKERS, *pytest_runs.CORE_SELECTION]
    return pytest_runs.run_pytest(driver, python, args, env=run_env, wrapper=hide_system_libraries(driver, dev_module))
