"""Quad remeshing along a designed field (nfield.core.quad_remesh, native/include/nfield/remesh/): properties
of the output on every test mesh, determinism, following a constraint, irregular vertices at the field's
singularities, dirty input, bad input, progress / cancel / GIL, and the CLI.

Runtime: about a minute on the shared 2-core machine (every test mesh is remeshed once at ~1,500 faces; the
bunny and the armadillo are marked `slow`)."""
from __future__ import annotations

import math
import subprocess
import sys
import threading

import numpy as np
import pytest

from conftest import MESH_NAMES, core_mesh, face_cycle, mesh_path, package_env, run_beside_main_loop
import meshgen
import mesh_reference as mref
from nfield.core import (
    DesignSession,
    DirectionConstraint,
    Mesh,
    field_directions,
    native,
    quad_remesh,
    smoothest_field,
    solve,
)
from nfield.core.remesh import polygons_to_arrays


def euler_charge(V, F) -> int:
    """sum over vertices (4 - valence) + sum over faces (4 - size); equals 4 chi for a closed polygon mesh."""
    off, idx = polygons_to_arrays(F)
    _, _, valence, _ = native().polygon_irregular_vertices(np.asarray(V), off, idx)
    valence = np.asarray(valence)
    used = valence > 0
    return int(np.sum(4 - valence[used]) + sum(4 - len(f) for f in F))


def vertex_distance_to_input(V, mesh) -> float:
    """Largest distance of the points V to the input surface (each point as a degenerate polygon, so that
    polygon_quality samples nothing else)."""
    n = len(V)
    off = np.arange(0, 3 * n + 1, 3)
    idx = np.repeat(np.arange(n), 3)
    active = np.asarray(mesh.native.face_active)
    tris = np.asarray(mesh.native.faces, dtype=np.int64)[active]
    q = native().polygon_quality(np.asarray(V, float), off, idx, np.asarray(mesh.native.positions), tris)
    return float(q["distance_to_reference"])


# ---------------------------------------------------------------------------------------------- every mesh
# The two largest meshes (69k and 86k faces) run the same code as the others on more data: `slow` (left out
# of `test --quick` and of the sanitizer job). They are remeshed at 3,000 faces: at 1,500 their thinnest parts
# (the bunny's ears, the armadillo's fingers and claws) are narrower than one quad.
LARGE = ("stanford-bunny.obj", "armadillo.obj")


@pytest.mark.parametrize("pure", [False, "pair", "subdivide"], ids=["quad-dominant", "pure-quads", "pure-subdivided"])
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in LARGE else n for n in MESH_NAMES])
def test_output_is_manifold_oriented_and_unflipped_on_every_test_mesh(name, pure):
    """Every test mesh, both modes, features kept (boundaries, sharp edges over 40 degrees): no edge in more than
    two faces, every vertex one fan, every edge walked both ways, and no flipped face: no corner with a scaled
    Jacobian <= 0 against the input's normal there (a face turned against the surface, folded over, or a dart;
    the definition of a non-positive Jacobian at a corner that invalidates a finite element; quad_mesh_stats,
    tested on hand-made flipped faces in test_remesh_stats.py)."""
    mesh = core_mesh(name)
    field = solve(mesh, n=4, order=2, align="curvature-max")
    target = 3000 if name in LARGE else 1500
    V, F, st = quad_remesh(mesh, field, target_faces=target, pure_quads=bool(pure), pure_quad_method=pure or "pair")
    print(name, {k: st[k] for k in ("num_faces", "quad_fraction", "irregular_vertices", "field_singularities",
                                    "alignment_mean_deg", "hausdorff_relative", "min_scaled_jacobian")}, st["untangle"])
    assert st["manifold"] and st["oriented"], st["manifold_report"]
    assert st["manifold_report"]["nonmanifold_vertices"] == 0 and st["manifold_report"]["inconsistent_edges"] == 0
    assert all(len(f) >= 3 and len(set(f)) == len(f) for f in F)
    assert np.isfinite(V).all()
    assert st["inverted_faces"] == 0 and st["min_scaled_jacobian"] > 0, st["untangle"]
    if pure:
        assert st["quad_fraction"] == 1.0
    # The face count follows the target: the lattice has one cell per edge_length^2 of area, so the count is
    # close to the target; 25% covers the area the lattice loses at boundaries, features and small parts.
    assert 0.75 * target < st["num_faces"] < 1.25 * target
    # Every output vertex lies on the input (projected onto it): up to rounding.
    assert vertex_distance_to_input(V, mesh) < 1e-9 * mesh.native.bounding_box_diagonal
    if mesh.report["num_boundary_edges"] == 0 and mesh.report["num_components"] == 1 and st["closed"]:
        chi = mesh.report["euler_characteristic"]
        assert euler_charge(V, F) == 4 * chi  # closed output of the input's topology


