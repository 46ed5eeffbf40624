"""Line and point lists the overlay draws: evenly spread glyph faces, n-direction glyphs, constraint arrows.

Pure numpy (no ``bpy``), object space; ``overlay`` turns the arrays into GPU batches.
"""
from __future__ import annotations

import numpy as np

__all__ = ["sample_faces", "glyph_segments", "constraint_arrow_segments", "project_to_region", "screen_min_length"]


def sample_faces(centroids: np.ndarray, areas: np.ndarray, target: int, seed_valid: np.ndarray | None = None
                 ) -> tuple[np.ndarray, float]:
    """Evenly spread, deterministic subset of faces (spatial hash, one face per grid cell).

    Returns ``(face indices sorted ascending, spacing)``; ``spacing`` is the cell size (0 when every valid
    face is kept). ``seed_valid``: optional bool mask of faces that may be picked (faces with a field).
    """
    faces = np.arange(len(centroids)) if seed_valid is None else np.flatnonzero(seed_valid)
    target = max(1, int(target))
    if len(faces) <= target:
        return faces, 0.0
    c = centroids[faces]
    total = float(np.sum(areas[faces]))
    lo = c.min(axis=0)
    h = max(np.sqrt(total / target), 1e-12)
    best = None
    for _ in range(4):  # a surface crosses more cells than area/h^2: adjust h towards the target count
        q = np.floor((c - lo) / h).astype(np.int64)
        dims = q.max(axis=0) + 1
        keys = (q[:, 0] * dims[1] + q[:, 1]) * dims[2] + q[:, 2]
        d2 = np.sum((c - lo - (q + 0.5) * h) ** 2, axis=1)
        order = np.lexsort((d2, keys))
        ks = keys[order]
        first = np.ones(len(ks), dtype=bool)
        first[1:] = ks[1:] != ks[:-1]
        picked = order[first]
        best = (picked, h)
        ratio = len(picked) / target
        if 0.85 <= ratio <= 1.0:
            break
        h *= np.sqrt(ratio) * (1.0 if ratio > 1.0 else 1.02)
    picked, h = best
    if len(picked) > target:  # deterministic thinning of the last few percent
        keep = np.linspace(0, len(picked) - 1, target).round().astype(np.int64)
        picked = np.sort(picked)[keep]
    return np.sort(faces[picked]), float(h)


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
