"""Quad remeshing along a designed cross field (native remesher, see native/include/nfield/remesh/).

    from nfield.core import Mesh, solve, quad_remesh
    mesh = Mesh.from_file("rocker-arm.obj")
    field = solve(mesh, n=4, order=2, align="curvature-max")
    V, faces, stats = quad_remesh(mesh, field, target_faces=5000)
    stats["quad_fraction"], stats["alignment_mean_deg"], stats["hausdorff_relative"]

The remesher follows "Instant Field-Aligned Meshes" (Jakob, Tarini, Panozzo, Sorkine-Hornung 2015) with
OUR field as the orientation field: the field is moved to vertices n-symmetrically (its singularities stay
within one ring of where they were designed; it is not re-optimised), a 4-PoSy position field is optimised
on a multiresolution hierarchy for the target edge length, and the quad-dominant mesh is extracted from it
(optionally made of quads only by one subdivision step). docs/quad_remeshing.md explains the choice.

Every result carries quality statistics (:func:`quad_mesh_stats`, also usable on any other polygon mesh,
e.g. a peer's output): quad fraction, irregular vertices against the field's singularity count, edge
alignment to the field, Hausdorff distance, scaled Jacobian, manifoldness and orientation.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from ._loader import native
from .mesh import Mesh
from .solve import FieldResult, _check_mesh

__all__ = ["QuadMesh", "quad_remesh", "quad_mesh_stats", "field_directions", "field_singularities",
           "polygons_to_arrays", "write_polygon_obj"]

#: symmetry orders a quad lattice can follow: n = 4 as is, n = 1 and n = 2 with their perpendicular
QUAD_SYMMETRIES = (1, 2, 4)


class QuadMesh(NamedTuple):
    """The remesher's result; unpacks as ``V, faces, stats``.

    vertices : float (V, 3), mesh units.
    faces : list of lists of vertex indices (counter-clockwise around the outward normal).
    stats : dict (see :func:`quad_mesh_stats`, plus the remesher's own report: ``edge_length``,
        ``lattice_spacing``, ``messages`` (what was skipped or repaired), ``components``, ``seconds``...).
    """

    vertices: np.ndarray
    faces: list
    stats: dict


# ---------------------------------------------------------------------- field input
def _check_symmetry(n: Any) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)):
        raise ValueError(f"n must be an integer, got {n!r}")
    n = int(n)
    if n not in QUAD_SYMMETRIES:
        raise ValueError(f"a quad mesh needs a cross field: n = 4 is used as is, n = 1 and n = 2 take the field and "
                         f"its perpendicular; an {n}-direction field has no quad structure (got n = {n})")
    return n


def field_directions(mesh: Mesh, field: Any, n: int | None = None) -> tuple[np.ndarray, int]:
    """One unit 3D direction of the cross field per triangle of ``mesh.native`` (zero rows where the field
    is undefined) and the field's symmetry order.

    field : a FieldResult, a DesignSession (its current field; solved if it has none), a complex array (T,)
        of representation vectors in the native face frames (then ``n`` is required), or a real array of
        3D vectors, one per input face (F, 3) or per triangle (T, 3) (``n`` defaults to 4; any one
        direction of the n per face).
    """
    from .session import DesignSession

    mesh = _check_mesh(mesh)
    nat = native()
    T = mesh.num_triangles
    active = np.asarray(mesh.native.face_active, dtype=bool)
    if isinstance(field, DesignSession):
        if field.mesh is not mesh:
            raise ValueError("the DesignSession belongs to another mesh than the one to remesh")
        field = field.field if field.field is not None else field.solve()
    if isinstance(field, FieldResult):
        if n is not None and int(n) != field.n:
            raise ValueError(f"n = {n} given, but the field has n = {field.n}")
        n = _check_symmetry(field.n)
        u = np.asarray(field.representation, dtype=np.complex128)
        if u.shape != (T,):
            raise ValueError(f"the field has {u.shape[0]} values but the mesh has {T} triangles (another mesh?)")
        return _directions_from_representation(mesh, u, n), n
    arr = np.asarray(field)
    if np.iscomplexobj(arr):
        if n is None:
            raise ValueError("a complex field (representation vectors) needs its symmetry order n")
        n = _check_symmetry(n)
        if arr.shape != (T,):
            raise ValueError(f"a complex field must have shape ({T},) (one value per triangle), got {arr.shape}")
        if not np.isfinite(arr).all():
            raise ValueError(f"the field has a non-finite value at triangle {int(np.flatnonzero(~np.isfinite(arr))[0])}")
        return _directions_from_representation(mesh, arr.astype(np.complex128), n), n
    n = _check_symmetry(4 if n is None else n)
    if arr.ndim != 2 or arr.shape[1] != 3 or not np.issubdtype(arr.dtype, np.number):
        raise ValueError(f"field must be a FieldResult, a DesignSession, a complex (T,) array or a real array of "
                         f"3D vectors (F, 3); got an array of shape {arr.shape}")
    arr = arr.astype(np.float64)
    if arr.shape[0] == mesh.num_faces:
        per_tri = arr[mesh.triangle_face]
    elif arr.shape[0] == T:
        per_tri = arr
    else:
        raise ValueError(f"field must have one 3D vector per face ({mesh.num_faces} rows) or per triangle "
                         f"({T} rows), got {arr.shape[0]} rows")
    if not np.isfinite(per_tri).all():
        bad = int(np.flatnonzero(~np.isfinite(per_tri).all(axis=1))[0])
        raise ValueError(f"the field has a non-finite vector at triangle {bad}")
    normals = np.asarray(mesh.native.face_normals, dtype=np.float64)
    tangent = per_tri - normals * np.sum(per_tri * normals, axis=1, keepdims=True)
    length = np.linalg.norm(tangent, axis=1)
    scale = np.linalg.norm(per_tri, axis=1)
    ok = active & (length > 1e-6 * np.maximum(scale, 1e-300))
    out = np.zeros((T, 3))
    out[ok] = tangent[ok] / length[ok, None]
    if not ok.any():
        raise ValueError("the field is zero (or normal to the surface) on every face: nothing to align the quads to")
    return out, n


def _directions_from_representation(mesh: Mesh, u: np.ndarray, n: int) -> np.ndarray:
    frames = np.asarray(native().FieldOperators(mesh.native, 1).frames, dtype=np.float64)  # (T, 2, 3)
    angle = np.angle(u) / n
    d = np.cos(angle)[:, None] * frames[:, 0] + np.sin(angle)[:, None] * frames[:, 1]
    d[np.abs(u) == 0] = 0.0
    if not np.any(np.abs(u) > 0):
        raise ValueError("the field is zero on every face: nothing to align the quads to")
    return d


def field_singularities(mesh: Mesh, directions: np.ndarray) -> list[tuple[int, float]]:
    """Singularities (vertex, index) of the cross field spanned by one direction per triangle (the 4-field
    of the directions and their perpendiculars; indices are multiples of 1/4)."""
    nat = native()
    ops = nat.FieldOperators(mesh.native, 4)
    idx = np.flatnonzero(np.linalg.norm(directions, axis=1) > 0)
    z = np.zeros(mesh.num_triangles, dtype=np.complex128)
    if idx.size:
        z[idx] = np.asarray(ops.tangent_to_representation(idx, np.ascontiguousarray(directions[idx])))
        z[idx] /= np.abs(z[idx])
    sv, si = nat.singularity_indices(ops, z)
    return [(int(v), float(i)) for v, i in zip(np.asarray(sv).tolist(), np.asarray(si).tolist())]


# ---------------------------------------------------------------------- polygon helpers
def polygons_to_arrays(faces: Sequence[Sequence[int]]) -> tuple[np.ndarray, np.ndarray]:
    """(offsets (F+1,), indices) of a list of polygons."""
    sizes = np.fromiter((len(f) for f in faces), dtype=np.int64, count=len(faces))
    offsets = np.zeros(len(faces) + 1, dtype=np.int64)
    np.cumsum(sizes, out=offsets[1:])
    indices = np.fromiter((int(i) for f in faces for i in f), dtype=np.int64, count=int(offsets[-1]))
    return offsets, indices


def _arrays_to_polygons(offsets: np.ndarray, indices: np.ndarray) -> list:
    idx = indices.tolist()
    off = offsets.tolist()
    return [idx[off[f]:off[f + 1]] for f in range(len(off) - 1)]


def write_polygon_obj(path: str, vertices: np.ndarray, faces: Sequence[Sequence[int]]) -> None:
    """Write a polygon mesh as Wavefront OBJ (1-based indices)."""
    with open(path, "w", encoding="ascii") as fh:
        fh.write("# nfield quad remesh\n")
        fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in np.asarray(vertices, dtype=np.float64))
        fh.writelines("f " + " ".join(str(int(i) + 1) for i in f) + "\n" for f in faces)


# ---------------------------------------------------------------------- statistics
def _reference(mesh: Mesh):
    active = np.asarray(mesh.native.face_active, dtype=bool)
    tris = np.ascontiguousarray(np.asarray(mesh.native.faces, dtype=np.int64)[active])
    return active, tris


def quad_mesh_stats(vertices: Any, faces: Sequence[Sequence[int]], mesh: Mesh, directions: np.ndarray | None = None,
                    singularities: Sequence | None = None) -> dict:
    """Quality statistics of a polygon mesh against the input ``mesh`` and (optionally) a cross field.

    directions : one 3D direction per triangle of ``mesh.native`` (see :func:`field_directions`); None skips
        the alignment statistics.
    singularities : the field's singularities (vertex, index) (None: computed from ``directions``).

    Keys: ``num_vertices``, ``num_faces``, ``num_quads``, ``num_triangles``, ``num_other``,
    ``quad_fraction``; ``irregular_interior`` (valence != 4), ``irregular_boundary`` (valence != 1 +
    round(angle / 90 deg)), ``irregular_vertices`` (their sum), ``field_singularities`` (count),
    ``irregular_per_singularity``; ``alignment_mean_deg``, ``alignment_p95_deg``, ``alignment_max_deg`` (angle of
    each edge to the nearest field direction at its midpoint, in [0, 45]); ``hausdorff`` (mesh units),
    ``hausdorff_relative`` (fraction of the input's bounding-box diagonal), ``distance_to_input``
    (one-sided, output to input); ``min_scaled_jacobian``, ``inverted_faces`` (scaled Jacobian <= 0);
    ``manifold``, ``oriented``, ``closed`` and the counts of ``manifold_report``.
    """
    mesh = _check_mesh(mesh)
    nat = native()
    V = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64).reshape(-1, 3))
    offsets, indices = polygons_to_arrays(faces)
    active, tris = _reference(mesh)
    ref_dirs = None
    if directions is not None:
        ref_dirs = np.ascontiguousarray(np.asarray(directions, dtype=np.float64)[active])
    man = nat.polygon_manifold_report(V, offsets, indices)
    irr_in, irr_b, valence, boundary = nat.polygon_irregular_vertices(V, offsets, indices)
    q = nat.polygon_quality(V, offsets, indices, np.asarray(mesh.native.positions, dtype=np.float64), tris, ref_dirs)
    sizes = np.diff(offsets)
    nf = int(sizes.size)
    jac = np.asarray(q["scaled_jacobians"])
    diag = float(mesh.native.bounding_box_diagonal)
    stats: dict[str, Any] = {
        "num_vertices": int(np.count_nonzero(np.asarray(valence) > 0)),
        "num_faces": nf,
        "num_quads": int(np.count_nonzero(sizes == 4)),
        "num_triangles": int(np.count_nonzero(sizes == 3)),
        "num_other": int(np.count_nonzero(sizes > 4)),
        "quad_fraction": float(np.count_nonzero(sizes == 4) / nf) if nf else 0.0,
        "irregular_interior": int(len(irr_in)),
        "irregular_boundary": int(len(irr_b)),
        "irregular_vertices": int(len(irr_in) + len(irr_b)),
        "irregular_vertex_list": [int(v) for v in np.concatenate([np.asarray(irr_in), np.asarray(irr_b)]).tolist()],
        "hausdorff": float(q["hausdorff"]),
        "hausdorff_relative": float(q["hausdorff"]) / diag if diag > 0 else float("nan"),
        "distance_to_input": float(q["distance_to_reference"]),
        "min_scaled_jacobian": float(jac.min()) if jac.size else float("nan"),
        "inverted_faces": int(np.count_nonzero(jac <= 0)),
        "manifold": bool(man["manifold"]),
        "oriented": bool(man["oriented"]),
        "closed": int(man["boundary_edges"]) == 0,
        "manifold_report": {k: (bool(v) if isinstance(v, bool) else int(v)) for k, v in man.items()},
    }
    if ref_dirs is not None:
        a = np.asarray(q["edge_alignment_degrees"], dtype=np.float64)
        a = a[np.isfinite(a)]
        stats["alignment_mean_deg"] = float(a.mean()) if a.size else float("nan")
        stats["alignment_p95_deg"] = float(np.percentile(a, 95)) if a.size else float("nan")
        stats["alignment_max_deg"] = float(a.max()) if a.size else float("nan")
        if singularities is None:
            singularities = field_singularities(mesh, np.asarray(directions, dtype=np.float64))
    if singularities is not None:
        ns = len(singularities)
        stats["field_singularities"] = ns
        stats["irregular_per_singularity"] = stats["irregular_vertices"] / ns if ns else float("nan")
    return stats


# ---------------------------------------------------------------------- remeshing
def _positive(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a positive number, got {value!r}") from None
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return v


# The native option: -1 makes both candidates, 1 pins the cones, 0 leaves them free.
_PURE_QUAD_CONES = {"best": -1, "pinned": 1, "free": 0}


def _number_in(value: Any, name: str, what: str, low: float, high: float) -> float:
    """float(value) when it lies in [low, high] (NaN does not); else ValueError "<name> must be <what>"."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {what}, got {value!r}") from None
    if not low <= v <= high:
        raise ValueError(f"{name} must be {what}, got {value!r}")
    return v