def test_pure_quads_are_all_quads_and_manifold():
    mesh = core_mesh("fandisk.obj")
    field = solve(mesh, n=4, order=2, align="curvature-max")
    V, F, st = quad_remesh(mesh, field, target_faces=2000, pure_quads=True)
    assert st["quad_fraction"] == 1.0 and all(len(f) == 4 for f in F)
    assert st["manifold"] and st["oriented"]
    assert 0.7 * 2000 < st["num_faces"] < 1.3 * 2000
    # every odd face of the quad-dominant mesh was paired (with another or with the boundary)
    conv = st["pure_quad_conversion"]
    assert conv["odd_faces"] > 0 and conv["unpaired"] == 0 and st["lattice_spacing"] == pytest.approx(st["edge_length"])


def _valences(offsets, indices):
    edges = set()
    for i in range(len(offsets) - 1):
        f = indices[offsets[i]:offsets[i + 1]]
        for a, b in zip(f, np.roll(f, -1)):
            edges.add((min(a, b), max(a, b)))
    valence = np.zeros(max(max(e) for e in edges) + 1, dtype=int)
    for a, b in edges:
        valence[a] += 1
        valence[b] += 1
    return valence


def test_pinned_cones_become_single_valence_3_vertices():
    """Pure quads by pairing, with the field's cones pinned to lattice points (pure_quad_cones=1): on a
    closed quad mesh of genus 0 the valences satisfy sum(4 - valence) = 4 chi = 8, so 8 valence-3 vertices
    and nothing else irregular is the least possible. The sphere's smoothest field has 8 cones of index
    +1/4; pinned, each becomes one valence-3 vertex on its cone and no odd face is left there, and at 300
    faces the output is that optimum. Left free (pure_quad_cones=0) the position field puts some of them
    inside lattice cells (triangles), and pairing those adds vertices of valence 3 and 5 (measured 10
    irregular vertices). The default tries both and keeps the better one. With one lattice spacing: the
    adaptive spacing (the default) leaves one valence-5 vertex more here (pinned cones fix the lattice at 8
    points, which a spacing that varies between them cannot always meet in whole steps)."""
    V, F = meshgen.icosphere(4)
    mesh = Mesh(V, F)
    field = smoothest_field(mesh, 4)
    cones = mesh.vertices[[v for v, _ in field.singularities]]
    directions, _ = field_directions(mesh, field)
    h = math.sqrt(float(mesh.native.total_area) / 300)
    runs = {}
    for mode in (0, 1, -1):
        r = native().quad_remesh(mesh.native, np.ascontiguousarray(directions), edge_length=h, pure_quads=True,
                                 pure_quad_cones=mode, adaptive_spacing=False)
        runs[mode] = r
        print(mode, dict(r["pure_quads"]))
    pinned = runs[1]
    valence = _valences(np.asarray(pinned["face_offsets"]), np.asarray(pinned["face_indices"]))
    assert pinned["pure_quads"]["pinned_cones"] == 8
    assert np.all(np.diff(np.asarray(pinned["face_offsets"])) == 4)
    assert sorted(set(valence.tolist())) == [3, 4] and int(np.sum(valence == 3)) == 8
    # each valence-3 vertex sits on its own cone: within an edge length (measured 0.1-0.6 h: the designed
    # singularity is an input vertex, the vertex cross field moves it into one of that vertex's triangles
    # (one input edge, about 0.4 h here), whose centroid is pinned; then the vertex is relaxed)
    Vq = np.asarray(pinned["vertices"])[valence == 3]
    d = np.linalg.norm(cones[:, None] - Vq[None], axis=2)
    assert np.all(d.min(axis=1) < h) and len(set(d.argmin(axis=1).tolist())) == 8
    free = _valences(np.asarray(runs[0]["face_offsets"]), np.asarray(runs[0]["face_indices"]))
    assert runs[0]["pure_quads"]["pinned_cones"] == 0 and int(np.sum(free != 4)) > 8
    both = runs[-1]["pure_quads"]
    assert both["irregular_pinned_cones"] == 8 and both["irregular_free_cones"] == int(np.sum(free != 4))
    assert both["pinned_cones"] == 8 and both["cones_tried"] == 8
    np.testing.assert_array_equal(runs[-1]["face_indices"], pinned["face_indices"])
    with pytest.raises(ValueError, match="pure_quad_cones"):
        native().quad_remesh(mesh.native, np.ascontiguousarray(directions), edge_length=h, pure_quad_cones=2)


