"""The stored design of an object (``obj.nfield``): reading it, writing it, and keeping it on the mesh.

The design is what the user made: hard constraints (face, direction, kind), pinned singularities (vertex,
index as numerator / the n it was placed at), the face list of an active region edit and the committed layers (faces + frozen values).
It lives in the object's properties (``properties.NFieldSettings``), so it is saved with the .blend and
restored by undo. This module is the only writer of those collections: the scripting API (``api``) and the
viewport tools go through it, so an item is always created, re-aimed and removed the same way (one item
per face or vertex, the list's active index following).

Mesh changes (:func:`remap_design`, called by ``api.sync`` with the freshly read mesh):

* no topology change: the recorded centroids/positions follow the moved vertices;
* a topology change: a constraint moves to the face whose centroid is nearest to the centroid recorded at
  placement, if that is within ``REMAP_TOLERANCE`` x the bounding-box diagonal; otherwise it is flagged
  ``stale`` (kept, shown in the panel, ignored by the solver). Singularities are remapped the same way by
  vertex position; layers and the active region are flagged stale / ended (their face lists cannot be
  remapped safely). Nothing is dropped silently.

Settings writes that must not trigger the property update callbacks (restoring a snapshot, ``configure``)
run inside :func:`suspended_updates`; ``handlers`` asks :func:`updates_suspended`.
"""
from __future__ import annotations

from contextlib import contextmanager
from typing import Iterable, Iterator

import numpy as np

from .errors import NFieldError
from .mesh_read import MeshArrays, topology_of

#: relative (to the bounding-box diagonal) distance within which a constraint follows its face centroid
REMAP_TOLERANCE = 1e-4
#: the settings a snapshot covers (configure() may change them; a failed solve puts them back)
SETTING_KEYS = ("symmetry", "energy", "alignment", "alignment_attribute", "strength", "solver_mode", "spectral_k",
                "live_update")


# ------------------------------------------------------------------------------------------ update suspension
_suspended = 0


@contextmanager
def suspended_updates() -> Iterator[None]:
    """Settings written inside this block do not re-solve through the property update callbacks."""
    global _suspended
    _suspended += 1
    try:
        yield
    finally:
        _suspended -= 1


def updates_suspended() -> bool:
    """True while settings are written inside suspended_updates()."""
    return _suspended > 0


# ------------------------------------------------------------------------------------------ reading
def desired_design(obj) -> tuple[dict, dict]:
    """(constraints {face: (kind, direction)}, singularities {vertex: index}) of the live (non-stale) items."""
    st = obj.nfield
    n = st.n
    dirs = {int(c.face): (c.kind, tuple(float(x) for x in c.direction)) for c in st.constraints if not c.stale}
    sings = {}
    for s in st.singularities:
        k = None if s.stale else singularity_numerator(s, n)
        if k is not None:
            sings[int(s.vertex)] = k / n
    return dirs, sings


def singularity_index(item, n: int) -> float:
    """The stored index of a singularity item (numerator / the n it was placed at)."""
    return item.numerator / (item.denominator or n)


def singularity_numerator(item, n: int) -> int | None:
    """The numerator k of the item's index at symmetry n (index = k / n), None if the index is no multiple
    of 1/n (e.g. +1/2 at n = 1): such an item is kept in the design but ignored and reported."""
    den = item.denominator or n
    if (item.numerator * n) % den:
        return None
    return item.numerator * n // den


def pin_denominators(obj) -> None:
    """Files from before the denominator was stored: their numerators refer to the n of the file; record
    that n so the index is kept from now on."""
    st = obj.nfield
    for s in st.singularities:
        if s.denominator == 0:
            s.denominator = st.n


def index_text(numerator: int, denominator: int) -> str:
    """+1/2, -1/4, +1 (reduced)."""
    from math import gcd

    g = gcd(abs(numerator), denominator) or 1
    p, q = numerator // g, denominator // g
    return f"{p:+d}" if q == 1 else f"{p:+d}/{q}"