def quad_remesh(mesh: Mesh, field: Any, *, target_faces: int | None = None, edge_length: float | None = None,
                n: int | None = None, pure_quads: bool = False, pure_quad_method: str = "pair",
                pure_quad_cones: str = "best",
                keep_boundary: bool = True, sharp_angle: float | None = 40.0, feature_field_angle: float = 35.0,
                seed: int = 0, iterations: int = 10, relax_iterations: int = 2, field_relax_iterations: int = 6,
                strict: bool = False, cancel_position_singularities: bool = True, fit_far_points: bool = True,
                split_thin_clusters: bool = True, adaptive_spacing: bool = True, max_spacing_ratio: float = 1.6,
                progress: Callable[[float], Any] | None = None, stats: bool = True) -> QuadMesh:
    """Remesh ``mesh`` into a quad-dominant (or pure quad) mesh whose edges follow ``field``.

    field : FieldResult, DesignSession, or per-face array (see :func:`field_directions`); n = 4 is used as
        is, n = 1 and n = 2 take the field and its perpendicular.
    target_faces : about this many output faces (quads), or
    edge_length : the output edge length in mesh units (give exactly one of the two).
    pure_quads : False: quad-dominant (a few triangles and pentagons near singularities); True: quads only.
    pure_quad_method : how pure quads are made. "pair" (default): at the target edge length, each odd face
        (triangle, pentagon) is joined to the nearest other one (or to the boundary) by a path of faces that
        are split into half-width quads; "subdivide": a lattice twice as coarse, every face split into quads
        once (about as many faces, but 1.5-3x further from the input).
    pure_quad_cones : with the "pair" method, where the field's singularities go. "pinned": each onto a
        lattice point (one valence-3 or -5 vertex per cone, no odd face to pair there); "free": where the
        position field puts them; "best" (default): both, keeping the one with fewer irregular vertices
        unless it flips more faces or lies further from the input (twice the work, on two threads).
        ``stats["pure_quad_conversion"]`` reports the irregular count of each candidate made.
    keep_boundary, sharp_angle : feature curves the output keeps: boundaries, and edges whose dihedral angle
        exceeds ``sharp_angle`` degrees (None or 0: none).
    feature_field_angle : a sharp edge is kept only where the field runs within this many degrees (0..45) of
        it on both its faces (a crease the field crosses diagonally is not forced into a lattice line).
    seed : the random lattice origins; the same seed gives the same mesh.
    iterations : Gauss-Seidel sweeps of the position field per hierarchy level.
    relax_iterations : smoothing steps (towards face centroids, then back onto the surface) after extraction.
    field_relax_iterations : relaxation along the field before the last untangling step: up to 3 global
        least-squares solves moving the vertices so that their edges run along the field, then this many
        local steps (each back onto the surface); after the far-point fit, once more with up to 3 of each
        (the fit's moved vertices held); 0 skips both.
    strict : True refuses (ValueError) a mesh with a component too small for the edge length; False
        leaves such components out and lists them in ``stats["messages"]``.
    cancel_position_singularities : pair the lattice's row ends (dislocations) with each other, with the
        field's singularities or with the boundary by a minimum-cost flow on the integer offsets, and
        re-solve the positions (fewer irregular vertices); ``stats["position_singularities"]`` reports
        the counts before and after. False keeps the position field as optimised.
    fit_far_points : move output vertices onto the input points the output misses by more than a quarter
        of the edge length (tips of toes and fingers one or two quads thick, rounded edges crossed as a chord),
        when that brings the output closer to the input on both sides and leaves no face's corner poor (at a
        crease point, a vertex put on it may take a face neighbour along to what it uncovers);
        ``stats["far_points"]`` reports the moves and the farthest input vertex before and after.
        Independently of this option every quad is then split (its first vertex chosen) along the diagonal
        nearer the input, the split Blender draws; ``stats["rotated_diagonals"]`` counts the quads turned.
    split_thin_clusters : split an output vertex whose surface points wrap round a part thinner than a
        lattice cell (a finger, a claw) into one vertex per side, so that its edges do not cut through the part;
        ``stats["extraction"]["split_clusters"]`` counts them.
    adaptive_spacing : let the lattice spacing follow the field's turning (the conformal scale of the field,
        the mean face size kept), so a field that turns without a singularity is followed by rows that do not
        end (default True; False: one spacing everywhere; pure_quad_method "subdivide" always uses one);
        ``stats["adaptive_spacing"]`` gives the range of spacing / edge length.
    max_spacing_ratio : with ``adaptive_spacing``, the spacing stays within [edge / ratio, edge * ratio]
        (1..4).
    progress : callable(fraction) returning False to cancel (raises ``nfield.core.Cancelled``); the call
        releases the GIL, so it can run in a worker thread.
    stats : False skips the quality statistics (only the remesher's own report is returned).

    Returns QuadMesh(vertices, faces, stats). Raises ValueError naming the problem for bad input.
    """
    t0 = time.perf_counter()
    mesh = _check_mesh(mesh)
    if pure_quad_method not in ("pair", "subdivide"):
        raise ValueError(f"pure_quad_method must be 'pair' or 'subdivide', got {pure_quad_method!r}")
    if pure_quad_cones not in _PURE_QUAD_CONES:
        raise ValueError(f"pure_quad_cones must be 'best', 'pinned' or 'free', got {pure_quad_cones!r}")
    directions, n = field_directions(mesh, field, n)
    if (target_faces is None) == (edge_length is None):
        raise ValueError("give exactly one of target_faces (number of output faces) or edge_length (mesh units)")
    area = float(mesh.native.total_area)
    if target_faces is not None:
        if isinstance(target_faces, bool) or not isinstance(target_faces, (int, np.integer)) or int(target_faces) < 1:
            raise ValueError(f"target_faces must be a positive integer, got {target_faces!r}")
        h = math.sqrt(area / int(target_faces))
    else:
        h = _positive(edge_length, "edge_length")
    if sharp_angle is None:
        sharp_angle = 0.0
    sharp_angle = float(sharp_angle)
    if not (math.isfinite(sharp_angle) and sharp_angle < 180):
        raise ValueError(f"sharp_angle must be below 180 degrees (0 or None: no sharp edges), got {sharp_angle!r}")
    feature_field_angle = _number_in(feature_field_angle, "feature_field_angle", "a number of degrees in 0..45", 0.0, 45.0)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**64:
        raise ValueError(f"seed must be an integer in [0, 2**64), got {seed!r}")
    if isinstance(relax_iterations, bool) or not isinstance(relax_iterations, (int, np.integer)) or not 0 <= int(relax_iterations) <= 100:
        raise ValueError(f"relax_iterations must be an integer in 0..100, got {relax_iterations!r}")
    if isinstance(field_relax_iterations, bool) or not isinstance(field_relax_iterations, (int, np.integer)) \
            or not 0 <= int(field_relax_iterations) <= 100:
        raise ValueError(f"field_relax_iterations must be an integer in 0..100, got {field_relax_iterations!r}")
    if not isinstance(fit_far_points, (bool, np.bool_)):
        raise ValueError(f"fit_far_points must be True or False, got {fit_far_points!r}")
    if not isinstance(split_thin_clusters, (bool, np.bool_)):
        raise ValueError(f"split_thin_clusters must be True or False, got {split_thin_clusters!r}")
    if not isinstance(adaptive_spacing, (bool, np.bool_)):
        raise ValueError(f"adaptive_spacing must be True or False, got {adaptive_spacing!r}")
    max_spacing_ratio = _number_in(max_spacing_ratio, "max_spacing_ratio", "a number in 1..4", 1.0, 4.0)
    if isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or not 1 <= int(iterations) <= 1000:
        raise ValueError(f"iterations must be an integer in 1..1000, got {iterations!r}")

    r = native().quad_remesh(mesh.native, np.ascontiguousarray(directions), edge_length=h, pure_quads=bool(pure_quads),
                             subdivide_for_pure_quads=pure_quad_method == "subdivide",
                             pure_quad_cones=_PURE_QUAD_CONES[pure_quad_cones],
                             keep_boundary=bool(keep_boundary), sharp_angle=sharp_angle,
                             feature_field_angle=feature_field_angle, seed=int(seed),
                             iterations=int(iterations), relax_iterations=int(relax_iterations),
                             field_relax_iterations=int(field_relax_iterations),
                             refuse_small_components=bool(strict),
                             cancel_position_singularities=bool(cancel_position_singularities),
                             fit_far_points=bool(fit_far_points),
                             split_thin_clusters=bool(split_thin_clusters),
                             adaptive_spacing=bool(adaptive_spacing), max_spacing_ratio=max_spacing_ratio,
                             progress=progress)
    V = np.asarray(r["vertices"], dtype=np.float64)
    faces = _arrays_to_polygons(np.asarray(r["face_offsets"]), np.asarray(r["face_indices"]))
    seconds = time.perf_counter() - t0
    out: dict[str, Any] = {}
    if stats:
        ts = time.perf_counter()
        out.update(quad_mesh_stats(V, faces, mesh, directions))
        out["seconds_stats"] = time.perf_counter() - ts
    out.update({
        "n": n,
        "edge_length": h,
        "lattice_spacing": float(r["lattice_spacing"]),
        "pure_quads": bool(pure_quads),
        "pure_quad_method": pure_quad_method if pure_quads else None,
        "seed": int(seed),
        "components": int(r["num_components"]),
        "remeshed_components": int(r["remeshed_components"]),
        "feature_edges": {"boundary": int(r["num_boundary_feature_edges"]), "sharp": int(r["num_sharp_feature_edges"])},
        "hierarchy_levels": int(r["num_levels"]),
        "extraction": dict(r["extraction"]),
        "cleanup": dict(r["cleanup"]),
        "untangle": dict(r["untangle"]),
        "pure_quad_conversion": dict(r["pure_quads"]),
        "position_singularities": dict(r["position_singularities"]),
        "far_points": dict(r["far_points"]),
        "rotated_diagonals": int(r["rotated_diagonals"]),
        "adaptive_spacing": (dict(r["adaptive_spacing"])
                             if adaptive_spacing and not (pure_quads and pure_quad_method == "subdivide") else None),
        "messages": list(r["messages"]) + [f"mesh: {line}" for line in mesh.report.get("summary", []) or []],
        "seconds": seconds,
        "seconds_native": dict(r["seconds"]),
        "vertex_feature_kind": np.asarray(r["vertex_feature_kind"]),
    })
    return QuadMesh(V, faces, out)
