"""The table of bad inputs shared by tests/test_bad_input_matrix.py (nfield.core and the CLI) and
tests/test_blender_failures.py (the add-on): each Case's mesh, parameters, constraints and documented outcome,
and check_field, the check of a returned field. Imports no nfield (the Blender suite imports it before it has
installed the extension)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import pytest

import meshgen as mg

# ------------------------------------------------------------------------------------------ meshes


def _grid():
    """4 x 4 vertex grid in z = 0: 18 triangles, 16 vertices, one boundary loop, interior vertices 5, 6, 9, 10."""
    return mg.grid(4, 4)


def _sphere():
    """Icosphere, 80 faces, 42 vertices (closed: every vertex is interior)."""
    return mg.icosphere(1)


def _single_triangle():
    return np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])


def _with(V, F, extra_v=(), extra_f=()):
    V2 = np.vstack([V, np.asarray(extra_v, float).reshape(-1, 3)]) if len(extra_v) else V
    F2 = np.vstack([F, np.asarray(extra_f, int).reshape(-1, 3)]) if len(extra_f) else F
    return V2, F2


def _nan_vertex():
    V, F = _grid()
    V = V.copy()
    V[3, 1] = np.nan
    return V, F


def _inf_vertex():
    V, F = _grid()
    V = V.copy()
    V[5, 0] = np.inf
    return V, F


def _index_out_of_range():
    V, F = _grid()
    F = F.copy()
    F[2, 1] = 99
    return V, F


def _negative_index():
    V, F = _grid()
    F = F.copy()
    F[2, 1] = -1
    return V, F


def _duplicate_face():
    V, F = _grid()
    return _with(V, F, extra_f=[F[3]])  # face 18 repeats face 3


def _zero_area():
    V, F = _grid()
    return _with(V, F, extra_v=[[2, 0, 0], [3, 0, 0], [4, 0, 0]], extra_f=[[16, 17, 18]])  # face 18: collinear


def _all_degenerate():
    return np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]]), np.array([[0, 1, 2]])


def _needle():
    V, F = _grid()
    # height 1e-9 over a base of 1: below the needle threshold (1e-7 x longest edge), so excluded
    return _with(V, F, extra_v=[[5, 0, 0], [6, 0, 0], [5.5, 1e-9, 0]], extra_f=[[16, 17, 18]])


def _unreferenced_vertex():
    V, F = _grid()
    return _with(V, F, extra_v=[[9, 9, 9]])  # vertex 16, used by no face


def _nonmanifold_edge():
    V, F = _grid()
    a, b, _ = F[4]
    return _with(V, F, extra_v=[[0.3, 0.3, 1.0]], extra_f=[[a, b, 16]])  # face 18: a fin on an edge of face 4


def _nonmanifold_vertex():
    """Two triangle fans (hexagons) sharing only their centre vertex 0 (a bowtie of disks)."""
    ang = np.arange(6) * np.pi / 3
    # fan A around (1, 0, 0) and fan B around (-1, 0, 0), both touching the origin with one ring vertex
    centre_a, centre_b = np.array([1.0, 0, 0]), np.array([-1.0, 0, 0])
    pa = centre_a + np.stack([np.cos(ang), np.sin(ang), 0 * ang], 1)  # pa[3] = origin
    pb = centre_b + np.stack([np.cos(ang + np.pi), np.sin(ang + np.pi), 0 * ang], 1)  # pb[3] = origin
    V = np.vstack([[0.0, 0, 0], centre_a, centre_b, np.delete(pa, 3, 0), np.delete(pb, 3, 0)])
    # indices: 0 shared, 1 centre A, 2 centre B, 3..7 ring A without the origin, 8..12 ring B
    ring_a = [3, 4, 5, 0, 6, 7]
    ring_b = [8, 9, 10, 0, 11, 12]
    F = [[1, ring_a[i], ring_a[(i + 1) % 6]] for i in range(6)] + [[2, ring_b[i], ring_b[(i + 1) % 6]] for i in range(6)]
    return V, np.array(F)


def _flipped_faces():
    V, F = _grid()
    F = F.copy()
    F[5] = F[5][::-1]
    F[11] = F[11][::-1]
    return V, F


def _moebius():
    return mg.mobius(20, 4)


def _components():
    """Two grids and an isolated triangle (faces 36): three components."""
    V, F = _grid()
    return np.vstack([V, V + [5, 0, 0], [[10, 0, 0], [11, 0, 0], [10, 1, 0]]]), np.vstack([F, F + 16, [[32, 33, 34]]])


def _subnormal_bumps():
    """A 3 x 3 grid whose z coordinates are subnormal (~1e-313): flat to double precision, yet its curvature
    alignment and solution come out subnormal."""
    V, F = mg.grid(3, 3)
    V = V.copy()
    V[:, 2] = 1e-313 * (1 + V[:, 0] - V[:, 1] ** 2)
    return V, F


def _scaled_sphere(s):
    def build():
        V, F = mg.icosphere(2)
        return V * s, F
    return build


def _sphere_ring_vectors(vertex=0):
    """Vector constraints on every face around `vertex` of _sphere(), tangent, not a rotation of each other
    by the ring's transport, plus (added by the case) a singularity there: contradictory."""
    V, F = _sphere()
    return [{"face": int(f), "vector": _tangent(V, F, f)} for f in range(len(F)) if vertex in F[f]]


