"""Lazy access to the compiled module ``nfield._native``.

Importing :mod:`nfield` or :mod:`nfield.core` never loads the compiled module; it is imported the first
time a computation needs it, through :func:`native`. If that fails (module missing, built for another
Python, missing shared library) the ImportError says which Python is running, which compiled files are
in the package folder, and how to rebuild.
"""
from __future__ import annotations

import importlib
import os
import re
import sys
from types import ModuleType

__all__ = ["native", "NativeModuleError"]

_module: ModuleType | None = None

# "_native.cpython-311-x86_64-linux-gnu.so", "_native.cp311-win_amd64.pyd", "_native.cpython-311d-darwin.so"
_TAG = re.compile(r"(?:cpython-|cp)(\d)(\d+)")


#: OpenBLAS keeps its worker threads spinning for 2^28 cycles (~0.1 s) after each parallel call by default: after a
#: factorization that is up to 0.1 s of a second core burnt while the rest of the solve and the caller run (on a
#: shared or busy machine it also slows them down). With 2^16 cycles (~30 us) they stay awake for calls in quick
#: succession (those of one supernode) and sleep right after a factorization (measured on the bunny, order 2: 10-20 %
#: less CPU time for a factorization, wall time unchanged within the noise). OpenBLAS reads it once, when it loads;
#: a value the user set is kept.
_OPENBLAS_THREAD_TIMEOUT = "16"


class NativeModuleError(ImportError):
    """The compiled module nfield._native could not be imported (message says why and how to fix)."""


def _package_name() -> str:
    # __package__ is "nfield.core" (or "<copy>.nfield.core" for a copy of the package under another name).
    return (__package__ or "nfield.core").rpartition(".")[0] or "nfield"


def _package_dir() -> str:
    return os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _built_for(filename: str) -> str | None:
    m = _TAG.search(filename)
    return f"{m.group(1)}.{m.group(2)}" if m else None


def _describe_failure(exc: BaseException) -> str:
    folder = _package_dir()
    try:
        found = sorted(f for f in os.listdir(folder) if f.startswith("_native"))
    except OSError:
        found = []
    here = f"{sys.version_info.major}.{sys.version_info.minor}"
    rebuild = (f"reinstall nfield for this Python (pip install), or in a checkout run build_addon.py build "
               f"--python {sys.executable}")
    versions = sorted({v for v in (_built_for(f) for f in found) if v}, key=lambda v: tuple(map(int, v.split("."))))
    if not found:
        what = f"no compiled module (_native*.so / _native*.pyd) is in {folder}; this is Python {here}"
    elif versions and here not in versions:
        what = (f"it was built for Python {', '.join(versions)}; this is Python {here} "
                f"(files in {folder}: {', '.join(found)})")
    else:
        what = (f"files in {folder}: {', '.join(found)} (built for Python {', '.join(versions) or 'unknown'}; "
                f"this is Python {here})")
    return f"nfield's compiled module nfield._native cannot be imported ({exc}): {what}: {rebuild}"


def native() -> ModuleType:
    """Return the compiled module ``nfield._native``, importing it on first use.

    Raises NativeModuleError (an ImportError) with the interpreter version, the compiled files found and
    the rebuild command when it cannot be imported.
    """
    global _module
    if _module is None:
        os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", _OPENBLAS_THREAD_TIMEOUT)
        try:
            _module = importlib.import_module(_package_name() + "._native")
        except ImportError as exc:
            raise NativeModuleError(_describe_failure(exc)) from exc
    return _module