def test_pure_quad_cones_option_of_the_core_call():
    """quad_remesh(pure_quad_cones=...) reaches the native choice: on the sphere at 300 faces (the native
    test above) "pinned" gives the optimum of 8 valence-3 vertices, "free" more, and "best" the pinned mesh;
    the statistics of each run count what its report says."""
    V, F = meshgen.icosphere(4)
    mesh = Mesh(V, F)
    field = smoothest_field(mesh, 4)
    # One lattice spacing, as in the native test above (the adaptive one measures 10 irregular vertices).
    runs = {c: quad_remesh(mesh, field, target_faces=300, pure_quads=True, pure_quad_cones=c, adaptive_spacing=False)
            for c in ("pinned", "free", "best")}
    pinned, free, best = (runs[c].stats for c in ("pinned", "free", "best"))
    assert pinned["irregular_vertices"] == 8 and pinned["pure_quad_conversion"]["pinned_cones"] == 8
    assert free["pure_quad_conversion"]["pinned_cones"] == 0 and free["irregular_vertices"] > 8
    assert best["pure_quad_conversion"]["irregular_free_cones"] == free["irregular_vertices"]
    assert best["pure_quad_conversion"]["irregular_pinned_cones"] == 8
    assert runs["best"].faces == runs["pinned"].faces
    with pytest.raises(ValueError, match="pure_quad_cones"):
        quad_remesh(mesh, field, target_faces=300, pure_quads=True, pure_quad_cones="auto", adaptive_spacing=False)


@pytest.mark.parametrize("name", ["fertility.off", "rocker-arm.obj"])
def test_pure_quads_at_full_resolution_stay_as_close_to_the_input_as_quad_dominant(name):
    """Pure quads by pairing the odd faces keep the quad-dominant lattice (the same spacing): only a few
    percent of the faces change, into half-width quads whose new vertices lie on the input. So the distance
    to the input stays that of the quad-dominant mesh (measured at 1,500 faces: fertility +18%, rocker arm
    -2%; 1.35x allows for the relaxation moving the vertices around the paths). (The subdivision of a
    lattice twice as coarse is 1.5-3x further away at 5,000 faces on four of the five benchmark meshes, but
    a Hausdorff distance is one worst point, and at 1,500 faces on the rocker arm it happens to be closer.)"""
    mesh = core_mesh(name)
    field = solve(mesh, n=4, order=2, align="curvature-max")
    dominant = quad_remesh(mesh, field, target_faces=1500).stats
    paired = quad_remesh(mesh, field, target_faces=1500, pure_quads=True).stats
    print(name, {k: (dominant[k], paired[k]) for k in ("hausdorff_relative", "irregular_vertices",
                                                       "alignment_mean_deg", "num_faces")})
    assert paired["quad_fraction"] == 1.0
    assert paired["hausdorff_relative"] < 1.35 * dominant["hausdorff_relative"]
    # the half rows follow the lattice rows: the alignment stays within a degree of the quad-dominant mesh's
    assert paired["alignment_mean_deg"] < dominant["alignment_mean_deg"] + 1.0


@pytest.mark.parametrize("name", ["fertility.off", "rocker-arm.obj"])
def test_relaxation_along_the_field_aligns_the_edges_better(name):
    """The relaxation along the field (a global least-squares solve of the vertices' tangent moves, then
    local steps; the off-axis parts measured with the field at each edge's midpoint, as the alignment
    statistic is) lowers the mean edge alignment: at 1,500 faces 3.41 -> 2.31 deg on fertility, 3.94 -> 2.66
    on the rocker arm. The local steps alone gained 0.25 deg on both, so a gain of 0.6 deg needs the solve.
    It flips nothing (guarded by the corner Jacobians)."""
    mesh = core_mesh(name)
    field = solve(mesh, n=4, order=2, align="curvature-max")
    plain = quad_remesh(mesh, field, target_faces=1500, field_relax_iterations=0).stats
    relaxed = quad_remesh(mesh, field, target_faces=1500).stats
    print(name, plain["alignment_mean_deg"], relaxed["alignment_mean_deg"])
    assert relaxed["alignment_mean_deg"] < plain["alignment_mean_deg"] - 0.6
    assert relaxed["inverted_faces"] == 0
    with pytest.raises(ValueError, match="field_relax_iterations"):
        quad_remesh(mesh, field, target_faces=1500, field_relax_iterations=-1)