def _bent_strip():
    """3 x 6 grid bent by z = sin(2x) cos(1.5y): 20 faces; vertex 7 is interior with faces 0 and 1 in its ring."""
    V, F = mg.grid(3, 6)
    V = V.copy()
    V[:, 2] = np.sin(2 * V[:, 0]) * np.cos(1.5 * V[:, 1])
    return V, F


def _all_faces_vectors():
    V, F = _sphere()
    return [{"face": int(f), "vector": _tangent(V, F, f)} for f in range(len(F))]


def _neighbour_opposite():
    """Direction constraints +x and -x on the two faces of the grid's first interior edge (n = 1: opposite)."""
    return [{"face": 0, "direction": [1.0, 0.0, 0.0]}, {"face": 1, "direction": [-1.0, 0.0, 0.0]}]


def _tangent(V, F, f, d=(0.3, 0.5, 0.7)):
    """normal(f) x d: a tangent vector of face f (as a list)."""
    a, b, c = V[F[f]]
    nrm = np.cross(b - a, c - a)
    nrm /= np.linalg.norm(nrm)
    return np.cross(nrm, d).tolist()


def _sphere_tangent(f):
    V, F = mg.icosphere(2)
    return _tangent(V, F, f)


# ------------------------------------------------------------------------------------------ the table
@dataclass(frozen=True)
class Case:
    name: str
    what: str                                   # one line for docs/hardening.md
    mesh: Callable[[], tuple]
    params: dict = field(default_factory=dict)  # n, order, strength, align (solve) or n, k (eig)
    constraints: tuple = ()                     # CLI JSON dicts: direction / vector / singularity
    error: str | None = None                    # regex of the error message; None: solves
    cli_error: str | None = None
    blender_error: str | None = None
    blender_na: str | None = None               # why the add-on layer cannot express the input
    command: str = "solve"                      # "solve" | "eig"
    components: int | None = None               # expected connected components of the result
    excluded: tuple = ()                        # faces the report excludes (zero rows)
    outcome: str = ""                           # documented behaviour (docs table), for solving cases

    @property
    def constraint_objects(self):
        return [dict(c) for c in self.constraints]

    def __repr__(self) -> str:  # pytest ids
        return self.name


S = lambda **kw: kw  # noqa: E731  (params)
SING_BOUNDARY_ERR = r"vertex 0\b.*(not an interior vertex|cannot carry a singularity)"
NA_INDEX = "a Blender mesh cannot hold a vertex index outside its vertex list"
NA_EIG = ("the add-on has no eigenvalue command: its spectral mode computes a basis of k eigenfields to solve in, "
          "it does not list eigenvalues")

