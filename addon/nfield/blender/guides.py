"""Reading guide sources from Blender data (no solving, no writing): marked edges, region borders, face
attributes and curve objects, as the arrays ``nfield.core``'s guide methods take.

Everything is read from the mesh object's *base* mesh (``obj.data``, modifiers ignored) in object space,
like ``mesh_read``. Vertex pairs are mesh vertex indices; per-face arrays have one value per polygon.

* :func:`marked_edges`: edges marked sharp or seam, and the borders of face sets or material slots (an edge
  is a border when the polygons around it carry different face sets / material indices);
* :func:`edge_attribute_edges`: the edges where an edge-domain BOOLEAN (or FLOAT > 0.5, INT != 0) attribute
  is set (cuts from a named attribute);
* :func:`face_values`: a face-domain FLOAT attribute (guide weight, guide rotation in radians);
* :func:`curve_polylines`: a curve object (Bezier / NURBS / poly curve, a Curves object, or a Grease Pencil
  object: legacy ``GPENCIL`` up to Blender 4.2, ``GREASEPENCIL`` from 4.3) as polylines in the mesh object's
  space, one per spline / stroke;
* :func:`comb_field` / :func:`write_comb_field`: the comb field stored as two face attributes
  (``COMB_DIRECTION`` FLOAT_VECTOR, ``COMB_WEIGHT`` FLOAT in [0, 1]); the mesh data is undoable and saved,
  so the comb strokes are too.
"""
from __future__ import annotations

import numpy as np

from .errors import NFieldError
from .mesh_read import named_attribute

__all__ = ["MARKED_SOURCES", "marked_edges", "edge_attribute_edges", "face_values", "curve_polylines",
           "CURVE_TYPES", "COMB_DIRECTION", "COMB_WEIGHT", "comb_field", "write_comb_field", "remove_comb_field"]

#: face attributes holding the comb field (unit tangent direction, object space) and its weight in [0, 1]
COMB_DIRECTION = "nfield_comb_direction"
COMB_WEIGHT = "nfield_comb_weight"

#: what a feature / cut can be read from, in the order the panel shows them
MARKED_SOURCES = ("SHARP", "SEAM", "FACE_SETS", "MATERIALS")
#: object types a curve guide can reference (Grease Pencil: "GPENCIL" in Blender 3.4 to 4.2, "GREASEPENCIL" from 4.3)
CURVE_TYPES = ("CURVE", "CURVES", "GPENCIL", "GREASEPENCIL")
_FACE_SET_ATTRIBUTE = ".sculpt_face_set"


def _edge_vertices(me) -> np.ndarray:
    buf = np.empty(len(me.edges) * 2, dtype=np.int32)
    me.edges.foreach_get("vertices", buf)
    return buf.reshape(-1, 2).astype(np.int64)


def _edge_flags(me, prop: str) -> np.ndarray:
    buf = np.zeros(len(me.edges), dtype=bool)
    me.edges.foreach_get(prop, buf)
    return buf


def _polygon_edges(me) -> tuple[np.ndarray, np.ndarray]:
    """(corner edges as sorted vertex pairs (corners, 2), polygon of every corner (corners,))."""
    nl = len(me.loops)
    corner_vert = np.empty(nl, dtype=np.int32)
    me.loops.foreach_get("vertex_index", corner_vert)
    np_ = len(me.polygons)
    start = np.empty(np_, dtype=np.int32)
    total = np.empty(np_, dtype=np.int32)
    me.polygons.foreach_get("loop_start", start)
    me.polygons.foreach_get("loop_total", total)
    poly = np.repeat(np.arange(np_, dtype=np.int64), total)
    nxt = np.arange(nl, dtype=np.int64) + 1
    last = (start + total - 1).astype(np.int64)
    nxt[last] = start  # each polygon's last corner closes onto its first
    pairs = np.sort(np.stack([corner_vert.astype(np.int64), corner_vert[nxt].astype(np.int64)], axis=1), axis=1)
    return pairs, poly