def test_pure_quad_method_is_checked():
    mesh = core_mesh("fandisk.obj")
    with pytest.raises(ValueError, match="pure_quad_method"):
        quad_remesh(mesh, np.zeros((mesh.native.num_faces, 3)), target_faces=500, pure_quads=True,
                    pure_quad_method="catmull-clark")


# ---------------------------------------------------------------------------------------------- determinism
def test_deterministic_per_seed():
    mesh = core_mesh("rocker-arm.obj")
    field = solve(mesh, n=4, order=2, align="curvature-max")
    a = quad_remesh(mesh, field, target_faces=800, seed=7, stats=False)
    b = quad_remesh(mesh, field, target_faces=800, seed=7, stats=False)
    c = quad_remesh(mesh, field, target_faces=800, seed=8, stats=False)
    assert np.array_equal(a.vertices, b.vertices) and a.faces == b.faces
    assert not (a.vertices.shape == c.vertices.shape and np.array_equal(a.vertices, c.vertices))


# ---------------------------------------------------------------------------------------------- follows the field
def _edge_angle_mod_90(V, F, centre, radius):
    """Circular mean (mod 90 degrees) of the directions of the edges whose midpoints lie within radius."""
    edges = {(min(a, b), max(a, b)) for f in F for a, b in zip(f, f[1:] + f[:1])}
    e = np.array(sorted(edges))
    mid = 0.5 * (V[e[:, 0]] + V[e[:, 1]])
    near = np.linalg.norm(mid[:, :2] - centre[:2], axis=1) < radius
    d = V[e[near, 1]] - V[e[near, 0]]
    theta = np.arctan2(d[:, 1], d[:, 0])
    z = np.mean(np.exp(4j * theta))
    return math.degrees(np.angle(z) / 4), abs(z), int(near.sum())


def test_rotating_a_single_constraint_rotates_the_edges_around_it():
    V, F = meshgen.grid(41, 41, random_diagonals=True, seed=3)
    mesh = Mesh(V, F)
    centre = np.array([0.5, 0.5, 0.0])
    face = int(np.argmin(np.linalg.norm(mref.face_centroids(V, F) - centre, axis=1)))
    angles = {}
    for degrees in (0.0, 30.0):
        t = math.radians(degrees)
        field = solve(mesh, n=4, order=2, constraints=[DirectionConstraint(face, (math.cos(t), math.sin(t), 0.0))])
        Vq, Fq, st = quad_remesh(mesh, field, target_faces=400, keep_boundary=False)
        angle, coherence, count = _edge_angle_mod_90(Vq, Fq, centre, 0.25)
        print(degrees, angle, coherence, count)
        assert count > 40 and coherence > 0.95  # the edges near the constraint form one straight grid
        angles[degrees] = angle
    turned = (angles[30.0] - angles[0.0]) % 90.0
    # 30 +- 3 degrees (the required tolerance): the field is exactly constant on the flat square (biharmonic
    # with one constraint), and the edges follow it to about a degree (alignment statistics).
    assert abs(turned - 30.0) <= 3.0, angles


def test_irregular_vertices_sit_at_the_fields_singularities():
    """On a sphere the smoothest cross field has 8 singularities of index +1/4. Every one of them gets an
    irregular vertex (valence 3) or a triangle within 2.5 edge lengths, and the irregular vertices
    concentrate there: they are on average clearly closer to a singularity than the output vertices are.
    Not all of them: the position field also has dislocations (a triangle next to a valence-5 vertex) away
    from the singularities, where the lattice must gain or lose a row (docs/quad_remeshing.md)."""
    V, F = meshgen.icosphere(4)
    mesh = Mesh(V, F)
    field = smoothest_field(mesh, 4)
    sings = [v for v, i in field.singularities]
    assert len(sings) == 8 and all(abs(i - 0.25) < 1e-9 for _, i in field.singularities)
    S = mesh.vertices[sings]
    Vq, Fq, st = quad_remesh(mesh, field, target_faces=600)
    h = st["edge_length"]
    irr = np.asarray(st["irregular_vertex_list"], dtype=int)
    marks = np.concatenate([Vq[irr], np.array([Vq[f].mean(0) for f in Fq if len(f) != 4]).reshape(-1, 3)])
    to_mark = np.linalg.norm(S[:, None] - marks[None], axis=2).min(axis=1) / h
    print("singularity -> nearest irregular vertex or non-quad face (edge lengths):", np.round(np.sort(to_mark), 2))
    assert to_mark.max() < 2.5
    def mean_distance(P):
        return float(np.linalg.norm(P[:, None] - S[None], axis=2).min(axis=1).mean())
    used = np.unique(np.concatenate([np.asarray(f) for f in Fq]))
    ratio = mean_distance(Vq[irr]) / mean_distance(Vq[used])
    print("irregular vertices: mean distance to a singularity / that of all vertices =", ratio, len(irr))
    # The ratio is 1 for irregular vertices spread like all the others; measured 0.64 (seed 0). 0.75 asks for
    # a clear concentration while leaving room for the dislocations described above.
    assert ratio < 0.75
    assert st["irregular_per_singularity"] == len(irr) / 8


