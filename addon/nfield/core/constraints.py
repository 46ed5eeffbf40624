"""Constraint types and the JSON constraint files of the command line.

File formats (a JSON list of objects, one constraint each):
  direction constraints  ``[{"face": 12, "direction": [x, y, z]}, ...]``
  vector constraints     ``[{"face": 3, "vector": [x, y, z]}, ...]``
  singularities          ``[{"vertex": 7, "index": 0.25}, ...]``
3D vectors are in the mesh's coordinates; they are projected onto the face's tangent plane. Face indices
refer to the input faces (polygons for polygon meshes). Mesh-dependent checks (range, excluded faces,
tangency, multiples of 1/n) happen in :func:`nfield.core.solve`.
"""
from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from typing import Any, Iterable

__all__ = [
    "DirectionConstraint",
    "VectorConstraint",
    "SingularityConstraint",
    "Constraint",
    "load_constraints",
    "constraint_from_dict",
]


def _index(value: Any, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        # accept numpy integers and integral floats from JSON-ish sources
        try:
            import numpy as np

            if isinstance(value, np.integer):
                return _index(int(value), what)
        except ImportError:  # pragma: no cover
            pass
        if isinstance(value, float) and value.is_integer():
            return _index(int(value), what)
        raise ValueError(f"{what} must be a non-negative integer, got {value!r}")
    if value < 0:
        raise ValueError(f"{what} must be a non-negative integer, got {value}")
    return int(value)


def _real(value: Any, must: str) -> float:
    """float(value); ValueError "<must>, got <value>" for a bool or anything float() refuses."""
    if isinstance(value, bool):
        raise ValueError(f"{must}, got {value!r}")
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{must}, got {value!r}") from None


def _vec3(value: Any, what: str) -> tuple[float, float, float]:
    try:
        items = list(value)
    except TypeError:
        raise ValueError(f"{what} must be a list of 3 numbers [x, y, z], got {value!r}") from None
    if len(items) != 3:
        raise ValueError(f"{what} must have 3 components [x, y, z], got {len(items)}")
    out = []
    for c in items:
        if isinstance(c, bool) or isinstance(c, str):
            raise ValueError(f"{what} must hold numbers, got {c!r}")
        try:
            x = float(c)
        except (TypeError, ValueError):
            raise ValueError(f"{what} must hold numbers, got {c!r}") from None
        if not math.isfinite(x):
            raise ValueError(f"{what} has a non-finite component: {c!r}")
        out.append(x)
    return (out[0], out[1], out[2])


@dataclass(frozen=True)
class DirectionConstraint:
    """Hard constraint: one of the n directions of `face` points along `direction` (projected to the face).

    Only the direction counts (its length is ignored). The n-direction spline (paper eq. 12) is solved.
    """

    face: int
    direction: tuple[float, float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "face", _index(self.face, "constraint face"))
        object.__setattr__(self, "direction", _vec3(self.direction, f"direction of the constraint on face {self.face}"))


@dataclass(frozen=True)
class VectorConstraint:
    """Hard constraint: the n-vector of `face` equals `vector` (projected; its length is kept), eq. 11."""

    face: int
    vector: tuple[float, float, float]

    def __post_init__(self) -> None:
        object.__setattr__(self, "face", _index(self.face, "constraint face"))
        object.__setattr__(self, "vector", _vec3(self.vector, f"vector of the constraint on face {self.face}"))


@dataclass(frozen=True)
class SingularityConstraint:
    """Hard constraint: interior vertex `vertex` is a singularity of index `index` (a multiple of 1/n)."""

    vertex: int
    index: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "vertex", _index(self.vertex, "singularity vertex"))
        idx = self.index
        if isinstance(idx, bool) or isinstance(idx, str):
            raise ValueError(f"index of the singularity at vertex {self.vertex} must be a number, got {idx!r}")
        try:
            x = float(idx)
        except (TypeError, ValueError):
            raise ValueError(f"index of the singularity at vertex {self.vertex} must be a number, "
                             f"got {idx!r}") from None
        if not math.isfinite(x):
            raise ValueError(f"index of the singularity at vertex {self.vertex} is not finite: {idx!r}")
        object.__setattr__(self, "index", x)


