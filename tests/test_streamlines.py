"""Hatching strokes: the native streamline tracer through nfield.core.trace_streamlines.

What is checked, and why the tolerances are what they are:
  * field alignment - inside a triangle the field is constant and the tracer integrates it exactly (a straight
    segment along one of the n directions), so every segment's n-symmetric angle to its triangle's field is
    rounding-level; the required bound (5 degrees) is asserted, plus 1e-6 rad as the real expectation
    (segments are at least 1e-9 h long, so rounding of coordinates of size ~diag gives < 1e-6 rad).
  * separation - every sample point of a stroke was tested against every earlier stroke's sample points at
    d_test = 0.5 d_sep, so sample points of different strokes are >= d_test (up to the < 1e-9 h snap of a
    point onto an edge: tolerance 1e-8 d_test). Between samples (segments of length <= h = 0.2 d_sep = 0.4
    d_test) the polylines can come closer: a point x on a segment is within h/2 of a vertex a; a vertex a at
    >= D from both ends of a segment of length <= h is >= sqrt(D^2 - h^2/4) from all of it; so the
    polylines stay >= sqrt(D^2 - h^2/4) - h/2 = 0.780 D apart. The polylines are resampled every 0.02 d_sep
    (sample distances overestimate the true distance by at most that) and 0.78 D - 0.02 d_sep = 0.74 D is
    asserted.
  * on the surface - points are convex combinations of their triangle's corners: barycentric coordinates in
    [-1e-9, 1 + 1e-9] and plane distance < 1e-9 * diagonal. Both endpoints of every segment are checked
    against the segment's triangle (so the segment lies inside it).
  * boundary - consecutive distinct triangles of a stroke are linked by a dual edge (an interior edge), or,
    where a stroke passes exactly through a vertex, by dual edges around that vertex; a boundary edge is
    never crossed.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import mesh_path
from nfield.core import Mesh, Strokes, native, solve, trace_streamlines


# ---------------------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def bunny():
    return Mesh.from_file(mesh_path("stanford-bunny.obj"))


@pytest.fixture(scope="module")
def bunny2(bunny):
    return solve(bunny, n=2, order=2, align="curvature-max")


@pytest.fixture(scope="module")
def bunny2_strokes(bunny, bunny2):
    return trace_streamlines(bunny, bunny2, spacing=0.02, seed=1)


@pytest.fixture(scope="module")
def fandisk():
    return Mesh.from_file(mesh_path("fandisk.obj"))


@pytest.fixture(scope="module")
def fandisk4(fandisk):
    return solve(fandisk, n=4, order=2, align="curvature-max")


@pytest.fixture(scope="module")
def fandisk4_cross(fandisk, fandisk4):
    return trace_streamlines(fandisk, fandisk4, spacing=0.02, cross_hatch=True, seed=5)


@pytest.fixture(scope="module")
def camel():
    return Mesh.from_file(mesh_path("camelhead.off"))


@pytest.fixture(scope="module")
def camel2(camel):
    return solve(camel, n=2, order=2, align="curvature-max")


@pytest.fixture(scope="module")
def camel_strokes(camel, camel2):
    return trace_streamlines(camel, camel2, spacing=0.015, seed=2)


# ---------------------------------------------------------------------------------------------- helpers
def _segment_field_angles(mesh: Mesh, field, strokes: Strokes) -> tuple[np.ndarray, np.ndarray]:
    """n-symmetric angle (radians) between each segment and its triangle's field directions (family
    offset applied), and the segment lengths."""
    ops = native().FieldOperators(mesh.native, field.n, field.weights)
    frames = np.asarray(ops.frames)  # (T, 2, 3)
    z = np.asarray(field.representation)
    n = field.n
    errs, lens = [], []
    for p, f, fam in zip(strokes.points, strokes.faces, strokes.families):
        v = np.diff(p, axis=0)
        t = f[:-1]
        x = np.einsum("ij,ij->i", v, frames[t, 0])
        y = np.einsum("ij,ij->i", v, frames[t, 1])
        off = 0.5 * math.pi if fam == 1 else 0.0
        d = n * np.arctan2(y, x) - np.angle(z[t]) - n * off
        errs.append(np.abs(np.remainder(d + math.pi, 2 * math.pi) - math.pi) / n)
        lens.append(np.linalg.norm(v, axis=1))
    return np.concatenate(errs), np.concatenate(lens)


def _barycentric(P: np.ndarray, T: np.ndarray, pts: np.ndarray, tris: np.ndarray):
    A, B, C = P[T[tris, 0]], P[T[tris, 1]], P[T[tris, 2]]
    e1, e2, w = B - A, C - A, pts - A
    d00 = np.einsum("ij,ij->i", e1, e1)
    d01 = np.einsum("ij,ij->i", e1, e2)
    d11 = np.einsum("ij,ij->i", e2, e2)
    d20 = np.einsum("ij,ij->i", w, e1)
    d21 = np.einsum("ij,ij->i", w, e2)
    den = d00 * d11 - d01 * d01
    b1 = (d11 * d20 - d01 * d21) / den
    b2 = (d00 * d21 - d01 * d20) / den
    normal = np.cross(e1, e2)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    return np.stack([1 - b1 - b2, b1, b2], axis=1), np.abs(np.einsum("ij,ij->i", w, normal))


def _resample(p: np.ndarray, spacing: float) -> np.ndarray:
    out = [p[:1]]
    for a, b in zip(p[:-1], p[1:]):
        k = max(1, int(math.ceil(np.linalg.norm(b - a) / spacing)))
        s = np.arange(1, k + 1)[:, None] / k
        out.append(a + s * (b - a))
    return np.concatenate(out)


def _min_distance_between_groups(points: np.ndarray, ids: np.ndarray, r: float) -> float:
    """Smallest distance between points with different ids, or r if none is closer than r (hash grid)."""
    c = np.floor(points / r).astype(np.int64)
    c -= c.min(axis=0) - 1
    dims = c.max(axis=0) + 2
    key = (c[:, 0] * dims[1] + c[:, 1]) * dims[2] + c[:, 2]
    order = np.argsort(key, kind="stable")
    ks, P, ids = key[order], points[order], ids[order]
    best = r
    idx = np.arange(len(ks))
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                nk = ks + (dx * dims[1] + dy) * dims[2] + dz
                lo = np.searchsorted(ks, nk, "left")
                hi = np.searchsorted(ks, nk, "right")
                for chunk in np.array_split(idx, max(1, len(idx) // 20000)):
                    cnt = hi[chunk] - lo[chunk]
                    if cnt.sum() == 0:
                        continue
                    src = np.repeat(chunk, cnt)
                    start = np.repeat(np.cumsum(cnt) - cnt, cnt)
                    dst = np.repeat(lo[chunk], cnt) + (np.arange(cnt.sum()) - start)
                    m = ids[src] != ids[dst]
                    if m.any():
                        best = min(best, float(np.linalg.norm(P[src[m]] - P[dst[m]], axis=1).min()))
    return best


def _dual_adjacency(mesh: Mesh) -> set:
    de = np.asarray(mesh.native.dual_edges())
    return {(int(a), int(b)) for a, b in de[:, :2]} | {(int(b), int(a)) for a, b in de[:, :2]}


# ---------------------------------------------------------------------------------------------- tests
@pytest.mark.slow
def test_strokes_cover_the_bunny(bunny, bunny2_strokes):
    s = bunny2_strokes
    assert s.num_strokes > 20 and s.num_points > 1000
    assert not s.stats["truncated"]
    # Total length ~ area / d_sep for evenly spaced strokes (spacing between d_test and ~d_sep).
    ideal = bunny.native.total_area / s.separation
    assert 0.7 * ideal < s.total_length < 2.0 * ideal
    assert s.stats["coverage"][0] > 0.97
    assert all(len(p) == len(f) >= 2 for p, f in zip(s.points, s.faces))
    assert min(s.lengths) >= 2 * 0.02 * bunny.native.bounding_box_diagonal * (1 - 1e-12)  # default min_length


@pytest.mark.parametrize("which", [pytest.param("bunny2", marks=pytest.mark.slow), "fandisk4"])
def test_segments_follow_the_field(which, request):
    if which == "bunny2":
        mesh, field, strokes = (request.getfixturevalue(k) for k in ("bunny", "bunny2", "bunny2_strokes"))
    else:
        mesh, field, strokes = (request.getfixturevalue(k) for k in ("fandisk", "fandisk4", "fandisk4_cross"))
    err, lens = _segment_field_angles(mesh, field, strokes)
    assert lens.min() > 0
    assert np.degrees(err.max()) < 5.0
    assert err.max() < 1e-6


@pytest.mark.parametrize("which", [pytest.param("bunny2_strokes", marks=pytest.mark.slow), "fandisk4_cross"])
def test_separation_between_strokes(which, request):
    strokes: Strokes = request.getfixturevalue(which)
    D, h = strokes.test_distance, strokes.step
    for fam in sorted(set(strokes.families)):
        sel = [i for i, f in enumerate(strokes.families) if f == fam]
        pts = np.concatenate([strokes.points[i] for i in sel])
        ids = np.concatenate([np.full(len(strokes.points[i]), i) for i in sel])
        assert _min_distance_between_groups(pts, ids, D) >= D * (1 - 1e-8)
        dense_step = 0.02 * strokes.separation
        dense = [_resample(strokes.points[i], dense_step) for i in sel]
        dpts = np.concatenate(dense)
        dids = np.concatenate([np.full(len(d), i) for d, i in zip(dense, sel)])
        bound = math.sqrt(D * D - h * h / 4) - h / 2 - dense_step
        assert bound > 0.73 * D
        assert _min_distance_between_groups(dpts, dids, D) >= bound


@pytest.mark.parametrize("which", [("bunny", "bunny2_strokes"), ("camel", "camel_strokes"),
                                   ("fandisk", "fandisk4_cross")])
def test_strokes_stay_on_the_surface(which, request):
    mesh, strokes = (request.getfixturevalue(k) for k in which)
    P, T = np.asarray(mesh.native.positions), np.asarray(mesh.native.faces)
    diag = mesh.native.bounding_box_diagonal
    pts = np.concatenate([p for p in strokes.points])
    tris = np.concatenate([f for f in strokes.faces])
    # every point on its own triangle, and the end of every segment on the segment's triangle
    ends = np.concatenate([p[1:] for p in strokes.points])
    seg_tris = np.concatenate([f[:-1] for f in strokes.faces])
    for q, t in ((pts, tris), (ends, seg_tris)):
        bary, dist = _barycentric(P, T, q, t)
        assert bary.min() >= -1e-9 and bary.max() <= 1 + 1e-9
        assert dist.max() < 1e-9 * diag
    assert np.asarray(mesh.native.face_active)[tris].all()


def test_no_stroke_crosses_a_boundary(camel, camel_strokes):
    assert camel.report["num_boundary_edges"] > 0
    adj = _dual_adjacency(camel)
    P, T = np.asarray(camel.native.positions), np.asarray(camel.native.faces)
    diag = camel.native.bounding_box_diagonal
    via_vertex = 0
    for p, f in zip(camel_strokes.points, camel_strokes.faces):
        for i in range(len(f) - 1):
            a, b = int(f[i]), int(f[i + 1])
            if a == b or (a, b) in adj:
                continue
            # passing exactly through a vertex: the point is that vertex, and a and b are linked by dual
            # edges among the faces around it
            shared = set(T[a]) & set(T[b])
            v = [u for u in shared if np.linalg.norm(P[u] - p[i + 1]) < 1e-9 * diag]
            assert v, f"stroke jumps from triangle {a} to {b}, which are not adjacent through an interior edge"
            fan = set(camel.native.vertex_ring_faces(v[0])) or set()
            assert a in fan and b in fan, "passage through a boundary vertex"
            via_vertex += 1
    assert via_vertex <= 5
    # some strokes end on the boundary (they stop there instead of crossing it)
    de = np.asarray(camel.native.dual_edges())
    interior = {tuple(sorted(e)) for e in de[:, 2:4]}
    edges = {}
    for t in np.flatnonzero(np.asarray(camel.native.face_active)):
        for k in range(3):
            e = tuple(sorted((int(T[t, k]), int(T[t, (k + 1) % 3]))))
            edges[e] = edges.get(e, 0) + 1
    boundary_vertices = {v for e, c in edges.items() if e not in interior for v in e}
    ends_on_boundary = 0
    for p, f in zip(camel_strokes.points, camel_strokes.faces):
        for q, t in ((p[0], f[0]), (p[-1], f[-1])):
            bary, _ = _barycentric(P, T, q[None], np.array([t]))
            corners = [int(T[t, k]) for k in range(3) if bary[0, k] > 1e-9]
            if len(corners) == 2 and all(c in boundary_vertices for c in corners) and \
                    tuple(sorted(corners)) not in interior:
                ends_on_boundary += 1
    assert ends_on_boundary > 0


def test_same_seed_same_strokes_and_different_seed_different(fandisk, fandisk4):
    a = trace_streamlines(fandisk, fandisk4, spacing=0.03, seed=11)
    b = trace_streamlines(fandisk, fandisk4, spacing=0.03, seed=11)
    c = trace_streamlines(fandisk, fandisk4, spacing=0.03, seed=12)
    assert a.num_strokes == b.num_strokes
    assert all(np.array_equal(p, q) for p, q in zip(a.points, b.points))
    assert all(np.array_equal(p, q) for p, q in zip(a.faces, b.faces))
    assert a.families == b.families
    assert a.num_strokes != c.num_strokes or any(
        p.shape != q.shape or not np.array_equal(p, q) for p, q in zip(a.points, c.points))


def _family_face_directions(mesh: Mesh, strokes: Strokes, family: int) -> dict:
    """Triangle -> unit direction of (one of) the family's segments inside it."""
    out = {}
    for p, f, fam in zip(strokes.points, strokes.faces, strokes.families):
        if fam != family:
            continue
        v = np.diff(p, axis=0)
        ln = np.linalg.norm(v, axis=1)
        for t, d, l in zip(f[:-1], v, ln):
            if l > 1e-3 * strokes.separation:
                out.setdefault(int(t), d / l)
    return out