CASES: list[Case] = [
    # ---- mesh data
    Case("empty_mesh", "no vertices, no faces", lambda: (np.zeros((0, 3)), np.zeros((0, 3), int)),
         error=r"mesh has no vertices", cli_error=r"no vertices", blender_error=r"is empty \(it has no faces\)"),
    Case("no_faces", "three vertices, no face", lambda: (np.eye(3), np.zeros((0, 3), int)),
         error=r"mesh has no faces", cli_error=r"no faces", blender_error=r"is empty \(it has no faces\)"),
    Case("single_triangle", "one triangle with a direction constraint", _single_triangle,
         params=S(n=4), constraints=({"face": 0, "direction": [1.0, 1.0, 0.0]},), components=1,
         outcome="solves: the constrained direction"),
    Case("single_triangle_singularity", "a singularity on a single triangle's (boundary) vertex",
         _single_triangle, params=S(n=4), constraints=({"vertex": 0, "index": 0.25},), error=SING_BOUNDARY_ERR),
    Case("nan_coordinate", "vertex 3 has a NaN coordinate", _nan_vertex,
         error=r"vertex 3 has a non-finite coordinate", cli_error=r"\.off:6: bad coordinate 'nan'"),
    Case("inf_coordinate", "vertex 5 has an infinite coordinate", _inf_vertex,
         error=r"vertex 5 has a non-finite coordinate", cli_error=r"\.off:8: bad coordinate 'inf'"),
    Case("index_out_of_range", "face 2 references vertex 99 of 16", _index_out_of_range,
         error=r"face 2 has a vertex index out of range \[0, 16\)", cli_error=r":21: vertex index 99 out of range 0\.\.15",
         blender_na=NA_INDEX),
    Case("negative_index", "face 2 references vertex -1", _negative_index,
         error=r"face 2 has a vertex index out of range \[0, 16\)", cli_error=r":21: vertex index -1 out of range 0\.\.15",
         blender_na=NA_INDEX),
    Case("duplicate_face", "face 18 repeats face 3", _duplicate_face, params=S(n=4),
         constraints=({"face": 3, "direction": [1.0, 0.0, 0.0]},), excluded=(18,), components=1,
         outcome="solves; the duplicate is excluded (zero row, listed in duplicate_faces)"),
    Case("constraint_on_duplicate_face", "a constraint on the excluded duplicate face 18", _duplicate_face,
         params=S(n=4), constraints=({"face": 18, "direction": [1.0, 0.0, 0.0]},),
         error=r"face 18\b.*excluded from the field"),
    Case("zero_area_face", "face 18 has three collinear vertices", _zero_area, params=S(n=2),
         excluded=(18,), components=1, outcome="solves; the face is excluded (zero row, listed in degenerate_faces)"),
    Case("needle_face", "face 18 has height 1e-9 over a base of 1", _needle, params=S(n=4, order=1),
         excluded=(18,), components=1, outcome="solves; the needle is excluded like a zero-area face"),
    Case("all_faces_degenerate", "the only face has zero area", _all_degenerate,
         error=r"no usable face"),
    Case("unreferenced_vertex", "vertex 16 is used by no face", _unreferenced_vertex, params=S(n=4),
         constraints=({"face": 7, "direction": [0.0, 1.0, 0.0]},), components=1,
         outcome="solves; the vertex is ignored (listed in unused_vertices)"),
    Case("singularity_on_unreferenced_vertex", "a singularity on the unused vertex 16", _unreferenced_vertex,
         params=S(n=4), constraints=({"vertex": 16, "index": 0.25},),
         error=r"vertex 16\b.*(not an interior vertex|cannot carry a singularity)"),
    Case("nonmanifold_edge", "face 18 is a fin on an edge of face 4", _nonmanifold_edge, params=S(n=4),
         constraints=({"face": 4, "direction": [1.0, 0.0, 0.0]}, {"face": 18, "direction": [0.0, 0.0, 1.0]}),
         components=2, outcome="solves; the non-manifold edge is a cut, so the fin is its own component"),
    Case("nonmanifold_vertex", "two fans share only vertex 0", _nonmanifold_vertex, params=S(n=4),
         constraints=({"face": 0, "direction": [0.0, 1.0, 0.0]},), components=2,
         outcome="solves per component (the fan without constraints gets its smoothest field)"),
    Case("singularity_on_nonmanifold_vertex", "a singularity on the shared vertex 0", _nonmanifold_vertex,
         params=S(n=4), constraints=({"vertex": 0, "index": 0.25},), error=SING_BOUNDARY_ERR),
    Case("inconsistent_orientation", "faces 5 and 11 are wound the other way", _flipped_faces, params=S(n=4),
         constraints=({"face": 5, "direction": [1.0, 1.0, 0.0]},), components=1,
         outcome="solves; flipped faces are re-oriented internally (listed in flipped_faces)"),
    Case("moebius_strip", "non-orientable strip, n = 1", _moebius, params=S(n=1, order=1),
         constraints=({"face": 0, "direction": [0.0, 0.0, 1.0]},), components=1,
         outcome="solves; the orientation seam becomes a cut (num_orientation_cuts)"),
    Case("components_and_isolated_triangle", "two grids and an isolated triangle", _components, params=S(n=4),
         constraints=({"face": 0, "direction": [1.0, 0.0, 0.0]}, {"face": 36, "direction": [0.0, 1.0, 0.0]}),
         components=3, outcome="solves per component; a component without data gets its smoothest field"),
    # found by tests/test_solver_properties.py (long profile): w / |w| overflowed to inf / NaN for subnormal w
    Case("subnormal_bumps", "grid with subnormal (1e-313) z coordinates, curvature alignment", _subnormal_bumps,
         params=S(n=2, order=1, align="curvature-max", strength=1e-3), components=1,
         outcome="solves: unit directions (the subnormal solution is normalized without overflow)"),
    Case("tiny_scale", "icosphere scaled by 1e-6, curvature alignment", _scaled_sphere(1e-6),
         params=S(n=4, align="curvature-max"), constraints=({"face": 0, "direction": _sphere_tangent(0)},),
         components=1, outcome="solves; same field as at scale 1 (strength is scale-free)"),
    Case("huge_scale", "icosphere scaled by 1e6, curvature alignment", _scaled_sphere(1e6),
         params=S(n=4, align="curvature-max"), constraints=({"face": 0, "direction": _sphere_tangent(0)},),
         components=1, outcome="solves; same field as at scale 1"),
    # ---- constraints
    Case("constraint_face_gone", "a constraint on face 99 of 18", _grid, params=S(n=4),
         constraints=({"face": 99, "direction": [1.0, 0.0, 0.0]},),
         error=r"face 99 is out of range: the mesh has 18 faces \(valid indices 0\.\.17\)"),
    Case("zero_direction", "direction (0, 0, 0) on face 0", _grid, params=S(n=4),
         constraints=({"face": 0, "direction": [0.0, 0.0, 0.0]},), error=r"face 0\b.*zero vector"),
    Case("normal_direction", "direction along the normal of face 0", _grid, params=S(n=4),
         constraints=({"face": 0, "direction": [0.0, 0.0, 2.0]},), error=r"face 0\b.*parallel to the face normal"),
    Case("tiny_direction", "direction (1e-300, 0, 0): only its direction counts", _grid, params=S(n=4),
         constraints=({"face": 0, "direction": [1e-300, 0.0, 0.0]},), components=1,
         blender_error=r"face 0\b.*zero vector",  # the add-on stores directions as float32: 1e-300 -> 0
         outcome="solves (the length of a direction is irrelevant); the add-on stores float32, so there it is "
                 "the zero vector"),
    Case("opposite_neighbours", "n = 1 directions +x and -x on adjacent faces 0 and 1", _grid, params=S(n=1),
         constraints=tuple(_neighbour_opposite()), components=1,
         outcome="solves: both hold exactly (the field turns between them)"),
    Case("contradictory_ring", "vector constraints on the ring of vertex 0 plus a singularity there", _sphere,
         params=S(n=4), constraints=tuple(_sphere_ring_vectors(0) + [{"vertex": 0, "index": 0.25}]),
         error=r"contradictory constraints.*singularity at vertex 0"),
    # found by tests/test_solver_properties.py: at order 3 the rank test of the Schur complement missed this
    # contradiction and the singularity's rows were violated by O(1); now every solve checks its rows
    Case("contradictory_high_order", "two vector constraints on the ring of vertex 7 plus index -1 there, order 3",
         _bent_strip, params=S(n=1, order=3),
         constraints=({"face": 0, "vector": [-0.20838045255661028, 0.8359095750930188, -0.5077723596850375]},
                      {"face": 1, "vector": [-0.2921966828870946, 0.833019497274182, -0.46978677681566094]},
                      {"vertex": 7, "index": -1.0}),
         error=r"contradictory constraints.*singularity at vertex 7"),
    Case("vector_on_every_face", "a vector constraint on each of the 80 faces (all degrees of freedom)",
         _sphere, params=S(n=4), constraints=tuple(_all_faces_vectors()), components=1,
         outcome="solves: the field is the constraints"),
    Case("more_constraints_than_dofs", "80 vector constraints plus a singularity (over-determined)", _sphere,
         params=S(n=4), constraints=tuple(_all_faces_vectors() + [{"vertex": 0, "index": 0.25}]),
         error=r"contradictory constraints"),
    Case("two_constraints_one_face", "a direction and a vector constraint on face 3", _grid, params=S(n=4),
         constraints=({"face": 3, "direction": [1.0, 0.0, 0.0]}, {"face": 3, "vector": [0.0, 1.0, 0.0]}),
         error=r"face 3 has more than one constraint",
         blender_error=None, blender_na="the add-on keeps one constraint per face: adding another re-aims it"),
    Case("singularity_index_too_large", "index 5 at vertex 0 (ring of 5 faces)", _sphere, params=S(n=4),
         constraints=({"vertex": 0, "index": 5.0},), error=r"vertex 0 cannot carry index 20/4"),
    Case("singularity_on_boundary", "a singularity on boundary vertex 0 of the grid", _grid, params=S(n=4),
         constraints=({"vertex": 0, "index": 0.25},), error=SING_BOUNDARY_ERR),
    Case("singularity_vertex_gone", "a singularity on vertex 1000 of 42", _sphere, params=S(n=4),
         constraints=({"vertex": 1000, "index": 0.25},), error=r"vertex 1000 is out of range: the mesh has 42 vertices"),
    Case("singularity_not_multiple", "index 0.3 for n = 4", _sphere, params=S(n=4),
         constraints=({"vertex": 0, "index": 0.3},), error=r"index 0\.3 at vertex 0 is not a multiple of 1/4"),
    # ---- parameters
    Case("n_zero", "n = 0", _grid, params=S(n=0), error=r"n \(symmetry order\) must be in 1\.\.64 \(got 0\)",
         cli_error=r"argument --n: n must be 1\.\.64 \(got 0\)", blender_error=r"n must be one of 1, 2, 3, 4, 6 \(got 0\)"),
    Case("n_too_large", "n = 65", _grid, params=S(n=65), error=r"n \(symmetry order\) must be in 1\.\.64 \(got 65\)",
         cli_error=r"argument --n: n must be 1\.\.64 \(got 65\)", blender_error=r"n must be one of 1, 2, 3, 4, 6 \(got 65\)"),
    Case("order_zero", "order = 0", _grid, params=S(order=0), error=r"order \(energy order\) must be in 1\.\.4 \(got 0\)",
         cli_error=r"argument --order: order must be 1, 2, 3 or 4 \(got 0\)",
         blender_error=r"order must be 1 \(harmonic\), 2 \(biharmonic\) or 3 \(triharmonic\) \(got 0\)"),
    Case("order_five", "order = 5", _grid, params=S(order=5), error=r"order \(energy order\) must be in 1\.\.4 \(got 5\)",
         cli_error=r"argument --order: order must be 1, 2, 3 or 4 \(got 5\)",
         blender_error=r"order must be 1 \(harmonic\), 2 \(biharmonic\) or 3 \(triharmonic\) \(got 5\)"),
    Case("strength_huge", "strength 1e7 (lambda beyond the mapped range)", _sphere,
         params=S(n=4, align="curvature-max", strength=1e7),
         error=r"strength must be a finite number in \[1e-06, 1e\+06\] \(got 1(e\+0?7|0000000\.0)\)"),
    Case("strength_tiny", "strength 1e-7", _sphere, params=S(n=4, align="curvature-max", strength=1e-7),
         error=r"strength must be a finite number in \[1e-06, 1e\+06\] \(got 1e-0?7\)"),
    Case("strength_negative", "strength -1", _sphere, params=S(n=4, align="curvature-max", strength=-1.0),
         error=r"strength must be a finite number in \[1e-06, 1e\+06\] \(got -1(\.0)?\)"),
    Case("strength_nan", "strength NaN", _sphere, params=S(n=4, align="curvature-max", strength=float("nan")),
         error=r"strength must be a finite number in \[1e-06, 1e\+06\] \(got nan\)"),
    Case("strength_limit", "strength 1e6, the largest admitted", _sphere,
         params=S(n=4, align="curvature-max", strength=1e6), components=1,
         outcome="solves: lambda = -1e6 (4 pi/A)^m, V stays positive definite"),
    Case("eig_k_too_large", "k = 81 eigenvalues of an 80-face mesh", _sphere, params=S(n=4, k=81), command="eig",
         error=r"k = 81 eigenvalues requested but the mesh has only 80 usable faces", blender_na=NA_EIG),
    Case("eig_k_zero", "k = 0", _sphere, params=S(n=4, k=0), command="eig",
         error=r"k \(number of eigenvalues\) must be >= 1 \(got 0\)", cli_error=r"argument --k: k must be >= 1 \(got 0\)",
         blender_na=NA_EIG),
    Case("eig_k_all", "k = 80 (the whole spectrum)", _sphere, params=S(n=4, k=80), command="eig", blender_na=NA_EIG,
         outcome="all 80 eigenvalues, ascending, finite"),
    Case("eig_single_triangle", "k = 1 on a single triangle", _single_triangle, params=S(n=1, k=1), command="eig",
         blender_na=NA_EIG, outcome="one eigenvalue, 0"),
]
CASE_BY_NAME = {c.name: c for c in CASES}
assert len(CASE_BY_NAME) == len(CASES), "duplicate case names"