@pytest.mark.parametrize("name", ["fertility.off", "rocker-arm.obj"])
def test_irregular_vertices_at_most_one_and_a_half_per_singularity(name):
    """The target on closed meshes: irregular vertices <= 1.5 x the field's singularities. Each cone
    should give one irregular vertex (or one non-quad face), and the flow pairs the lattice's row ends; the
    clean-up mends cones extracted as a valence-6 vertex beside a triangle, or as two valence-3 vertices on a
    pentagon (measured at 2,000 faces: fertility 46 for 48 singularities, 0.96; rocker arm 31 for 31, 1.0;
    at 5,000 faces with the benchmark's field the two mends take fertility from 1.54 to 1.25). Cones left
    as clusters of three or four irregular vertices are mended by edge rotations and diagonal collapses
    (lower_irregularity): the rocker arm here has 25 irregular vertices with them, 31 without. The mends are
    checked on one lattice spacing, where these figures were measured: the adaptive spacing (the default,
    whose target is checked first) moves the clusters with the field's last rounding digits, so which mends a
    platform's build makes there varies (the Python 3.13 wheel: none needed on the rocker arm, 25 irregular)."""
    mesh = core_mesh(name)
    field = solve(mesh, n=4, order=2, align="curvature-max")
    default = quad_remesh(mesh, field, target_faces=2000).stats
    assert default["irregular_per_singularity"] <= 1.5
    assert default["manifold"] and default["oriented"] and default["inverted_faces"] == 0
    V, F, st = quad_remesh(mesh, field, target_faces=2000, adaptive_spacing=False)
    print(name, default["irregular_vertices"], st["irregular_vertices"], st["field_singularities"], st["cleanup"])
    assert st["irregular_per_singularity"] <= 1.5
    assert st["cleanup"]["split_cones"] + st["cleanup"]["merged_cones"] > 0
    assert st["manifold"] and st["oriented"] and st["inverted_faces"] == 0
    if name == "rocker-arm.obj":
        # Each move lowers the count by at least one (measured: 2 moves, 31 -> 25); 28 leaves room for a
        # platform's rounding to shift one cluster while still failing if the moves stop being made.
        assert st["cleanup"]["lowered_irregularity"] > 0 and st["irregular_vertices"] <= 28


# ---------------------------------------------------------------------------------------------- dirty input
def test_two_components_a_hole_and_a_tiny_part():
    V1, F1 = meshgen.icosphere(3)
    V2, F2 = meshgen.icosphere(3)
    V2 = V2 * 0.7 + np.array([3.0, 0.0, 0.0])
    # A hole: remove a cap of the second sphere (radius ~0.42, several edge lengths across).
    keep2 = ~np.any(V2[F2][:, :, 2] > 0.56, axis=1)
    V3, F3 = meshgen.icosphere(1)
    V3 = V3 * 0.01 + np.array([0.0, 3.0, 0.0])  # far too small for the target edge
    V = np.concatenate([V1, V2, V3])
    F = np.concatenate([F1, F2[keep2] + len(V1), F3 + len(V1) + len(V2)])
    mesh = Mesh(V, F)
    field = solve(mesh, n=4, order=2, align="curvature-max")
    Vq, Fq, st = quad_remesh(mesh, field, target_faces=600)
    assert st["components"] == 3 and st["remeshed_components"] == 2
    assert any("too small" in m and "not remeshed" in m for m in st["messages"])
    assert st["manifold"] and st["oriented"]
    # Both big components are covered: output vertices near each sphere.
    r1 = np.linalg.norm(Vq, axis=1)
    r2 = np.linalg.norm(Vq - [3.0, 0.0, 0.0], axis=1)
    assert (np.abs(r1 - 1.0) < 0.05).sum() > 100 and (np.abs(r2 - 0.7) < 0.05).sum() > 50
    assert st["manifold_report"]["boundary_edges"] > 0  # the hole stays a hole
    with pytest.raises(ValueError, match="too small for the target edge length"):
        quad_remesh(mesh, field, target_faces=600, strict=True)


