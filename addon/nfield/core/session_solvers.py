"""The native solvers behind DesignSession (a mixin; the state lives on the session object).

One solve gathers its inputs (frozen faces, the user's constraints outside them, the combined guide field and
the hard guide directions: `_SolveInputs`), then runs the exact solver (native ExactSolver: factored once per
key, constraints brought up to date by `_sync` with the fewest native calls) or the reduced solver of spectral
mode (native ReducedSolver in the cached basis). What a factorization depends on is its key (`_exact_key`):
the guide *weights* are part of V, the guide *targets* only of the right-hand side.
"""
from __future__ import annotations

import dataclasses
import hashlib
import itertools
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ._loader import native


# A reduced solve whose constraint rows are violated by more than this (relative) warns: with enough
# eigenfields the rows hold to ~1e-12 (tests/test_spectral.py); 1e-6 is far above rounding and far below
# a visible deviation.
SPECTRAL_RESIDUAL_WARNING = 1e-6
_tokens = itertools.count(1)


@dataclass
class _SolveInputs:
    """What one solve needs besides the settings (DesignSession._solve_inputs)."""

    frozen_tris: np.ndarray
    frozen_values: np.ndarray
    frozen_key: Any
    dirs: dict          # input face -> 3D direction (the user's constraints outside frozen faces)
    vecs: dict          # input face -> 3D vector
    sings: dict         # vertex -> index
    kind: str           # "direction" | "vector"
    guide_dirs: dict    # triangle -> unit representation vector (hard features and curves)
    alignment: Any      # combined guide field per triangle (complex) or None
    matrix_weight: Any  # per-triangle weight of the alignment term in n-vector splines, or None
    report: Any         # GuideReport
    weight_digest: Any  # WeightDigest of matrix_weight when it is not uniformly 1, else None


class WeightDigest:
    """The digest of non-uniform guide weights (part of the exact solver's key), computed when first compared:
    a live edit, keyed by its region's own weights, never needs it (0.7 ms on 86k faces). The weights are the
    session's own array, never changed in place."""

    __slots__ = ("_weight", "_digest")

    def __init__(self, weight: np.ndarray) -> None:
        self._weight, self._digest = weight, None

    @property
    def digest(self) -> str:
        if self._digest is None:
            self._digest = hashlib.blake2b(np.ascontiguousarray(self._weight).tobytes(), digest_size=16).hexdigest()
            self._weight = None
        return self._digest

    def __eq__(self, other: object) -> bool:
        return isinstance(other, WeightDigest) and (self is other or self.digest == other.digest)

    def __hash__(self) -> int:
        return hash(self.digest)


def _token() -> int:
    """A never-repeating key for cache invalidation (id() of freed objects gets reused)."""
    return next(_tokens)