# ------------------------------------------------------------------------------------------ checks
#: direction constraints: |sin| of the representation-space angle between w_f and d_f. The Schur row holds to
#: rounding (~1e-13 relative, test_splines.py); 1e-8 leaves room for ill-conditioned meshes (needles kept as
#: slivers, scales 1e+-6) without letting a real violation (>= 1e-3 for any wrong field) through.
CONSTRAINT_TOL = 1e-8
#: unit length / tangency of output directions: they are normalized in double precision, so 1e-9 is generous
UNIT_TOL = 1e-9


def check_field(directions, normals, active, n, constraints, *, raw=None, rep=None, report=None, case=None,
                singularities=None, tol_unit=UNIT_TOL, tol_constraint=CONSTRAINT_TOL):
    """Assertions shared by the layers for a field that solved.

    directions (F, 3) first unit direction per face; normals (F, 3); active (F,) bool (faces the mesh keeps);
    raw / rep: raw solution w and the representation of each constraint (core only: exact checks).
    """
    d = np.asarray(directions, float)
    assert np.isfinite(d).all(), "non-finite direction"
    lengths = np.linalg.norm(d, axis=1)
    assert np.abs(lengths[active] - 1).max() < tol_unit, f"not unit: {np.abs(lengths[active] - 1).max()}"
    assert np.all(lengths[~active] == 0), "excluded faces must have zero rows"
    tang = np.abs(np.einsum("ij,ij->i", d, normals))[active]
    assert tang.max() < tol_unit * 10, f"not tangent: {tang.max()}"
    for c in constraints:
        if "face" not in c:
            continue
        f = c["face"]
        v = np.asarray(c.get("direction", c.get("vector")), float)
        v = v / np.abs(v).max()
        t = v - normals[f] * (normals[f] @ v)
        t /= np.linalg.norm(t)
        # one of the n directions is t: angle of d_f to t is a multiple of 2 pi / n
        ang = np.arctan2(np.cross(d[f], t) @ normals[f], d[f] @ t)
        period = 2 * np.pi / n
        err = abs((ang + period / 2) % period - period / 2)
        assert err < max(tol_constraint, 1e-6 if raw is None else tol_constraint), (f, err)
    if raw is not None:
        assert np.isfinite(raw).all()
        for c, z in zip([c for c in constraints if "face" in c], rep):
            w = raw[c["face"]]
            if "direction" in c:
                zn = z / abs(z)
                sin = abs((np.conj(zn) * w).imag) / abs(w)
                assert sin < tol_constraint, (c["face"], sin)
                assert (np.conj(zn) * w).real > 0, f"face {c['face']} points along -d"
            else:
                assert abs(w - z) <= tol_constraint * max(1.0, abs(z)), (c["face"], abs(w - z))
    if singularities is not None:
        got = dict(singularities)
        for c in constraints:
            if "vertex" in c:
                assert got.get(c["vertex"]) == pytest.approx(c["index"]), (c, got)
    if case is not None and report is not None:
        if case.components is not None:
            assert report["num_components"] == case.components, report["num_components"]
        for f in case.excluded:
            assert not active[f]
