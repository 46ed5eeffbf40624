"""The sanitizer job of `build_addon.py sanitize` (docs/hardening.md): the core suite against a module built
with AddressSanitizer and UndefinedBehaviorSanitizer.

Not a test module: build_addon.py imports it (driver()) and passes itself as `driver`, for its run, say,
Failure and build helpers; this file holds only what is particular to the job.
"""
from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest_runs

# What the job runs: the core suite (no bpy, no Debian Blender) without the tests marked `slow` (the same code
# paths as the rest on 20k-70k face meshes, about 6x slower under ASan/UBSan) or `no_sanitizer` (they run no
# native code, or measure memory and address-space limits, which ASan changes).
SANITIZER_SELECTION = ["-m", "not blender and not gui and not slow and not no_sanitizer"]

# A line with one of these in the output of the sanitized run is a sanitizer report.
SANITIZER_REPORT_MARKERS = ("ERROR: AddressSanitizer", "SUMMARY: AddressSanitizer", "runtime error:",
                            "SUMMARY: UndefinedBehaviorSanitizer")


def build_sanitized_module(driver, python: str | None = None) -> Path:
    """The module built with -fsanitize=address,undefined (CMake option NFIELD_SANITIZE) into
    build/<interpreter>-asan/; never copied into addon/."""
    info = driver.interpreter_info(str(python or driver.VENV_PY))
    build_dir = driver.BUILD_ROOT / f"cp{info['tag']}-asan"
    driver.cmake_build(build_dir, {
        "CMAKE_BUILD_TYPE": "RelWithDebInfo",
        "NFIELD_SANITIZE": "ON",
        "NFIELD_BUILD_TESTS": "OFF",
        "Python_EXECUTABLE": info["path"],
        "pybind11_DIR": driver.pybind11_cmake_dir(),
    })
    module = build_dir / f"_native{info['ext_suffix']}"
    if not module.is_file():
        raise driver.Failure(f"the sanitizer build did not produce {module}")
    driver.say(f"sanitizer build (not copied into addon/): {module}")
    return module


def gcc_runtime(driver, name: str) -> str:
    """Absolute path of gcc's sanitizer runtime (libasan.so / libubsan.so), which the module links."""
    path = driver.run(["gcc", f"-print-file-name={name}"], capture=True, quiet=True).stdout.strip()
    if not os.path.isabs(path) or not os.path.exists(path):
        raise driver.Failure(f"gcc has no {name} (Debian: apt-get install gcc; it ships with gcc 12)")
    return path


def sanitizer_tree(driver, module: Path) -> Path:
    """A throw-away mirror of the repository layout next to the sanitizer build: addon/nfield (package
    sources plus the sanitized module, never the normal one) and tests/ (the test files; data/ and
    examples/ linked). The tests find addon/ relative to their own file, so they and the CLI subprocesses
    they start import the sanitized package, not the working copy's."""
    tree = module.parent / "pytree"
    shutil.rmtree(tree, ignore_errors=True)
    shutil.copytree(driver.PACKAGE_DIR, tree / "addon" / "nfield",
                    ignore=shutil.ignore_patterns("__pycache__", "_native*", "*.tmp"))
    shutil.copy2(module, tree / "addon" / "nfield" / module.name)
    (tree / "tests").mkdir()
    for path in (driver.ROOT / "tests").glob("*.py"):
        shutil.copy2(path, tree / "tests" / path.name)
    (tree / "tests" / "data").symlink_to(driver.ROOT / "tests" / "data")
    (tree / "examples").symlink_to(driver.ROOT / "examples")
    return tree


def sanitizer_env(driver, tree: Path, module: Path) -> dict:
    """Environment of the sanitized test run. Every ASan/UBSan report aborts the process that hit it
    (halt_on_error + abort_on_error, and the module is built with -fno-sanitize-recover=all): the pytest
    process then dies with SIGABRT, and a CLI subprocess that a test starts exits with -6, which no test
    expects. Leak detection is off: CPython does not free everything at exit by design, and those
    reports would drown any real one (the fuzzers keep LeakSanitizer on for the library)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(tree / "addon"), str(tree / "tests")])
    env["LD_PRELOAD"] = " ".join([gcc_runtime(driver, "libasan.so"), gcc_runtime(driver, "libubsan.so")])
    env["ASAN_OPTIONS"] = "detect_leaks=0:halt_on_error=1:abort_on_error=1:check_initialization_order=1"
    env["UBSAN_OPTIONS"] = "halt_on_error=1:abort_on_error=1:print_stacktrace=1"
    env["NFIELD_SANITIZED_MODULE"] = str(tree / "addon" / "nfield" / module.name)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


def is_sanitizer_report(line: str) -> bool:
    return any(marker in line for marker in SANITIZER_REPORT_MARKERS)


def run_sanitizer_job(driver, pytest_args: list[str]) -> int:
    """Builds the ASan/UBSan module and runs the core suite against it (see SANITIZER_SELECTION).
    Fails on a pytest failure (including the abort a report causes) or a report line in the output."""
    start = time.monotonic()
    module = build_sanitized_module(driver)
    built = time.monotonic()
    tree = sanitizer_tree(driver, module)
    # --capture=sys: pytest's default fd capture would swallow a report written to fd 2 by the runtime
    # (the process aborts before the captured text is shown); sys capture leaves fd 2 alone.
    cmd = [driver.VENV_PY, "-m", "pytest", "-p", "sanitized_module_check", "-p", "no:cacheprovider", "-q",
           "--capture=sys", "--durations=10", *pytest_runs.PYTEST_WORKERS, *SANITIZER_SELECTION, str(tree / "tests"), *pytest_args]
    code, reports = driver.run_teed(cmd, env=sanitizer_env(driver, tree, module), cwd=tree,
                                    keep=is_sanitizer_report)
    end = time.monotonic()
    driver.say(f"sanitizer job: build {built - start:.0f} s, tests {end - built:.0f} s, pytest exit {code}, "
               f"{len(reports)} sanitizer report line(s)")
    if reports:
        raise driver.Failure("sanitizer report(s) in the output above:\n  " + "\n  ".join(reports[:10]))
    if code != 0:
        how = f"killed by signal {-code} (a sanitizer abort?)" if code < 0 else f"exit {code}"
        raise driver.Failure(f"pytest under ASan/UBSan failed ({how})", 1)
    return 0
