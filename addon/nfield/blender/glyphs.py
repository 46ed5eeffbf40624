"""Line and point lists the overlay draws: evenly spread glyph faces, n-direction glyphs, constraint arrows.

Pure numpy (no ``bpy``), object space; ``overlay`` turns the arrays into GPU batches.
"""
from __future__ import annotations

import numpy as np

__all__ = ["sample_faces", "glyph_segments", "constraint_arrow_segments"]


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
    Even n: segments c +- L d_j for j < n/2 (d_{j+n/2} = -d_j). Odd n: c -> c + L d_j for every j.
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
