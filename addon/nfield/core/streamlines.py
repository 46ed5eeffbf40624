"""Hatching strokes: evenly spaced streamlines of a designed field (native tracer, see streamlines.hpp).

    from nfield.core import Mesh, solve, trace_streamlines
    mesh = Mesh.from_file("stanford-bunny.obj")
    field = solve(mesh, n=2, order=2, align="curvature-max")
    strokes = trace_streamlines(mesh, field, spacing=0.01)   # 1% of the bounding-box diagonal
    strokes.points[0]      # (k, 3) polyline on the surface

The field is constant per triangle, so inside a triangle a stroke is a straight segment; at an edge it
continues along the neighbour's direction closest to the transported incoming one (no flips). Strokes are
evenly spaced in the spirit of Jobard & Lefer: neighbouring strokes are about ``spacing`` apart, and a
stroke stops when it comes closer than half the spacing to another one, at boundaries, next to
singularities and where the field vanishes.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field as dc_field
from typing import Any

import numpy as np

from ._loader import native
from .mesh import Mesh
from .solve import FieldResult

__all__ = ["Strokes", "trace_streamlines"]


@dataclass
class Strokes:
    """Strokes traced on a mesh.

    Attributes
    ----------
    points : list of float (k, 3) arrays, one polyline per stroke, on the surface (mesh units).
    faces : list of int (k,) arrays: faces[s][i] is the triangle (of ``mesh.native``) containing the segment
        points[s][i] -> points[s][i+1] (for the last point, the triangle it lies in). Points where a stroke
        crosses an edge lie on both triangles of the edge.
    families : list of int, 0 for the main family, 1 for the cross-hatching family.
    lengths : list of float, stroke lengths (mesh units).
    separation : the separation distance d_sep in mesh units (``spacing`` times the bounding-box diagonal).
    test_distance : d_test = 0.5 d_sep: strokes of one family never come closer than this at sample points
        (times 1 / max(density, 0.1) where a density is given).
    step : the sample spacing along strokes (0.2 d_sep; shorter where a stroke crosses an edge).
    stats : the tracer's counters (num_points, num_strokes, num_discarded, num_candidates,
        num_blocked_faces, num_singularities, truncated, coverage per family).
    seconds : wall time of the tracing.
    """

    points: list
    faces: list
    families: list
    lengths: list
    separation: float
    test_distance: float
    step: float
    n: int
    seed: int
    stats: dict = dc_field(default_factory=dict)
    seconds: float = 0.0

    @property
    def num_strokes(self) -> int:
        return len(self.points)

    @property
    def num_points(self) -> int:
        return int(sum(len(p) for p in self.points))

    @property
    def total_length(self) -> float:
        return float(sum(self.lengths))

    def to_dict(self, include_points: bool = True) -> dict:
        """JSON-friendly dict (plain lists; points and faces only with include_points)."""
        d: dict[str, Any] = {
            "num_strokes": self.num_strokes,
            "num_points": self.num_points,
            "total_length": self.total_length,
            "separation": float(self.separation),
            "test_distance": float(self.test_distance),
            "step": float(self.step),
            "n": int(self.n),
            "seed": int(self.seed),
            "seconds": float(self.seconds),
            "stats": {k: (list(v) if isinstance(v, (list, tuple)) else v) for k, v in self.stats.items()},
            "families": [int(f) for f in self.families],
            "lengths": [float(x) for x in self.lengths],
        }
        if include_points:
            d["points"] = [np.asarray(p, dtype=float).tolist() for p in self.points]
            d["faces"] = [np.asarray(f, dtype=int).tolist() for f in self.faces]
        return d


def _positive(value: Any, name: str, allow_none: bool = False) -> float | None:
    if value is None and allow_none:
        return None
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return v


def _density(mesh: Mesh, density: Any) -> tuple[np.ndarray | None, bool]:
    """Per-vertex or per-input-face density in [0, 1] -> (array for the native mesh, per_vertex)."""
    if density is None:
        return None, True
    d = np.asarray(density, dtype=np.float64)
    if d.ndim != 1:
        raise ValueError(f"density must be a 1-D array (one value per vertex or per face), got shape {d.shape}")
    if not np.all(np.isfinite(d)):
        raise ValueError("density values must be finite")
    if d.size and (d.min() < 0.0 or d.max() > 1.0):
        raise ValueError(f"density values must be in [0, 1], got range [{d.min():g}, {d.max():g}]")
    nv, nf = mesh.num_vertices, mesh.num_faces
    if d.shape[0] == nv:  # per vertex wins when V == F (documented)
        return np.ascontiguousarray(d), True
    if d.shape[0] == nf:
        return np.ascontiguousarray(d[mesh.triangle_face]), False
    raise ValueError(f"density must have one value per vertex ({nv}) or per face ({nf}), got {d.shape[0]}")


def trace_streamlines(mesh: Mesh, field: FieldResult, spacing: float = 0.01, family: int = 0,
                      cross_hatch: bool = False, max_length: float | None = None,
                      min_length: float | None = None, seed: int = 0, density: Any = None,
                      max_points: int = 5_000_000) -> Strokes:
    """Evenly spaced strokes following `field` on `mesh`.

    Parameters
    ----------
    mesh : the Mesh the field was solved on.
    field : a FieldResult of that mesh (``solve``, ``smoothest_field``, a session layer's result).
    spacing : separation between neighbouring strokes as a fraction of the bounding-box diagonal, in
        (0, 1]; d_sep = spacing * diagonal (mesh units).
    family : which of the n directions strokes follow where a stroke starts without a neighbour
        (0..n-1; later strokes follow their neighbour's direction so a region keeps one family).
    cross_hatch : also trace the family rotated by 90 degrees (the other family of a 2- or 4-field;
        allowed for n = 1, 2, 4), family id 1.
    max_length : maximum stroke length as a fraction of the diagonal (None: unlimited).
    min_length : strokes shorter than this fraction of the diagonal are discarded (None: 2 * spacing).
    seed : integer >= 0; the same seed gives identical strokes.
    density : optional per-vertex or per-face array in [0, 1] modulating the spacing locally:
        d_sep(p) = d_sep / max(density(p), 0.1) (per-vertex values are interpolated inside triangles).
        An array whose length equals both counts is taken per vertex.
    max_points : hard cap on the total number of polyline points (about 100 bytes each while tracing);
        when reached, tracing stops and ``stats["truncated"]`` is True. Roughly
        area / (spacing^2 * diagonal^2 * 0.2) points are needed: ~70k for the bunny at 1%.

    Faces in the result are triangles of ``mesh.native`` (``mesh.triangle_face`` maps them to input faces).
    Raises ValueError for invalid arguments.
    """
    if not isinstance(mesh, Mesh):
        raise ValueError(f"mesh must be an nfield.core.Mesh, got {type(mesh).__name__}")
    if not isinstance(field, FieldResult):
        raise ValueError(f"field must be a FieldResult (from nfield.core.solve), got {type(field).__name__}")
    z = np.asarray(field.representation, dtype=np.complex128)
    if z.shape != (mesh.num_triangles,):
        raise ValueError(f"field has {z.shape[0] if z.ndim == 1 else z.shape} values but the mesh has "
                         f"{mesh.num_triangles} triangles: was it solved on this mesh?")
    spacing = _positive(spacing, "spacing")
    if spacing > 1.0:
        raise ValueError(f"spacing is a fraction of the bounding-box diagonal and must be <= 1, got {spacing}")
    if spacing < 1e-4:
        raise ValueError(f"spacing {spacing} is too small (minimum 1e-4 of the bounding-box diagonal)")
    n = int(field.n)
    if isinstance(family, bool) or not isinstance(family, (int, np.integer)) or not 0 <= int(family) < n:
        raise ValueError(f"family must be an integer in 0..{n - 1} for n = {n}, got {family!r}")
    if not isinstance(cross_hatch, (bool, np.bool_)):
        raise ValueError(f"cross_hatch must be True or False, got {cross_hatch!r}")
    if cross_hatch and n not in (1, 2, 4):
        raise ValueError(f"cross_hatch needs n = 1, 2 or 4 (the 90-degree family), got n = {n}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or int(seed) < 0 or int(seed) >= 2**64:
        raise ValueError(f"seed must be an integer in [0, 2**64), got {seed!r}")
    diag = float(mesh.native.bounding_box_diagonal)
    d_sep = spacing * diag
    max_len = _positive(max_length, "max_length", allow_none=True)
    min_len = 2.0 * spacing if min_length is None else float(min_length)
    if not math.isfinite(min_len) or min_len < 0:
        raise ValueError(f"min_length must be a finite number >= 0, got {min_length!r}")
    dens, per_vertex = _density(mesh, density)
    if isinstance(max_points, bool) or not isinstance(max_points, (int, np.integer)) or int(max_points) < 2:
        raise ValueError(f"max_points must be an integer >= 2, got {max_points!r}")

    nat = native()
    t0 = time.perf_counter()
    ops = nat.FieldOperators(mesh.native, n, field.weights)
    pts, fcs, fams, lens, stats = nat.trace_streamlines(
        ops, z, d_sep, family=int(family), cross_hatch=bool(cross_hatch),
        max_length=math.inf if max_len is None else max_len * diag, min_length=min_len * diag,
        seed=int(seed), density=dens, density_per_vertex=per_vertex, max_total_points=int(max_points))
    return Strokes(points=list(pts), faces=list(fcs), families=[int(f) for f in fams],
                   lengths=[float(x) for x in lens], separation=d_sep, test_distance=0.5 * d_sep,
                   step=0.2 * d_sep, n=n, seed=int(seed), stats=dict(stats), seconds=time.perf_counter() - t0)
