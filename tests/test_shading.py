"""nfield.core.shading (pure numpy helpers behind the Blender output attributes)."""
from __future__ import annotations

import numpy as np
import pytest

from nfield.core import shading

pytestmark = pytest.mark.no_sanitizer  # pure NumPy


def _grid(nx=6, ny=5, bump=0.2):
    xs, ys = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 1, ny), indexing="ij")
    v = np.stack([xs.ravel(), ys.ravel(), bump * np.sin(3 * xs.ravel()) * np.cos(2 * ys.ravel())], axis=1)
    tris = []
    for i in range(nx - 1):
        for j in range(ny - 1):
            a, b, c, d = i * ny + j, (i + 1) * ny + j, (i + 1) * ny + j + 1, i * ny + j + 1
            tris += [(a, b, c), (a, c, d)]
    return v, np.array(tris)


def _tangent_dirs(v, t, angle_of_face):
    n = np.cross(v[t[:, 1]] - v[t[:, 0]], v[t[:, 2]] - v[t[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    e1 = v[t[:, 1]] - v[t[:, 0]]
    e1 -= n * np.einsum("ij,ij->i", e1, n)[:, None]
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(n, e1)
    return np.cos(angle_of_face)[:, None] * e1 + np.sin(angle_of_face)[:, None] * e2, n


def test_smoothed_directions_are_n_symmetry_invariant_unit_and_tangent():
    v, t = _grid()
    rng = np.random.default_rng(1)
    base = 0.3 + 0.05 * rng.standard_normal(len(t))
    for n in (1, 2, 4, 6):
        d0, _ = _tangent_dirs(v, t, base)
        # each face reports a different one of its n directions: the average must not change
        d1, _ = _tangent_dirs(v, t, base + 2 * np.pi / n * rng.integers(0, n, len(t)))
        s0 = shading.vertex_smoothed_directions(v, t, d0, n)
        s1 = shading.vertex_smoothed_directions(v, t, d1, n)
        lengths = np.linalg.norm(s0, axis=1)
        assert np.allclose(lengths, 1.0)
        # compare as n-direction sets: exp(i n angle) equal <=> angle difference multiple of 2 pi / n
        ang = np.arctan2(np.linalg.norm(np.cross(s0, s1), axis=1), np.einsum("ij,ij->i", s0, s1))
        assert np.all(np.abs(np.sin(n * ang / 2)) < 1e-9) if n > 1 else np.allclose(ang, 0, atol=1e-9)


def test_polygon_tangent_directions_and_singularity_index():
    d = np.array([[1.0, 0, 0], [0, 0, 0], [1, 1, 1]])
    nrm = np.array([[0, 0, 1.0], [0, 0, 1], [0, 0, 2]])
    out = shading.polygon_tangent_directions(d, nrm)
    assert np.allclose(out, [[1, 0, 0], [0, 0, 0], [2 ** -0.5, 2 ** -0.5, 0]])
    assert shading.vertex_singularity_index(4, [(1, 0.25), (3, -0.5)]).tolist() == [0, 0.25, 0, -0.5]


def test_smoothed_directions_are_combed_to_agree_with_their_neighbours():
    """A smooth field without singularities that turns by 3 radians across a bumpy grid: each vertex's
    principal angle would jump at the branch cut (neighbours pointing opposite ways, a seam for a renderer
    interpolating the tangent); combed, every pair of neighbouring vertices agrees: for n = 2 their
    directions make an acute angle, for n = 4 an angle below 45 degrees. The field turns by at most 0.1 rad
    between neighbours here, so a correct comb is never near those thresholds."""
    v, t = _grid(nx=31, ny=21, bump=0.1)
    rng = np.random.default_rng(3)
    centre_x = v[t].mean(axis=1)[:, 0]
    edges = np.unique(np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1), axis=0)
    for n, limit in ((2, 90.0), (4, 45.0)):
        d, _ = _tangent_dirs(v, t, 3.0 * centre_x + 2 * np.pi / n * rng.integers(0, n, len(t)))
        s = shading.vertex_smoothed_directions(v, t, d, n)
        a, b = s[edges[:, 0]], s[edges[:, 1]]
        angle = np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b)))
        assert angle.max() < limit, (n, angle.max())
        # still the same n-direction set at every vertex as the uncombed average (a rotation by 2 pi k / n)
        d2, _ = _tangent_dirs(v, t, 3.0 * centre_x)
        ref = shading.vertex_smoothed_directions(v, t, d2, n)
        ang = np.arctan2(np.linalg.norm(np.cross(s, ref), axis=1), np.einsum("ij,ij->i", s, ref))
        assert np.all(np.abs(np.sin(n * ang / 2)) < 1e-9)
