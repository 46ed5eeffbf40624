"""The legs of `build_addon.py test` (the whole suite) and `test --quick` (the inner loop).

Not a test module: build_addon.py imports it (driver()) and passes itself as `driver`, for its set-up, build,
packaging and run helpers; this file holds the order of the legs, how each is run and how they are reported.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import fuzz_run
import installed_package
from pytest_runs import BLENDER_SELECTION, GUI_SELECTION, PYTEST_WORKERS, QUICK_SELECTION, installed_env, run_pytest

class Legs:
    """The legs of a test run, each timed; `summary()` prints one line per leg (ok/FAILED, what, time)."""

    def __init__(self, driver):
        self.driver = driver
        self.rows: list[tuple[str, bool, str]] = []

    def run(self, title: str, job) -> bool:
        """Runs job() -> (ok, detail) or raises the driver's Failure; records the outcome and its wall time."""
        start = time.monotonic()
        try:
            ok, detail = job()
        except self.driver.Failure as exc:
            print(f"build_addon: error: {exc}", file=sys.stderr, flush=True)
            ok, detail = False, "FAILED"
        self.rows.append((title, ok, f"{detail} in {time.monotonic() - start:.0f} s"))
        return ok

    def skip(self, title: str, reason: str) -> None:
        self.rows.append((title, True, f"skipped: {reason}"))

    def summary(self) -> bool:
        self.driver.say("summary:")
        for title, ok, detail in self.rows:
            self.driver.say(f"  {'ok    ' if ok else 'FAILED'}  {title}: {detail}")
        return all(ok for _, ok, _ in self.rows)


def run_test_command(driver, pytest_args: list[str]) -> int:
    """The whole test suite, leg by leg: set-up, builds, wheels and zips, C++ tests, `pip install .` under
    each Python, the core suite under each Python from its repaired wheel, the headless Blender suite under
    each bpy release from the extension zip, the real-window tests, then the sanitizer job and a short fuzz
    run. `--quick` first: the inner loop instead. Other pytest arguments: only `pytest tests <args>` in .venv
    (plus the hardening jobs unless NFIELD_SKIP_HARDENING=1)."""
    if pytest_args[:1] == ["--"]:  # `build_addon.py test -- -k foo`: the separator is not for pytest
        pytest_args = pytest_args[1:]
    if pytest_args[:1] == ["--quick"]:
        return run_quick_suite(driver, pytest_args[1:])
    legs = Legs(driver)
    legs.run("setup", lambda: (driver.cmd_setup() == 0, "done"))
    envs = driver.ready_envs()
    if not legs.run("build, wheels and zips", lambda: (driver.cmd_package(argparse.Namespace(python=None)) == 0,
                                                       f"Python {', '.join(e.version for e in envs if e.builds)}")):
        legs.summary()
        return 1
    if pytest_args:
        names_paths = any(not a.startswith("-") and Path(a.split("::")[0]).exists() for a in pytest_args)
        legs.run("pytest " + " ".join(pytest_args),
                 lambda: run_pytest(driver, driver.VENV_PY, ([] if names_paths else ["tests"]) + pytest_args))
        return run_hardening_jobs(driver, legs)
    main_env = driver.MAIN_ENV
    main_build = driver.BUILD_ROOT / ("cp%d%d-cp%d%d-linux_x86_64" % (*main_env.python, *main_env.python))
    if (main_build / "CTestTestfile.cmake").exists():  # C++ tests (native/tests/*.cpp); before pip's builds
        legs.run("C++ tests (ctest)", lambda: run_ctest(driver, main_build))
    for env in envs:
        if env.core_suite:
            legs.run(f"pip install . (Python {env.version})",
                     lambda env=env: installed_package.pip_install_check(driver, env))
    for env in envs:
        if env.core_suite:
            tag = "cp" + env.version.replace(".", "")
            wheel = next(driver.DIST.glob(f"nfield-*-{tag}-{tag}-manylinux_*.whl"))
            dev_module = driver.PACKAGE_DIR / f"_native.cpython-{tag[2:]}-x86_64-linux-gnu.so"
            legs.run(f"core suite, Python {env.version}, from {wheel.name} (system libraries hidden)",
                     lambda env=env, wheel=wheel, dev=dev_module:
                     installed_package.core_suite_from_wheel(driver, env, wheel, dev))
    for env in sorted(envs, key=lambda e: [int(x) for x in e.bpy.split(".")]):
        legs.run(f"headless Blender suite, bpy {env.bpy} (Python {env.version}), extension zip",
                 lambda env=env: run_pytest(driver, env.python_path, ["tests", *BLENDER_SELECTION],
                                            env=installed_env()))
    for env in (e for e in driver.ALL_ENVS if e not in envs):
        legs.skip(f"Python {env.version} legs (bpy {env.bpy})", f"no CPython {env.version} on this machine")
    legs.run("Debian Blender 3.4 (real window, legacy zip)",
             lambda: run_pytest(driver, driver.VENV_PY, ["tests", *GUI_SELECTION], env=installed_env()))
    return run_hardening_jobs(driver, legs)


def run_quick_suite(driver, pytest_args: list[str]) -> int:
    """The inner loop (about a minute): build for .venv's Python only, the C++ tests, and the core suite
    without the `slow` tests; no wheels, no zip, no Blender, no hardening jobs."""
    legs = Legs(driver)
    legs.run("setup", lambda: (driver.cmd_setup() == 0, "done"))
    module = driver.build()
    if (module.parent / "CTestTestfile.cmake").exists():
        legs.run("C++ tests (ctest)", lambda: run_ctest(driver, module.parent))
    legs.run("core suite without slow tests, Python %s" % driver.MAIN_ENV.version,
             lambda: run_pytest(driver, driver.VENV_PY, ["tests", "-q", *PYTEST_WORKERS, *QUICK_SELECTION,
                                                         *pytest_args]))
    return 0 if legs.summary() else 1


def run_ctest(driver, build_dir: Path) -> tuple[bool, str]:
    """The C++ unit tests (native/tests/*.cpp) of one build directory."""
    proc = driver.run(["ctest", "--test-dir", build_dir, "--output-on-failure"], check=False)
    return proc.returncode == 0, "ctest"


def run_hardening_jobs(driver, legs: Legs) -> int:
    """After the pytest legs: the sanitizer job and a short fuzz run (docs/hardening.md), each timed, then
    the summary of every leg. Runs even when a leg failed, so one CI run reports everything.
    NFIELD_SKIP_HARDENING=1 skips both (fast local iteration; CI never sets it)."""
    if os.environ.get("NFIELD_SKIP_HARDENING", "") not in ("", "0"):
        driver.say("NFIELD_SKIP_HARDENING is set: skipping the sanitizer job and the fuzz run")
    else:
        seconds = fuzz_run.FUZZ_SECONDS_IN_TEST
        legs.run("sanitizer job (ASan/UBSan pytest)", lambda: (driver.cmd_sanitize([]) == 0, "passed"))
        legs.run(f"fuzz run ({seconds} s per target)",
                 lambda: (driver.cmd_fuzz(argparse.Namespace(seconds=seconds, targets=[])) == 0, "passed"))
    return 0 if legs.summary() else 1