Constraint = DirectionConstraint | VectorConstraint | SingularityConstraint

_SCHEMAS = {
    "direction": (DirectionConstraint, ("face", "direction")),
    "vector": (VectorConstraint, ("face", "vector")),
    "singularity": (SingularityConstraint, ("vertex", "index")),
}
_EXAMPLES = {
    "direction": '[{"face": 12, "direction": [1.0, 0.0, 0.0]}]',
    "vector": '[{"face": 3, "vector": [1.0, 0.0, 0.0]}]',
    "singularity": '[{"vertex": 7, "index": 0.25}]',
}


def _kind_of(keys: Iterable[str]) -> str | None:
    keys = set(keys)
    for kind, (_, fields) in _SCHEMAS.items():
        if fields[1] in keys:
            return kind
    return None


def constraint_from_dict(entry: Any, kind: str | None = None, where: str = "constraint") -> Constraint:
    """Build a constraint from one JSON object. `kind` ("direction" | "vector" | "singularity") enforces a
    type; None infers it from the keys. Raises ValueError naming the problem."""
    if kind is not None and kind not in _SCHEMAS:
        raise ValueError(f"unknown constraint kind {kind!r} (expected one of {', '.join(_SCHEMAS)})")
    if not isinstance(entry, dict):
        raise ValueError(f"{where}: expected a JSON object like {_EXAMPLES[kind or 'direction']}, "
                         f"got {type(entry).__name__} {json.dumps(entry)[:60]}")
    found = _kind_of(entry.keys())
    if found is None:
        expected = (" and ".join(f'"{k}"' for k in _SCHEMAS[kind][1])) if kind else \
            '"face" and "direction", "face" and "vector", or "vertex" and "index"'
        raise ValueError(f"{where}: expected keys {expected}, got {sorted(entry.keys())}")
    if kind is not None and found != kind:
        raise ValueError(f"{where}: this file holds {kind} constraints like {_EXAMPLES[kind]}, "
                         f"but the entry is a {found} constraint")
    cls, fields = _SCHEMAS[found]
    missing = [k for k in fields if k not in entry]
    if missing:
        raise ValueError(f"{where}: missing key {', '.join(repr(k) for k in missing)}")
    unknown = sorted(set(entry) - set(fields))
    if unknown:
        raise ValueError(f"{where}: unknown key {', '.join(repr(k) for k in unknown)} "
                         f"(a {found} constraint has keys {', '.join(repr(k) for k in fields)})")
    try:
        return cls(*(entry[k] for k in fields))
    except ValueError as exc:
        raise ValueError(f"{where}: {exc}") from None


def load_constraints(path: str | os.PathLike, kind: str | None = None) -> list[Constraint]:
    """Read a constraint JSON file (see the module docstring) and return the constraints in file order.

    `kind` ("direction" | "vector" | "singularity") requires every entry to be of that type; None accepts
    any mix. Raises ValueError (missing/unreadable file, invalid JSON, wrong schema) naming file and entry.
    """
    p = os.fspath(path)
    try:
        with open(p, "r", encoding="utf-8") as fh:
            text = fh.read()
    except FileNotFoundError:
        raise ValueError(f"constraint file not found: {p}") from None
    except IsADirectoryError:
        raise ValueError(f"constraint path is a directory, not a file: {p}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read constraint file {p}: {exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"constraint file {p} is not valid JSON: {exc.msg} at line {exc.lineno} "
                         f"column {exc.colno}") from None
    if not isinstance(data, list):
        raise ValueError(f"constraint file {p} must contain a JSON list of objects like "
                         f"{_EXAMPLES[kind or 'direction']}, got a JSON {_json_type(data)}")
    return [constraint_from_dict(e, kind, where=f"{p}: entry {i}") for i, e in enumerate(data)]


def _json_type(x: Any) -> str:
    if isinstance(x, dict):
        return "object"
    if isinstance(x, str):
        return "string"
    if isinstance(x, bool):
        return "boolean"
    if isinstance(x, (int, float)):
        return "number"
    if x is None:
        return "null"
    return type(x).__name__
