"""The guide computations behind DesignSession: one combined guide field and the hard guide constraints.

GuideEngine owns the native GuideGeometry of one mesh (frames, edge table, closest-point tree; built once)
and caches every intermediate result by what it depends on, so a live edit recomputes only its own layer:
moving a curve re-projects that curve and rebuilds the curve layer (milliseconds), a comb stroke touches the
comb layer, a weight change only the final sum. See guides.py for the combination rule.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ._loader import native
from .guides import HARD_MERGE_TOLERANCE_DEGREES, CurveGuide, FeatureGuide, GuideReport
from .mesh import Mesh


@dataclass
class GuideInputs:
    """Everything the guide field depends on besides the base alignment (per input face unless noted)."""

    weight: np.ndarray | None = None       # alignment weight of the base guide, >= 0
    rotation: np.ndarray | None = None     # radians, turns the base guide
    features: FeatureGuide | None = None
    curves: dict[str, CurveGuide] | None = None
    comb_directions: np.ndarray | None = None  # (F, 3)
    comb_weights: np.ndarray | None = None     # (F,), in [0, 1]
    comb_weight: float = 1.0

    def has_soft(self) -> bool:
        return bool((self.features is not None and self.features.mode == "soft")
                    or any(c.mode == "soft" for c in (self.curves or {}).values())
                    or (self.comb_weights is not None and np.any(self.comb_weights > 0)))

    def has_any(self) -> bool:
        return (self.weight is not None or self.rotation is not None or self.features is not None
                or bool(self.curves) or (self.comb_weights is not None and np.any(self.comb_weights > 0)))


def local_stiffness(ops, order: int) -> np.ndarray:
    """Per triangle: the diagonal of the energy matrix E_order at the face over (unit A_f), unit = (4 pi /
    area)^order the strength unit of strength_to_lambda (spline_solver.hpp). A local guide of weight 1 then
    holds its faces as firmly as the smoothness couples them to their neighbours, whatever the mesh's size
    and resolution (docs/guides.md). Zero on excluded faces."""
    A = np.asarray(ops.mass, dtype=np.float64)
    if order <= 2:
        r, c, v = (np.asarray(x) for x in ops.energy_matrix(1))
        if order == 1:
            diag = np.bincount(r[r == c], v[r == c].real, minlength=len(A))
        else:  # (S M^-1 S)_ff = sum_j |S_jf|^2 / A_j (S Hermitian)
            inv = np.divide(1.0, A, out=np.zeros_like(A), where=A > 0)
            diag = np.bincount(c, np.abs(v) ** 2 * inv[r], minlength=len(A))
    else:
        r, c, v = (np.asarray(x) for x in ops.energy_matrix(order))
        diag = np.bincount(r[r == c], v[r == c].real, minlength=len(A))
    unit = (4.0 * np.pi / float(ops.mesh.total_area)) ** order
    return np.divide(diag, unit * A, out=np.zeros_like(A), where=A > 0)


class GuideEngine:
    def __init__(self, mesh: Mesh):
        self.mesh = mesh
        self._geometry = None
        self._cache: dict[str, tuple[Any, Any]] = {}

    # ------------------------------------------------------------------ helpers
    @property
    def geometry(self):
        if self._geometry is None:
            self._geometry = native().GuideGeometry(self.mesh.native)
        return self._geometry

    @property
    def diagonal(self) -> float:
        return float(self.mesh.native.bounding_box_diagonal)

    def _cached(self, slot: str, key, compute):
        hit = self._cache.get(slot)
        if hit is not None and hit[0] == key:
            return hit[1]
        value = compute()
        self._cache[slot] = (key, value)
        return value

    def per_triangle(self, per_face: np.ndarray) -> np.ndarray:
        return np.asarray(per_face)[self.mesh.triangle_face]

    # ------------------------------------------------------------------ features
    def feature_set(self, fg: FeatureGuide):
        return self._cached("features", fg.key(), lambda: self.geometry.detect_features(
            boundary=fg.boundary, sharp_angle=-1.0 if fg.sharp_angle is None else fg.sharp_angle,
            edges=fg.edges if len(fg.edges) else None, corner_angle=fg.corner_angle))

    def feature_layer(self, fg: FeatureGuide, n: int):
        fs = self.feature_set(fg)
        return self._cached("feature_layer", (fg.key(), fg.width, n),
                            lambda: self.geometry.feature_band(fs, n, fg.width))

    # ------------------------------------------------------------------ curves
    def projected(self, name: str, curve: CurveGuide):
        g = self.geometry
        spacing = 0.5 * g.typical_edge_length
        return self._cached(f"curve:{name}", curve.key(), lambda: g.project_curve(
            curve.points, spacing, curve.tolerance * self.diagonal))

    def curve_layer(self, curves: dict[str, CurveGuide], n: int):
        soft = [(name, c) for name, c in sorted(curves.items()) if c.mode == "soft" and c.weight > 0]
        if not soft:
            return None
        key = (n, tuple((name, c.key(), c.width, c.weight) for name, c in soft))
        projected = [self.projected(name, c) for name, c in soft]
        return self._cached("curve_layer", key, lambda: self.geometry.curve_band(
            projected, [c.width * self.diagonal for _, c in soft], [c.weight for _, c in soft], n))

    # ------------------------------------------------------------------ comb
    def begin_comb_stroke(self, directions: np.ndarray, weights: np.ndarray, n: int, radius: float, falloff: str,
                          strength: float) -> "CombStroke":
        """A stroke on the comb field given per input face (`radius`: fraction of the diagonal) that takes its
        samples in batches (CombStroke.add)."""
        return CombStroke(self, directions, weights, n, radius * self.diagonal, falloff, strength)

    def comb_stroke(self, directions: np.ndarray, weights: np.ndarray, n: int, points, stroke_directions,
                    radius: float, falloff: str, strength: float):
        """One stroke on the comb field given per input face; returns (directions, weights, changed input
        faces)."""
        stroke = self.begin_comb_stroke(directions, weights, n, radius, falloff, strength)
        stroke.add(points, stroke_directions)
        return stroke.directions, stroke.weights, stroke.changed_faces

    def comb_layer(self, directions: np.ndarray, weights: np.ndarray, token, n: int):
        tf = self.mesh.triangle_face
        return self._cached("comb_layer", (token, n), lambda: self.geometry.comb_guide(
            np.ascontiguousarray(directions[tf]), np.ascontiguousarray(weights[tf]), n))

    # ------------------------------------------------------------------ the guide field
    def guide_field(self, base: np.ndarray | None, inputs: GuideInputs, n: int, comb_token, areas: np.ndarray,
                    stiffness: np.ndarray):
        """(value per triangle or None, weight per triangle or None, report).

        The alignment term of the spline is sum_f A_f W_f |u_f - g_f|^2 (times the strength), written with the
        weight W = a + k sum_s w_s and the weighted target value W g = a e^{i n theta} u_base + k s sum_s w_s G_s
        (docs/guides.md): the sum of the sources' own terms, up to a constant. k (`stiffness`, per triangle)
        measures the local guides in units of the energy's own stiffness at the face. The base guide always
        takes part with its weight a (1 unless painted), also without a base field (align "none": target 0,
        the paper's unaligned spline), so that without guides nothing changes. Returns (None, None) when there
        is no guide and no per-face weight at all: the solver's plain uniform system."""
        report = GuideReport()
        T = self.mesh.num_triangles
        if base is None and not inputs.has_any():
            return None, None, report
        weight = np.ones(T) if inputs.weight is None else self.per_triangle(inputs.weight).astype(np.float64)
        value = np.zeros(T, dtype=np.complex128) if base is None else weight * np.asarray(base, dtype=np.complex128)
        if inputs.rotation is not None:
            value *= np.exp(1j * n * self.per_triangle(inputs.rotation))
        scale = 1.0
        if base is not None:
            total = float(areas.sum())
            rms = float(np.sqrt((areas * np.abs(base) ** 2).sum() / total)) if total > 0 else 0.0
            if rms > 0 and np.isfinite(rms):
                scale = rms
        fg = inputs.features
        if fg is not None:
            fs = self.feature_set(fg)
            report.feature_edges = len(np.asarray(fs.edge_ids))
            report.feature_chains = len(fs.chains)
            report.corners = [int(v) for v in np.asarray(fs.corners)]
            if fg.mode == "soft" and fg.weight > 0:
                v, w = self.feature_layer(fg, n)
                value += (fg.weight * scale) * stiffness * np.asarray(v)
                weight += fg.weight * stiffness * np.asarray(w)
        curves = inputs.curves or {}
        for name, c in sorted(curves.items()):
            p = self.projected(name, c)
            report.curves[name] = {"samples": int(p.num_samples), "missed": int(p.num_missed),
                                   "max_distance": float(p.max_distance) / self.diagonal}
            if p.num_missed:
                report.missed_curves.append(name)
        layer = self.curve_layer(curves, n)
        if layer is not None:
            value += scale * stiffness * np.asarray(layer[0])
            weight += stiffness * np.asarray(layer[1])
        if inputs.comb_weights is not None and inputs.comb_weight > 0 and np.any(inputs.comb_weights > 0):
            v, w = self.comb_layer(inputs.comb_directions, inputs.comb_weights, comb_token, n)
            value += (inputs.comb_weight * scale) * stiffness * np.asarray(v)
            weight += inputs.comb_weight * stiffness * np.asarray(w)
        return value, weight, report

    def hard_directions(self, inputs: GuideInputs, n: int, report: GuideReport):
        """{triangle: unit representation vector} of the hard features and curves, contradictions dropped
        (recorded in report.dropped with the guides involved)."""
        faces, dirs, sources, names = [], [], [], []
        fg = inputs.features
        if fg is not None and fg.mode == "hard":
            fs = self.feature_set(fg)
            f, d, s = self._cached("feature_hard", (fg.key(), fg.every, n),
                                   lambda: self.geometry.feature_hard(fs, n, fg.every))
            faces.append(np.asarray(f))
            dirs.append(np.asarray(d))
            sources.append(np.asarray(s))
            names = [f"feature chain {i}" for i in range(len(fs.chains))]
        base = len(names)
        for k, (name, c) in enumerate(sorted((inputs.curves or {}).items())):
            names.append(f"curve {name!r}")
            if c.mode != "hard":
                continue
            f, d, s = self.geometry.curve_hard(self.projected(name, c), n, c.every, base + k)
            faces.append(np.asarray(f))
            dirs.append(np.asarray(d))
            sources.append(np.asarray(s))
        if not faces:
            return {}
        f, d, dropped = native().merge_hard_directions(
            np.concatenate(faces), np.concatenate(dirs), np.concatenate(sources), n,
            np.radians(HARD_MERGE_TOLERANCE_DEGREES))
        for face, a, b, degrees in dropped:
            report.dropped.append({"face": int(self.mesh.triangle_face[face]), "triangle": int(face),
                                   "reason": f"{names[a]} and {names[b]} ask for directions {degrees:.3g} degrees "
                                             f"apart (the {n}-symmetry cannot hold both)"})
        return {int(t): complex(z) for t, z in zip(np.asarray(f).tolist(), np.asarray(d))}


class CombStroke:
    """A comb stroke in progress on the comb field of one mesh (per input face, i.e. per polygon).

    The native stroke works per triangle (comb.hpp: after each batch of samples its field equals that of one
    stroke of all the samples so far); a polygon takes the value of its most strongly combed changed triangle.
    ``directions`` / ``weights`` are the field after the samples so far, ``changed_faces`` the input faces
    the stroke changed."""

    def __init__(self, engine: GuideEngine, directions: np.ndarray, weights: np.ndarray, n: int, radius: float,
                 falloff: str, strength: float):
        tf = engine.mesh.triangle_face
        self._tf = tf
        self._native = engine.geometry.begin_comb_stroke(np.ascontiguousarray(directions[tf]),
                                                         np.ascontiguousarray(weights[tf]), n, radius, falloff,
                                                         strength)
        self._tri_d = np.array(directions[tf], dtype=np.float64)
        self._tri_w = np.array(weights[tf], dtype=np.float64)
        self._before = (np.array(directions, dtype=np.float64), np.array(weights, dtype=np.float64))
        self.directions, self.weights = self._before[0].copy(), self._before[1].copy()
        self._num_polygons = len(weights)

    def add(self, points, stroke_directions) -> np.ndarray:
        """Adds samples (points on the surface, drag directions; (k, 3) each). Returns the input faces whose
        value this batch may have changed."""
        reached, d, w = self._native.add(np.asarray(points, dtype=np.float64).reshape(-1, 3),
                                         np.asarray(stroke_directions, dtype=np.float64).reshape(-1, 3))
        reached = np.asarray(reached, dtype=np.int64)
        if not len(reached):
            return reached
        self._tri_d[reached] = np.asarray(d)
        self._tri_w[reached] = np.asarray(w)
        polygons = np.unique(self._tf[reached])
        touched = np.zeros(self._num_polygons, dtype=bool)
        touched[polygons] = True
        changed = np.zeros(len(self._tf), dtype=bool)
        changed[np.asarray(self._native.changed, dtype=np.int64)] = True
        candidates = np.flatnonzero(changed & touched[self._tf])
        self.directions[polygons], self.weights[polygons] = self._before[0][polygons], self._before[1][polygons]
        order = candidates[np.argsort(self._tri_w[candidates], kind="stable")]  # the strongest is written last
        self.directions[self._tf[order]] = self._tri_d[order]
        self.weights[self._tf[order]] = self._tri_w[order]
        return polygons

    @property
    def changed_faces(self) -> np.ndarray:
        return np.unique(self._tf[np.asarray(self._native.changed, dtype=np.int64)])
