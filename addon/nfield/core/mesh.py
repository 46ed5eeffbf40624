"""Triangle/polygon meshes for field design (wraps ``nfield._native.Mesh``).

Face numbering seen by users ("input faces"):
  * a mesh built from triangles (``Mesh(vertices, triangles)``) has one input face per triangle;
  * a mesh read from a file that contains polygons (OBJ quads, n-gons) is fan-triangulated by the reader;
    its input faces are the *polygons*. Constraints name polygons, and per-face output has one row per
    polygon, taken from the polygon's first triangle.
The native mesh and every native array work per triangle; :attr:`Mesh.face_to_polygon` maps triangle ->
input face and :attr:`Mesh.polygon_first_triangle` input face -> its first triangle.
"""
from __future__ import annotations

import os
from typing import Any

import numpy as np

from ._loader import native

__all__ = ["Mesh", "SUPPORTED_EXTENSIONS"]

SUPPORTED_EXTENSIONS = (".obj", ".off", ".ply")


class Mesh:
    """A validated triangle mesh plus the polygon structure it came from.

    Parameters
    ----------
    vertices : array_like (V, 3) of float
    faces : array_like (T, 3) of int, triangles (0-based vertex indices)
    face_to_polygon : optional array_like (T,) of int, the input polygon of each triangle (as produced by
        fan triangulation, triangles of one polygon in order). None: every triangle is its own input face.
    num_polygons : number of input polygons (default: max(face_to_polygon) + 1).
    source : optional file path the mesh was read from (informational).

    Raises ValueError naming the problem (wrong shape, NaN/inf coordinates, index out of range, empty mesh).
    Degenerate faces are not an error: they are *excluded* (listed in ``report["degenerate_faces"]``), get
    no field value and cannot carry constraints.
    """

    def __init__(self, vertices: Any, faces: Any, *, face_to_polygon: Any = None,
                 num_polygons: int | None = None, source: str | None = None) -> None:
        v = np.asarray(vertices)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f"vertices must be an array of shape (V, 3), got shape {v.shape}")
        if v.shape[0] == 0:
            raise ValueError("mesh has no vertices")
        if not (np.issubdtype(v.dtype, np.floating) or np.issubdtype(v.dtype, np.integer)):
            raise ValueError(f"vertices must be numbers, got dtype {v.dtype}")
        v = np.ascontiguousarray(v, dtype=np.float64)
        bad = ~np.isfinite(v).all(axis=1)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"vertex {i} has a non-finite coordinate (NaN or inf): {v[i].tolist()} "
                             f"({int(bad.sum())} such vertices)")

        f = np.asarray(faces)
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f"faces must be an array of shape (F, 3) (triangles), got shape {f.shape}")
        if f.shape[0] == 0:
            raise ValueError("mesh has no faces")
        if not np.issubdtype(f.dtype, np.integer):
            if np.issubdtype(f.dtype, np.floating) and np.all(np.isfinite(f)) and np.all(f == np.round(f)):
                f = f.astype(np.int64)
            else:
                raise ValueError(f"faces must hold integer vertex indices, got dtype {f.dtype}")
        if f.min() < 0 or f.max() >= v.shape[0]:
            bad_rows = np.flatnonzero(((f < 0) | (f >= v.shape[0])).any(axis=1))
            r = int(bad_rows[0])
            raise ValueError(f"face {r} has a vertex index out of range [0, {v.shape[0]}): {f[r].tolist()}")
        f = np.ascontiguousarray(f, dtype=np.int32)

        t = f.shape[0]
        if face_to_polygon is not None:
            ftp = np.asarray(face_to_polygon)
            if ftp.shape != (t,) or not np.issubdtype(ftp.dtype, np.integer):
                raise ValueError(f"face_to_polygon must be an integer array of shape ({t},), got "
                                 f"shape {ftp.shape} dtype {ftp.dtype}")
            ftp = ftp.astype(np.int64)
            npoly = int(num_polygons) if num_polygons is not None else int(ftp.max()) + 1
            if ftp.min() < 0 or ftp.max() >= npoly:
                raise ValueError(f"face_to_polygon has entries outside [0, {npoly})")
        else:
            if num_polygons is not None and int(num_polygons) != t:
                raise ValueError("num_polygons given without face_to_polygon")
            ftp = None
            npoly = t

        self.native = native().Mesh(v, f)
        self.vertices = v
        self.faces = f
        self.face_to_polygon = ftp
        self.num_polygons = npoly
        self.source = source
        if ftp is None:
            self._triangle_face = np.arange(t, dtype=np.int64)
            self._first_triangle = np.arange(t, dtype=np.int64)
        else:
            self._triangle_face = ftp
            first = np.full(npoly, -1, dtype=np.int64)
            # reversed assignment: the smallest triangle index of each polygon wins
            first[ftp[::-1]] = np.arange(t - 1, -1, -1, dtype=np.int64)
            self._first_triangle = first
        self._report: dict | None = None

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_file(cls, path: str | os.PathLike) -> "Mesh":
        """Read an OBJ, OFF or PLY file (polygons are fan-triangulated; see the module docstring).

        Raises FileNotFoundError if the file does not exist, ValueError for an unsupported extension or a
        malformed / invalid file (the message names the file and the problem).
        """
        p = os.fspath(path)
        if not os.path.exists(p):
            raise FileNotFoundError(f"mesh file not found: {p}")
        if os.path.isdir(p):
            raise IsADirectoryError(f"mesh path is a directory, not a file: {p}")
        ext = os.path.splitext(p)[1].lower()
        if ext not in SUPPORTED_EXTENSIONS:
            raise ValueError(f"unsupported mesh format '{ext or p}' for {p} (expected .obj, .off or .ply)")
        try:
            positions, triangles, triangle_polygon, num_polygons = native().read_mesh(p)
        except ValueError as exc:
            msg = str(exc)
            if os.path.basename(p) not in msg:
                msg = f"{p}: {msg}"
            raise ValueError(msg) from None
        try:
            return cls(positions, triangles, face_to_polygon=np.asarray(triangle_polygon),
                       num_polygons=int(num_polygons), source=p)
        except ValueError as exc:
            raise ValueError(f"{p}: {exc}") from None

    # ------------------------------------------------------------------ sizes
    @property
    def num_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def num_faces(self) -> int:
        """Number of input faces: polygons for a mesh read from a polygon file, else triangles."""
        return int(self.num_polygons)

    @property
    def num_triangles(self) -> int:
        return int(self.faces.shape[0])

    @property
    def has_polygons(self) -> bool:
        """True when input faces are not 1:1 with triangles."""
        return self.face_to_polygon is not None and not (
            self.num_polygons == self.num_triangles
            and np.array_equal(self.face_to_polygon, np.arange(self.num_triangles)))

    @property
    def report(self) -> dict:
        """The native mesh report (indices refer to triangles), JSON-friendly, with "summary" lines."""
        if self._report is None:
            self._report = _jsonable(self.native.report())
        return self._report

    # ------------------------------------------------------------------ face numbering
    @property
    def triangle_face(self) -> np.ndarray:
        """(T,) input face of each triangle."""
        return self._triangle_face

    @property
    def polygon_first_triangle(self) -> np.ndarray:
        """(num_faces,) first triangle of each input face (-1 if the polygon produced no triangle)."""
        return self._first_triangle

    def face_triangle(self, face: int) -> int:
        """The triangle that represents input face `face` (its first triangle). Raises ValueError."""
        if isinstance(face, bool) or not isinstance(face, (int, np.integer)):
            raise ValueError(f"face index must be an integer, got {face!r}")
        face = int(face)
        if not 0 <= face < self.num_faces:
            raise ValueError(f"face {face} is out of range: the mesh has {self.num_faces} faces "
                             f"(valid indices 0..{self.num_faces - 1})")
        t = int(self._first_triangle[face])
        if t < 0:
            raise ValueError(f"face {face} has no triangle (polygon with fewer than 3 vertices)")
        return t

    def per_face(self, per_triangle: np.ndarray) -> np.ndarray:
        """Take rows of a per-triangle array for each input face (first triangle; zeros if none)."""
        arr = np.asarray(per_triangle)
        idx = self._first_triangle
        if self.face_to_polygon is None:
            return arr.copy()
        out = np.zeros((idx.shape[0],) + arr.shape[1:], dtype=arr.dtype)
        ok = idx >= 0
        out[ok] = arr[idx[ok]]
        return out

    def __repr__(self) -> str:
        src = f", source={self.source!r}" if self.source else ""
        return (f"Mesh(vertices={self.num_vertices}, faces={self.num_faces}, "
                f"triangles={self.num_triangles}{src})")


def _jsonable(obj: Any) -> Any:
    """Convert numpy scalars/arrays and tuples recursively to plain JSON types (non-finite floats -> None)."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        x = float(obj)
        return x if np.isfinite(x) else None
    return obj