def _border_edges(me, labels: np.ndarray) -> np.ndarray:
    """Edges (sorted vertex pairs) whose polygons do not all carry the same label."""
    pairs, poly = _polygon_edges(me)
    if len(pairs) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    lab = labels[poly]
    uniq, inverse = np.unique(pairs, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    lo = np.full(len(uniq), np.iinfo(np.int64).max)
    hi = np.full(len(uniq), np.iinfo(np.int64).min)
    np.minimum.at(lo, inverse, lab)
    np.maximum.at(hi, inverse, lab)
    return uniq[lo != hi]


def marked_edges(obj, sources) -> np.ndarray:
    """(k, 2) int64 vertex pairs of the edges marked by `sources` (a subset of MARKED_SOURCES), without
    duplicates. Face sets: the sculpt face-set attribute (no attribute: one face set, no borders)."""
    me = obj.data
    sources = set(sources)
    unknown = sources - set(MARKED_SOURCES)
    if unknown:
        raise NFieldError(f"unknown edge source(s) {sorted(unknown)} (expected {', '.join(MARKED_SOURCES)})")
    parts = [np.zeros((0, 2), dtype=np.int64)]
    if sources & {"SHARP", "SEAM"} and len(me.edges):
        ev = _edge_vertices(me)
        if "SHARP" in sources:
            parts.append(ev[_edge_flags(me, "use_edge_sharp")])
        if "SEAM" in sources:
            parts.append(ev[_edge_flags(me, "use_seam")])
    if "MATERIALS" in sources and len(me.polygons):
        mat = np.empty(len(me.polygons), dtype=np.int32)
        me.polygons.foreach_get("material_index", mat)
        parts.append(_border_edges(me, mat.astype(np.int64)))
    if "FACE_SETS" in sources and len(me.polygons):
        attr = me.attributes.get(_FACE_SET_ATTRIBUTE)
        if attr is not None and attr.domain == "FACE" and attr.data_type == "INT":
            sets = np.empty(len(me.polygons), dtype=np.int32)
            attr.data.foreach_get("value", sets)
            parts.append(_border_edges(me, sets.astype(np.int64)))
    edges = np.sort(np.concatenate(parts), axis=1)
    return np.unique(edges, axis=0) if len(edges) else edges


def edge_attribute_edges(obj, name: str) -> np.ndarray:
    """(k, 2) vertex pairs of the edges where the edge-domain attribute `name` is set (BOOLEAN true, FLOAT
    > 0.5 or INT != 0). NFieldError naming the problem if there is no such edge attribute."""
    me = obj.data
    attr = named_attribute(obj, name, "cut attribute", "EDGE", ("BOOLEAN", "FLOAT", "INT"),
                           unset="cuts come from an edge attribute but no attribute name is set")
    n = len(me.edges)
    if attr.data_type == "BOOLEAN":
        flags = np.zeros(n, dtype=bool)
        attr.data.foreach_get("value", flags)
    elif attr.data_type == "FLOAT":
        vals = np.empty(n, dtype=np.float32)
        attr.data.foreach_get("value", vals)
        flags = vals > 0.5
    else:
        vals = np.empty(n, dtype=np.int32)
        attr.data.foreach_get("value", vals)
        flags = vals != 0
    return _edge_vertices(me)[flags]


def face_values(obj, name: str, what: str) -> np.ndarray:
    """The face-domain FLOAT attribute `name` as (polygons,) float64. `what` names its role in messages
    ("guide weight", "guide rotation"). NFieldError if it is missing, of another domain or type, or not finite."""
    me = obj.data
    attr = named_attribute(obj, name, f"{what} attribute", "FACE", ("FLOAT",))
    vals = np.empty(len(me.polygons), dtype=np.float32)
    attr.data.foreach_get("value", vals)
    out = vals.astype(np.float64)
    bad = ~np.isfinite(out)
    if bad.any():
        raise NFieldError(f"{what} attribute '{name}' is not finite at face {int(np.flatnonzero(bad)[0])}")
    return out


def _chains(num_points: int, edges: np.ndarray) -> list[list[int]]:
    """Point chains of a graph of polylines (every point has at most two neighbours): open chains from an
    end, then closed loops (the first point repeated at the end)."""
    nbrs: list[list[int]] = [[] for _ in range(num_points)]
    for a, b in edges.tolist():
        nbrs[a].append(b)
        nbrs[b].append(a)
    seen = np.zeros(num_points, dtype=bool)
    chains: list[list[int]] = []
    starts = [v for v in range(num_points) if len(nbrs[v]) == 1] + [v for v in range(num_points) if len(nbrs[v]) == 2]
    for s in starts:
        if seen[s]:
            continue
        chain, prev, cur = [s], -1, s
        seen[s] = True
        while True:
            nxt = next((w for w in nbrs[cur] if w != prev and not seen[w]), None)
            if nxt is None:
                if len(nbrs[s]) == 2 and s in nbrs[cur] and len(chain) > 2:
                    chain.append(s)  # a closed loop
                break
            chain.append(nxt)
            seen[nxt] = True
            prev, cur = cur, nxt
        if len(chain) >= 2:
            chains.append(chain)
    return chains


def _point_lines(positions: np.ndarray, offsets: np.ndarray) -> list[np.ndarray]:
    """The runs positions[offsets[i]:offsets[i + 1]] with two points or more."""
    return [positions[a:b] for a, b in zip(offsets[:-1], offsets[1:]) if b - a >= 2]


def _curves_lines(cd) -> list[np.ndarray]:
    """A Curves data block's curves (control points)."""
    pos = np.empty(len(cd.points) * 3, dtype=np.float32)
    cd.points.foreach_get("position", pos)
    offsets = np.empty(len(cd.curves) + 1, dtype=np.int32)
    cd.curve_offset_data.foreach_get("value", offsets)
    return _point_lines(pos.reshape(-1, 3).astype(np.float64), offsets)


def _frame_at(frames, current: int):
    """The legacy Grease Pencil frame shown at scene frame `current`: the last keyframe at or before it."""
    shown = [f for f in frames if f.frame_number <= current]
    return max(shown, key=lambda f: f.frame_number) if shown else None


def _grease_pencil_lines(gp_obj, scene) -> list[tuple[np.ndarray, np.ndarray]]:
    """(4x4 matrix from the layer's space to world space, points (k, 3)) of every stroke of the visible
    layers at the scene's current frame (hidden layers are skipped)."""
    out = []
    current = scene.frame_current if scene is not None else 0
    for layer in gp_obj.data.layers:
        if layer.hide:
            continue
        if gp_obj.type == "GREASEPENCIL":  # Blender 4.3+: layers -> frame -> drawing (a Curves geometry)
            frame = layer.current_frame()
            drawing = None if frame is None else frame.drawing
            if drawing is None or not len(drawing.curve_offsets):
                continue
            pos = np.empty(len(drawing.attributes["position"].data) * 3, dtype=np.float32)
            drawing.attributes["position"].data.foreach_get("vector", pos)
            offsets = np.empty(len(drawing.curve_offsets), dtype=np.int32)
            drawing.curve_offsets.foreach_get("value", offsets)
            lines = _point_lines(pos.reshape(-1, 3).astype(np.float64), offsets)
            local = np.array(layer.matrix_local, dtype=np.float64)
            parent_inverse = np.array(layer.matrix_parent_inverse, dtype=np.float64)
        else:  # the legacy object (Blender 3.4 to 4.2): layers -> frames -> strokes -> points
            frame = layer.active_frame or _frame_at(layer.frames, current)
            if frame is None:
                continue
            lines = []
            for stroke in frame.strokes:
                pos = np.empty(len(stroke.points) * 3, dtype=np.float32)
                stroke.points.foreach_get("co", pos)
                if len(stroke.points) >= 2:
                    lines.append(pos.reshape(-1, 3).astype(np.float64))
            local = np.array(layer.matrix_layer, dtype=np.float64)
            parent_inverse = np.array(layer.matrix_inverse, dtype=np.float64)
        if layer.parent is not None:  # a parented layer follows its parent object instead of the GP object
            to_world = np.array(layer.parent.matrix_world, dtype=np.float64) @ parent_inverse @ local
        else:
            to_world = np.array(gp_obj.matrix_world, dtype=np.float64) @ local
        out += [(to_world, p) for p in lines]
    return out


def curve_polylines(curve_obj, mesh_obj, depsgraph=None) -> list[np.ndarray]:
    """The splines of `curve_obj` as polylines ((k, 3) float64, k >= 2) in `mesh_obj`'s object space.

    Curve objects (Bezier, NURBS, poly) are evaluated as Blender draws them (their resolution, modifiers and
    all, when a depsgraph is given); Curves objects use their control points; Grease Pencil objects the
    points of every stroke of their visible layers at the current frame (the layer's own transform and
    parent applied). NFieldError for other types or a curve without a spline of two points."""
    if curve_obj is None:
        raise NFieldError("the curve guide has no curve object (it was deleted?)")
    if curve_obj.type not in CURVE_TYPES:
        raise NFieldError(f"object '{curve_obj.name}' is a {curve_obj.type.lower()}: a curve guide needs a curve, "
                          f"curves or grease pencil object")
    world_to_mesh = np.array(mesh_obj.matrix_world.inverted(), dtype=np.float64)
    to_world = np.array(curve_obj.matrix_world, dtype=np.float64)
    placed: list[tuple[np.ndarray, np.ndarray]] = []  # (matrix to world space, points)
    if curve_obj.type == "CURVES":
        placed = [(to_world, p) for p in _curves_lines(curve_obj.data)]
    elif curve_obj.type in ("GPENCIL", "GREASEPENCIL"):
        scenes = curve_obj.users_scene
        scene = depsgraph.scene if depsgraph is not None else (scenes[0] if scenes else None)
        placed = _grease_pencil_lines(curve_obj, scene)
    else:
        src = curve_obj.evaluated_get(depsgraph) if depsgraph is not None else curve_obj
        me = src.to_mesh()
        try:
            nv = len(me.vertices)
            pts = np.empty(nv * 3, dtype=np.float32)
            me.vertices.foreach_get("co", pts)
            pts = pts.reshape(-1, 3).astype(np.float64)
            ev = _edge_vertices(me)
        finally:
            src.to_mesh_clear()
        placed = [(to_world, pts[c]) for c in _chains(nv, ev)]
    if not placed:
        raise NFieldError(f"curve '{curve_obj.name}' has no spline with two points or more")
    out = []
    for m, p in placed:
        h = np.c_[p, np.ones(len(p))] @ (world_to_mesh @ m).T
        out.append(np.ascontiguousarray(h[:, :3]))
    return out


def comb_field(obj) -> tuple[np.ndarray, np.ndarray] | None:
    """(directions (P, 3), weights (P,)) of the stored comb field, None if the mesh has none. NFieldError if
    the attributes exist with another domain or type, or the weights leave [0, 1]."""
    me = obj.data
    d_attr, w_attr = me.attributes.get(COMB_DIRECTION), me.attributes.get(COMB_WEIGHT)
    if d_attr is None and w_attr is None:
        return None
    if d_attr is None or w_attr is None or (d_attr.domain, d_attr.data_type) != ("FACE", "FLOAT_VECTOR") or (
            w_attr.domain, w_attr.data_type) != ("FACE", "FLOAT"):
        raise NFieldError(f"the comb field needs a FACE FLOAT_VECTOR attribute '{COMB_DIRECTION}' and a FACE FLOAT "
                          f"attribute '{COMB_WEIGHT}' on mesh '{me.name}' (clear the comb to start again)")
    n = len(me.polygons)
    d = np.empty(n * 3, dtype=np.float32)
    d_attr.data.foreach_get("vector", d)
    w = np.empty(n, dtype=np.float32)
    w_attr.data.foreach_get("value", w)
    w = np.clip(w.astype(np.float64), 0.0, None)
    if not np.isfinite(w).all() or (w > 1.0 + 1e-6).any():
        raise NFieldError(f"comb weight attribute '{COMB_WEIGHT}' must hold values in [0, 1]")
    return d.reshape(-1, 3).astype(np.float64), np.minimum(w, 1.0)


def write_comb_field(obj, directions: np.ndarray, weights: np.ndarray) -> None:
    """Store the comb field in the two face attributes (created when missing)."""
    me = obj.data
    for name, kind in ((COMB_DIRECTION, "FLOAT_VECTOR"), (COMB_WEIGHT, "FLOAT")):
        attr = me.attributes.get(name)
        if attr is not None and (attr.domain != "FACE" or attr.data_type != kind):
            me.attributes.remove(attr)
            attr = None
        if attr is None:
            me.attributes.new(name, kind, "FACE")
    me.attributes[COMB_DIRECTION].data.foreach_set("vector", np.asarray(directions, np.float32).ravel())
    me.attributes[COMB_WEIGHT].data.foreach_set("value", np.asarray(weights, np.float32).ravel())
    me.update()


def remove_comb_field(obj) -> bool:
    """Remove the comb attributes; True if there were any."""
    me = obj.data
    found = False
    for name in (COMB_DIRECTION, COMB_WEIGHT):
        attr = me.attributes.get(name)
        if attr is not None:
            me.attributes.remove(attr)
            found = True
    return found
