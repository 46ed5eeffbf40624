"""pytest plugin for `build_addon.py sanitize`: refuse to run unless the sanitized module is the one loaded.

A sanitizer job that silently imported the normal build (from addon/, or through .venv's nfield-addon.pth)
would pass without checking anything. `build_addon.py sanitize` loads this plugin (-p) and names the
module it built in NFIELD_SANITIZED_MODULE; at session start the plugin imports nfield._native and stops
the run (exit 3) unless that exact file was imported and the ASan runtime is mapped into the process.
At the end it checks again, in case a test re-imported the package from elsewhere.
Not a test module (no test_ prefix): the normal test run never loads it.
"""
from __future__ import annotations

import os
import sys

import pytest


def _problem() -> str | None:
    expected = os.environ.get("NFIELD_SANITIZED_MODULE")
    if not expected:
        return "NFIELD_SANITIZED_MODULE is not set (run through `python3 build_addon.py sanitize`)"
    import nfield._native as native

    if not os.path.samefile(native.__file__, expected):
        return f"imported {native.__file__}, not the sanitized module {expected}"
    if sys.modules["nfield._native"] is not native:
        return "nfield._native was replaced during the run"
    with open("/proc/self/maps") as maps:
        if "libasan" not in maps.read():
            return "the AddressSanitizer runtime is not loaded (LD_PRELOAD missing?)"
    return None


def pytest_sessionstart(session):
    problem = _problem()
    if problem:
        pytest.exit(f"sanitizer run misconfigured: {problem}", returncode=3)
    print(f"\n[sanitized module] {os.environ['NFIELD_SANITIZED_MODULE']}", flush=True)


def pytest_sessionfinish(session, exitstatus):
    problem = _problem()
    if problem:
        print(f"sanitizer run misconfigured: {problem}", file=sys.stderr, flush=True)
        session.exitstatus = 3