def test_nonmanifold_edge_is_cut_and_slivers_are_survived():
    # Three square sheets sharing the edge x = 0.5 (a "book"), plus sliver triangles in one sheet.
    Va, Fa = meshgen.grid(21, 21)
    Vb = Va[:, [0, 2, 1]] * [1, 1, 1] + [0, 0, 0]  # the sheet in the xz plane, sharing y = 0 ... edge
    sheets_V = [Va, Va[:, [0, 2, 1]], Va[:, [0, 2, 1]] * [1, 1, -1]]
    V = np.concatenate(sheets_V)
    F = np.concatenate([Fa + k * len(Va) for k in range(3)])
    # Weld the shared row y = 0 of sheet 0 with z = 0 rows of sheets 1, 2 (same positions).
    key = {tuple(np.round(p, 9)): i for i, p in enumerate(V)}
    remap = np.array([key[tuple(np.round(p, 9))] for p in V])
    F = remap[F]
    del Vb
    sliver = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 1e-4], [2.0, 0.0, 0.0]]) + [5.0, 5.0, 0.0]
    mesh = Mesh(np.concatenate([V, sliver]), np.concatenate([F, [[len(V), len(V) + 1, len(V) + 2]]]))
    assert len(mesh.report["nonmanifold_edges"]) > 0
    field = solve(mesh, n=4, order=2, align="none", constraints=[DirectionConstraint(0, (1.0, 0.0, 0.0))])
    Vq, Fq, st = quad_remesh(mesh, field, target_faces=300)
    assert st["manifold"] and st["oriented"]
    assert any("non-manifold" in m for m in st["messages"])
    assert any("too small" in m for m in st["messages"])  # the lone sliver is its own tiny component


# ---------------------------------------------------------------------------------------------- bad input
@pytest.fixture(scope="module")
def fandisk():
    mesh = core_mesh("fandisk.obj")
    return mesh, solve(mesh, n=4, order=2, align="curvature-max")


@pytest.mark.parametrize("kwargs, message", [
    ({}, "exactly one of target_faces"),
    ({"target_faces": 100, "edge_length": 0.1}, "exactly one of target_faces"),
    ({"target_faces": 0}, "target_faces must be a positive integer"),
    ({"target_faces": 2.5}, "target_faces must be a positive integer"),
    ({"edge_length": -1.0}, "edge_length must be a positive"),
    ({"edge_length": float("nan")}, "edge_length must be a positive"),
    ({"target_faces": 100, "sharp_angle": 200.0}, "sharp_angle must be below 180"),
    ({"target_faces": 100, "seed": -1}, "seed must be an integer"),
    ({"target_faces": 100, "feature_field_angle": 50}, "feature_field_angle must be a number of degrees in 0..45"),
    ({"target_faces": 100, "iterations": 0}, "iterations must be an integer in 1..1000"),
    ({"target_faces": 100, "n": 3}, "n = 3 given, but the field has n = 4"),
    ({"edge_length": 1e6}, "every component of the mesh is too small"),
    ({"target_faces": 10**9}, "would make about 1e.09 faces; at most 2e.06"),
])
def test_bad_parameters_are_named(fandisk, kwargs, message):
    mesh, field = fandisk
    with pytest.raises(ValueError, match=message):
        quad_remesh(mesh, field, **kwargs)


def test_bad_fields_are_named(fandisk):
    mesh, field = fandisk
    six = solve(mesh, n=6, order=2, align="none", constraints=[DirectionConstraint(0, (1.0, 0.0, 0.0))])
    with pytest.raises(ValueError, match="n = 4 is used as is, n = 1 and n = 2 take the field"):
        quad_remesh(mesh, six, target_faces=100)
    with pytest.raises(ValueError, match="one 3D vector per face"):
        quad_remesh(mesh, np.zeros((5, 3)), target_faces=100)
    with pytest.raises(ValueError, match="zero .or normal to the surface. on every face"):
        quad_remesh(mesh, np.zeros((mesh.num_faces, 3)), target_faces=100)
    bad = field.directions.copy()
    bad[7] = np.nan
    with pytest.raises(ValueError, match="non-finite vector at triangle 7"):
        quad_remesh(mesh, bad, target_faces=100)
    with pytest.raises(ValueError, match="needs its symmetry order n"):
        quad_remesh(mesh, field.representation, target_faces=100)
    other = core_mesh("sphere.obj")
    with pytest.raises(ValueError, match="another mesh"):
        quad_remesh(mesh, DesignSession(other), target_faces=100)