def invalid_for_n(obj) -> list[str]:
    """Messages for the live singularities whose index is no multiple of 1/n at the object's n."""
    st = obj.nfield
    n = st.n
    return [f"singularity at vertex {s.vertex}: index {index_text(s.numerator, s.denominator or n)} is not a "
            f"multiple of 1/{n} at n = {n} (ignored until n allows it or it is changed)"
            for s in st.singularities if not s.stale and singularity_numerator(s, n) is None]


def design_state(obj) -> tuple:
    """What of the design lives only in a solver session: the active region and the committed layers."""
    st = obj.nfield
    return (bool(st.region_active), tuple(len(l.faces) for l in st.layers if not l.stale))


def stale_items(obj) -> list[str]:
    """Descriptions of the constraints / singularities / layers flagged stale."""
    st = obj.nfield
    out = [f"constraint on face {c.face}" for c in st.constraints if c.stale]
    out += [f"singularity at vertex {s.vertex}" for s in st.singularities if s.stale]
    out += [f"singularity at vertex {s.vertex} (index invalid for n = {st.n})" for s in st.singularities
            if not s.stale and singularity_numerator(s, st.n) is None]
    out += [f"layer '{l.name}'" for l in st.layers if l.stale]
    return out


def constraint_item(obj, face: int):
    """The live constraint item on `face`, or None."""
    return next((c for c in obj.nfield.constraints if c.face == face and not c.stale), None)


def singularity_item(obj, vertex: int):
    """The live singularity item at `vertex`, or None."""
    return next((s for s in obj.nfield.singularities if s.vertex == vertex and not s.stale), None)


def layer_arrays(layer) -> tuple[np.ndarray, np.ndarray]:
    """(faces, frozen values (k, 3)) of a stored layer."""
    faces = np.array([it.face for it in layer.faces], dtype=np.int64)
    values = np.array([tuple(it.value) for it in layer.faces], dtype=np.float64).reshape(-1, 3)
    return faces, values


def live_layer_position(obj, index: int) -> int:
    """Position of stored layer `index` among the live (non-stale) layers: its index in the session."""
    live = [i for i, l in enumerate(obj.nfield.layers) if not l.stale]
    return live.index(int(index))


# ------------------------------------------------------------------------------------------ writing
def _index_of(items, key: str, value) -> int | None:
    """Index of the live item whose `key` (face / vertex) is `value`, else of a stale one, else None."""
    idx = next((i for i, it in enumerate(items) if getattr(it, key) == value and not it.stale), None)
    if idx is None:
        idx = next((i for i, it in enumerate(items) if getattr(it, key) == value), None)
    return idx


def _clamped_index(index: int, items) -> int:
    """`index` moved inside `items` (0 when empty): a list's active index after an item was removed."""
    return max(0, min(index, len(items) - 1))


def _set_item(st, items: str, active: str, item, values: dict):
    """Write `values` into `item` of collection st.<items>, adding a new item (made the active one, st.<active>)
    when `item` is None. Returns the item."""
    if item is None:
        coll = getattr(st, items)
        item = coll.add()
        setattr(st, active, len(coll) - 1)
    for key, value in values.items():
        setattr(item, key, value)
    return item


def _remove_item(st, items: str, active: str, key: str, value: int, missing) -> None:
    """Remove the item of st.<items> whose `key` is `value` (a stale one if no live one) and keep the active
    index st.<active> in range; NFieldError(missing(sorted keys present)) when there is none."""
    coll = getattr(st, items)
    idx = _index_of(coll, key, value)
    if idx is None:
        raise NFieldError(missing(sorted(getattr(it, key) for it in coll) or "none"))
    coll.remove(idx)
    setattr(st, active, _clamped_index(getattr(st, active), coll))


def set_constraint(obj, face: int, direction, kind: str, centroid) -> object:
    """Create or re-aim the live constraint on `face` (validated by the caller). Returns the item."""
    return _set_item(obj.nfield, "constraints", "active_constraint_index", constraint_item(obj, face),
                     {"face": face, "direction": tuple(direction), "kind": kind, "stale": False,
                      "centroid": tuple(centroid)})