def test_cross_hatching_gives_two_perpendicular_families(fandisk, fandisk4_cross, bunny, bunny2):
    s = fandisk4_cross
    assert set(s.families) == {0, 1}
    d0 = _family_face_directions(fandisk, s, 0)
    d1 = _family_face_directions(fandisk, s, 1)
    common = sorted(set(d0) & set(d1))
    assert len(common) > 100
    ang = np.degrees(np.arccos(np.clip([abs(float(d0[t] @ d1[t])) for t in common], 0, 1)))
    # The tracer combs the 4-field into a pair of 2-fields (strokes stop at the comb's seams), so in every
    # triangle crossed by both families they are exactly perpendicular (rounding: 1e-4 degrees).
    assert np.all(np.abs(ang - 90) < 1e-4)
    # n = 2: the second family is the field rotated by 90 degrees everywhere.
    s2 = trace_streamlines(bunny, bunny2, spacing=0.03, cross_hatch=True, seed=3)
    err, _ = _segment_field_angles(bunny, bunny2, s2)
    assert err.max() < 1e-6
    e0 = _family_face_directions(bunny, s2, 0)
    e1 = _family_face_directions(bunny, s2, 1)
    both = sorted(set(e0) & set(e1))
    assert len(both) > 100
    ang2 = np.degrees(np.arccos(np.clip([abs(float(e0[t] @ e1[t])) for t in both], 0, 1)))
    assert np.all(np.abs(ang2 - 90) < 1e-4)


