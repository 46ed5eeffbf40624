"""Session-level fixtures for the nfield tests.

Only the location of the public test meshes lives here (tests/data/, see tests/data/README.md).
Helpers: ``mesh_path(name)`` (plain function, ``from conftest import mesh_path``) and the
session fixture ``data_dir``.
"""
from __future__ import annotations

from pathlib import Path

import pytest

DATA_DIR = Path(__file__).resolve().parent / "data"

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


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The directory holding the test meshes (tests/data/)."""
    return DATA_DIR
