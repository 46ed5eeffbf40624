"""Independent numpy references for the nfield tests (numpy only): measurements of a mesh (centroids, normals and
areas, edge lengths, statistics, closest faces, corner angles, angle defects, valences), the paper's discrete
operators built from scratch (Sections 3, 4, 6 and Appendix A: frames, transport r_ij, weights w_ij, the
Hermitian S, M; tests compare the native code with them only through frame-invariant quantities), and small
dense helpers. The procedural meshes themselves are in meshgen.py.
"""
from __future__ import annotations


import numpy as np


def face_centroids(V, F):
    return np.asarray(V)[np.asarray(F)].mean(axis=1)


def face_normals_areas(V, F):
    V = np.asarray(V, float)
    F = np.asarray(F)
    c = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    ln = np.linalg.norm(c, axis=1)
    return c / np.maximum(ln, 1e-300)[:, None], 0.5 * ln


def mean_edge_length(V, F):
    V = np.asarray(V, float)
    F = np.asarray(F)
    e = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    return float(np.linalg.norm(V[e[:, 0]] - V[e[:, 1]], axis=1).mean())


def mesh_stats(V, F):
    """Numpy topology summary: chi (over used vertices), #boundary edges, #non-manifold edges,
    #edges whose two faces are inconsistently oriented, number of components."""
    F = np.asarray(F, dtype=np.int64)
    de = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key = np.sort(de, axis=1)
    uniq, inv, cnt = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    used = np.unique(F)
    chi = len(used) - len(uniq) + len(F)
    # an edge shared by two faces is consistent iff it appears once in each direction
    fwd = de[:, 0] < de[:, 1]
    nfwd = np.bincount(inv, weights=fwd.astype(float), minlength=len(uniq))
    inconsistent = int(np.sum((cnt == 2) & (nfwd != 1)))
    # components via union-find over faces sharing an edge
    parent = np.arange(len(F))

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    face_of = np.tile(np.arange(len(F)), 3)
    order = np.argsort(inv, kind="stable")
    s_inv = inv[order]
    s_face = face_of[order]
    for k in range(1, len(order)):
        if s_inv[k] == s_inv[k - 1]:
            ra, rb = find(s_face[k]), find(s_face[k - 1])
            if ra != rb:
                parent[ra] = rb
    comps = len({find(x) for x in range(len(F))})
    return {"chi": int(chi), "boundary_edges": int(np.sum(cnt == 1)),
            "nonmanifold_edges": int(np.sum(cnt > 2)), "inconsistent_edges": inconsistent,
            "components": comps, "vertices_used": int(len(used)), "edges": int(len(uniq))}


def closest_faces(V, F, Q):
    """Index of the face containing the closest point of the mesh to each query point (brute
    force, exact point-triangle distance)."""
    V = np.asarray(V, float)
    F = np.asarray(F)
    A, B, C = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    out = []
    for q in np.atleast_2d(Q):
        out.append(int(np.argmin(_point_triangle_dist2(q, A, B, C))))
    return np.array(out, dtype=np.int64)


def _point_triangle_dist2(p, A, B, C):
    """Squared distance from p to triangles (A,B,C), vectorised (Ericson, Real-Time Collision
    Detection, 5.1.5, via clamped barycentric projection onto the plane and the three edges)."""
    def seg_d2(P0, P1):
        d = P1 - P0
        t = np.clip(((p - P0) * d).sum(1) / np.maximum((d * d).sum(1), 1e-300), 0, 1)
        x = P0 + t[:, None] * d - p
        return (x * x).sum(1)

    n = np.cross(B - A, C - A)
    nn = (n * n).sum(1)
    t = ((p - A) * n).sum(1) / np.maximum(nn, 1e-300)
    X = p - t[:, None] * n  # projection on the plane
    # barycentric inside test
    c0 = (np.cross(B - A, X - A) * n).sum(1)
    c1 = (np.cross(C - B, X - B) * n).sum(1)
    c2 = (np.cross(A - C, X - C) * n).sum(1)
    inside = (c0 >= 0) & (c1 >= 0) & (c2 >= 0)
    d_in = t * t * nn
    d_edge = np.minimum(np.minimum(seg_d2(A, B), seg_d2(B, C)), seg_d2(C, A))
    return np.where(inside, d_in, d_edge)


def wrap_angle(a):
    """Wrap to (-pi, pi]."""
    a = np.asarray(a, float)
    w = np.mod(a + np.pi, 2 * np.pi) - np.pi
    return np.where(w == -np.pi, np.pi, w)


# ---------------------------------------------------------------------------------------------
# Independent reference of the paper's operators (dense/complex, small meshes only)
# ---------------------------------------------------------------------------------------------