def test_line_field_and_array_and_session_inputs(fandisk):
    mesh, field = fandisk
    line = solve(mesh, n=2, order=2, align="curvature-max")
    V2, F2, s2 = quad_remesh(mesh, line, target_faces=500)
    assert s2["n"] == 2 and s2["manifold"]
    # The same field given as per-face vectors, as representation vectors and as a session (which solves the
    # same problem again: its field differs by about 1e-13): with one lattice spacing, the same mesh to 1e-9.
    a = quad_remesh(mesh, field, target_faces=500, stats=False, adaptive_spacing=False)
    b = quad_remesh(mesh, field.directions, target_faces=500, stats=False, adaptive_spacing=False)
    c = quad_remesh(mesh, field.representation, n=4, target_faces=500, stats=False, adaptive_spacing=False)
    session = DesignSession(mesh, n=4, order=2, align="curvature-max")
    d = quad_remesh(mesh, session, target_faces=500, stats=False, adaptive_spacing=False)
    for other in (b, c, d):
        assert other.faces == a.faces and np.allclose(other.vertices, a.vertices, atol=1e-9)
    # With the adaptive spacing (the default), a global solve of the field's turning, rounding-level
    # differences of the field reach the output's positions: the per-face vectors and the representation
    # give the same faces, the vertices within 1e-3 of the edge length (measured 8.2e-5 = 2.3e-4 h). The
    # session's field (1e-13 off) gave 469 faces against 471: not compared. A face may start at another of
    # its vertices (step 14 picks the diagonal nearer the input, a near tie between the two on some
    # platforms' builds), so the faces are compared as vertex cycles.
    a = quad_remesh(mesh, field, target_faces=500, stats=False)
    for other in (quad_remesh(mesh, field.directions, target_faces=500, stats=False),
                  quad_remesh(mesh, field.representation, n=4, target_faces=500, stats=False)):
        assert [face_cycle(f) for f in other.faces] == [face_cycle(f) for f in a.faces]
        assert np.abs(other.vertices - a.vertices).max() <= 1e-3 * a.stats["edge_length"]


# ---------------------------------------------------------------------------------------------- progress, cancel, GIL
class _CallbackStop(Exception):
    pass


def _raising_above(fraction):
    """A progress callback that raises once the fraction passes ``fraction``."""
    def callback(f):
        if f > fraction:
            raise _CallbackStop("from the callback")
    return callback


def test_progress_cancel_and_gil(fandisk):
    mesh, field = fandisk
    seen = []
    quad_remesh(mesh, field, target_faces=1000, progress=lambda f: seen.append(f), stats=False)
    assert seen[0] == 0.0 and seen[-1] == 1.0 and all(b >= a for a, b in zip(seen, seen[1:]))
    with pytest.raises(native().Cancelled):
        quad_remesh(mesh, field, target_faces=1000, progress=lambda f: f < 0.5)
    with pytest.raises(_CallbackStop):
        quad_remesh(mesh, field, target_faces=1000, progress=_raising_above(0.3))
    threads = []
    box = run_beside_main_loop(lambda: quad_remesh(mesh, field, target_faces=3000, stats=False,
                                                   progress=lambda f: threads.append(threading.current_thread().name)))
    assert "error" not in box, box.get("error")
    print(f"remesh {box['seconds']:.3f} s, main loop {box['count']} iterations, longest gap {box['gap'] * 1e3:.1f} ms")
    assert set(threads) == {"solver"}
    # The GIL is released: the main loop kept running (the longest pause is a small part of the work).
    assert box["gap"] < 0.25 * box["seconds"]


def test_both_cone_candidates_report_progress_from_the_calling_thread_and_cancel(fandisk):
    """Pure quads by pairing with pure_quad_cones="best" make the pinned candidate on a second native thread
    while the calling thread makes the free one. The callback still runs only on the calling thread, sees a
    monotone fraction ending at 1, and a cancel or an exception from it stops both candidates."""
    mesh, field = fandisk
    seen, threads = [], set()

    def record(f):
        seen.append(f)
        threads.add(threading.get_ident())
    both = quad_remesh(mesh, field, target_faces=1000, pure_quads=True, progress=record, stats=False)
    assert threads == {threading.get_ident()}
    assert seen[-1] == 1.0 and all(b >= a for a, b in zip(seen, seen[1:])) and 0.0 <= seen[0] < 0.5
    # The result is one of the two candidates, made as each alone would make it.
    conv = both.stats["pure_quad_conversion"]
    alone = quad_remesh(mesh, field, target_faces=1000, pure_quads=True, stats=False,
                        pure_quad_cones="pinned" if conv["pinned_cones"] else "free")
    assert both.faces == alone.faces and np.array_equal(both.vertices, alone.vertices)
    with pytest.raises(native().Cancelled):
        quad_remesh(mesh, field, target_faces=1000, pure_quads=True, progress=lambda f: f < 0.3)
    with pytest.raises(_CallbackStop):
        quad_remesh(mesh, field, target_faces=1000, pure_quads=True, progress=_raising_above(0.6))


