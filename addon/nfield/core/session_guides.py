"""Guide authoring methods of DesignSession (a mixin; the state lives on the session object).

Every method validates its input completely before it changes anything, so a ValueError leaves the design
as it was. Guide edits never refactor the n-direction solver (docs/guides.md): they change the guide field,
i.e. the right-hand side. Cuts change the operators (a refactorization and, in spectral mode, another basis).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ._loader import native
from .constraints import DirectionConstraint, SingularityConstraint, VectorConstraint
from .guide_engine import GuideEngine, GuideInputs, local_stiffness
from .guides import FALLOFFS, CurveGuide, FeatureGuide, GuideReport, Symmetry, _edge_pairs, _finite, parse_features


def _stroke_samples(points: Any, directions: Any) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(points, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or d.shape != p.shape or len(p) == 0:
        raise ValueError(f"a comb stroke needs points and directions of the same shape (k, 3), k >= 1; got "
                         f"{p.shape} and {d.shape}")
    return p, d


class SessionGuides:
    """Mixin of DesignSession: features, curves, comb, weights, rotations, cuts and mirror symmetry."""

    def _init_guides(self) -> None:
        self._guide = GuideInputs(curves={})
        self._guide_version = 0       # bumped by every guide edit
        self._comb_token = 0
        self._stroke = None           # (CombStroke, comb directions and weights before it) while one is in progress
        self._engine = GuideEngine(self.mesh)
        self._cuts = np.zeros((0, 2), dtype=np.int64)
        self._cut = None              # (native cut mesh, info) or None
        self._cuts_token = 0          # bumped when the cuts change (the operators depend on them)
        self._symmetry: Symmetry | None = None
        self._mirror = None           # native MirrorMap of the original mesh, when symmetry is on
        self.guide_report: GuideReport | None = None
        self._stiffness = None
        self._stiffness_key = None

    def _guide_changed(self) -> None:
        self._guide_version += 1
        self._dirty = True

    def _per_face_array(self, values: Any, name: str, lo: float | None) -> np.ndarray | None:
        if values is None:
            return None
        a = np.asarray(values, dtype=np.float64)
        if a.shape != (self.mesh.num_faces,):
            raise ValueError(f"{name} must have one value per face ({self.mesh.num_faces}), got shape {a.shape}")
        bad = ~np.isfinite(a) if lo is None else ~(np.isfinite(a) & (a >= lo))
        if bad.any():
            f = int(np.flatnonzero(bad)[0])
            raise ValueError(f"{name} at face {f} is {a[f]!r}: values must be finite" + ("" if lo is None else f" and >= {lo:g}"))
        return a.copy()

    # ------------------------------------------------------------------ weights and rotation of the base guide
    def set_alignment_weight(self, weights: Any) -> None:
        """Per-face weight (>= 0, one per input face) of the base alignment (curvature or user field); None:
        1 everywhere. A weight of 0 removes the base alignment there (Blender: a painted face attribute)."""
        self._guide.weight = self._per_face_array(weights, "alignment weight", 0.0)
        self._guide_changed()

    def set_alignment_rotation(self, angles: Any) -> None:
        """Per-face angle (radians, one per input face) that turns the base alignment; None: no rotation."""
        self._guide.rotation = self._per_face_array(angles, "alignment rotation", None)
        self._guide_changed()

    @property
    def alignment_weight(self) -> np.ndarray | None:
        return None if self._guide.weight is None else self._guide.weight.copy()

    @property
    def alignment_rotation(self) -> np.ndarray | None:
        return None if self._guide.rotation is None else self._guide.rotation.copy()

    # ------------------------------------------------------------------ features
    def set_features(self, features: FeatureGuide | str | None = None, **options: Any) -> FeatureGuide | None:
        """Feature alignment: a FeatureGuide, a spec string ("boundary,sharp:30") plus FeatureGuide options
        (mode, weight, width, every, edges, corner_angle), or None to remove it."""
        if isinstance(features, str):
            fg = parse_features(features, **options)
        elif isinstance(features, FeatureGuide):
            if options:
                raise ValueError("give options either in the FeatureGuide or as keywords with a spec string")
            fg = features
        elif features is None and options:
            fg = FeatureGuide(**options)
        elif features is None:
            fg = None
        else:
            raise ValueError(f"features must be a FeatureGuide, a spec string or None, got {type(features).__name__}")
        if fg is not None and len(fg.edges) and int(fg.edges.max()) >= self.mesh.num_vertices:
            raise ValueError(f"feature edge vertex {int(fg.edges.max())} is out of range (the mesh has "
                             f"{self.mesh.num_vertices} vertices)")
        if fg is not None:
            self._engine.feature_set(fg)  # detect now: unknown marked edges are reported here
        self._guide.features = fg
        self._guide_changed()
        return fg

    @property
    def features(self) -> FeatureGuide | None:
        return self._guide.features

    # ------------------------------------------------------------------ curves
    def set_curve(self, name: str, points: Any, **options: Any) -> CurveGuide:
        """Add or replace the curve guide `name` (a polyline in mesh coordinates; options as CurveGuide:
        mode, weight, width, tolerance, every). Replacing a curve is the live edit of dragging it."""
        if not isinstance(name, str) or not name:
            raise ValueError("a curve guide needs a non-empty name")
        curve = points if isinstance(points, CurveGuide) and not options else CurveGuide(points, **options)
        self._guide.curves[name] = curve
        self._guide_changed()
        return curve

    def remove_curve(self, name: str) -> None:
        if name not in self._guide.curves:
            raise ValueError(f"there is no curve guide named {name!r}")
        del self._guide.curves[name]
        self._guide_changed()

    @property
    def curves(self) -> dict[str, CurveGuide]:
        return dict(self._guide.curves)

    # ------------------------------------------------------------------ comb
    def comb(self, points: Any, directions: Any, radius: float, falloff: str = "smooth",
             strength: float = 1.0) -> np.ndarray:
        """One comb stroke: samples (points on the surface, drag directions) painted within `radius`
        (fraction of the bounding-box diagonal) with a falloff ("smooth", "linear", "constant") and a
        strength in (0, 1]. Accumulates into the comb field (see comb_field) and returns the input faces it
        changed (what a Blender undo step stores)."""
        p, d = _stroke_samples(points, directions)
        self.begin_comb_stroke(radius, falloff, strength)
        try:
            self.extend_comb_stroke(p, d)
        except ValueError:
            self.cancel_comb_stroke()
            raise
        return self.end_comb_stroke()

    def begin_comb_stroke(self, radius: float, falloff: str = "smooth", strength: float = 1.0) -> None:
        """Start a brush stroke that takes its samples in batches (extend_comb_stroke, as the mouse moves):
        after every batch the comb field is that of one stroke (comb) of all the samples so far, so a live
        solve can follow the brush. end_comb_stroke finishes it, cancel_comb_stroke puts the comb field back."""
        radius = _finite(radius, "comb radius (fraction of the diagonal)", 0.0, 1.0, open_lo=True)
        strength = _finite(strength, "comb strength", 0.0, 1.0, open_lo=True)
        if falloff not in FALLOFFS:
            raise ValueError(f"unknown falloff {falloff!r} (expected one of {', '.join(FALLOFFS)})")
        dirs, weights = self.comb_field
        self._stroke = (self._engine.begin_comb_stroke(dirs, weights, self._settings["n"], radius, falloff, strength),
                        self._guide.comb_directions, self._guide.comb_weights)

    def extend_comb_stroke(self, points: Any, directions: Any) -> np.ndarray:
        """Add samples to the stroke in progress; returns the input faces whose comb value they may change."""
        if self._stroke is None:
            raise ValueError("no comb stroke in progress (begin_comb_stroke first)")
        p, d = _stroke_samples(points, directions)
        stroke = self._stroke[0]
        touched = stroke.add(p, d)
        if len(touched):
            self._set_comb_arrays(stroke.directions.copy(), stroke.weights.copy())
        return touched

    def end_comb_stroke(self) -> np.ndarray:
        """Finish the stroke in progress; returns every input face it changed."""
        if self._stroke is None:
            raise ValueError("no comb stroke in progress")
        changed = self._stroke[0].changed_faces
        self._stroke = None
        return changed

    def cancel_comb_stroke(self) -> None:
        """Drop the stroke in progress: the comb field goes back to what it was before the stroke."""
        if self._stroke is None:
            return
        _, dirs, weights = self._stroke
        self._stroke = None
        if dirs is None:
            self.clear_comb()
        else:
            self._set_comb_arrays(dirs, weights)

    @property
    def comb_stroke_active(self) -> bool:
        return self._stroke is not None

    def set_comb(self, directions: Any, weights: Any) -> None:
        """Restore a stored comb field: (F, 3) unit tangent directions and (F,) weights in [0, 1] per input face."""
        d = np.asarray(directions, dtype=np.float64)
        if d.shape != (self.mesh.num_faces, 3) or not np.isfinite(d).all():
            raise ValueError(f"comb directions must be a finite array of shape ({self.mesh.num_faces}, 3)")
        w = self._per_face_array(weights, "comb weight", 0.0)
        if w is not None and (w > 1).any():
            raise ValueError(f"comb weight at face {int(np.flatnonzero(w > 1)[0])} is above 1 (weights lie in [0, 1])")
        self._stroke = None
        self._set_comb_arrays(d.copy(), w)

    def clear_comb(self) -> None:
        self._stroke = None
        self._guide.comb_directions = self._guide.comb_weights = None
        self._comb_token += 1
        self._guide_changed()

    def _set_comb_arrays(self, dirs: np.ndarray, weights: np.ndarray) -> None:
        self._guide.comb_directions, self._guide.comb_weights = dirs, weights
        self._comb_token += 1
        self._guide_changed()

    @property
    def comb_field(self) -> tuple[np.ndarray, np.ndarray]:
        """(directions (F, 3), weights (F,)) per input face; zeros where nothing was combed."""
        if self._guide.comb_weights is None:
            return np.zeros((self.mesh.num_faces, 3)), np.zeros(self.mesh.num_faces)
        return self._guide.comb_directions.copy(), self._guide.comb_weights.copy()

    # ------------------------------------------------------------------ cuts
    def set_cuts(self, edges: Any) -> dict:
        """Cut the connection along these edges (vertex pairs; None or empty: no cuts): the field may jump
        across them, as across boundaries. Returns {"opened", "unopened", "already_cut"}."""
        pairs = _edge_pairs(edges, "cut edges")
        if len(pairs) and int(pairs.max()) >= self.mesh.num_vertices:
            raise ValueError(f"cut edge vertex {int(pairs.max())} is out of range (the mesh has "
                             f"{self.mesh.num_vertices} vertices)")
        cut = None
        info = {"opened": 0, "unopened": [], "already_cut": []}
        if len(pairs):
            cut_mesh, _origin, opened, unopened, already = native().cut_mesh(self.mesh.native, pairs)
            info = {"opened": int(opened), "unopened": np.asarray(unopened).tolist(),
                    "already_cut": np.asarray(already).tolist()}
            cut = (cut_mesh, info)
        self._cuts, self._cut = pairs, cut
        self._cuts_token += 1
        self._dirty = True
        return info

    @property
    def cuts(self) -> np.ndarray:
        return self._cuts.copy()

    def _solve_native_mesh(self):
        """The native mesh the field lives on: the input mesh, or the input mesh cut open along the cuts."""
        return self.mesh.native if self._cut is None else self._cut[0]

    # ------------------------------------------------------------------ mirror symmetry
    def set_symmetry(self, axis: str | Symmetry | None = None, offset: float = 0.0, tolerance: float = 1e-5,
                     partial: bool = False) -> dict | None:
        """Make the field mirror-symmetric about the plane {axis = offset}: the solve holds
        u(mirror(f)) = reflect(u(f)) exactly. Faces without a mirror partner (within `tolerance`, a fraction of
        the diagonal) make it refuse with their list (ValueError), unless partial=True, which applies the
        symmetry to the matched faces. None switches symmetry off. Returns the matching summary."""
        if axis is None:
            self._symmetry = self._mirror = None
            self._dirty = True
            return None
        sym = axis if isinstance(axis, Symmetry) else Symmetry(axis, offset, tolerance, partial)
        diag = float(self.mesh.native.bounding_box_diagonal)
        mirror = native().MirrorMap(self.mesh.native, sym.axis, sym.offset, sym.tolerance * diag)
        info = self._symmetry_info(mirror, sym)
        if info["unmatched"] and not sym.partial:
            faces = info["unmatched"]
            shown = ", ".join(str(f) for f in faces[:20]) + (" ..." if len(faces) > 20 else "")
            raise ValueError(f"the mesh is not symmetric about {sym.axis} = {sym.offset:g} within {sym.tolerance:g} of "
                             f"its diagonal: {len(faces)} face(s) have no mirror partner ({shown}); raise the "
                             f"tolerance, or apply the symmetry to the matched faces only (partial=True; command line: "
                             f"--symmetry-partial)")
        self._symmetry, self._mirror = sym, mirror
        self._dirty = True
        return info

    def _symmetry_info(self, mirror, sym: Symmetry) -> dict:
        tf = self.mesh.triangle_face
        unmatched = np.unique(tf[np.asarray(mirror.unmatched, dtype=np.int64)]).tolist()
        diag = float(self.mesh.native.bounding_box_diagonal)
        return {"axis": sym.axis, "offset": sym.offset, "matched": int(mirror.num_matched), "unmatched": unmatched,
                "max_mismatch": float(mirror.max_mismatch) / diag if diag > 0 else 0.0}

    @property
    def symmetry(self) -> Symmetry | None:
        return self._symmetry

    @property
    def symmetry_info(self) -> dict | None:
        """The matching summary of the current symmetry (what set_symmetry returned), None when it is off."""
        return None if self._mirror is None else self._symmetry_info(self._mirror, self._symmetry)

    def mirrored(self, constraint):
        """The mirror image of a DirectionConstraint, VectorConstraint or SingularityConstraint (the same
        index at the mirror vertex: a reflection keeps indices), or None where there is no partner."""
        if self._mirror is None:
            raise ValueError("mirror symmetry is off: call set_symmetry first")
        axis = "xyz".index(self._symmetry.axis)
        if isinstance(constraint, SingularityConstraint):
            v = int(np.asarray(self._mirror.vertex_partner)[constraint.vertex])
            return None if v < 0 else SingularityConstraint(v, constraint.index)
        t = self.mesh.face_triangle(constraint.face)
        partner = int(np.asarray(self._mirror.partner)[t])
        if partner < 0:
            return None
        face = int(self.mesh.triangle_face[partner])
        vec = np.array(constraint.direction if isinstance(constraint, DirectionConstraint) else constraint.vector)
        vec[axis] = -vec[axis]
        cls = DirectionConstraint if isinstance(constraint, DirectionConstraint) else VectorConstraint
        return cls(face, tuple(vec.tolist()))

    def mirrored_samples(self, points: Any, directions: Any) -> tuple[np.ndarray, np.ndarray, list[int]]:
        """The mirror images of comb samples: (points, directions, unmatched). Points and directions are
        reflected about the mirror plane; a sample whose face (the face nearest to it) has no mirror partner
        has no image (partial symmetry): its index is listed in `unmatched`."""
        if self._mirror is None:
            raise ValueError("mirror symmetry is off: call set_symmetry first")
        p, d = _stroke_samples(points, directions)
        axis = "xyz".index(self._symmetry.axis)
        faces = np.asarray(self._engine.geometry.closest_faces(p), dtype=np.int64)
        partner = np.asarray(self._mirror.partner)
        ok = (faces >= 0) & (partner[np.maximum(faces, 0)] >= 0)
        p, d = p[ok].copy(), d[ok].copy()
        p[:, axis] = 2.0 * self._symmetry.offset - p[:, axis]
        d[:, axis] = -d[:, axis]
        return p, d, np.flatnonzero(~ok).tolist()

    def mirror_design(self) -> int:
        """Design helper: add the mirror image of every constraint and singularity that has no counterpart
        yet (what the Blender tools do for each new constraint). Returns how many were added."""
        added = 0
        for c in self.constraints:
            m = self.mirrored(c)
            if m is None:
                continue
            if isinstance(m, SingularityConstraint):
                if m.vertex not in self._sings:
                    self.set_singularity(m.vertex, m.index)
                    added += 1
            elif m.face not in self._dirs and m.face not in self._vecs:
                (self.set_direction if isinstance(m, DirectionConstraint) else self.set_vector)(
                    m.face, m.direction if isinstance(m, DirectionConstraint) else m.vector)
                added += 1
        return added

    def _symmetric_constraints(self, want: dict, guide_triangles: set) -> dict:
        """With mirror symmetry a constraint also holds at its mirror face (the solve works on symmetric
        fields), so of a constraint and its exact mirror image only one is passed to the solver. A user
        constraint that contradicts the mirror image of another is an error naming both; a hard guide
        direction that does is dropped (reported) in favour of the other side."""
        n = self._settings["n"]
        partner = np.asarray(self._mirror.partner)
        vpartner = np.asarray(self._mirror.vertex_partner)
        tf = self.mesh.triangle_face
        out = {"dir": dict(want["dir"]), "vec": dict(want["vec"]), "sing": dict(want["sing"])}
        for kind in ("dir", "vec"):
            for t in sorted(out[kind]):
                p = int(partner[t])
                if p < 0 or p == t or t not in out[kind]:
                    continue
                other = "vec" if kind == "dir" else "dir"
                if p in out[other]:
                    raise ValueError(f"the {'direction' if kind == 'dir' else 'vector'} constraint on face {tf[t]} and "
                                     f"the other kind of constraint on its mirror face {tf[p]} cannot both hold "
                                     f"with mirror symmetry: remove one of them")
                if p not in out[kind]:
                    continue
                image = complex(np.asarray(self._mirror.map(np.array([t]), np.array([out[kind][t]]), n))[0])
                if abs(image - out[kind][p]) <= 1e-9 * max(1.0, abs(image)):
                    del out[kind][max(t, p)]
                elif t in guide_triangles or p in guide_triangles:
                    del out[kind][p if p in guide_triangles else t]
                else:
                    raise ValueError(f"the constraints on face {tf[t]} and on its mirror face {tf[p]} contradict "
                                     f"mirror symmetry (one is not the reflection of the other): remove one of "
                                     f"them (the symmetry then mirrors the other)")
        for v in sorted(out["sing"]):
            w = int(vpartner[v])
            if w < 0 or w == v or v not in out["sing"] or w not in out["sing"]:
                continue
            if out["sing"][v] != out["sing"][w]:
                raise ValueError(f"the singularities at vertex {v} (index {out['sing'][v]}/{n}) and at its mirror "
                                 f"vertex {w} (index {out['sing'][w]}/{n}) contradict mirror symmetry (a reflection "
                                 f"keeps indices)")
            del out["sing"][max(v, w)]
        return out

    # ------------------------------------------------------------------ for the solve
    def _guide_alignment(self, ops, base: np.ndarray | None):
        """(alignment per triangle or None, matrix weights per triangle or None, hard {triangle: rep}, report)."""
        n, order = self._settings["n"], self._settings["order"]
        areas = np.asarray(ops.mass, dtype=np.float64)
        key = (self._ops_token, order)
        if self._stiffness_key != key:
            self._stiffness, self._stiffness_key = local_stiffness(ops, order), key
        value, weight, report = self._engine.guide_field(base, self._guide, n, self._comb_token, areas,
                                                         self._stiffness)
        if weight is not None and self._mirror is not None:
            # On symmetric fields only the symmetrized weight matters (docs/guides.md): passing it keeps V
            # commuting with the mirror (and spares the solver a second factorization)
            partner = np.asarray(self._mirror.partner)
            matched = partner >= 0
            weight = weight.copy()
            weight[matched] = 0.5 * (weight[matched] + weight[partner[matched]])
        if weight is not None:
            # A component on which every weight is 0 has no alignment term at all; on a flat or developable piece
            # E_m alone is singular there. Such a component is solved as the paper's unaligned spline: weight 1,
            # target 0 (its field follows the constraints and smoothness only, as intended).
            comp = np.asarray(self._solve_native_mesh().face_component)
            # (inactive faces, component -1, land in bin 0: no fancy indexing over the whole mesh per edit)
            total = np.bincount(comp + 1, weights=weight * areas, minlength=int(comp.max()) + 2)[1:]
            dead = np.flatnonzero(total <= 0)
            if dead.size:
                weight = weight.copy()
                weight[(comp >= 0) & np.isin(comp, dead)] = 1.0
                report.unweighted_components = int(dead.size)
        hard = self._engine.hard_directions(self._guide, n, report)
        if self._cut is not None:
            info = self._cut[1]
            report.cuts = {"opened": info["opened"], "unopened": info["unopened"]}
        if self._mirror is not None:
            report.symmetry = self._symmetry_info(self._mirror, self._symmetry)
        return value, weight, hard, report