class SessionSolvers:
    """Mixin of DesignSession: the inputs of a solve, the exact and the reduced solver, their constraints."""

    def _spectral_applies(self, inputs: "_SolveInputs") -> bool:
        """Spectral mode solves in the basis unless the problem needs what the basis cannot hold: frozen faces
        (region edits, layers), mirror symmetry and non-uniform guide weights (the weights make U^H V U a dense
        k x k matrix instead of a diagonal) use the exact solver (docs/guides.md)."""
        return (self._settings["mode"] == "spectral" and not inputs.frozen_tris.size and self._mirror is None
                and inputs.weight_digest is None)

    def _weight_arguments(self, inputs: "_SolveInputs") -> dict:
        """ExactSolver keywords for the guide weights: none when they are uniformly 1 (the plain system)."""
        return {} if inputs.weight_digest is None else {"alignment_weight": inputs.matrix_weight}

    def _solve_inputs(self) -> "_SolveInputs":
        """Frozen faces, the constraints outside them, the guide field and the hard guide constraints."""
        frozen_tris, frozen_values, frozen_key = self._frozen()
        frozen_set = set(frozen_tris.tolist())
        nm = self._solve_native_mesh()
        dirs = {f: d for f, d in self._dirs.items() if not self._face_frozen(f, frozen_set)}
        vecs = {f: v for f, v in self._vecs.items() if not self._face_frozen(f, frozen_set)}
        sings = {v: i for v, i in self._sings.items() if not any(t in frozen_set for t in nm.vertex_ring_faces(v))}
        alignment, matrix_weight, hard, report = self._guided(self._operators())
        # Hard guide directions give way to the user's own constraints and singularities on the same faces.
        report = dataclasses.replace(report, dropped=list(report.dropped))
        user = {self.mesh.face_triangle(f): f for f in itertools.chain(self._dirs, self._vecs)}
        ring = {t: v for v in self._sings for t in nm.vertex_ring_faces(v)}
        guide_dirs = {}
        for t, z in hard.items():
            if t in frozen_set:
                continue  # held by its frozen value
            if t in user:
                report.dropped.append({"face": int(self.mesh.triangle_face[t]), "triangle": t,
                                       "reason": f"the user's constraint on face {user[t]} takes its place"})
            elif t in ring:
                report.dropped.append({"face": int(self.mesh.triangle_face[t]), "triangle": t,
                                       "reason": f"on the ring of the singularity at vertex {ring[t]}"})
            else:
                guide_dirs[t] = z
        report.hard_constraints = len(guide_dirs)
        kind = "vector" if vecs and not dirs and not guide_dirs else "direction"
        return _SolveInputs(frozen_tris, frozen_values, frozen_key, dirs, vecs, sings, kind, guide_dirs, alignment,
                            matrix_weight, report, self._weight_digest)

    def _guided(self, ops):
        """The combined guide field and hard guide directions (guides.py), cached by what they depend on."""
        s = self._settings
        key = (self._ops_token, s["order"], self._alignment_version(), self._guide_version, s["comb_weight"],
               id(self._mirror))
        if self._guided_key != key:
            self._guide.comb_weight = s["comb_weight"]
            self._guided_value = self._guide_alignment(ops, self._alignment_field(ops))
            self._guided_key = key
            self._guided_token = _token()
            weight = self._guided_value[1]
            active = np.asarray(self._solve_native_mesh().face_active, dtype=bool)
            uniform = weight is None or bool(np.all(weight[active] == 1.0))
            self._weight_digest = None if uniform else WeightDigest(weight)
        return self._guided_value

    def _exact_key(self, inputs: "_SolveInputs") -> tuple:
        """What the ExactSolver's factorization depends on: not the guide targets (set_alignment changes the
        right-hand side only), but the guide weights, which are part of V."""
        s = self._settings
        # (an n-vector spline without any guide value uses a small regularisation instead of the strength:
        # whether there is one decides lambda, so it belongs to the key)
        no_target = inputs.kind == "vector" and inputs.alignment is None
        return (self._ops_token, s["order"], s["strength"], inputs.weight_digest, inputs.kind, inputs.frozen_key,
                no_target)

    @property
    def constraint_residual(self) -> float:
        """After a spectral solve: the largest violation of a constraint row by the reduced solution,
        relative to the largest constrained value (the field is then snapped onto its constraints at the
        constrained faces). ~1e-12 when k is large enough for the constraints; 0 after an exact solve."""
        if self.field is None or self.field.mode != "spectral" or self._reduced is None:
            return 0.0
        return float(self._reduced.constraint_residual)

    def _vector_triangles(self, vecs: dict) -> list[int]:
        return sorted(int(self.mesh.face_triangle(f)) for f in vecs)

    def _solve_exact(self, ops, inputs: "_SolveInputs"):
        s = self._settings
        key = self._exact_key(inputs)
        frozen_tris, frozen_values = inputs.frozen_tris, inputs.frozen_values
        vec_tris = self._vector_triangles(inputs.vecs)
        if self._solver is None or key != self._solver_key or self._solver.needs_refactorization(vec_tris):
            # lambda = 0 (n-vector spline without any guide value): the vector constraints are the anchors that
            # keep V positive definite on flat meshes (spline_solver.hpp); otherwise no anchors (none needed).
            anchored = inputs.kind == "vector" and inputs.alignment is None
            solver = native().ExactSolver(ops, s["order"], s["strength"], inputs.alignment, inputs.kind,
                                          progress=self.progress,
                                          frozen_faces=frozen_tris if frozen_tris.size else None,
                                          frozen_values=frozen_values if frozen_tris.size else None,
                                          anchor_faces=np.asarray(vec_tris, dtype=np.int64) if anchored else None,
                                          **self._weight_arguments(inputs))
            # Only replace the old solver once the new one exists: a failed or cancelled factorization
            # leaves the session as it was.
            self._solver, self._solver_key = solver, key
            self._solver_alignment, self._solver_mirror = self._guided_token, None
            self._in_solver = {"dir": {}, "vec": {}, "sing": {}}
        if self._solver_alignment != self._guided_token:
            self._solver.set_alignment(inputs.alignment)  # a guide edit: right-hand side only
            self._solver_alignment = self._guided_token
        if self._solver_mirror is not self._mirror:
            self._solver.set_symmetry(self._mirror)
            self._solver_mirror = self._mirror
            self._in_solver = self._sync(self._solver, self._in_solver, ops, dataclasses.replace(
                inputs, dirs={}, vecs={}, sings={}, guide_dirs={}))  # re-place every constraint below
        try:
            self._in_solver = self._sync(self._solver, self._in_solver, ops, inputs)
        except Exception:
            self._solver = self._solver_key = None  # its constraint state is unknown now: rebuild next time
            raise
        w = np.asarray(self._solver.solve(), dtype=np.complex128)
        return w, float(self._solver.lambda_), list(self._solver.sign_fixed_faces)

    def _solve_reduced(self, ops, inputs: "_SolveInputs"):
        s = self._settings
        self.precompute()
        # Neither the strength nor the guide field is part of the key: a strength change only changes the
        # diagonal Lambda (set_strength, O(k)), a guide edit only the projection U^H M u' (set_alignment, O(N k)).
        key = (self._basis_key, s["order"], inputs.kind)
        if self._reduced is None or key != self._reduced_key:
            solver = native().ReducedSolver(ops, self._basis, s["order"], s["strength"], inputs.alignment,
                                            inputs.kind)
            self._reduced, self._reduced_key = solver, key
            self._reduced_alignment = self._guided_token
            self._in_reduced = {"dir": {}, "vec": {}, "sing": {}}
        else:
            self._reduced.set_strength(s["strength"])
            if self._reduced_alignment != self._guided_token:
                self._reduced.set_alignment(inputs.alignment)
                self._reduced_alignment = self._guided_token
        try:
            self._in_reduced = self._sync(self._reduced, self._in_reduced, ops, inputs)
        except Exception:
            self._reduced = self._reduced_key = None
            raise
        w = np.asarray(self._reduced.solve(), dtype=np.complex128)
        residual = float(self._reduced.constraint_residual)
        if residual > SPECTRAL_RESIDUAL_WARNING:
            warnings.warn(f"the first k={s['k']} eigenfields cannot meet every constraint exactly (largest row "
                          f"violation {residual:.1e} of the constrained values; constraints very close to each "
                          f"other need finer eigenfields): raise k or use the exact mode", RuntimeWarning,
                          stacklevel=3)
        if self._reduced.uncovered_components:
            warnings.warn(f"{self._reduced.uncovered_components} mesh component(s) are not reached by any of the "
                          f"first k={s['k']} eigenfields: their field is zero; raise k (at least the number of "
                          f"components) or use the exact mode", RuntimeWarning, stacklevel=3)
        return w, float(self._reduced.lambda_), list(self._reduced.sign_fixed_faces)

    def _sync(self, solver, have: dict, ops, inputs: "_SolveInputs") -> dict:
        """Bring a native solver's constraints from state `have` to the wanted one with the fewest calls;
        returns the new state."""
        dirs, vecs, sings = inputs.dirs, inputs.vecs, inputs.sings
        want: dict[str, dict] = {"dir": dict(inputs.guide_dirs), "vec": {}, "sing": {}}
        for kind, items in (("dir", dirs), ("vec", vecs)):
            if items:
                faces = list(items)
                tris = np.array([self.mesh.face_triangle(f) for f in faces], dtype=np.int64)
                z = np.asarray(ops.tangent_to_representation(tris, np.array([items[f] for f in faces])))
                for t, zz in zip(tris.tolist(), z):
                    want[kind][t] = complex(zz / abs(zz)) if kind == "dir" else complex(zz)
        n = self._settings["n"]
        for v, index in sings.items():
            want["sing"][v] = int(round(index * n))
        if self._mirror is not None and getattr(solver, "symmetric", False):
            want = self._symmetric_constraints(want, set(inputs.guide_dirs))
        for t in set(have["dir"]) | set(have["vec"]):
            if t not in want["dir"] and t not in want["vec"]:
                solver.remove_constraint(t)
        for v in have["sing"]:
            if v not in want["sing"]:
                solver.remove_singularity(v)
        for t, z in want["dir"].items():
            if have["dir"].get(t) != z:
                solver.set_direction_constraint(t, z)
        for t, z in want["vec"].items():
            if have["vec"].get(t) != z:
                solver.set_vector_constraint(t, z)
        for v, num in want["sing"].items():
            if have["sing"].get(v) != num:
                solver.set_singularity(v, num)
        return want
