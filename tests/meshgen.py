"""Procedural test meshes and small numpy helpers for the nfield test suite (numpy only).

Every generator returns ``(V, F)``: ``V`` float64 (n, 3) positions, ``F`` int64 (m, 3) triangles,
consistently oriented (outward normals for closed surfaces, +z for flat meshes) unless stated.

Measurements of meshes and the independent numpy reference of the paper's operators are in
mesh_reference.py.
"""
from __future__ import annotations

import math

import numpy as np

from mesh_reference import mean_edge_length

# ---------------------------------------------------------------------------------------------
# Basic surfaces
# ---------------------------------------------------------------------------------------------


def icosahedron(radius: float = 1.0):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    V = np.array(
        [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0],
         [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
         [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=float)
    F = np.array(
        [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
         [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
         [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
         [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    V *= radius / np.linalg.norm(V, axis=1, keepdims=True)
    return V, F


def project_to_sphere(radius: float = 1.0, center=(0.0, 0.0, 0.0)):
    c = np.asarray(center, dtype=float)

    def proj(V):
        d = V - c
        return c + radius * d / np.linalg.norm(d, axis=1, keepdims=True)

    return proj


def project_to_torus(R: float, r: float):
    """Closest-point projection onto the torus of radii R (centre circle) and r (tube), axis z."""

    def proj(V):
        u = np.arctan2(V[:, 1], V[:, 0])
        c = np.stack([R * np.cos(u), R * np.sin(u), np.zeros_like(u)], axis=1)
        d = V - c
        return c + r * d / np.linalg.norm(d, axis=1, keepdims=True)

    return proj


def midpoint_subdivide(V, F, project=None, return_parent: bool = False):
    """1-to-4 split of every triangle (a,b,c) -> (a,ab,ca), (ab,b,bc), (ca,bc,c), (ab,bc,ca).

    New vertices are edge midpoints, optionally mapped by ``project`` (a function (k,3) -> (k,3),
    applied to the new vertices only). Children of face f are faces 4f..4f+3; with
    ``return_parent`` the parent index of every new face is returned too. Orientation is kept.
    """
    V = np.asarray(V, dtype=float)
    F = np.asarray(F, dtype=np.int64)
    nv = len(V)
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key = np.sort(e, axis=1)
    uniq, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    mid = 0.5 * (V[uniq[:, 0]] + V[uniq[:, 1]])
    if project is not None:
        mid = project(mid)
    m = len(F)
    ab = nv + inv[:m]
    bc = nv + inv[m:2 * m]
    ca = nv + inv[2 * m:]
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    F2 = np.stack([
        np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
        np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)], axis=1).reshape(-1, 3)
    V2 = np.concatenate([V, mid])
    if return_parent:
        return V2, F2, np.repeat(np.arange(m), 4)
    return V2, F2


def icosphere(subdivisions: int = 2, radius: float = 1.0):
    """Subdivided icosahedron projected to the sphere: 20*4^s faces, chi = 2."""
    V, F = icosahedron(radius)
    proj = project_to_sphere(radius)
    for _ in range(subdivisions):
        V, F = midpoint_subdivide(V, F, project=proj)
    return V, F


def _grid_faces(nu, nv, idx, rng, random_diagonals, periodic_u, periodic_v):
    """Triangulate the quads (i,j),(i+1,j),(i+1,j+1),(i,j+1) of a vertex index grid ``idx``."""
    faces = []
    iu = nu if periodic_u else nu - 1
    iv = nv if periodic_v else nv - 1
    flips = rng.random((iu, iv)) < 0.5 if random_diagonals else np.zeros((iu, iv), bool)
    for i in range(iu):
        for j in range(iv):
            a = idx[i, j]
            b = idx[(i + 1) % nu, j]
            c = idx[(i + 1) % nu, (j + 1) % nv]
            d = idx[i, (j + 1) % nv]
            if flips[i, j]:
                faces += [(a, b, d), (b, c, d)]
            else:
                faces += [(a, b, c), (a, c, d)]
    return np.array(faces, dtype=np.int64)


def torus(R: float = 2.0, r: float = 0.7, nu: int = 48, nv: int = 16, perturb: float = 0.0,
          random_diagonals: bool = False, seed: int = 0):
    """Torus around the z axis, u around the axis (nu samples), v around the tube (nv samples).

    ``perturb`` moves each vertex in parameter space by up to ``perturb`` grid steps in u and v
    (uniformly at random), so vertices stay exactly on the torus (tangential perturbation);
    ``random_diagonals`` picks the diagonal of every quad at random. chi = 0, outward normals.
    """
    rng = np.random.default_rng(seed)
    u = 2 * np.pi * np.arange(nu) / nu
    v = 2 * np.pi * np.arange(nv) / nv
    U, W = np.meshgrid(u, v, indexing="ij")
    if perturb:
        U = U + perturb * (2 * np.pi / nu) * rng.uniform(-1, 1, U.shape)
        W = W + perturb * (2 * np.pi / nv) * rng.uniform(-1, 1, W.shape)
    X = np.stack([(R + r * np.cos(W)) * np.cos(U), (R + r * np.cos(W)) * np.sin(U), r * np.sin(W)],
                 axis=-1).reshape(-1, 3)
    idx = np.arange(nu * nv).reshape(nu, nv)
    F = _grid_faces(nu, nv, idx, rng, random_diagonals, True, True)
    return X, F


def torus_frame(R: float, P):
    """Analytic (u, v) angles and unit tangents e_u (around the z axis), e_v (around the tube) at
    points P near a torus of centre radius R."""
    P = np.asarray(P, float)
    u = np.arctan2(P[:, 1], P[:, 0])
    rho = np.hypot(P[:, 0], P[:, 1])
    v = np.arctan2(P[:, 2], rho - R)
    e_u = np.stack([-np.sin(u), np.cos(u), np.zeros_like(u)], 1)
    e_v = np.stack([-np.sin(v) * np.cos(u), -np.sin(v) * np.sin(u), np.cos(v)], 1)
    return u, v, e_u, e_v


def cylinder(radius: float = 1.0, height: float = 2.0, nu: int = 32, nz: int = 16,
             perturb: float = 0.0, random_diagonals: bool = False, seed: int = 0):
    """Open cylinder around the z axis (two boundary loops, chi = 0), outward normals."""
    rng = np.random.default_rng(seed)
    u = 2 * np.pi * np.arange(nu) / nu
    z = np.linspace(-height / 2, height / 2, nz)
    U, Z = np.meshgrid(u, z, indexing="ij")
    if perturb:
        U = U + perturb * (2 * np.pi / nu) * rng.uniform(-1, 1, U.shape)
        dz = height / (nz - 1)
        inner = np.zeros_like(Z)
        inner[:, 1:-1] = perturb * dz * rng.uniform(-1, 1, (nu, nz - 2))
        Z = Z + inner
    X = np.stack([radius * np.cos(U), radius * np.sin(U), Z], -1).reshape(-1, 3)
    idx = np.arange(nu * nz).reshape(nu, nz)
    F = _grid_faces(nu, nz, idx, rng, random_diagonals, True, False)
    return X, F


def grid(nx: int = 10, ny: int = 10, width: float = 1.0, height: float = 1.0,
         random_diagonals: bool = False, seed: int = 0):
    """Flat rectangle [0,width] x [0,height] in z = 0, nx x ny vertices, normals +z (chi = 1)."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0, width, nx)
    y = np.linspace(0, height, ny)
    X, Y = np.meshgrid(x, y, indexing="ij")
    P = np.stack([X, Y, np.zeros_like(X)], -1).reshape(-1, 3)
    idx = np.arange(nx * ny).reshape(nx, ny)
    F = _grid_faces(nx, ny, idx, rng, random_diagonals, False, False)
    return P, F


def _stitch_rings(a_idx, a_ang, b_idx, b_ang):
    """Triangulate the band between two concentric closed rings (inner a, outer b) by merging
    their vertices by angle; faces are counter-clockwise seen from +z."""
    faces = []
    na, nb = len(a_idx), len(b_idx)
    i = j = 0
    while i < na or j < nb:
        a0, a1 = a_idx[i % na], a_idx[(i + 1) % na]
        b0, b1 = b_idx[j % nb], b_idx[(j + 1) % nb]
        ta = a_ang[(i + 1) % na] + (2 * np.pi if i + 1 >= na else 0)
        tb = b_ang[(j + 1) % nb] + (2 * np.pi if j + 1 >= nb else 0)
        if j >= nb or (i < na and ta <= tb):
            faces.append((a0, b0, a1))
            i += 1
        else:
            faces.append((a0, b0, b1))
            j += 1
    return faces


def disk(rings: int = 8, radius: float = 1.0, a: float = 1.0, b: float = 1.0):
    """Flat disk (or ellipse with semi-axes a*radius, b*radius) of concentric rings, ring k with
    6k vertices; normals +z, one boundary loop, chi = 1."""
    P = [np.zeros(3)]
    ring_idx, ring_ang = [np.array([0])], [np.array([0.0])]
    for k in range(1, rings + 1):
        ang = 2 * np.pi * np.arange(6 * k) / (6 * k)
        rr = radius * k / rings
        start = len(P)
        for t in ang:
            P.append(np.array([a * rr * np.cos(t), b * rr * np.sin(t), 0.0]))
        ring_idx.append(np.arange(start, start + 6 * k))
        ring_ang.append(ang)
    faces = []
    c = 0
    for t in range(6):
        faces.append((c, ring_idx[1][t], ring_idx[1][(t + 1) % 6]))
    for k in range(1, rings):
        faces += _stitch_rings(ring_idx[k], ring_ang[k], ring_idx[k + 1], ring_ang[k + 1])
    return np.array(P), np.array(faces, dtype=np.int64)


def mobius(nu: int = 40, nw: int = 6, width: float = 0.5, R: float = 1.0):
    """Moebius strip (non-orientable, one boundary loop, chi = 0). The faces are oriented
    consistently except across the closing seam, where orientation cannot agree."""
    u = 2 * np.pi * np.arange(nu) / nu
    w = np.linspace(-width, width, nw)
    U, W = np.meshgrid(u, w, indexing="ij")
    X = np.stack([(R + W * np.cos(U / 2)) * np.cos(U), (R + W * np.cos(U / 2)) * np.sin(U),
                  W * np.sin(U / 2)], -1).reshape(-1, 3)
    idx = np.arange(nu * nw).reshape(nu, nw)
    faces = []
    for i in range(nu):
        for j in range(nw - 1):
            a, d = idx[i, j], idx[i, j + 1]
            if i + 1 < nu:
                b, c = idx[i + 1, j], idx[i + 1, j + 1]
            else:  # u = 2 pi is u = 0 with w -> -w
                b, c = idx[0, nw - 1 - j], idx[0, nw - 2 - j]
            faces += [(a, b, c), (a, c, d)]
    return X, np.array(faces, dtype=np.int64)


def bumpy_sphere(subdivisions: int = 3, amplitude: float = 0.15, seed: int = 0,
                 jitter: float = 0.3):
    """Icosphere with a smooth random radial bump field and random tangential vertex jitter
    (``jitter`` in units of the local edge length) so the triangulation is irregular; chi = 2."""
    rng = np.random.default_rng(seed)
    V, F = icosphere(subdivisions)
    h = mean_edge_length(V, F)
    t = rng.normal(size=V.shape)
    t -= (t * V).sum(1, keepdims=True) * V
    V = V + jitter * h * t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12) \
        * rng.uniform(0, 1, (len(V), 1))
    V /= np.linalg.norm(V, axis=1, keepdims=True)
    dirs = rng.normal(size=(4, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    bump = sum(np.exp(3.0 * (V @ d - 1.0)) * s for d, s in zip(dirs, [1, -1, 1, -1]))
    return V * (1.0 + amplitude * bump)[:, None], F


# ---------------------------------------------------------------------------------------------
# Convex hulls and irregular triangulations
# ---------------------------------------------------------------------------------------------


def convex_hull(P, seed: int = 0):
    """Incremental 3D convex hull of points in general position; returns outward triangles.
    Points inside the hull are left unused (they do not occur for points on a sphere)."""
    P = np.asarray(P, dtype=float)
    rng = np.random.default_rng(seed)
    n = len(P)
    order = list(rng.permutation(n))
    # initial tetrahedron from four affinely independent points
    i0 = order[0]
    i1 = max(order[1:], key=lambda k: np.linalg.norm(P[k] - P[i0]))
    d01 = P[i1] - P[i0]
    i2 = max(order, key=lambda k: np.linalg.norm(np.cross(d01, P[k] - P[i0])))
    nrm = np.cross(d01, P[i2] - P[i0])
    i3 = max(order, key=lambda k: abs(np.dot(nrm, P[k] - P[i0])))
    if np.dot(nrm, P[i3] - P[i0]) > 0:
        i1, i2 = i2, i1
    cap = 2 * n + 8
    Fa = np.zeros((cap, 3), np.int64)
    N = np.zeros((cap, 3))
    D = np.full(cap, np.inf)  # dead / unused slots are never visible
    m = 0

    def add(tris):
        nonlocal m
        tris = np.asarray(tris, np.int64).reshape(-1, 3)
        a, b, c = P[tris[:, 0]], P[tris[:, 1]], P[tris[:, 2]]
        nn = np.cross(b - a, c - a)
        nn /= np.linalg.norm(nn, axis=1, keepdims=True)
        k = len(tris)
        if m + k > len(Fa):
            raise RuntimeError("convex_hull: capacity exceeded")
        Fa[m:m + k], N[m:m + k], D[m:m + k] = tris, nn, (nn * a).sum(1)
        m += k

    add([(i0, i1, i2), (i0, i3, i1), (i1, i3, i2), (i2, i3, i0)])
    eps = 1e-12 * np.ptp(P, axis=0).max()
    used = {i0, i1, i2, i3}
    for k in order:
        if k in used:
            continue
        vf = np.nonzero(N[:m] @ P[k] - D[:m] > eps)[0]
        if len(vf) == 0:
            continue
        edges = set()
        for f in vf:
            a, b, c = Fa[f]
            edges.update([(a, b), (b, c), (c, a)])
        horizon = [(a, b, k) for (a, b) in edges if (b, a) not in edges]
        D[vf] = np.inf  # remove visible faces
        if m + len(horizon) > len(Fa):  # compact
            alive = np.isfinite(D[:m])
            cnt = int(alive.sum())
            Fa[:cnt], N[:cnt], D[:cnt] = Fa[:m][alive], N[:m][alive], D[:m][alive]
            D[cnt:] = np.inf
            m = cnt
        add(horizon)
        used.add(k)
    return Fa[:m][np.isfinite(D[:m])].copy()


def blue_noise_sphere(n_points: int, seed: int = 0, density=None, min_dist_factor: float = 0.6,
                      max_tries: int = 400000):
    """Random points on the unit sphere with a minimum-distance (dart throwing) rule, using a grid
    hash. ``density`` (a function of (k,3) points -> relative density in (0,1]) makes the spacing
    non-uniform: the local minimum distance scales with density**-0.5."""
    rng = np.random.default_rng(seed)
    base = min_dist_factor * math.sqrt(4 * math.pi / n_points)
    rmax = base / math.sqrt(0.05) if density is not None else base
    cell = rmax
    grid_ = {}
    pts = []
    tries = 0
    while len(pts) < n_points and tries < max_tries:
        c = rng.normal(size=(512, 3))
        c /= np.linalg.norm(c, axis=1, keepdims=True)
        dens = np.ones(len(c)) if density is None else np.maximum(density(c), 0.05)
        tries += len(c)
        keys = np.floor(c / cell).astype(np.int64)
        for p, dd, key in zip(c, dens, keys):
            r = base / math.sqrt(dd)
            kx, ky, kz = key
            ok = True
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    for dz in (-1, 0, 1):
                        for q in grid_.get((kx + dx, ky + dy, kz + dz), ()):
                            if (p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2 < r * r:
                                ok = False
                                break
                        if not ok:
                            break
                    if not ok:
                        break
                if not ok:
                    break
            if not ok:
                continue
            pts.append(p)
            grid_.setdefault((kx, ky, kz), []).append(p)
            if len(pts) >= n_points:
                break
    return np.asarray(pts)


def irregular_ellipsoid(a: float = 1.6, b: float = 1.0, c: float = 0.6, n_points: int = 600,
                        seed: int = 0, density=None, twist: float = 0.0):
    """Closed ellipsoid x^2/a^2 + y^2/b^2 + z^2/c^2 = 1 with an irregular, asymmetric
    triangulation: blue-noise random points on the unit sphere (optionally with a non-uniform
    density), convex hull (= spherical Delaunay), then the affine map diag(a,b,c) (the hull of an
    affine image is the affine image of the hull). ``twist`` (radians per unit of x) moves the
    vertices along the unit sphere by a rotation about the x axis of angle twist * x before the
    affine map, keeping the connectivity: the triangles get sheared in a chiral pattern (no mirror
    symmetry), while every vertex stays exactly on the ellipsoid. The *shape* is symmetric under the
    three coordinate reflections up to the sampling, the triangulation is not."""
    S = blue_noise_sphere(n_points, seed=seed, density=density)
    F = convex_hull(S, seed=seed)
    used = np.unique(F)
    remap = -np.ones(len(S), np.int64)
    remap[used] = np.arange(len(used))
    S = S[used]
    if twist:
        t = twist * S[:, 0]
        S = np.stack([S[:, 0], S[:, 1] * np.cos(t) - S[:, 2] * np.sin(t),
                      S[:, 1] * np.sin(t) + S[:, 2] * np.cos(t)], 1)
    return S * np.array([a, b, c]), remap[F]


def delaunay_2d(P2, seed: int = 0):
    """Delaunay triangulation of 2D points (lower convex hull of the lifted points), CCW faces."""
    P2 = np.asarray(P2, float)
    L = np.column_stack([P2, (P2 ** 2).sum(1)])
    F = convex_hull(L, seed=seed)
    a, b, c = L[F[:, 0]], L[F[:, 1]], L[F[:, 2]]
    nz = np.cross(b - a, c - a)[:, 2]
    F = F[nz < 0]  # lower hull: outward normal points down
    return F[:, [0, 2, 1]]


def irregular_ellipse(a: float = 2.0, b: float = 1.0, n_boundary: int = 48,
                      n_interior: int = 200, seed: int = 0):
    """Flat ellipse (exactly symmetric boundary polygon) triangulated from random interior points
    by Delaunay: symmetric shape, non-symmetric triangulation; normals +z, chi = 1."""
    rng = np.random.default_rng(seed)
    t = 2 * np.pi * np.arange(n_boundary) / n_boundary
    B = np.stack([a * np.cos(t), b * np.sin(t)], 1)
    h = 2 * np.pi * math.sqrt((a * a + b * b) / 2) / n_boundary
    pts = []
    while len(pts) < n_interior:
        q = rng.uniform(-1, 1, 2) * [a, b]
        if (q[0] / a) ** 2 + (q[1] / b) ** 2 > (1 - 0.5 * h / min(a, b)) ** 2:
            continue
        if pts and np.min(np.linalg.norm(np.asarray(pts) - q, axis=1)) < 0.5 * h:
            continue
        pts.append(q)
    P2 = np.concatenate([B, np.asarray(pts)])
    F = delaunay_2d(P2, seed=seed)
    return np.column_stack([P2, np.zeros(len(P2))]), F


# ---------------------------------------------------------------------------------------------
# Mesh helpers
# ---------------------------------------------------------------------------------------------


def cyclic_rotate_faces(F, seed: int = 0):
    """Rotate each face's vertex list cyclically by a random 0, 1 or 2 steps: the geometry,
    orientation and face numbering are unchanged, only the native first-edge frame changes."""
    F = np.asarray(F, dtype=np.int64)
    k = np.random.default_rng(seed).integers(0, 3, len(F))
    idx = (np.arange(3)[None, :] + k[:, None]) % 3
    return np.take_along_axis(F, idx, axis=1)


def box(k: int = 4, other_diagonal_below: bool = False):
    """Closed cube [-1, 1]^3, each side a k x k grid of quads split into triangles, outward normals.
    other_diagonal_below: the three sides facing -x, -y, -z split their quads along the other diagonal."""
    verts: dict[tuple, int] = {}
    V: list = []
    F: list = []

    def vid(p):
        key = tuple(np.round(p, 12))
        if key not in verts:
            verts[key] = len(V)
            V.append(p)
        return verts[key]

    t = np.linspace(-1, 1, k + 1)
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u_ax, v_ax = [a for a in range(3) if a != axis]
            for i in range(k):
                for j in range(k):
                    quad = []
                    for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1)):
                        p = np.zeros(3)
                        p[axis] = sign
                        p[u_ax], p[v_ax] = t[i + di], t[j + dj]
                        quad.append(vid(p))
                    a, b, c, d = quad if not (other_diagonal_below and sign < 0) else quad[1:] + quad[:1]
                    tri = [(a, b, c), (a, c, d)]
                    # orient outward: normal of (a, b, c) must point along sign * e_axis
                    P = [np.array(V[x]) for x in tri[0]]
                    if np.cross(P[1] - P[0], P[2] - P[0])[axis] * sign < 0:
                        tri = [(a, c, b), (a, d, c)]
                    F += tri
    return np.array(V, dtype=float), np.array(F, dtype=np.int64)
