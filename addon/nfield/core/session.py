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

import copy
import dataclasses
import hashlib
import itertools
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ._loader import native
from .constraints import DirectionConstraint, SingularityConstraint, VectorConstraint
from .mesh import Mesh
from . import spectral
from .guides import _finite
from .session_guides import SessionGuides
from .session_live import SessionLive
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


@dataclass(frozen=True)
class Layer:
    """A committed local edit: faces (input numbering) whose field values are held fixed."""

    faces: np.ndarray       # input faces of the region
    triangles: np.ndarray   # their triangles
    values: np.ndarray      # raw field values (complex, per triangle) held fixed
    token: int = field(default_factory=_token, compare=False)


@dataclass
class _Region:
    """A region edit in progress: its faces and triangles, and what cancel_region puts back."""

    faces: np.ndarray          # input faces of the region (sorted, unique)
    triangles: np.ndarray      # their triangles
    saved: tuple               # (direction, vector, singularity constraints) before begin_region
    dirty: bool                # the session's dirty flag before begin_region
    field_before: Any          # the FieldResult before begin_region
    frozen_values: np.ndarray  # raw solution per triangle: the values of everything outside the region
    token: int = field(default_factory=_token)


class DesignSession(SessionGuides, SessionLive):
    """One mesh, its settings and its constraints, with a warm solver. See the module docstring; guide
    authoring (features, curves, comb, weights, cuts, symmetry) is in session_guides.py."""

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

    # ------------------------------------------------------------------ local editing
    def begin_region(self, faces) -> None:
        """Restrict edits to `faces` (input numbering); everything else keeps its current value exactly."""
        if self._region is not None:
            raise ValueError("a region edit is already in progress: commit or cancel it first")
        faces = np.unique(np.asarray(faces, dtype=np.int64).ravel())
        if faces.size == 0:
            raise ValueError("the region is empty: select at least one face")
        if faces[0] < 0 or faces[-1] >= self.mesh.num_faces:
            raise ValueError(f"region face {int(faces[0] if faces[0] < 0 else faces[-1])} is out of range "
                             f"(mesh has {self.mesh.num_faces} faces)")
        if self.field is None:
            self.solve()
        tris = np.flatnonzero(np.isin(self.mesh.triangle_face, faces))
        self._region = _Region(faces=faces, triangles=tris,
                               saved=(copy.deepcopy(self._dirs), copy.deepcopy(self._vecs), dict(self._sings)),
                               dirty=self._dirty, field_before=self.field,
                               frozen_values=np.asarray(self.field.raw_solution).copy())

    def commit_region(self) -> Layer:
        """End the region edit; its field becomes a layer held fixed by later global solves."""
        if self._region is None:
            raise ValueError("no region edit in progress")
        if self.field is None or self.field is self._region.field_before or self._dirty:
            self.solve()
        tris = self._region.triangles
        active = np.asarray(self.mesh.native.face_active, dtype=bool)
        tris = tris[active[tris]]
        layer = Layer(faces=self._region.faces, triangles=tris,
                      values=np.asarray(self.field.raw_solution)[tris].copy())
        self._layers.append(layer)
        self._region = None
        return layer

    def cancel_region(self) -> None:
        """End the region edit and restore the constraints and field from before begin_region."""
        if self._region is None:
            raise ValueError("no region edit in progress")
        self._dirs, self._vecs, self._sings = self._region.saved
        self.field = self._region.field_before
        self._dirty = self._region.dirty
        self._region = None

    @property
    def in_region(self) -> bool:
        return self._region is not None

    @property
    def layers(self) -> list[Layer]:
        return list(self._layers)

    def restore_layer(self, faces, vectors) -> Layer:
        """Re-create a committed layer from stored data (after a reload or undo): `faces` (input numbering)
        and one 3D vector per face whose direction is the field's first direction and whose length is the
        raw field magnitude. Polygons get the same vector on each of their triangles (projected)."""
        faces = np.asarray(faces, dtype=np.int64).ravel()
        vectors = np.asarray(vectors, dtype=np.float64).reshape(-1, 3)
        if faces.shape[0] != vectors.shape[0]:
            raise ValueError(f"restore_layer needs one vector per face ({faces.shape[0]} faces, "
                             f"{vectors.shape[0]} vectors)")
        if faces.size and (faces.min() < 0 or faces.max() >= self.mesh.num_faces):
            raise ValueError(f"layer face out of range (mesh has {self.mesh.num_faces} faces)")
        if not np.isfinite(vectors).all():
            raise ValueError("layer vectors must be finite")
        per_face = dict(zip(faces.tolist(), range(len(faces))))
        active = np.asarray(self.mesh.native.face_active, dtype=bool)
        tris = np.flatnonzero(np.isin(self.mesh.triangle_face, faces) & active)
        rows = np.array([per_face[int(f)] for f in self.mesh.triangle_face[tris]], dtype=np.int64)
        values = np.asarray(self._operators().tangent_to_representation(tris, np.ascontiguousarray(vectors[rows])))
        layer = Layer(faces=np.unique(faces), triangles=tris, values=values.astype(np.complex128))
        self._layers.append(layer)
        return layer

    def release_layer(self, i: int) -> None:
        if self._region is not None:
            raise ValueError("finish the region edit before releasing a layer")
        if not 0 <= i < len(self._layers):
            raise ValueError(f"layer {i} does not exist (there are {len(self._layers)})")
        del self._layers[i]

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

    def _spectral_applies(self, inputs: "_SolveInputs") -> bool:
        """Spectral mode solves in the basis unless the problem needs what the basis cannot hold: frozen faces
        (region edits, layers), mirror symmetry and non-uniform guide weights (the weights make U^H V U a dense
        k x k matrix instead of a diagonal) use the exact solver (docs/guides.md)."""
        return (self._settings["mode"] == "spectral" and not inputs.frozen_tris.size and self._mirror is None
                and inputs.weight_digest is None)

    def _weight_arguments(self, inputs: "_SolveInputs") -> dict:
        """ExactSolver keywords for the guide weights: none when they are uniformly 1 (the plain system)."""
        return {} if inputs.weight_digest is None else {"alignment_weight": inputs.matrix_weight}

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

    # ------------------------------------------------------------------ internals
    def _check_face_constraint(self, c, attr: str, label: str) -> None:
        _face_vectors(self.mesh, [c], attr, label)  # range, excluded, zero, normal-parallel
        if self._region is not None and c.face not in set(self._region.faces.tolist()):
            raise ValueError(f"face {c.face} is outside the region being edited")

    def _ring_in_region(self, v: int) -> bool:
        region = set(self._region.triangles.tolist())
        return all(t in region for t in self._solve_native_mesh().vertex_ring_faces(v))

    def _face_frozen(self, face: int, frozen_set: set) -> bool:
        return int(self.mesh.face_triangle(face)) in frozen_set

    def _frozen(self):
        """(triangles, values, key) of the faces held fixed in the next solve. With mirror symmetry a face is
        held only if its mirror face is held too (the symmetric solve needs both or neither)."""
        tris, values, key = self._frozen_unclosed()
        if self._mirror is not None and tris.size:
            partner = np.asarray(self._mirror.partner)
            held = np.zeros(self.mesh.num_triangles, dtype=bool)
            held[tris] = True
            keep = (partner[tris] < 0) | held[np.maximum(partner[tris], 0)]
            tris, values = tris[keep], values[keep]
        return tris, values, key

    def _frozen_unclosed(self):
        if self._region is not None:
            active = np.asarray(self.mesh.native.face_active, dtype=bool)
            free = np.zeros(self.mesh.num_triangles, dtype=bool)
            free[self._region.triangles] = True
            tris = np.flatnonzero(active & ~free)
            return tris, self._region.frozen_values[tris], ("region", self._region.token)
        if not self._layers:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.complex128), ()
        tris = np.concatenate([layer.triangles for layer in self._layers])
        values = np.concatenate([layer.values for layer in self._layers])
        # A later layer overrides an earlier one on shared faces.
        _, last = np.unique(tris[::-1], return_index=True)
        keep = len(tris) - 1 - last
        return tris[keep], values[keep], tuple(layer.token for layer in self._layers)

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