# ---------------------------------------------------------------------------------------------- CLI
def _cli(*args):
    # The environment is kept (the sanitizer job's LD_PRELOAD / ASAN_OPTIONS must reach the child).
    env = package_env()
    env.pop("NFIELD_DEBUG", None)
    return subprocess.run([sys.executable, "-m", "nfield", *map(str, args)], capture_output=True, text=True,
                          env=env, timeout=300)


def test_cli_remesh(tmp_path):
    out = tmp_path / "fandisk_quads.obj"
    r = _cli("remesh", mesh_path("fandisk.obj"), "--faces", 800, "--out", out)
    assert r.returncode == 0, r.stderr
    assert "quads" in r.stdout and "Hausdorff" in r.stdout
    faces = [line for line in out.read_text().splitlines() if line.startswith("f ")]
    assert 600 < len(faces) < 1000 and sum(len(f.split()) == 5 for f in faces) > 0.9 * len(faces)
    # With a field file (as written by `solve --out`) and JSON output.
    field = tmp_path / "field.npy"
    assert _cli("solve", mesh_path("fandisk.obj"), "--n", 2, "--align", "curvature-max", "--out", field).returncode == 0
    r = _cli("remesh", mesh_path("fandisk.obj"), "--field", field, "--n", 2, "--faces", 500, "--out", out,
             "--pure-quads", "--json")
    assert r.returncode == 0, r.stderr
    import json
    st = json.loads(r.stdout)
    assert st["quad_fraction"] == 1.0 and st["n"] == 2 and st["pure_quad_method"] == "pair"
    assert st["pure_quad_conversion"]["irregular_free_cones"] >= 0  # the default made both candidates
    r = _cli("remesh", mesh_path("fandisk.obj"), "--field", field, "--n", 2, "--faces", 500, "--out", out,
             "--pure-quads", "--pure-quad-cones", "free", "--json")
    assert r.returncode == 0, r.stderr
    st = json.loads(r.stdout)
    assert st["pure_quad_conversion"]["pinned_cones"] == 0 and st["pure_quad_conversion"]["irregular_free_cones"] == -1
    r = _cli("remesh", mesh_path("fandisk.obj"), "--faces", 500, "--out", out, "--pure-quads",
             "--pure-quad-method", "subdivide", "--json")
    assert r.returncode == 0, r.stderr
    st = json.loads(r.stdout)
    # the subdivided lattice is twice as coarse as the output's edge length
    assert st["quad_fraction"] == 1.0 and st["pure_quad_method"] == "subdivide"
    assert st["lattice_spacing"] == pytest.approx(2 * st["edge_length"])
    # Failures: one line, exit 2.
    r = _cli("remesh", mesh_path("fandisk.obj"), "--faces", 500, "--out", tmp_path / "x.ply")
    assert r.returncode == 2 and "remesh writes .obj" in r.stderr
    r = _cli("remesh", mesh_path("fandisk.obj"), "--field", field, "--n", 3, "--faces", 500, "--out", out)
    assert r.returncode == 2 and "no quad structure" in r.stderr
    r = _cli("remesh", mesh_path("fandisk.obj"), "--edge-length", 1e6, "--out", out)
    assert r.returncode == 2 and "too small for the target edge length" in r.stderr


@pytest.mark.no_sanitizer  # reads bench/ (not copied into the sanitizer job's tree); no native code
def test_benchmark_names_the_missing_instant_meshes_peer(monkeypatch, tmp_path):
    """bench/remesh.py looks for the benchmark-only peer in bench/.peers (where `build_addon.py bench`
    installs it); when it is missing, the peer's row fails with a message saying how to install it."""
    import importlib.util
    bench = mesh_path("fandisk.obj").parents[2] / "bench"
    monkeypatch.syspath_prepend(str(bench))
    spec = importlib.util.spec_from_file_location("bench_remesh_under_test", bench / "remesh.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert module.PEERS_DIR == bench / ".peers"
    monkeypatch.setattr(module, "PEERS_DIR", tmp_path / "no-peers")
    monkeypatch.setitem(sys.modules, "pyinstantmeshes", None)  # import fails even where it is installed
    with pytest.raises(RuntimeError, match=r"build_addon\.py bench.*bench/\.peers"):
        module.run_instant_meshes(core_mesh("fandisk.obj"), 500)