def test_density_modulation(bunny, bunny2):
    P = bunny.vertices
    x = P[:, 0]
    cut = np.median(x)
    density = np.where(x > cut, 1.0, 0.25)
    s = trace_streamlines(bunny, bunny2, spacing=0.015, seed=4, density=density)
    T = np.asarray(bunny.native.faces)
    centroid_x = P[T].mean(axis=1)[:, 0]
    area = np.asarray(bunny.native.face_areas)
    high = centroid_x > cut
    length_high = length_low = 0.0
    for p, f in zip(s.points, s.faces):
        seg = np.linalg.norm(np.diff(p, axis=0), axis=1)
        h = high[f[:-1]]
        length_high += seg[h].sum()
        length_low += seg[~h].sum()
    ratio = (length_high / area[high].sum()) / (length_low / area[~high].sum())
    # spacing ratio 4 -> stroke length per area ratio ~4 (less near the transition); ask for > 2.5
    assert ratio > 2.5
    # per-face density gives the same kind of result
    fd = np.where(centroid_x > cut, 1.0, 0.25)
    s2 = trace_streamlines(bunny, bunny2, spacing=0.015, seed=4, density=fd)
    assert abs(s2.total_length - s.total_length) < 0.25 * s.total_length


def test_length_limits(fandisk, fandisk4):
    diag = fandisk.native.bounding_box_diagonal
    s = trace_streamlines(fandisk, fandisk4, spacing=0.03, max_length=0.1, min_length=0.05)
    assert s.num_strokes > 0
    assert max(s.lengths) <= 0.1 * diag * (1 + 1e-9)
    assert min(s.lengths) >= 0.05 * diag
    for p, ln in zip(s.points, s.lengths):
        assert abs(np.linalg.norm(np.diff(p, axis=0), axis=1).sum() - ln) < 1e-9 * diag