def remove_constraint(obj, face: int) -> None:
    """Remove the constraint on `face` (a stale one with that face number if no live one)."""
    _remove_item(obj.nfield, "constraints", "active_constraint_index", "face", face,
                 lambda faces: f"face {face} has no constraint (constrained faces: {faces})")


def clear_constraints(obj, stale_only: bool = False) -> int:
    """Remove all constraints (or only the stale ones). Returns how many were removed."""
    st = obj.nfield
    removed = 0
    for i in reversed(range(len(st.constraints))):
        if not stale_only or st.constraints[i].stale:
            st.constraints.remove(i)
            removed += 1
    st.active_constraint_index = 0
    return removed


def set_singularity(obj, vertex: int, numerator: int, position) -> object:
    """Create or change the live singularity at `vertex` (index = numerator / n; validated by the caller)."""
    st = obj.nfield
    return _set_item(st, "singularities", "active_singularity_index", singularity_item(obj, vertex),
                     {"vertex": vertex, "numerator": int(numerator), "denominator": st.n, "stale": False,
                      "position": tuple(position)})


def remove_singularity(obj, vertex: int) -> None:
    """Remove the singularity at `vertex` (a stale one with that vertex number if no live one)."""
    _remove_item(obj.nfield, "singularities", "active_singularity_index", "vertex", vertex,
                 lambda verts: f"vertex {vertex} has no prescribed singularity (pinned vertices: {verts})")


def clear_singularities(obj) -> int:
    st = obj.nfield
    k = len(st.singularities)
    st.singularities.clear()
    st.active_singularity_index = 0
    return k


def start_region(obj, faces: Iterable[int]) -> None:
    st = obj.nfield
    st.region_faces.clear()
    for f in faces:
        st.region_faces.add().face = f
    st.region_active = True


def end_region(obj) -> None:
    st = obj.nfield
    st.region_active = False
    st.region_faces.clear()


def add_layer(obj, faces: Iterable[int], values: np.ndarray):
    """Append a committed layer (`values`: one frozen 3D value per face) and make it the active one."""
    st = obj.nfield
    layer = st.layers.add()
    layer.name = f"Layer {len(st.layers)}"
    for f, v in zip(faces, values):
        item = layer.faces.add()
        item.face = f
        item.value = v
    st.active_layer_index = len(st.layers) - 1
    return layer


def remove_layer(obj, index: int) -> None:
    st = obj.nfield
    st.layers.remove(int(index))
    st.active_layer_index = _clamped_index(st.active_layer_index, st.layers)


# ------------------------------------------------------------------------------------------ snapshots
def snapshot_design(obj) -> tuple:
    """Constraints and singularities of `obj` as plain tuples (for restore_design)."""
    st = obj.nfield
    cons = [(c.face, tuple(c.direction), c.kind, c.stale, tuple(c.centroid)) for c in st.constraints]
    sings = [(s.vertex, s.numerator, s.denominator, s.stale, tuple(s.position)) for s in st.singularities]
    return cons, sings


def restore_design(obj, saved: tuple) -> None:
    st = obj.nfield
    cons, sings = saved
    st.constraints.clear()
    for face, d, kind, stale, centroid in cons:
        c = st.constraints.add()
        c.face, c.direction, c.kind, c.stale, c.centroid = face, d, kind, stale, centroid
    st.singularities.clear()
    for vertex, num, den, stale, pos in sings:
        s = st.singularities.add()
        s.vertex, s.numerator, s.denominator, s.stale, s.position = vertex, num, den, stale, pos
    st.active_constraint_index = _clamped_index(st.active_constraint_index, st.constraints)
    st.active_singularity_index = _clamped_index(st.active_singularity_index, st.singularities)


def snapshot(obj) -> tuple:
    """The user's settings and design (constraints, singularities, list positions) of `obj`, for restore()."""
    st = obj.nfield
    settings = tuple(getattr(st, k) for k in SETTING_KEYS)
    return settings, snapshot_design(obj), (st.active_constraint_index, st.active_singularity_index)


