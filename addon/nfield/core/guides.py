"""Guides: feature edges, curves, the comb, per-face weights and rotations, cuts and mirror symmetry (no bpy).

A design has one *base alignment* (``align``: principal curvature or a user field, as before) and any number
of further guide sources. They all end up in one guide field u' with one value per face; how they combine,
and why weight edits never refactor the n-direction solver, is explained in docs/guides.md. In short, for
the n-direction spline (the default) the alignment term is linear in u' (paper eq. 9), so several guides
simply add:

    u'_f = a_f e^{i n theta_f} u_base,f  +  s * ( w_feat * F_f  +  sum_curves w_c * C_f  +  w_comb * K_f )

where a_f is the per-face alignment weight (a painted attribute), theta_f the per-face rotation, F, C, K
the feature, curve and comb layers (weight times unit direction, |.| <= weight), and s the root mean square
magnitude of the base guide (1 without one), so that a guide weight of 1 pulls like a typical face of the
base guide. Hard features and hard curves become direction constraints instead (with the +d rule of user
constraints); where they contradict each other they are dropped and reported.

Lengths (curve width and tolerance, comb radius) are fractions of the mesh's bounding-box diagonal, like
the streamline spacing. Face indices are input faces (polygons for polygon meshes), vertex indices are the
mesh's vertices.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .constraints import _real

__all__ = [
    "FeatureGuide",
    "CurveGuide",
    "Symmetry",
    "GuideReport",
    "FEATURE_MODES",
    "FALLOFFS",
    "parse_features",
]

FEATURE_MODES = ("soft", "hard")
FALLOFFS = ("smooth", "linear", "constant")
MIRROR_AXES = ("x", "y", "z")
#: largest mirror matching tolerance (fraction of the diagonal): beyond it a vertex's image meets many
#: candidates and the matching means little (and grows quadratic in cost)
MAX_MIRROR_TOLERANCE = 0.1
#: two hard guide directions on one face that differ by more than this (degrees of field angle, modulo the
#: n-symmetry) contradict each other: the face gets no constraint and is reported
HARD_MERGE_TOLERANCE_DEGREES = 1.0


def _finite(value: Any, name: str, lo: float | None = None, hi: float | None = None, *, open_lo: bool = False) -> float:
    x = _real(value, f"{name} must be a number")
    bad = not math.isfinite(x) or (lo is not None and (x <= lo if open_lo else x < lo)) or (hi is not None and x > hi)
    if bad:
        lo_s = "" if lo is None else (f"> {lo:g}" if open_lo else f">= {lo:g}")
        hi_s = "" if hi is None else f"<= {hi:g}"
        rng = " and ".join(s for s in (lo_s, hi_s) if s)
        raise ValueError(f"{name} must be a finite number{' ' + rng if rng else ''}, got {value!r}")
    return x


def _count(value: Any, name: str, lo: int = 1) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer >= {lo}, got {value!r}")
    if int(value) < lo:
        raise ValueError(f"{name} must be an integer >= {lo}, got {int(value)}")
    return int(value)


def _mode(value: Any, what: str) -> str:
    if value not in FEATURE_MODES:
        raise ValueError(f"{what} mode must be 'soft' or 'hard', got {value!r}")
    return value


def _edge_pairs(edges: Any, what: str) -> np.ndarray:
    """(k, 2) int64 array of vertex pairs."""
    if edges is None:
        return np.zeros((0, 2), dtype=np.int64)
    arr = np.asarray(edges)
    if arr.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError(f"{what} must be a list of vertex pairs (shape (k, 2)), got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.integer):
        if np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr)):
            arr = arr.astype(np.int64)
        else:
            raise ValueError(f"{what} must hold integer vertex indices, got dtype {arr.dtype}")
    if arr.min() < 0:
        raise ValueError(f"{what}: vertex indices must be >= 0 (got {int(arr.min())})")
    return np.ascontiguousarray(arr, dtype=np.int64)


def _check_guide_options(guide, what: str, width, every_means: str) -> None:
    """Check and store the options feature and curve guides share: mode, weight, the (checked) width, every."""
    _mode(guide.mode, what)
    object.__setattr__(guide, "weight", _finite(guide.weight, f"{what} weight", 0.0))
    object.__setattr__(guide, "width", width)
    object.__setattr__(guide, "every", _count(guide.every, f"{what} 'every' ({every_means})"))


@dataclass(frozen=True)
class FeatureGuide:
    """Align the field with feature edges.

    boundary : boundary edges are features.
    sharp_angle : edges whose faces bend by more than this many degrees are features (None: none).
    edges : further feature edges as vertex pairs (Blender: sharp/seam edges, face-set or material borders).
    mode : "soft" (weighted alignment on the faces within `width` edge rings, weight falling off linearly)
        or "hard" (direction constraints on the faces next to every `every`-th edge of each feature chain).
    weight : soft mode, relative to the base guide (see the module docstring).
    width : soft mode, in edge rings (1: only the faces next to the edges).
    every : hard mode, constrain the faces next to every k-th edge along each chain.
    corner_angle : a chain turning by more than this (degrees) has a corner there.
    """

    boundary: bool = True
    sharp_angle: float | None = None
    edges: Any = None
    mode: str = "soft"
    weight: float = 1.0
    width: int = 2
    every: int = 1
    corner_angle: float = 45.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "boundary", bool(self.boundary))
        if self.sharp_angle is not None:
            object.__setattr__(self, "sharp_angle", _finite(self.sharp_angle, "sharp angle (degrees)", 0.0, 179.0))
        object.__setattr__(self, "edges", _edge_pairs(self.edges, "feature edges"))
        _check_guide_options(self, "feature", _count(self.width, "feature width (edge rings)"), "every k-th edge")
        object.__setattr__(self, "corner_angle", _finite(self.corner_angle, "corner angle (degrees)", 0.0, 180.0))
        if not self.boundary and self.sharp_angle is None and len(self.edges) == 0:
            raise ValueError("a feature guide needs boundary=True, a sharp angle or marked edges")

    def key(self) -> tuple:
        """What the detected edges depend on."""
        return (self.boundary, self.sharp_angle, self.edges.tobytes(), self.corner_angle)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, FeatureGuide) and self.key() == other.key() and (
            self.mode, self.weight, self.width, self.every) == (other.mode, other.weight, other.width, other.every)

    def __hash__(self) -> int:
        return hash((self.key(), self.mode, self.weight, self.width, self.every))


def parse_features(spec: str, **options: Any) -> FeatureGuide:
    """FeatureGuide from the command line's spec: comma-separated "boundary" and "sharp[:ANGLE]" (default 30
    degrees), e.g. "boundary,sharp:30". `options` are the other FeatureGuide fields."""
    if not isinstance(spec, str) or not spec.strip():
        raise ValueError("feature spec must name 'boundary' and/or 'sharp[:degrees]', e.g. 'boundary,sharp:30'")
    boundary, sharp = False, None
    for part in (p.strip() for p in spec.split(",")):
        name, _, arg = part.partition(":")
        if name == "boundary" and not arg:
            boundary = True
        elif name == "sharp":
            sharp = _finite(arg, f"sharp angle in {part!r}", 0.0, 179.0) if arg else 30.0
        else:
            raise ValueError(f"unknown feature {part!r} in {spec!r} (expected 'boundary' or 'sharp[:degrees]')")
    return FeatureGuide(boundary=boundary, sharp_angle=sharp, **options)


@dataclass(frozen=True, eq=False)
class CurveGuide:
    """A 3D polyline (k >= 2 points, mesh coordinates) projected onto the surface; its tangents guide the field.

    mode : "soft" (alignment within `width`, smooth falloff) or "hard" (direction constraints on every
        `every`-th face the curve crosses).
    width, tolerance : fractions of the bounding-box diagonal. Parts of the curve farther than `tolerance`
        from the surface are ignored and reported.
    """

    points: Any
    mode: str = "soft"
    weight: float = 1.0
    width: float = 0.02
    tolerance: float = 0.01
    every: int = 1

    def __post_init__(self) -> None:
        p = np.asarray(self.points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 2:
            raise ValueError(f"curve points must be an array of shape (k, 3) with k >= 2, got shape {p.shape}")
        if not np.isfinite(p).all():
            raise ValueError(f"curve point {int(np.flatnonzero(~np.isfinite(p).all(axis=1))[0])} is not finite")
        object.__setattr__(self, "points", np.ascontiguousarray(p))
        _check_guide_options(self, "curve", _finite(self.width, "curve width", 0.0, 1.0), "every k-th crossed face")
        object.__setattr__(self, "tolerance", _finite(self.tolerance, "curve tolerance", 0.0, 1.0))

    def key(self) -> tuple:
        return (self.points.tobytes(), self.tolerance)


@dataclass(frozen=True)
class Symmetry:
    """Mirror symmetry about the plane {axis = offset} (mesh coordinates).

    tolerance : fraction of the bounding-box diagonal within which a vertex's mirror image must meet a vertex
        (at most 0.1).
    partial : what to do with faces that have no mirror partner: False refuses (ValueError listing them),
        True applies the symmetry to the matched faces only.
    """

    axis: str = "x"
    offset: float = 0.0
    tolerance: float = 1e-5
    partial: bool = False

    def __post_init__(self) -> None:
        if self.axis not in MIRROR_AXES:
            raise ValueError(f"mirror axis must be 'x', 'y' or 'z', got {self.axis!r}")
        object.__setattr__(self, "offset", _finite(self.offset, "mirror plane offset"))
        object.__setattr__(self, "tolerance", _finite(self.tolerance, "mirror tolerance (fraction of the diagonal)",
                                                      0.0, MAX_MIRROR_TOLERANCE))
        object.__setattr__(self, "partial", bool(self.partial))


@dataclass
class GuideReport:
    """What the guides did in the last solve (JSON-friendly through to_dict()).

    feature_edges, feature_chains : detected feature edges and chains; corners : vertices where features meet
    or turn sharply; hard_constraints : direction constraints the hard guides imposed; dropped : faces whose
    hard guide directions were not imposed, with the reason; curves : per curve name, samples, missed samples
    and the largest distance to the surface (fraction of the diagonal); missed_curves : names of curves that
    miss the surface by more than their tolerance somewhere; cuts : edges opened and edges that could not
    open; symmetry : axis, matched and unmatched faces, largest vertex mismatch (fraction of the diagonal).
    """

    feature_edges: int = 0
    feature_chains: int = 0
    corners: list[int] = field(default_factory=list)
    hard_constraints: int = 0
    dropped: list[dict] = field(default_factory=list)
    curves: dict[str, dict] = field(default_factory=dict)
    missed_curves: list[str] = field(default_factory=list)
    cuts: dict | None = None
    symmetry: dict | None = None
    unweighted_components: int = 0   # components whose weights were all 0: solved with weight 1, target 0

    def to_dict(self) -> dict:
        return {
            "feature_edges": self.feature_edges,
            "feature_chains": self.feature_chains,
            "corners": [int(v) for v in self.corners],
            "hard_constraints": self.hard_constraints,
            "dropped": list(self.dropped),
            "curves": dict(self.curves),
            "missed_curves": list(self.missed_curves),
            "cuts": self.cuts,
            "symmetry": self.symmetry,
            "unweighted_components": self.unweighted_components,
        }

    def summary(self) -> list[str]:
        """One line per notable item (for the CLI and the UI)."""
        lines = []
        if self.feature_edges:
            lines.append(f"features: {self.feature_edges} edges in {self.feature_chains} chains, "
                         f"{len(self.corners)} corners")
        if self.hard_constraints or self.dropped:
            lines.append(f"hard guides: {self.hard_constraints} direction constraints, {len(self.dropped)} dropped")
        for d in self.dropped[:5]:
            lines.append(f"  dropped face {d['face']}: {d['reason']}")
        if len(self.dropped) > 5:
            lines.append(f"  ... and {len(self.dropped) - 5} more")
        for name in self.missed_curves:
            c = self.curves[name]
            lines.append(f"curve {name!r} misses the surface: {c['missed']} of {c['samples']} samples farther than "
                         f"its tolerance (up to {c['max_distance']:.3g} of the diagonal)")
        if self.cuts:
            lines.append(f"cuts: {self.cuts['opened']} edges opened" +
                         (f", {len(self.cuts['unopened'])} isolated edges could not open"
                          if self.cuts["unopened"] else ""))
        if self.symmetry:
            s = self.symmetry
            lines.append(f"mirror symmetry ({s['axis']}): {s['matched']} faces matched, "
                         f"{len(s['unmatched'])} without partner")
        return lines