def test_to_dict_is_json(fandisk, fandisk4):
    s = trace_streamlines(fandisk, fandisk4, spacing=0.05)
    d = json.loads(json.dumps(s.to_dict()))
    assert d["num_strokes"] == s.num_strokes == len(d["points"]) == len(d["faces"])
    assert len(d["points"][0][0]) == 3
    assert "points" not in s.to_dict(include_points=False)


def test_input_validation(fandisk, fandisk4, bunny2):
    bad = [
        dict(spacing=0), dict(spacing=-0.1), dict(spacing=2.0), dict(spacing=float("nan")), dict(spacing="x"),
        dict(family=4), dict(family=-1), dict(family=1.5), dict(cross_hatch="yes"), dict(seed=-1),
        dict(max_length=0), dict(min_length=-1), dict(max_points=1), dict(density=np.ones(3)),
        dict(density=np.full(fandisk.num_vertices, 2.0)),
        dict(density=np.full(fandisk.num_vertices, np.nan)), dict(density=np.ones((fandisk.num_vertices, 2))),
    ]
    for kw in bad:
        with pytest.raises(ValueError):
            trace_streamlines(fandisk, fandisk4, **kw)
    with pytest.raises(ValueError):
        trace_streamlines(fandisk, bunny2)  # field of another mesh
    with pytest.raises(ValueError):
        trace_streamlines(fandisk, "not a field")
    f3 = solve(fandisk, n=3)
    with pytest.raises(ValueError, match="cross_hatch"):
        trace_streamlines(fandisk, f3, cross_hatch=True)
    assert trace_streamlines(fandisk, f3, spacing=0.05).num_strokes > 0  # odd n traces fine


