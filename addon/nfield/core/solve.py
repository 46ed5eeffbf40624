"""n-field splines, spectra and smoothest fields over the compiled solver (paper sections 4-7)."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Iterable, Sequence

import numpy as np

from ._loader import native
from .constraints import (
    DirectionConstraint,
    SingularityConstraint,
    VectorConstraint,
    _real,
    constraint_from_dict,
)
from .mesh import Mesh, _jsonable

__all__ = ["FieldResult", "solve", "eigenvalues", "smoothest_field", "ALIGN_CHOICES", "WEIGHT_CHOICES"]

ALIGN_CHOICES = ("none", "curvature-max", "curvature-min", "field")
WEIGHT_CHOICES = ("geometric", "combinatorial")
#: a 3D direction whose tangent projection is shorter than this fraction of its length is "normal"
TANGENT_TOLERANCE = 1e-6
#: |index * n - round(index * n)| allowed for a singularity index
INDEX_TOLERANCE = 1e-9
#: symmetry orders the native operators accept (FieldOperators: 1..64)
MAX_N = 64
#: admissible alignment strengths (kMinStrength, kMaxStrength of spline_solver.hpp): lambda = -strength
#: (4 pi/A)^m stays negative, far below the paper's bound lambda_hat_1^m, so V stays positive definite
MIN_STRENGTH, MAX_STRENGTH = 1e-6, 1e6


@dataclass
class FieldResult:
    """A designed n-direction field.

    Attributes
    ----------
    n : symmetry order.
    representation : complex (T,) the unit field u = w / |w| per triangle of ``mesh.native`` in the native
        face frames (0 on excluded faces and where the solution vanishes). For triangle meshes T = F.
    raw_solution : complex (T,) the solver's unnormalized solution w.
    directions : float (F, 3) first of the n unit directions per input face (polygon: its first triangle);
        zero rows on excluded faces.
    singularities : list of (vertex, index) for every interior vertex with a non-zero index of u (None when
        solved with details=False).
    energy : E_order(u) = u^H E_order u of the *unit* (per-face normalized) field u, complex form, the
        paper's scale (see docs and conventions). For smoothest_field the order is 1 (Dirichlet energy).
    seconds : wall time of the computation (operators, solve, post-processing).
    sign_fixed_faces : input faces whose direction constraint was pinned as a vector constraint by the
        solver to guarantee +d (see ExactSolver.sign_fixed_faces).
    mesh_report : the mesh report dict (indices refer to triangles).
    """

    n: int
    order: int
    align: str
    strength: float | None
    weights: str
    representation: np.ndarray
    raw_solution: np.ndarray
    directions: np.ndarray
    singularities: list[tuple[int, float]] | None
    energy: float
    seconds: float
    sign_fixed_faces: list[int]
    mesh_report: dict
    lambda_: float | None = None
    mode: str = "exact"              # "exact" or "spectral" (reduced solve in a basis of basis_size eigenfields)
    basis_size: int | None = None
    guides: Any = None               # GuideReport of the solve (DesignSession), None without guides
    live_region: int | None = None   # faces re-solved by a live local solve (DesignSession.solve(live=True))
    _all_directions: np.ndarray = field(default=None, repr=False)  # type: ignore[assignment]

    @property
    def num_faces(self) -> int:
        return int(self.directions.shape[0])

    def all_directions(self) -> np.ndarray:
        """float (F, n, 3): the n unit directions per input face (zeros on excluded faces)."""
        if callable(self._all_directions):  # computed on first use (live solves skip it)
            object.__setattr__(self, "_all_directions", self._all_directions())
        return self._all_directions

    def to_dict(self) -> dict:
        """JSON-friendly summary without the per-face arrays (the CLI's ``--json`` object)."""
        return _jsonable({
            "faces": self.num_faces,
            "n": self.n,
            "order": self.order,
            "align": self.align,
            "strength": self.strength,
            "weights": self.weights,
            "energy": self.energy,
            "lambda": self.lambda_,
            "singularities": None if self.singularities is None else [{"vertex": int(v), "index": float(i)} for v, i in self.singularities],
            "sign_fixed_faces": [int(f) for f in self.sign_fixed_faces],
            "mesh_report": self.mesh_report,
            "seconds": self.seconds,
            "guides": None if self.guides is None else self.guides.to_dict(),
        })


# ---------------------------------------------------------------------- parameter checks
def _check_int(value: Any, name: str, lo: int, hi: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer, got {value!r}")
    v = int(value)
    if v < lo or (hi is not None and v > hi):
        rng = f">= {lo}" if hi is None else f"in {lo}..{hi}"
        raise ValueError(f"{name} must be {rng} (got {v})")
    return v


def _check_n(n: Any) -> int:
    return _check_int(n, "n (symmetry order)", 1, MAX_N)


def _check_order(order: Any) -> int:
    return _check_int(order, "order (energy order)", 1, 4)


def _check_weights(weights: Any) -> str:
    if weights not in WEIGHT_CHOICES:
        raise ValueError(f"unknown weights {weights!r} (expected one of {', '.join(WEIGHT_CHOICES)})")
    return weights


def _check_strength(strength: Any) -> float:
    must = f"strength must be a finite number in [{MIN_STRENGTH:g}, {MAX_STRENGTH:g}]"
    s = _real(strength, must)
    if not (math.isfinite(s) and MIN_STRENGTH <= s <= MAX_STRENGTH):
        raise ValueError(f"{must} (got {strength!r})")
    return s


def _check_alignment_field(align: str, alignment_field: Any) -> None:
    """An alignment field is given exactly when align is "field"."""
    if align == "field" and alignment_field is None:
        raise ValueError('align="field" needs alignment_field, an (F, 3) array of 3D vectors per face')
    if align != "field" and alignment_field is not None:
        raise ValueError(f'alignment_field is only used with align="field" (got align={align!r})')


def _check_mesh(mesh: Any) -> Mesh:
    if not isinstance(mesh, Mesh):
        raise TypeError(f"mesh must be an nfield.core.Mesh, got {type(mesh).__name__}")
    if mesh.native.num_active_faces == 0:
        raise ValueError("the mesh has no usable faces (all faces are degenerate)")
    return mesh


def _as_constraint(c: Any, where: str):
    if isinstance(c, (DirectionConstraint, VectorConstraint, SingularityConstraint)):
        return c
    if isinstance(c, dict):
        return constraint_from_dict(c, None, where=where)
    raise ValueError(f"{where}: expected a DirectionConstraint, VectorConstraint, SingularityConstraint or "
                     f"dict, got {type(c).__name__}")


def _sort_constraints(constraints: Iterable, vector_constraints: Iterable, singularities: Iterable):
    dirs: list[DirectionConstraint] = []
    vecs: list[VectorConstraint] = []
    sings: list[SingularityConstraint] = []
    for name, items in (("constraints", constraints), ("vector_constraints", vector_constraints),
                        ("singularities", singularities)):
        for i, c in enumerate(items or ()):
            c = _as_constraint(c, f"{name}[{i}]")
            if name == "vector_constraints" and not isinstance(c, VectorConstraint):
                raise ValueError(f"vector_constraints[{i}] is a {type(c).__name__}, expected VectorConstraint")
            if name == "singularities" and not isinstance(c, SingularityConstraint):
                raise ValueError(f"singularities[{i}] is a {type(c).__name__}, expected SingularityConstraint")
            (dirs if isinstance(c, DirectionConstraint) else vecs if isinstance(c, VectorConstraint)
             else sings).append(c)
    return dirs, vecs, sings


def _face_vectors(mesh: Mesh, items: Sequence, attr: str, label: str):
    """Map input faces to triangles and check the 3D vectors: in range, active, non-zero, tangent. All items are
    checked at once; the error names the first item that fails, with the first check it fails in that order."""
    k = len(items)
    tris = np.zeros(k, dtype=np.int64)
    if k == 0:
        return tris, np.empty((0, 3), dtype=np.float64)
    face_errors: dict[int, ValueError] = {}
    for i, c in enumerate(items):
        try:
            tris[i] = mesh.face_triangle(c.face)
        except ValueError as exc:
            face_errors[i] = exc
    d = np.array([np.asarray(getattr(c, attr), dtype=np.float64) for c in items]).reshape(k, 3)
    active = np.asarray(mesh.native.face_active, dtype=bool)[tris]
    normals = np.asarray(mesh.native.face_normals, dtype=np.float64)[tris]
    # Tangency is judged on d / max|d_i|: the norm of d itself under- or overflows for tiny (1e-300) or huge
    # (1e308) components, which are valid directions.
    big = np.abs(d).max(axis=1)
    zero = big == 0.0
    unit = d / np.where(zero, 1.0, big)[:, None]
    length = np.linalg.norm(unit, axis=1)
    proj = unit - normals * (unit * normals).sum(axis=1)[:, None]
    parallel = np.linalg.norm(proj, axis=1) < TANGENT_TOLERANCE * length
    overflow = np.zeros(k, dtype=bool) if attr == "direction" else ~np.isfinite(big * length)
    bad = ~active | zero | parallel | overflow
    bad[list(face_errors)] = True
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        c, t = items[i], int(tris[i])
        if i in face_errors:
            raise face_errors[i]
        if not active[i]:
            what = f"face {c.face}" if not mesh.has_polygons else f"face {c.face} (triangle {t})"
            raise ValueError(f"{label} on {what}: the face is excluded from the field (degenerate: zero area, "
                             f"repeated vertex, needle or duplicate face)")
        if zero[i]:
            raise ValueError(f"{label} on face {c.face}: the {attr} is the zero vector")
        if parallel[i]:
            raise ValueError(f"{label} on face {c.face}: the {attr} {d[i].tolist()} is parallel to the face "
                             f"normal (it has no tangent component)")
        raise ValueError(f"{label} on face {c.face}: the {attr} {d[i].tolist()} is too long (its length "
                         f"overflows a double)")
    if attr == "direction":
        d = unit / length[:, None]  # only the direction counts: keep the native projection in range
    return tris, d


def _check_duplicates(dirs, vecs, sings) -> None:
    seen: dict[int, str] = {}
    for c, kind in [(c, "direction") for c in dirs] + [(c, "vector") for c in vecs]:
        if c.face in seen:
            raise ValueError(f"face {c.face} has more than one constraint ({seen[c.face]} and {kind}); "
                             f"give at most one constraint per face")
        seen[c.face] = kind
    seen_v: set[int] = set()
    for s in sings:
        if s.vertex in seen_v:
            raise ValueError(f"vertex {s.vertex} has more than one singularity constraint")
        seen_v.add(s.vertex)


def _singularity_numerators(mesh: Mesh, sings: Sequence[SingularityConstraint], n: int,
                            native_mesh: Any = None) -> list[tuple[int, int]]:
    """native_mesh: the mesh the field lives on when it differs from mesh.native (cut open along cuts)."""
    nm = mesh.native if native_mesh is None else native_mesh
    out = []
    for s in sings:
        if not 0 <= s.vertex < mesh.num_vertices:
            raise ValueError(f"singularity vertex {s.vertex} is out of range: the mesh has {mesh.num_vertices} "
                             f"vertices (valid indices 0..{mesh.num_vertices - 1})")
        if not nm.vertex_is_interior(s.vertex):
            raise ValueError(f"singularity vertex {s.vertex} is not an interior vertex (it is on the boundary, "
                             f"on a cut, non-manifold, unused or next to an excluded face): only interior vertices "
                             f"carry an index")
        num = s.index * n
        rounded = round(num)
        if abs(num - rounded) > INDEX_TOLERANCE:
            # the nearest singular index (k != 0: index 0 is no singularity)
            k = min((c for c in (math.floor(num), math.ceil(num)) if c != 0), key=lambda c: abs(c - num))
            raise ValueError(f"singularity index {s.index!r} at vertex {s.vertex} is not a multiple of 1/{n} "
                             f"(for n = {n} an index is k/{n} with a non-zero integer k; the nearest is "
                             f"{k}/{n} = {k / n:g})")
        out.append((s.vertex, int(rounded)))
    return out


def _result(mesh: Mesh, ops, w, *, n, order, align, strength, weights, lam, sign_fixed, t0,
            details: bool = True, mode: str = "exact", basis_size: int | None = None, guides: Any = None) -> FieldResult:
    """The FieldResult of a raw solution w (per triangle). The unit field, the first direction per face, the energy
    and the singularities come from one native pass (field_summary.hpp). details=False (live editing) skips the
    energy (NaN) and the singularity search (None)."""
    w = np.asarray(w, dtype=np.complex128)
    u, first_tri, energy, sv, si = native().field_summary(ops, w, order, details)
    first = np.ascontiguousarray(mesh.per_face(first_tri)) if mesh.has_polygons else first_tri  # one row per face
    sings = [(int(v), float(i)) for v, i in zip(sv.tolist(), si.tolist())] if details else None
    return _assemble_result(mesh, ops, w, u, first, sings, energy, n=n, order=order, align=align, strength=strength,
                            weights=weights, lam=lam, sign_fixed=sign_fixed, t0=t0, mode=mode, basis_size=basis_size,
                            guides=guides)


@dataclass
class ResultSummary:
    """What a FieldResult derives from its raw solution, as private copies: the base a live result is updated
    from (DesignSession keeps the one of its last exact solve; the result handed out may be changed by its user)."""

    unit: np.ndarray
    first: np.ndarray
    energy: float
    singularities: list[tuple[int, float]] | None

    @classmethod
    def of(cls, result: FieldResult) -> "ResultSummary":
        sings = None if result.singularities is None else list(result.singularities)
        return cls(result.representation.copy(), result.directions.copy(), result.energy, sings)


def _live_result(previous: ResultSummary, mesh: Mesh, ops, w, triangles, *, n, order, align, strength, weights, lam,
                 sign_fixed, t0, details: bool = True, guides: Any = None) -> FieldResult:
    """The FieldResult of a live local solve (DesignSession.solve(live=True)), from the summary of the solve it
    started from: w differs from that solve's raw solution only on `triangles` (the region), so only their unit
    field and first directions are computed; the energy is the previous energy plus its change on the region
    (energy_rows.hpp), and the singularities are searched again only at the region's vertices. The same result
    as _result(w) (the arrays and the singularities exactly, the energy to rounding), at a cost proportional to
    the region instead of the mesh (but for copying the per-face arrays). A previous solve without details (NaN
    energy, no singularities) gives way to a full pass when details are asked for."""
    w = np.asarray(w, dtype=np.complex128)
    triangles = np.asarray(triangles, dtype=np.int64)
    nat = native()
    unit_there, first_there = nat.field_summary_faces(ops, w, triangles)
    u = previous.unit.copy()
    u[triangles] = unit_there
    first = previous.first.copy()
    faces = mesh.triangle_face[triangles]
    stands_for = mesh.polygon_first_triangle[faces] == triangles  # the triangle whose direction its face shows
    first[faces[stands_for]] = first_there[stands_for]
    energy, sings = math.nan, None
    if details and math.isfinite(previous.energy) and previous.singularities is not None:
        energy = previous.energy + nat.energy_change(ops, order, previous.unit, u, triangles)
        sv, si = nat.singularity_indices_near(ops, u, triangles)
        near = set(sv.tolist())
        sings = sorted([(v, i) for v, i in previous.singularities if v not in near]
                       + [(int(v), float(i)) for v, i in zip(sv.tolist(), si.tolist())])
    elif details:
        _, _, energy, sv, si = nat.field_summary(ops, w, order, True)
        sings = [(int(v), float(i)) for v, i in zip(sv.tolist(), si.tolist())]
    return _assemble_result(mesh, ops, w, u, first, sings, energy, n=n, order=order, align=align, strength=strength,
                            weights=weights, lam=lam, sign_fixed=sign_fixed, t0=t0, mode="exact", basis_size=None,
                            guides=guides)


def _assemble_result(mesh: Mesh, ops, w, u, first, sings, energy, *, n, order, align, strength, weights, lam,
                     sign_fixed, t0, mode, basis_size, guides) -> FieldResult:
    tf = mesh.triangle_face
    fixed = sorted({int(tf[int(t)]) for t in sign_fixed})
    all_faces = lambda: mesh.per_face(np.asarray(ops.representation_to_directions(u), dtype=np.float64))
    return FieldResult(
        n=n, order=order, align=align, strength=strength, weights=weights,
        representation=u, raw_solution=w,
        directions=first,
        singularities=sings, energy=float(energy), seconds=time.perf_counter() - t0,
        sign_fixed_faces=fixed, mesh_report=mesh.report, lambda_=lam, mode=mode, basis_size=basis_size, guides=guides,
        _all_directions=all_faces,
    )


# ---------------------------------------------------------------------- public API
def solve(mesh: Mesh, n: int = 4, order: int = 2, align: str = "none", strength: float = 1.0,
          constraints: Iterable = (), vector_constraints: Iterable = (), singularities: Iterable = (),
          weights: str = "geometric", alignment_field: Any = None, *, features: Any = None,
          alignment_weight: Any = None, alignment_rotation: Any = None, curves: Any = None, cuts: Any = None,
          symmetry: Any = None) -> FieldResult:
    """Design an n-direction field (n-field spline, paper sections 4-7).

    mesh : nfield.core.Mesh.
    n : symmetry order 1..64 (1 vector field, 2 line field, 4 cross field ...).
    order : energy order 1..4 (1 harmonic, 2 biharmonic ...).
    align : "none" | "curvature-max" | "curvature-min" | "field" (then `alignment_field` is an (F, 3) array
        of 3D vectors per input face; their tangent length weights the alignment).
    strength : in [1e-6, 1e6], weight of the alignment (mapped to lambda by the native strength_to_lambda).
    constraints : DirectionConstraint (or SingularityConstraint / VectorConstraint, dispatched by type).
    vector_constraints : VectorConstraint. With vector constraints and no direction constraints the n-vector
        spline (eq. 8/11) is solved; otherwise the n-direction spline (eq. 9/12), with vector constraints
        added as value constraints.
    singularities : SingularityConstraint (index a multiple of 1/n, interior vertices only).
    weights : "geometric" | "combinatorial".
    Guides (nfield.core.guides, docs/guides.md), keyword-only:
    features : a FeatureGuide or a spec string such as "boundary,sharp:30" (soft mode, defaults).
    alignment_weight, alignment_rotation : per input face, the base alignment's weight (>= 0) and turn (radians).
    curves : {name: CurveGuide} (or a list, named by position).
    cuts : (k, 2) vertex pairs of edges across which the field may jump.
    symmetry : a Symmetry, or an axis "x" | "y" | "z" (exact mirror symmetry; refuses unmatched faces).
    With any guide the solve runs through a DesignSession (same result type, with `guides`, the GuideReport).

    Raises ValueError (bad parameter or constraint; the message names it) or RuntimeError (numerical failure).
    """
    if any(x is not None for x in (features, alignment_weight, alignment_rotation, curves, cuts, symmetry)):
        return _solve_guided(mesh, n=n, order=order, align=align, strength=strength, constraints=constraints,
                             vector_constraints=vector_constraints, singularities=singularities, weights=weights,
                             alignment_field=alignment_field, features=features, alignment_weight=alignment_weight,
                             alignment_rotation=alignment_rotation, curves=curves, cuts=cuts, symmetry=symmetry)
    t0 = time.perf_counter()
    mesh = _check_mesh(mesh)
    n = _check_n(n)
    order = _check_order(order)
    strength = _check_strength(strength)
    weights = _check_weights(weights)
    if align not in ALIGN_CHOICES:
        raise ValueError(f"unknown align {align!r} (expected one of {', '.join(ALIGN_CHOICES)})")
    _check_alignment_field(align, alignment_field)

    dirs, vecs, sings = _sort_constraints(constraints, vector_constraints, singularities)
    _check_duplicates(dirs, vecs, sings)
    d_tris, d_vecs = _face_vectors(mesh, dirs, "direction", "direction constraint")
    v_tris, v_vecs = _face_vectors(mesh, vecs, "vector", "vector constraint")
    sing_nums = _singularity_numerators(mesh, sings, n)

    nat = native()
    ops = nat.FieldOperators(mesh.native, n, weights)

    alignment = None
    if align in ("curvature-max", "curvature-min"):
        alignment = np.asarray(nat.alignment_field(ops, align), dtype=np.complex128)
    elif align == "field":
        af = np.asarray(alignment_field, dtype=np.float64)
        if af.shape != (mesh.num_faces, 3):
            raise ValueError(f"alignment_field must have shape ({mesh.num_faces}, 3) (one 3D vector per input "
                             f"face), got {af.shape}")
        if not np.isfinite(af).all():
            bad = int(np.flatnonzero(~np.isfinite(af).all(axis=1))[0])
            raise ValueError(f"alignment_field has a non-finite vector at face {bad}")
        per_tri = af[mesh.triangle_face]
        idx = np.flatnonzero(np.asarray(mesh.native.face_active, dtype=bool))
        alignment = np.zeros(mesh.num_triangles, dtype=np.complex128)
        alignment[idx] = np.asarray(ops.tangent_to_representation(idx, np.ascontiguousarray(per_tri[idx])))

    kind = "vector" if vecs and not dirs else "direction"
    # One-shot solver: vector constraints are substituted (anchors), direction constraints and singularities go
    # through the Schur system without cached columns: one factorization and one or two solves.
    solver = nat.ExactSolver(ops, order, strength, alignment, kind,
                             anchor_faces=np.asarray(v_tris, dtype=np.int64) if len(vecs) else None,
                             cache_columns=False)

    if len(dirs):
        zd = np.asarray(ops.tangent_to_representation(d_tris, d_vecs), dtype=np.complex128)
        for c, t, z in zip(dirs, d_tris, zd):
            _native_call(solver.set_direction_constraint, (int(t), complex(z / abs(z))), mesh, c.face, int(t))
    if len(vecs):
        zv = np.asarray(ops.tangent_to_representation(v_tris, v_vecs), dtype=np.complex128)
        for c, t, z in zip(vecs, v_tris, zv):
            _native_call(solver.set_vector_constraint, (int(t), complex(z)), mesh, c.face, int(t))
    for v, num in sing_nums:
        solver.set_singularity(int(v), int(num))

    w = np.asarray(solver.solve(), dtype=np.complex128)
    lam = getattr(solver, "lambda_", None)
    return _result(mesh, ops, w, n=n, order=order, align=align, strength=strength, weights=weights,
                   lam=None if lam is None else float(lam), sign_fixed=list(solver.sign_fixed_faces), t0=t0)


def _solve_guided(mesh: Mesh, *, n, order, align, strength, constraints, vector_constraints, singularities, weights,
                  alignment_field, features, alignment_weight, alignment_rotation, curves, cuts, symmetry) -> FieldResult:
    """solve() with guides: one DesignSession, set up and solved once."""
    from .session import DesignSession

    t0 = time.perf_counter()
    mesh = _check_mesh(mesh)
    _check_alignment_field(align, alignment_field)
    dirs, vecs, sings = _sort_constraints(constraints, vector_constraints, singularities)
    _check_duplicates(dirs, vecs, sings)
    s = DesignSession(mesh, n=n, order=order, align=align, strength=strength, weights=weights,
                      alignment_field=alignment_field)
    if cuts is not None:
        s.set_cuts(cuts)
    if symmetry is not None:
        s.set_symmetry(symmetry)
    if features is not None:
        s.set_features(features)
    s.set_alignment_weight(alignment_weight)
    s.set_alignment_rotation(alignment_rotation)
    if curves is not None:
        items = curves.items() if isinstance(curves, dict) else ((str(i), c) for i, c in enumerate(curves))
        for name, c in items:
            s.set_curve(str(name), c)
    for c in dirs:
        s.set_direction(c.face, c.direction)
    for c in vecs:
        s.set_vector(c.face, c.vector)
    for c in sings:
        s.set_singularity(c.vertex, c.index)
    result = s.solve()
    result.seconds = time.perf_counter() - t0
    return result


def _native_call(fn, args, mesh: Mesh, face: int, tri: int) -> None:
    try:
        fn(*args)
    except ValueError as exc:
        if mesh.has_polygons and face != tri:
            raise ValueError(f"constraint on face {face} (triangle {tri}): {exc}") from None
        raise


def eigenvalues(mesh: Mesh, n: int, k: int, weights: str = "geometric") -> np.ndarray:
    """The k smallest eigenvalues of S z = lambda M z (complex form: each eigenvalue once), ascending.

    On a sphere of radius R they approach 2 (l (l + 1) - n^2) / R^2, l >= n (multiplicity 2l + 1).
    """
    mesh = _check_mesh(mesh)
    n = _check_n(n)
    k = _check_int(k, "k (number of eigenvalues)", 1)
    weights = _check_weights(weights)
    if k > mesh.native.num_active_faces:
        raise ValueError(f"k = {k} eigenvalues requested but the mesh has only "
                         f"{mesh.native.num_active_faces} usable faces")
    ops = native().FieldOperators(mesh.native, n, weights)
    vals, _vecs = native().eigen(ops, k)
    return np.asarray(vals, dtype=np.float64)


def smoothest_field(mesh: Mesh, n: int, weights: str = "geometric") -> FieldResult:
    """The smoothest n-direction field (first eigenvector of each connected component), normalized per face.

    Its `energy` is the harmonic energy E_1 of the unit field (order 1).
    """
    t0 = time.perf_counter()
    mesh = _check_mesh(mesh)
    n = _check_n(n)
    weights = _check_weights(weights)
    ops = native().FieldOperators(mesh.native, n, weights)
    w = np.asarray(native().smoothest_field(ops), dtype=np.complex128)
    return _result(mesh, ops, w, n=n, order=1, align="none", strength=None, weights=weights, lam=None,
                   sign_fixed=[], t0=t0)