def restore(obj, saved: tuple) -> bool:
    """Put back what snapshot() saw, without re-solving (update callbacks are suspended). Only what differs is
    written. Returns True if anything was changed."""
    st = obj.nfield
    settings, design, active = saved
    changed = False
    with suspended_updates():
        for key, value in zip(SETTING_KEYS, settings):
            if getattr(st, key) != value:
                setattr(st, key, value)
                changed = True
        if snapshot_design(obj) != design:
            restore_design(obj, design)
            changed = True
        if (st.active_constraint_index, st.active_singularity_index) != active:
            st.active_constraint_index, st.active_singularity_index = active
    return changed


# ------------------------------------------------------------------------------------------ remapping
def _remap_items(items, key: str, position: str, points: np.ndarray, what: str, tol: float, notes: list,
                 mention_stale: bool) -> None:
    """Move each item's `key` (face / vertex) to the element of `points` nearest its stored `position` (within
    `tol`, one item per element); items without one are flagged stale. Each change is noted in `notes`."""
    taken: set[int] = set()
    for it in items:
        new = _nearest(points, np.asarray(getattr(it, position), dtype=np.float64), tol)
        old = getattr(it, key)
        if new is None or new in taken:
            if not it.stale:
                notes.append(f"{what} {old} flagged stale: its {key} no longer exists")
            it.stale = True
            continue
        taken.add(new)
        if new != old or it.stale:
            notes.append(f"{what} {old} remapped to {key} {new}" + (" (was stale)" if mention_stale and it.stale
                                                                     else ""))
        setattr(it, key, new)
        it.stale = False


def remap_design(obj, arrays: MeshArrays) -> list[str]:
    """Bring the stored design of `obj` in line with its current mesh (see the module docstring).

    Returns human-readable notes about what was remapped or flagged. Writes ``mesh_signature``.
    """
    st = obj.nfield
    notes: list[str] = []
    old_sig = st.mesh_signature
    if old_sig == arrays.signature:
        return notes
    same_topology = bool(old_sig) and topology_of(old_sig) == topology_of(arrays.signature)
    st.mesh_signature = arrays.signature
    if same_topology or not old_sig:
        if not old_sig:
            # first contact (design created by an older file / by script): validate indices only
            for c in st.constraints:
                if not c.stale and c.face >= arrays.num_polygons:
                    c.stale = True
                    notes.append(f"constraint on face {c.face} flagged stale: face out of range")
            for s in st.singularities:
                if not s.stale and s.vertex >= arrays.vertices.shape[0]:
                    s.stale = True
                    notes.append(f"singularity at vertex {s.vertex} flagged stale: vertex out of range")
        for c in st.constraints:
            if not c.stale and c.face < arrays.num_polygons:
                c.centroid = arrays.polygon_centers[c.face]
        for s in st.singularities:
            if not s.stale and s.vertex < arrays.vertices.shape[0]:
                s.position = arrays.vertices[s.vertex]
        return notes

    diag = float(np.linalg.norm(np.ptp(arrays.vertices, axis=0))) if arrays.vertices.shape[0] else 0.0
    tol = REMAP_TOLERANCE * max(diag, 1e-12)
    _remap_items(st.constraints, "face", "centroid", arrays.polygon_centers, "constraint on face", tol, notes,
                 mention_stale=True)
    _remap_items(st.singularities, "vertex", "position", arrays.vertices, "singularity at vertex", tol, notes,
                 mention_stale=False)
    for layer in st.layers:
        if not layer.stale:
            layer.stale = True
            notes.append(f"layer '{layer.name}' flagged stale: the topology changed")
    if st.region_active:
        st.region_active = False
        notes.append("region edit ended: the topology changed (its faces are kept in region_faces)")
    return notes


def _nearest(points: np.ndarray, p: np.ndarray, tol: float) -> int | None:
    if points.shape[0] == 0:
        return None
    d = np.linalg.norm(points - p[None, :], axis=1)
    i = int(np.argmin(d))
    return i if d[i] <= tol else None
