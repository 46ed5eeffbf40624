"""Line and point lists the overlay draws: glyph faces spread evenly on screen, n-direction glyphs, constraint
arrows with a minimum size on screen.

Pure numpy (no ``bpy``), object space; ``overlay`` turns the arrays into GPU batches.
"""
from __future__ import annotations

import numpy as np

__all__ = ["pixels_per_unit", "sample_on_screen", "glyph_segments", "constraint_arrow_segments", "project_to_region",
           "screen_min_length"]


def _clip(points: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Clip coordinates (k, 4) of object-space points under the 4x4 matrix m."""
    return points @ m[:, :3].T + m[:, 3]


def _speed(h: np.ndarray, m: np.ndarray, size) -> np.ndarray:
    """pixels_per_unit from clip coordinates h (k, 4) of the points."""
    w = h[:, 3:4]
    ok = w[:, 0] > 1e-12
    w = np.where(ok[:, None], w, 1.0)
    # d(x/w)/dp = (M0 w - x M3) / w^2, scaled from clip to pixels
    jx = (m[0, :3] * w - h[:, 0:1] * m[3, :3]) * ((0.5 * size[0]) / w ** 2)
    jy = (m[1, :3] * w - h[:, 1:2] * m[3, :3]) * ((0.5 * size[1]) / w ** 2)
    a, b, c = np.einsum("ij,ij->i", jx, jx), np.einsum("ij,ij->i", jx, jy), np.einsum("ij,ij->i", jy, jy)
    sigma2 = 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)  # largest eigenvalue of J J^T
    return np.where(ok, np.sqrt(sigma2), 0.0)


def pixels_per_unit(points: np.ndarray, mvp: np.ndarray, size: tuple[float, float]) -> np.ndarray:
    """Screen pixels per object-space unit at each point (k, 3) under `mvp` (projection x view x world, 4x4)
    in a region of `size` (width, height): the largest singular value of the derivative of the point's
    region position, i.e. how far on screen a unit step in the most visible direction moves it. 0 for points
    behind the viewer (clip w <= 0)."""
    m = np.asarray(mvp, dtype=np.float64)
    return _speed(_clip(np.asarray(points, dtype=np.float64), m), m, size)


def sample_on_screen(centroids: np.ndarray, normals: np.ndarray, mvp: np.ndarray, size: tuple[float, float],
                     spacing_px: float, cap: int, valid: np.ndarray | None = None, margin: float = 0.1
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Faces whose glyphs are spread evenly *on screen*, about `spacing_px` pixels apart, at most `cap`.

    Only faces in front of the viewer whose centroid projects into the region (widened by `margin` x its
    size on each side) are candidates (``valid``: optional bool mask of faces that may be picked). Each
    candidate's cell size in object space is spacing_px / pixels_per_unit, rounded to a power-of-two level
    (so a perspective view keeps about the same spacing on screen near and far); one face per cell of its
    level is kept: the one whose centroid is nearest the cell's centre. Faces that face the viewer and faces
    that face away are sampled apart, so the back of a thin part never takes the place of its visible front.
    When more than `cap` faces would be kept, the cells grow until they fit (then a deterministic thinning
    of the last few percent). Zooming in therefore shows more glyphs per unit of surface, zooming out fewer.

    Returns ``(face indices sorted ascending, cell size in object units per returned face)``.
    """
    faces = np.arange(len(centroids)) if valid is None else np.flatnonzero(valid)
    cap = max(1, int(cap))
    empty = (np.zeros(0, dtype=np.int64), np.zeros(0))
    if len(faces) == 0:
        return empty
    m = np.asarray(mvp, dtype=np.float64)
    c = np.asarray(centroids, dtype=np.float64)[faces]
    h = _clip(c, m)
    w = np.where(h[:, 3] > 1e-12, h[:, 3], np.nan)  # behind the viewer: NaN fails every test below
    lim = 1.0 + 2.0 * margin  # NDC of the widened region
    inside = (np.abs(h[:, 0] / w) <= lim) & (np.abs(h[:, 1] / w) <= lim)
    faces, c, h = faces[inside], c[inside], h[inside]
    speed = _speed(h, m, size)
    keep = speed > 0
    faces, c, h, speed = faces[keep], c[keep], h[keep], speed[keep]
    if len(faces) == 0:
        return empty
    # facing: NDC depth decreases along the normal (towards the viewer)
    nrm = np.asarray(normals, dtype=np.float64)[faces]
    front = ((nrm @ m[2, :3]) * h[:, 3] - h[:, 2] * (nrm @ m[3, :3]) < 0).astype(np.int64)
    cell = float(spacing_px) / speed
    base = float(cell.min())
    level = np.maximum(np.floor(np.log2(cell / base) + 0.5), 0).astype(np.int64)
    group = level * 2 + front  # cells of one level and one side compete
    lo = c.min(axis=0)
    for _ in range(6):
        size_l = base * np.exp2(level)
        rel = (c - lo) / size_l[:, None]
        q = np.floor(rel).astype(np.int64)
        d2 = np.sum((rel - q - 0.5) ** 2, axis=1)  # in [0, 0.75]: squared distance to the cell centre / size^2
        dims = q.max(axis=0) + 1
        span = float(group.max() + 1) * float(dims[0]) * float(dims[1]) * float(dims[2])
        if span * 1024 < 2.0 ** 62:  # one int64 key (cell, then the distance in 1/1024 steps): one argsort
            key = ((group * dims[0] + q[:, 0]) * dims[1] + q[:, 1]) * dims[2] + q[:, 2]
            order = np.argsort(key * 1024 + np.minimum(d2 * (1024 / 0.75), 1023).astype(np.int64))
        else:  # an object many thousand cells across: sort the parts of the key
            key = None
            order = np.lexsort((d2, q[:, 2], q[:, 1], q[:, 0], group))
        first = np.ones(len(order), dtype=bool)
        if key is not None:
            ks = key[order]
            first[1:] = ks[1:] != ks[:-1]
        else:
            ks = np.stack([group, q[:, 0], q[:, 1], q[:, 2]], axis=1)[order]
            first[1:] = np.any(ks[1:] != ks[:-1], axis=1)
        picked, h_used = faces[order[first]], size_l[order[first]]
        if len(picked) <= cap:
            break
        base *= np.sqrt(len(picked) / cap) * 1.05  # coarser cells everywhere until the count fits
    if len(picked) > cap:  # deterministic thinning of what is left over
        sel = np.linspace(0, len(picked) - 1, cap).round().astype(np.int64)
        picked, h_used = picked[sel], h_used[sel]
    order = np.argsort(picked)
    return picked[order], h_used[order]


def glyph_segments(centroids: np.ndarray, normals: np.ndarray, half_length: np.ndarray,
                   directions: np.ndarray, lift: np.ndarray) -> np.ndarray:
    """Line-list vertices (float32 (2 * segments, 3)) for n-direction glyphs.

    ``directions`` (k, n, 3) unit directions of the k sampled faces (zero rows = no field: skipped).
    Even n: segments c +- L d_j for j < n/2 (d_{j+n/2} = -d_j). Odd n: c -> c + L d_j for every j, each with
    an arrowhead (two strokes in the tangent plane at the tip), since an odd-n direction has a sign.
    """
    k, n, _ = directions.shape
    base = centroids + normals * lift[:, None]
    hl = half_length[:, None, None]
    if n % 2 == 0 and n > 0:
        d = directions[:, : n // 2, :] * hl
        a = base[:, None, :] - d
        b = base[:, None, :] + d
    else:
        d = directions * (2.0 * hl)  # one-sided: same visual length as a centred segment
        a = np.broadcast_to(base[:, None, :], d.shape)
        b = base[:, None, :] + d
    valid = np.any(directions[:, : a.shape[1], :] != 0.0, axis=2)
    seg = np.stack([a, b], axis=2)[valid]  # (m, 2, 3)
    if n % 2 == 1:
        side = np.cross(np.broadcast_to(normals[:, None, :], d.shape), d)  # |side| = |d| (d is tangent)
        left = b - 0.3 * d + 0.2 * side
        right = b - 0.3 * d - 0.2 * side
        heads = np.concatenate([np.stack([b, left], axis=2)[valid], np.stack([b, right], axis=2)[valid]])
        seg = np.concatenate([seg, heads])
    return np.ascontiguousarray(seg.reshape(-1, 3), dtype=np.float32)


def constraint_arrow_segments(origins: np.ndarray, normals: np.ndarray, directions: np.ndarray,
                              length: np.ndarray) -> np.ndarray:
    """Arrow line-list (shaft + two head strokes in the tangent plane) for each constraint."""
    if len(origins) == 0:
        return np.zeros((0, 3), dtype=np.float32)
    d = directions / np.maximum(np.linalg.norm(directions, axis=1, keepdims=True), 1e-30)
    side = np.cross(normals, d)
    tip = origins + d * length[:, None]
    head = 0.3 * length[:, None]
    left = tip - d * head + side * head * 0.6
    right = tip - d * head - side * head * 0.6
    seg = np.stack([origins, tip, tip, left, tip, right], axis=1)
    return np.ascontiguousarray(seg.reshape(-1, 3), dtype=np.float32)


def project_to_region(points: np.ndarray, mvp: np.ndarray, size: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Region pixels (k, 2) of object-space points under `mvp` (projection x view x world, 4x4) in a region
    of `size` (width, height), and their clip w (<= 0: behind the viewer)."""
    h = np.c_[points, np.ones(len(points))] @ np.asarray(mvp, dtype=np.float64).T
    w = np.where(np.abs(h[:, 3]) > 1e-12, h[:, 3], 1e-12)
    px = np.c_[(h[:, 0] / w + 1.0) * 0.5 * size[0], (h[:, 1] / w + 1.0) * 0.5 * size[1]]
    return px, h[:, 3]


def screen_min_length(tails: np.ndarray, dirs: np.ndarray, length: np.ndarray, mvp: np.ndarray,
                      size: tuple[float, float], min_px: float, max_stretch: float) -> np.ndarray:
    """Arrow lengths (object space) stretched so that each arrow tail -> tail + dir * length is at least
    `min_px` pixels long on screen, by at most `max_stretch` x (an arrow pointing at the viewer stays short
    rather than huge). The stretch is computed at the drawn length; in perspective a longer arrow's tip moves
    slightly in depth, so the result is within a few percent of `min_px` for arrows much shorter than their
    distance to the eye."""
    a, wa = project_to_region(tails, mvp, size)
    b, wb = project_to_region(tails + dirs * length[:, None], mvp, size)
    px = np.linalg.norm(b - a, axis=1)
    stretch = np.where(px > 1e-6, min_px / np.maximum(px, 1e-6), max_stretch)
    stretch = np.clip(stretch, 1.0, max_stretch)
    stretch[(wa <= 0) | (wb <= 0)] = 1.0  # behind the viewer: leave as is
    return length * stretch
