"""Per-vertex / per-polygon versions of a designed field for shading and export (pure numpy, no bpy).

These helpers turn the per-face output of :func:`nfield.core.solve` into data that is convenient for
renderers and geometry nodes:

* :func:`polygon_tangent_directions` — project per-polygon directions onto each polygon's own tangent plane
  (a polygon's direction comes from its first triangle; for non-planar polygons this makes it tangent to the
  polygon's average plane). Planar polygons are unchanged up to rounding.
* :func:`vertex_smoothed_directions` — an n-symmetry-aware average at each vertex: the incident faces'
  directions are rotated into the vertex tangent plane (minimal rotation from the face normal to the vertex
  normal), encoded as representation vectors exp(i n phi) in a vertex frame, averaged with area weights, and
  decoded back to one unit direction. Averaging the representation vectors (rather than the raw directions)
  is what makes the result independent of which of the n directions each face reports. Vertices where the
  average vanishes (e.g. at singularities) get the zero vector. Which of its n directions a vertex reports
  is then *combed*: chosen to agree with its neighbours, so that a renderer
  interpolating the vector across a triangle (a tangent for anisotropic shading) sees no seam except where
  the field's symmetry forces one (paths from singularities of fractional index).
* :func:`vertex_singularity_index` — a dense per-vertex index array from a sparse list.
"""
from __future__ import annotations

import numpy as np

__all__ = ["polygon_tangent_directions", "vertex_smoothed_directions", "vertex_singularity_index"]


def _normalize_rows(a: np.ndarray, eps: float = 1e-300) -> tuple[np.ndarray, np.ndarray]:
    norm = np.linalg.norm(a, axis=1)
    out = np.zeros_like(a)
    ok = norm > eps
    out[ok] = a[ok] / norm[ok, None]
    return out, ok


