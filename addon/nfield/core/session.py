"""DesignSession: the editing engine behind the interactive tool and batch scripts (no bpy).

A session holds one mesh, the design settings and the user's constraints, and keeps the native solver
warm between edits:

* Exact live mode. The native ExactSolver factors V = E_m - lambda M once per setting of (n, order,
  alignment, strength, frozen faces) and caches V^-1 e_f for every constrained face. Re-aiming an existing
  constraint (the drag in the UI) then costs no sparse solve (only the small Schur system, eqs. 13-14);
  a constraint on a new face costs one complex back-substitution (both real columns at once); removing a
  constraint costs nothing. A solve that brings many new faces at once (more than four: a loaded design)
  solves directly (a forward substitution along each face's elimination-tree path, then one solve) and the
  next solve without new faces computes their columns in one block. Changing n, order, alignment or strength refactors (lazily, on the
  next solve). An n-vector spline without alignment (lambda = 0, the paper's eq. 8 exactly) substitutes the
  vector constraints present when it factors ("anchors": what keeps V positive definite on flat and
  developable meshes); removing one of them refactors, adding others does not.

* Local editing (paper section 9) and the way back. ``begin_region(faces)`` freezes every other face at
  its current value: the next solves factor only the region (the energy's stencil reaches the frozen
  faces around it, which act as boundary values), and every frozen face is copied bit-identically into
  the result. ``commit_region()`` turns the region's field into a *layer*: a set of frozen values kept in
  later global solves, so the local edit survives global editing; ``release_layer(i)`` lets those faces
  follow the global solve again. Local, global and local editing can so alternate freely, which the
  paper's tool could not do.

* Spectral mode (paper section 8), ``mode="spectral"``. The first k eigenfields (default 500) are computed
  once per mesh, n and weights (minutes on a large mesh; ``precompute()`` with progress and cancellation)
  and cached on disk (``nfield.core.spectral``), then every solve is a reduced solve of k unknowns
  (eqs. 16-18): about a millisecond whatever the mesh size, plus the reconstruction U x. Unlike the exact
  mode, changing the alignment *strength* costs nothing (only the diagonal Lambda changes), so it can be
  dragged live. The result is the low-pass approximation of the exact spline (constraints still hold
  exactly where the basis can represent them; ``constraint_residual`` says how well). Solves with frozen
  faces (a region edit or committed layers) always use the exact solver: the reduced basis cannot hold
  faces fixed, and the region system is small anyway.

Constraints and singularities that lie on frozen faces are held by the frozen values themselves; they stay
in the session (nothing is dropped) and act again as soon as their faces are free.
"""
from __future__ import annotations

import time
from typing import Any, Callable

import numpy as np

from ._loader import native
from .constraints import DirectionConstraint, SingularityConstraint, VectorConstraint
from .mesh import Mesh
from . import spectral
from .guides import _finite
from .session_guides import SessionGuides
from .session_live import SessionLive
from .session_regions import Layer, SessionRegions, _Region
from .session_solvers import SessionSolvers, _token
from .solve import (
    ALIGN_CHOICES,
    FieldResult,
    _check_mesh,
    _check_n,
    _check_order,
    _check_strength,
    _check_weights,
    ResultSummary,
    _face_vectors,
    _live_result,
    _result,
    _singularity_numerators,
)

ProgressCallback = Callable[[float], Any]