class ReferenceOperators:
    """Paper operators built from scratch with numpy for a clean, closed or bordered, manifold,
    consistently oriented mesh (no cleaning). Frames: x = first edge of the face as given,
    y = N x x. Complex Hermitian form: E(z) = sum_e w_e |r_e z_i - z_j|^2 = z^H S z."""

    def __init__(self, V, F, n: int, weights: str = "geometric"):
        self.V = V = np.asarray(V, float)
        self.F = F = np.asarray(F, np.int64)
        self.n = n
        nF = len(F)
        N, A = face_normals_areas(V, F)
        self.normals, self.areas = N, A
        x = V[F[:, 1]] - V[F[:, 0]]
        x /= np.linalg.norm(x, axis=1, keepdims=True)
        y = np.cross(N, x)
        self.frames = np.stack([x, y], 1)
        # dual edges: directed edge (a,b) in face i and (b,a) in face j
        de = {}
        for f in range(nF):
            for k in range(3):
                de[(int(F[f, k]), int(F[f, (k + 1) % 3]))] = f
        E = []
        for (a, b), i in de.items():
            j = de.get((b, a))
            if j is not None and a < b:
                E.append((i, j, a, b))
        self.dual = np.array(E, dtype=np.int64).reshape(-1, 4)
        i, j, a, b = self.dual.T
        e = V[b] - V[a]
        ai = np.arctan2((e * y[i]).sum(1), (e * x[i]).sum(1))
        aj = np.arctan2((e * y[j]).sum(1), (e * x[j]).sum(1))
        self.r = np.exp(1j * n * (aj - ai))
        if weights == "geometric":
            self.w = 3 * (e * e).sum(1) / (A[i] + A[j])
        else:
            self.w = np.ones(len(E))

    def S_dense(self):
        nF = len(self.F)
        S = np.zeros((nF, nF), complex)
        i, j = self.dual[:, 0], self.dual[:, 1]
        np.add.at(S, (i, i), self.w)
        np.add.at(S, (j, j), self.w)
        np.add.at(S, (i, j), -self.w * np.conj(self.r))
        np.add.at(S, (j, i), -self.w * self.r)
        return S

    def energy(self, z):
        i, j = self.dual[:, 0], self.dual[:, 1]
        return float(np.sum(self.w * np.abs(self.r * z[i] - z[j]) ** 2))

    def eigenvalues(self):
        S = self.S_dense()
        m = 1 / np.sqrt(self.areas)
        return np.linalg.eigvalsh(m[:, None] * S * m[None, :])

    def to_representation(self, vec3):
        """3D vectors per face -> complex representation (|z| = |projected vector|)."""
        x, y = self.frames[:, 0], self.frames[:, 1]
        vx, vy = (vec3 * x).sum(1), (vec3 * y).sum(1)
        return np.hypot(vx, vy) * np.exp(1j * self.n * np.arctan2(vy, vx))


# ---------------------------------------------------------------------------------------------
# Small numpy utilities shared by the tests
# ---------------------------------------------------------------------------------------------


def dense_from_coo(rows, cols, vals, size: int):
    """Dense complex matrix from COO triplets (duplicates are summed)."""
    A = np.zeros((size, size), complex)
    np.add.at(A, (np.asarray(rows, np.int64), np.asarray(cols, np.int64)), np.asarray(vals))
    return A


def generalized_eigvalsh(A, mass):
    """Eigenvalues of A z = lambda diag(mass) z for Hermitian A (dense, ascending)."""
    m = 1.0 / np.sqrt(np.asarray(mass, float))
    B = m[:, None] * A * m[None, :]
    return np.linalg.eigvalsh(0.5 * (B + B.conj().T))


def corner_angles(V, F):
    """(F, 3) interior angles of each face at its three corners."""
    V = np.asarray(V, float)
    F = np.asarray(F)
    out = np.zeros(F.shape)
    for k in range(3):
        a, b, c = V[F[:, k]], V[F[:, (k + 1) % 3]], V[F[:, (k + 2) % 3]]
        u, w = b - a, c - a
        out[:, k] = np.arctan2(np.linalg.norm(np.cross(u, w), axis=1), (u * w).sum(1))
    return out


def angle_defects(V, F):
    """2 pi - sum of corner angles per vertex (meaningful for interior vertices)."""
    F = np.asarray(F)
    ang = corner_angles(V, F)
    s = np.zeros(len(V))
    np.add.at(s, F.reshape(-1), ang.reshape(-1))
    return 2 * np.pi - s


def vertex_valence(F, nv: int):
    return np.bincount(np.asarray(F).reshape(-1), minlength=nv)