def polygon_tangent_directions(directions: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(P, 3) unit directions projected onto the planes with the given (P, 3) normals; zero rows stay zero."""
    d = np.asarray(directions, dtype=np.float64)
    nrm, _ = _normalize_rows(np.asarray(normals, dtype=np.float64))
    proj = d - nrm * np.einsum("ij,ij->i", d, nrm)[:, None]
    out, ok = _normalize_rows(proj, 1e-12)
    zero = np.linalg.norm(d, axis=1) == 0
    out[zero] = 0.0
    return out


def _vertex_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.zeros_like(normals)
    use_y = np.abs(normals[:, 0]) > 0.9
    helper[~use_y, 0] = 1.0
    helper[use_y, 1] = 1.0
    e1, _ = _normalize_rows(np.cross(normals, helper))
    e2 = np.cross(normals, e1)
    return e1, e2


def vertex_smoothed_directions(vertices: np.ndarray, triangles: np.ndarray, triangle_directions: np.ndarray,
                               n: int) -> np.ndarray:
    """(V, 3) n-symmetry-aware area-weighted average of the per-triangle directions at every vertex.

    vertices (V, 3), triangles (T, 3) int, triangle_directions (T, 3) (any one of the n directions per
    triangle; zero rows are ignored), n the symmetry. Unit rows; zero where no face contributes or the
    average of the representation vectors vanishes.
    """
    v = np.asarray(vertices, dtype=np.float64)
    t = np.asarray(triangles, dtype=np.int64)
    d = np.asarray(triangle_directions, dtype=np.float64)
    nv = v.shape[0]
    cross = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    area2 = np.linalg.norm(cross, axis=1)
    fn, fok = _normalize_rows(cross)
    w = 0.5 * area2 * fok * (np.linalg.norm(d, axis=1) > 0)
    vn = np.zeros((nv, 3))
    for c in range(3):
        np.add.at(vn, t[:, c], fn * w[:, None])
    vn, vok = _normalize_rows(vn)
    e1, e2 = _vertex_frames(vn)
    z = np.zeros(nv, dtype=np.complex128)
    for c in range(3):
        vi = t[:, c]
        a, b = fn, vn[vi]
        axis = np.cross(a, b)
        cosang = np.einsum("ij,ij->i", a, b)
        good = cosang > -1 + 1e-9
        denom = np.where(good, 1.0 + cosang, 1.0)
        vd = np.cross(axis, d)
        rd = d + vd + np.cross(axis, vd) / denom[:, None]
        phi = np.arctan2(np.einsum("ij,ij->i", rd, e2[vi]), np.einsum("ij,ij->i", rd, e1[vi]))
        np.add.at(z, vi, np.where(good, w, 0.0) * np.exp(1j * n * phi))
    total = np.zeros(nv)
    for c in range(3):
        np.add.at(total, t[:, c], w)
    mag = np.abs(z)
    ok = vok & (mag > 1e-9 * np.maximum(total, 1e-300))
    ang = np.angle(z) / n
    ang[~ok] = np.nan
    ang = _comb_angles(ang, t, e1, e2, n)
    out = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2
    out[~ok] = 0.0
    return out


def _vertex_neighbours(triangles: np.ndarray, nv: int) -> tuple[np.ndarray, np.ndarray]:
    """CSR adjacency (offsets (nv + 1,), neighbours) of the vertex graph of `triangles`."""
    a = triangles.ravel()
    b = triangles[:, [1, 2, 0]].ravel()
    key = np.unique(np.concatenate([a * nv + b, b * nv + a]))  # both directions of every edge, sorted by source
    src, dst = key // nv, key % nv
    offsets = np.zeros(nv + 1, dtype=np.int64)
    np.add.at(offsets, src + 1, 1)
    return np.cumsum(offsets), dst


def _comb_angles(ang: np.ndarray, triangles: np.ndarray, e1: np.ndarray, e2: np.ndarray, n: int) -> np.ndarray:
    """Per-vertex angles (in each vertex's frame e1, e2; NaN = no direction) shifted by multiples of 2 pi / n
    so that each vertex agrees with the neighbour it is reached from, breadth first from the first vertex of
    each connected part (one numpy step per ring of the search)."""
    if n <= 1:
        return ang
    nv = len(ang)
    offsets, nbr = _vertex_neighbours(np.asarray(triangles, dtype=np.int64), nv)
    has = ~np.isnan(ang)
    done = ~has
    step = 2 * np.pi / n
    out = ang.copy()
    direction = np.zeros((nv, 3))
    while not np.all(done):
        root = int(np.flatnonzero(~done)[0])
        done[root] = True
        direction[root] = np.cos(out[root]) * e1[root] + np.sin(out[root]) * e2[root]
        frontier = np.array([root])
        while len(frontier):
            counts = offsets[frontier + 1] - offsets[frontier]
            src = np.repeat(frontier, counts)
            dst = nbr[_ranges(offsets[frontier], counts)]
            fresh = ~done[dst]
            src, dst = src[fresh], dst[fresh]
            dst, first = np.unique(dst, return_index=True)
            src = src[first]
            # the neighbour's direction in this vertex's frame: the nearest of the n angles to it
            d = direction[src]
            phi = np.arctan2(np.einsum("ij,ij->i", d, e2[dst]), np.einsum("ij,ij->i", d, e1[dst]))
            out[dst] += step * np.round((phi - out[dst]) / step)
            direction[dst] = np.cos(out[dst])[:, None] * e1[dst] + np.sin(out[dst])[:, None] * e2[dst]
            done[dst] = True
            frontier = dst
    return out


def _ranges(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Concatenation of arange(s, s + c) for each (s, c), without a Python loop."""
    first = np.repeat(np.cumsum(counts) - counts, counts)
    return np.repeat(starts, counts) + (np.arange(int(counts.sum())) - first)


def vertex_singularity_index(num_vertices: int, singularities) -> np.ndarray:
    """(V,) float array with the index of each listed (vertex, index) pair and 0 elsewhere."""
    out = np.zeros(int(num_vertices), dtype=np.float64)
    for vtx, idx in singularities:
        out[int(vtx)] = float(idx)
    return out