class DesignSession(SessionGuides, SessionLive, SessionRegions, SessionSolvers):
    """One mesh, its settings and its constraints, with a warm solver. See the module docstring; guide
    authoring (features, curves, comb, weights, cuts, symmetry) is in session_guides.py, live edits in
    session_live.py, region edits and layers in session_regions.py, the native solvers in session_solvers.py."""

    def __init__(self, mesh: Mesh, n: int = 4, order: int = 2, align: str = "none", strength: float = 1.0,
                 weights: str = "geometric", alignment_field: Any = None, mode: str = "exact",
                 k: int = spectral.DEFAULT_K, precision: str = spectral.DEFAULT_PRECISION, cache_dir: Any = None,
                 progress: ProgressCallback | None = None):
        """mode: "exact" or "spectral"; k, precision ("single" | "double"): the spectral basis;
        cache_dir: where bases are cached (None: the default, False: no disk cache); progress(fraction):
        called during factorizations and basis computations, returning False cancels them."""
        self.mesh = _check_mesh(mesh)
        self.progress = progress
        self.cache_dir = cache_dir
        self._settings: dict[str, Any] = {}
        self._dirs: dict[int, np.ndarray] = {}
        self._vecs: dict[int, np.ndarray] = {}
        self._sings: dict[int, float] = {}
        self._layers: list[Layer] = []
        self._region: _Region | None = None
        self._ops = None
        self._ops_key = None
        self._ops_token = 0
        self._dirty = True  # constraints changed since the last solve
        self._alignment = None
        self._alignment_key = None
        self._solver = None
        self._solver_key = None
        self._in_solver: dict[str, dict] = {"dir": {}, "vec": {}, "sing": {}}
        self._basis = None
        self._basis_key = None
        self.basis_info: spectral.BasisInfo | None = None
        self._reduced = None
        self._reduced_key = None
        self._in_reduced: dict[str, dict] = {"dir": {}, "vec": {}, "sing": {}}
        self.field: FieldResult | None = None
        self._guided_value = None
        self._guided_key = None
        self._guided_token = 0
        self._weight_digest = None
        self._solver_alignment = self._solver_mirror = None
        self._init_guides()
        self._init_live()
        self.configure(n=n, order=order, align=align, strength=strength, weights=weights,
                       alignment_field=alignment_field, mode=mode, k=k, precision=precision, comb_weight=1.0)

    # ------------------------------------------------------------------ settings
    def configure(self, **settings: Any) -> None:
        """Change n, order, align, strength, weights, alignment_field, mode, k, precision or comb_weight (the
        comb's weight relative to the base guide, >= 0).

        The exact solver refactors lazily on the next solve (any change but mode, k, precision); in spectral
        mode a strength change is free and n or weights need another basis (from the cache or computed)."""
        allowed = {"n", "order", "align", "strength", "weights", "alignment_field", "mode", "k", "precision",
                   "comb_weight"}
        unknown = set(settings) - allowed
        if unknown:
            raise ValueError(f"unknown setting(s) {sorted(unknown)} (expected some of {sorted(allowed)})")
        new = dict(self._settings)
        new.update(settings)
        new["n"] = _check_n(new["n"])
        new["order"] = _check_order(new["order"])
        new["strength"] = _check_strength(new["strength"])
        new["weights"] = _check_weights(new["weights"])
        if new["mode"] not in ("exact", "spectral"):
            raise ValueError(f"unknown solver mode {new['mode']!r} (expected 'exact' or 'spectral')")
        new["k"] = spectral.check_k(new["k"])  # against the mesh size when the basis is needed
        new["precision"] = spectral.check_precision(new["precision"])
        new["comb_weight"] = _finite(new["comb_weight"], "comb weight", 0.0)
        if new["align"] not in ALIGN_CHOICES:
            raise ValueError(f"unknown align {new['align']!r} (expected one of {', '.join(ALIGN_CHOICES)})")
        if new["align"] == "field":
            af = new.get("alignment_field")
            if af is None:
                raise ValueError('align="field" needs alignment_field, an (F, 3) array of 3D vectors per face')
            af = np.asarray(af, dtype=np.float64)
            if af.shape != (self.mesh.num_faces, 3) or not np.isfinite(af).all():
                raise ValueError(f"alignment_field must be a finite array of shape ({self.mesh.num_faces}, 3)")
            new["alignment_field"] = af
        if self._settings and new["n"] != self._settings["n"]:
            for v, index in self._sings.items():
                if abs(index * new["n"] - round(index * new["n"])) > 1e-9:
                    raise ValueError(f"the singularity at vertex {v} has index {index}, which is not a multiple "
                                     f"of 1/{new['n']}: remove it before changing n to {new['n']}")
        self._settings = new
        self._dirty = True

    @property
    def settings(self) -> dict[str, Any]:
        return {k: v for k, v in self._settings.items() if k != "alignment_field"}

    @property
    def mode(self) -> str:
        return self._settings["mode"]

    # ------------------------------------------------------------------ spectral basis
    def precompute(self, progress: ProgressCallback | None = None) -> spectral.BasisInfo:
        """Make the spectral basis for the current n, weights, k and precision available: from memory, the
        disk cache, or computed (progress(fraction) is called; returning False cancels with
        nfield.core.Cancelled and leaves the session as it was). Works in either mode, so a tool can
        precompute before switching to spectral mode."""
        ops = self._operators()
        s = self._settings
        key = (self._ops_token, s["k"], s["precision"])
        if self._basis is None or self._basis_key != key:
            basis, info = spectral.load_or_compute_basis(ops, s["k"], s["precision"], self.cache_dir,
                                                         progress if progress is not None else self.progress)
            # Only replace the old basis once the new one exists (cancel or failure keep the old state).
            self._basis, self._basis_key, self.basis_info = basis, key, info
        return self.basis_info

    @property
    def has_basis(self) -> bool:
        """True when the basis for the current settings is in memory (no computation before a solve)."""
        s = self._settings
        if self._basis is None or self._ops_key != self._ops_wanted():
            return False
        return self._basis_key == (self._ops_token, s["k"], s["precision"])

    def basis_available(self) -> bool:
        """True when a solve in spectral mode needs no basis computation: the basis is in memory or a cache
        file for the current settings exists (its content is validated when loaded)."""
        if self.has_basis:
            return True
        s = self._settings
        return spectral.cached_basis_path(self._operators(), s["k"], s["precision"], self.cache_dir) is not None

    def low_pass(self, field=None, details: bool = True) -> FieldResult:
        """The low-pass filter (paper section 8) of a field onto the first k eigenfields: the current
        solution's raw field by default, or a complex per-triangle field. Computes the basis if needed."""
        t0 = time.perf_counter()
        self.precompute()
        if field is None:
            if self.field is None:
                self.solve(details=False)
            field = self.field.raw_solution
        ops = self._operators()
        w = spectral.low_pass(ops, self._basis, field)
        s = self._settings
        return _result(self.mesh, ops, w, n=s["n"], order=s["order"], align=s["align"],
                       strength=s["strength"], weights=s["weights"], lam=None, sign_fixed=[], t0=t0,
                       details=details, mode="spectral", basis_size=int(self._basis.size))

    # ------------------------------------------------------------------ constraints
    def set_direction(self, face: int, direction) -> None:
        """Add or re-aim a hard direction constraint (3D vector, projected onto the face)."""
        self._set_face_constraint(DirectionConstraint, face, direction, "direction", self._dirs, self._vecs)

    def set_vector(self, face: int, vector) -> None:
        """Add or change a hard n-vector constraint (3D vector; its tangent length is the magnitude)."""
        self._set_face_constraint(VectorConstraint, face, vector, "vector", self._vecs, self._dirs)

    def _set_face_constraint(self, kind, face: int, value, attr: str, into: dict, other: dict) -> None:
        """Checks the constraint, then stores its 3D vector in `into` (replacing one of the other kind)."""
        c = kind(int(face), tuple(float(x) for x in np.asarray(value, dtype=float).ravel()))
        self._check_face_constraint(c, attr, f"{attr} constraint")
        other.pop(c.face, None)
        into[c.face] = np.asarray(getattr(c, attr), dtype=np.float64)
        self._dirty = True

    def remove(self, face: int) -> None:
        face = int(face)
        self._dirty = True
        if face in self._dirs:
            del self._dirs[face]
        elif face in self._vecs:
            del self._vecs[face]
        else:
            raise ValueError(f"face {face} has no constraint to remove")

    def set_singularity(self, vertex: int, index: float) -> None:
        """Pin a singularity of the given index (a multiple of 1/n) at an interior vertex."""
        s = SingularityConstraint(int(vertex), float(index))
        ((v, num),) = _singularity_numerators(self.mesh, [s], self._settings["n"], self._solve_native_mesh())
        lo, hi = self.index_range(v)
        n = self._settings["n"]
        if not lo <= num / n <= hi:
            raise ValueError(f"vertex {v} cannot carry index {s.index:g}: with its ring of "
                             f"{len(self._solve_native_mesh().vertex_ring_faces(v))} faces the index must lie in "
                             f"[{lo:g}, {hi:g}] (multiples of 1/{n})")
        if self._region is not None and not self._ring_in_region(v):
            raise ValueError(f"vertex {v} is outside the region being edited")
        self._sings[v] = num / n
        self._dirty = True

    def remove_singularity(self, vertex: int) -> None:
        if int(vertex) not in self._sings:
            raise ValueError(f"vertex {vertex} has no singularity constraint to remove")
        del self._sings[int(vertex)]
        self._dirty = True

    def index_range(self, vertex: int) -> tuple[float, float]:
        """The smallest and largest index (multiples of 1/n) the vertex can carry; ValueError if none."""
        lo, hi = native().singularity_numerator_range(self._operators(), int(vertex))
        n = self._settings["n"]
        return lo / n, hi / n

    @property
    def constraints(self) -> list:
        out: list = [DirectionConstraint(f, tuple(d)) for f, d in sorted(self._dirs.items())]
        out += [VectorConstraint(f, tuple(v)) for f, v in sorted(self._vecs.items())]
        out += [SingularityConstraint(v, i) for v, i in sorted(self._sings.items())]
        return out

    # ------------------------------------------------------------------ solving
    def solve(self, details: bool = True, live: bool = False) -> FieldResult:
        """Solve with the current settings and constraints; returns (and keeps in .field) a FieldResult.

        details=False is for live dragging: it skips the energy (NaN) and the singularity search (None),
        which cost more than the solve itself on large meshes. live=True is for guide edits during an
        interaction (dragging a curve, a comb stroke, painting weights): an edit that changed guide weights is
        solved exactly in a region around it with the rest held fixed (session_live.py; the result's
        live_region says how many faces), and the global solve is left for later (pending_work())."""
        t0 = time.perf_counter()
        s = self._settings
        ops = self._operators()
        inputs = self._solve_inputs()
        region = None
        if self._spectral_applies(inputs):
            w, lam, sign_fixed = self._solve_reduced(ops, inputs)
            mode, basis_size = "spectral", int(self._basis.size)
        else:
            region = self._live_region(inputs) if live else None
            if region is not None:
                base = self._base_record.summary  # the result of the solve the region starts from
                w, lam, sign_fixed = self._solve_local(ops, inputs, region)
                self._remember_base(inputs, w, live=True)  # the next live edit starts from this field
            else:
                w, lam, sign_fixed = self._solve_exact(ops, inputs)
                self._remember_base(inputs, w)
            mode, basis_size = "exact", None
        self._dirty = False
        self.guide_report = inputs.report
        settings = dict(n=s["n"], order=s["order"], align=s["align"], strength=s["strength"], weights=s["weights"],
                        lam=lam, sign_fixed=sign_fixed, t0=t0, details=details, guides=inputs.report)
        if region is not None and base is not None:  # only the region changed: update its faces of the result
            self.field = _live_result(base, self.mesh, ops, w, region, **settings)
        else:
            self.field = _result(self.mesh, ops, w, mode=mode, basis_size=basis_size, **settings)
        if mode == "exact":  # the base of the next live edit
            self._base_record.summary = ResultSummary.of(self.field)
        self.field.live_region = None if region is None else int(len(region))
        return self.field

    def pending_work(self, live: bool = False) -> str | None:
        """What the next solve() must compute before it can solve: "basis" (spectral mode, the basis is
        neither in memory nor cached: minutes), "factorization" (exact mode with new settings, constraints
        kind or frozen faces: about a second per 100k faces), or None (a fast incremental solve). Lets a UI
        move the long work to a worker thread. live=True asks about solve(live=True): a guide edit solved in
        a region needs no global factorization while the last solve (global or live) of the same operators
        and settings is there to start from."""
        inputs = self._solve_inputs()
        if self._spectral_applies(inputs):
            return None if self.basis_available() else "basis"
        if live and self._ops_key == self._ops_wanted() and self._live_base_ready(inputs):
            return None
        if self._ops_key != self._ops_wanted() or self._solver is None or self._global_due:
            return "factorization"
        if self._exact_key(inputs) != self._solver_key:
            return "factorization"
        return "factorization" if self._solver.needs_refactorization(self._vector_triangles(inputs.vecs)) else None

    # ------------------------------------------------------------------ internals
    def _check_face_constraint(self, c, attr: str, label: str) -> None:
        _face_vectors(self.mesh, [c], attr, label)  # range, excluded, zero, normal-parallel
        if self._region is not None and c.face not in set(self._region.faces.tolist()):
            raise ValueError(f"face {c.face} is outside the region being edited")

    def _ops_wanted(self) -> tuple:
        """What the operators depend on: n, the edge weights and the cuts."""
        return (self._settings["n"], self._settings["weights"], self._cuts_token)

    def _operators(self):
        key = self._ops_wanted()
        if self._ops_key != key:
            self._ops = native().FieldOperators(self._solve_native_mesh(), *key[:2])
            self._ops_key = key
            self._ops_token = _token()
            self._alignment_key = None
        return self._ops

    def _alignment_version(self):
        s = self._settings
        af = s.get("alignment_field")
        return (s["align"], None if af is None or s["align"] != "field" else af.tobytes().__hash__())

    def _alignment_field(self, ops):
        key = (self._ops_token, self._alignment_version())
        if self._alignment_key != key:
            s = self._settings
            nat = native()
            if s["align"] in ("curvature-max", "curvature-min"):
                self._alignment = np.asarray(nat.alignment_field(ops, s["align"]), dtype=np.complex128)
            elif s["align"] == "field":
                per_tri = s["alignment_field"][self.mesh.triangle_face]
                idx = np.flatnonzero(np.asarray(self.mesh.native.face_active, dtype=bool))
                self._alignment = np.zeros(self.mesh.num_triangles, dtype=np.complex128)
                self._alignment[idx] = np.asarray(ops.tangent_to_representation(idx, np.ascontiguousarray(per_tri[idx])))
            else:
                self._alignment = None
            self._alignment_key = key
        return self._alignment

