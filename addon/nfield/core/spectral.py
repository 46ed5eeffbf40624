"""Spectral reduction (paper section 8): the eigenbasis, its disk cache, and low-pass filtering (no bpy).

The first k eigenfields of the n-field Laplacian (S z = lambda M z) take minutes to compute on a large mesh,
so they are cached on disk. A cache file is named by ``nfield._native.basis_cache_key`` (mesh content hash,
n, edge weights, number of unknowns, k, precision) and its header repeats that key: a file computed for
another mesh (the user edited it), another n or other weights is never used, and a truncated or corrupt file
is recomputed. A cached basis with more eigenpairs than asked for is truncated instead of recomputed
(the first k' eigenpairs of a basis are the basis of size k').

Where the cache lives: ``cache_dir`` argument, else ``$NFIELD_CACHE_DIR``, else
``$XDG_CACHE_HOME/nfield/bases`` (``~/.cache/nfield/bases``). ``cache_dir=False`` disables it.

Memory: k vectors of one complex value per face, 8 bytes each in single precision ("single", the default)
and 16 in "double" (e.g. 69k faces, k = 500: 265 MB / 530 MB). Single precision changes the reduced
solution by ~3e-7 relative (bench/results/spectral.md: largest direction change 0.002 degrees, six orders
below the reduction error) and halves both the memory and the reconstruction time; "double" is for
comparisons with the exact solver at full precision.
"""
from __future__ import annotations

import os
import re
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ._loader import native
from .solve import _check_int

DEFAULT_K = 500
DEFAULT_PRECISION = "single"
PRECISIONS = ("double", "single")
CACHE_SUFFIX = ".nfb"

ProgressCallback = Callable[[float], Any]


@dataclass(frozen=True)
class BasisInfo:
    """Where a basis came from: source is "computed", "cache" or "cache (truncated from k=...)"."""

    k: int
    precision: str
    source: str
    seconds: float
    memory_bytes: int
    path: Path | None


def default_cache_dir() -> Path:
    env = os.environ.get("NFIELD_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "nfield" / "bases"


def check_k(k: Any, num_unknowns: int | None = None) -> int:
    """k as an int >= 1 (and at most the number of field unknowns when given)."""
    k = _check_int(k, "k (number of eigenfields)", 1)
    if num_unknowns is not None and k > num_unknowns:
        raise ValueError(f"k={k} eigenfields is more than the mesh's {num_unknowns} field unknowns "
                         f"(one per non-degenerate face): choose k <= {num_unknowns}")
    return k


def check_precision(precision: str) -> str:
    if precision not in PRECISIONS:
        raise ValueError(f"unknown basis precision {precision!r} (expected 'double' or 'single')")
    return precision


def _cache_dir(cache_dir) -> Path | None:
    if cache_dir is False:
        return None
    return Path(cache_dir) if cache_dir is not None else default_cache_dir()


def basis_path(ops, k: int, precision: str = "double", cache_dir=None) -> Path | None:
    """The cache file of a basis of k eigenpairs of `ops` (None when the cache is disabled)."""
    d = _cache_dir(cache_dir)
    if d is None:
        return None
    return d / (native().basis_cache_key(ops, int(k), check_precision(precision)) + CACHE_SUFFIX)


def _larger_cached(ops, k: int, precision: str, directory: Path) -> list[tuple[int, Path]]:
    """Cached bases of the same operators with more than k eigenpairs, smallest first."""
    key = native().basis_cache_key(ops, k, precision)
    m = re.fullmatch(r"(.*-k)\d+(-[^-]+)", key)
    if m is None or not directory.is_dir():
        return []
    found = []
    for p in directory.glob(f"{m.group(1)}*{m.group(2)}{CACHE_SUFFIX}"):
        km = re.fullmatch(re.escape(m.group(1)) + r"(\d+)" + re.escape(m.group(2) + CACHE_SUFFIX), p.name)
        if km and int(km.group(1)) > k:
            found.append((int(km.group(1)), p))
    return sorted(found)


def cached_basis_path(ops, k: int, precision: str = "double", cache_dir=None) -> Path | None:
    """The cache file load_or_compute_basis would read (exact k, else the smallest larger k), or None.
    Only the file name is checked, not its content (load validates that)."""
    directory = _cache_dir(cache_dir)
    if directory is None:
        return None
    path = basis_path(ops, k, precision, cache_dir)
    if path is not None and path.is_file():
        return path
    larger = _larger_cached(ops, int(k), check_precision(precision), directory)
    return larger[0][1] if larger else None


def load_or_compute_basis(ops, k: int = DEFAULT_K, precision: str = "single", cache_dir=None,
                          progress: ProgressCallback | None = None, tolerance: float = 1e-10):
    """The basis of k eigenpairs of `ops`: from the disk cache when a valid file exists, else computed
    (progress(fraction) is called; returning False cancels with nfield.core.Cancelled) and saved.

    Returns (basis, BasisInfo). ValueError for an impossible k; a cache that cannot be written only warns
    (the basis is still returned)."""
    nat = native()
    k = check_k(k, int(ops.mesh.num_active_faces))
    precision = check_precision(precision)
    t0 = time.perf_counter()
    directory = _cache_dir(cache_dir)
    path = basis_path(ops, k, precision, cache_dir)
    if path is not None and path.is_file():
        try:
            basis = nat.SpectralBasis.load(str(path), ops, k, precision)
            return basis, BasisInfo(k, precision, "cache", time.perf_counter() - t0, basis.memory_bytes, path)
        except ValueError as e:  # stale or corrupt: recompute below (and overwrite it)
            warnings.warn(f"ignoring the cached spectral basis {path.name}: {e}", RuntimeWarning, stacklevel=2)
    if directory is not None:
        for big_k, big_path in _larger_cached(ops, k, precision, directory):
            try:
                basis = nat.SpectralBasis.load(str(big_path), ops, big_k, precision).truncated(k)
            except ValueError:
                continue
            return basis, BasisInfo(k, precision, f"cache (truncated from k={big_k})", time.perf_counter() - t0,
                                    basis.memory_bytes, big_path)
    basis = nat.SpectralBasis.compute(ops, k, precision, progress, tolerance)
    seconds = time.perf_counter() - t0
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            basis.save(str(path))
        except (OSError, ValueError) as e:
            warnings.warn(f"could not write the spectral basis cache {path}: {e}", RuntimeWarning, stacklevel=2)
            path = None
    return basis, BasisInfo(k, precision, "computed", seconds, basis.memory_bytes, path)


def low_pass(ops, basis, field):
    """U U^H M field: the projection of a per-triangle complex field onto the first k eigenfields.

    This is the paper's low-pass filter: the result keeps the field's large-scale structure and drops
    variations finer than the k-th eigenfield's wavelength."""
    import numpy as np

    return np.asarray(native().low_pass(ops, basis, np.asarray(field, dtype=np.complex128)))