def test_vanishing_field_gives_no_strokes(fandisk, fandisk4):
    from dataclasses import replace
    zero = replace(fandisk4, representation=np.zeros_like(fandisk4.representation))
    s = trace_streamlines(fandisk, zero, spacing=0.05)
    assert s.num_strokes == 0


def test_point_cap_truncates(fandisk, fandisk4):
    s = trace_streamlines(fandisk, fandisk4, spacing=0.01, max_points=3000)
    assert s.stats["truncated"]
    assert s.num_points <= 3000


def test_random_field_terminates_and_stays_on_surface(fandisk, fandisk4):
    """A field with no coherence (random angles, 5% zeros): strokes are short but valid."""
    from dataclasses import replace
    rng = np.random.default_rng(0)
    z = np.exp(1j * rng.uniform(0, 2 * np.pi, fandisk.num_triangles))
    z[rng.random(z.size) < 0.05] = 0
    field = replace(fandisk4, representation=z)
    s = trace_streamlines(fandisk, field, spacing=0.01, cross_hatch=True, min_length=0,
                          density=rng.random(fandisk.num_vertices))
    assert s.num_strokes > 0 and not s.stats["truncated"]
    err, _ = _segment_field_angles(fandisk, field, s)
    assert err.max() < 1e-6
    P, T = np.asarray(fandisk.native.positions), np.asarray(fandisk.native.faces)
    bary, dist = _barycentric(P, T, np.concatenate(s.points), np.concatenate(s.faces))
    assert bary.min() >= -1e-9 and bary.max() <= 1 + 1e-9
    assert np.all(z[np.concatenate(s.faces)] != 0)
