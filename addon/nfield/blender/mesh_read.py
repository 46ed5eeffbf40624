"""The one reader of Blender meshes: arrays, the mesh signature, the BVH for picking and the overlay's geometry.

Everything is read from the object's *base* mesh (``obj.data``; modifiers are ignored) in object space.
Polygons are triangulated with ``mesh.loop_triangles``; the faces nfield.core sees are the polygons.

**The change check.** :func:`mesh_arrays` computes the mesh *signature*: the vertex/edge/polygon/corner
counts, a hash of the topology (corner vertices and polygon starts) and a hash of every coordinate. It is
the only test of "has the mesh changed" in the add-on: the session cache, the design's remapping, the
picking BVH and the overlay's geometry are all keyed by it, so they go stale together and never disagree.
Reading it costs one pass over the coordinates and the corners (``foreach_get``) plus a hash; the
triangulation and the per-polygon geometry are cached per object and reused while their key is unchanged.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass

import numpy as np
from mathutils.bvhtree import BVHTree

from ..core import Mesh
from .errors import NFieldError

__all__ = ["MeshArrays", "OverlayGeometry", "check_mesh_object", "mesh_arrays", "topology_of", "core_mesh",
           "attribute_values", "read_face_vectors", "vertex_group_weights", "polygon_vertices", "selected_polygons",
           "bvh", "overlay_geometry", "forget"]


@dataclass
class MeshArrays:
    vertices: np.ndarray          # (V, 3) float64 object space
    triangles: np.ndarray         # (T, 3) int32
    triangle_polygon: np.ndarray  # (T,) int64
    num_polygons: int
    polygon_centers: np.ndarray   # (P, 3) mean of the corners
    polygon_normals: np.ndarray   # (P, 3) unit Newell normals (zero for degenerate polygons)
    polygon_areas: np.ndarray     # (P,) vector area (|Newell sum| / 2: the area for planar polygons, as Blender)
    signature: str                # counts:topology hash:coordinate hash -- THE change check
    topology: str                 # the topology part of the signature
    corner_vert: np.ndarray       # (corners,) int32 vertex of every polygon corner
    loop_start: np.ndarray        # (P,) int32 first corner of every polygon


@dataclass
class OverlayGeometry:
    """What the overlay draws from, per mesh signature (object space)."""

    signature: str
    centroids: np.ndarray   # (P, 3)
    normals: np.ndarray     # (P, 3)
    areas: np.ndarray       # (P,)
    edge_len: np.ndarray    # (P,) mean length of the polygon's edges
    positions: np.ndarray   # (V, 3)
    vnormals: np.ndarray    # (V, 3) Blender's vertex normals


# object name -> cached data of its last read (dropped by forget())
_topology_cache: dict[str, tuple] = {}  # (prefix key, triangles, triangle_polygon, loop_start, topology)
_geometry_cache: dict[str, tuple] = {}  # (signature, polygon centers, normals, areas)
_bvh_cache: dict[str, tuple] = {}       # (signature, BVHTree)
_overlay_cache: dict[str, OverlayGeometry] = {}


def forget(obj_name: str | None = None) -> None:
    """Drop what was read of one object's mesh (or of all)."""
    for d in (_topology_cache, _geometry_cache, _bvh_cache, _overlay_cache):
        if obj_name is None:
            d.clear()
        else:
            d.pop(obj_name, None)


def check_mesh_object(obj):
    """`obj` if it is a mesh object with at least one polygon, else NFieldError naming the problem."""
    if obj is None:
        raise NFieldError("no active object: select a mesh object")
    if getattr(obj, "type", None) != "MESH":
        kind = getattr(obj, "type", type(obj).__name__)
        raise NFieldError(f"object '{getattr(obj, 'name', obj)}' is a {str(kind).lower()}, not a mesh")
    if len(obj.data.polygons) == 0:
        raise NFieldError(f"mesh '{obj.data.name}' of object '{obj.name}' is empty (it has no faces)")
    return obj


# ------------------------------------------------------------------------------------------ arrays
def _corner_verts(me, nl: int) -> np.ndarray:
    out = np.empty(nl, dtype=np.int32)
    attr = me.attributes.get(".corner_vert") if hasattr(me, "attributes") else None
    if attr is not None and attr.domain == "CORNER" and attr.data_type == "INT":
        attr.data.foreach_get("value", out)  # Blender 4.x: raw array, ~100x faster than loops
    else:
        me.loops.foreach_get("vertex_index", out)
    return out


def mesh_arrays(obj) -> MeshArrays:
    """Read the base mesh of `obj` (object space). Raises NFieldError for non-mesh objects.

    Cheap when nothing changed: the triangulation is cached per object and reused while the topology key
    (counts + corner vertices + polygon starts) is unchanged; centroids/normals are computed with numpy.
    """
    if obj is None:
        raise NFieldError("no active object: select a mesh object")
    if obj.type != "MESH":
        raise NFieldError(f"object '{obj.name}' is a {obj.type.lower()}, not a mesh")
    if obj.mode == "EDIT":
        obj.update_from_editmode()
    me = obj.data
    nv, ne, np_, nl = len(me.vertices), len(me.edges), len(me.polygons), len(me.loops)
    verts32 = np.empty(nv * 3, dtype=np.float32)
    me.vertices.foreach_get("co", verts32)
    corner_vert = _corner_verts(me, nl)
    topo = hashlib.blake2b(digest_size=8)
    topo.update(np.array([nv, ne, np_, nl], dtype=np.int64).tobytes())
    topo.update(corner_vert.tobytes())
    prefix_key = (nv, ne, np_, nl, topo.copy().hexdigest())  # everything but the polygon starts
    cached = _topology_cache.get(obj.name)
    loop_start = None
    if cached is not None and cached[0] == prefix_key:
        loop_start = cached[3]
    if loop_start is None:
        loop_start = np.empty(np_, dtype=np.int32)
        me.polygons.foreach_get("loop_start", loop_start)
    topo.update(loop_start.tobytes())
    topology = topo.hexdigest()
    if cached is not None and cached[4] == topology:
        tris, tri_poly = cached[1], cached[2]
    else:
        me.calc_loop_triangles()
        nt = len(me.loop_triangles)
        tris = np.empty(nt * 3, dtype=np.int32)
        me.loop_triangles.foreach_get("vertices", tris)
        tris = tris.reshape(nt, 3)
        tp = np.empty(nt, dtype=np.int32)
        me.loop_triangles.foreach_get("polygon_index", tp)
        tri_poly = tp.astype(np.int64)
    _topology_cache[obj.name] = (prefix_key, tris, tri_poly, loop_start, topology)
    geo = hashlib.blake2b(verts32.tobytes(), digest_size=8).hexdigest()
    verts = verts32.reshape(nv, 3).astype(np.float64)
    sig = f"{nv}/{ne}/{np_}/{nl}:{topology}:{geo}"
    geo_cached = _geometry_cache.get(obj.name)
    if geo_cached is not None and geo_cached[0] == sig:
        centers, normals, areas = geo_cached[1:]
    else:
        centers, normals, areas = _polygon_geometry(verts, corner_vert, loop_start)
        _geometry_cache[obj.name] = (sig, centers, normals, areas)
    return MeshArrays(verts, tris, tri_poly, np_, centers, normals, areas, sig, topology, corner_vert, loop_start)


def _polygon_order(corner_vert: np.ndarray, loop_start: np.ndarray):
    """(order, sorted starts, sizes in polygon order, sizes in sorted order, next corner of every corner)."""
    np_ = loop_start.shape[0]
    order = np.argsort(loop_start, kind="stable")  # loop_start is normally increasing already
    starts = loop_start[order]
    sizes_sorted = np.diff(np.append(starts, corner_vert.shape[0])).astype(np.int64)
    sizes = np.empty(np_, dtype=np.int64)
    sizes[order] = sizes_sorted
    idx = np.arange(corner_vert.shape[0])
    poly_of_corner = np.repeat(order, sizes_sorted)  # corners are contiguous per polygon
    first = loop_start[poly_of_corner]
    nxt = np.where(idx + 1 < first + sizes[poly_of_corner], idx + 1, first)
    return order, starts, sizes, sizes_sorted, nxt


def _polygon_geometry(verts: np.ndarray, corner_vert: np.ndarray, loop_start: np.ndarray):
    """Mean of the corners, unit Newell normal and vector area of every polygon. The Newell sum
    sum_corners p x p_next is twice the polygon's vector area (exact for any polygon, planar or not)."""
    np_ = loop_start.shape[0]
    if np_ == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    order, starts, _, sizes_sorted, nxt = _polygon_order(corner_vert, loop_start)
    p = verts[corner_vert]
    centers = np.empty((np_, 3))
    centers[order] = np.add.reduceat(p, starts, axis=0) / sizes_sorted[:, None]
    q = verts[corner_vert[nxt]]
    normals = np.empty((np_, 3))
    normals[order] = np.add.reduceat(np.cross(p, q), starts, axis=0)
    length = np.linalg.norm(normals, axis=1)
    ok = length > 0
    normals[ok] /= length[ok, None]
    return centers, normals, 0.5 * length


def topology_of(signature: str) -> str:
    """The counts and topology hash of a signature (equal before and after a pure vertex move)."""
    parts = signature.split(":")
    return ":".join(parts[:2]) if len(parts) >= 2 else signature


def core_mesh(arrays: MeshArrays) -> Mesh:
    """nfield.core.Mesh of the triangulated polygons (input faces = polygons). Raises NFieldError."""
    if arrays.vertices.shape[0] == 0 or arrays.num_polygons == 0 or arrays.triangles.shape[0] == 0:
        raise NFieldError("the mesh is empty (it has no faces); nfield needs a mesh with faces")
    try:
        return Mesh(arrays.vertices, arrays.triangles, face_to_polygon=arrays.triangle_polygon,
                    num_polygons=arrays.num_polygons)
    except ValueError as exc:
        raise NFieldError(f"the mesh cannot be used: {exc}") from None


# ------------------------------------------------------------------------------------------ attributes
_DOMAIN_SIZE = {"FACE": "polygons", "POINT": "vertices"}


def attribute_values(obj, name: str, domain: str, data_type: str) -> np.ndarray | None:
    """The attribute `name` of the base mesh as float64, (count, 3) for FLOAT_VECTOR and (count,) for FLOAT,
    INT or BOOLEAN; None if there is none of that domain ("FACE" or "POINT") and type."""
    me = obj.data
    attr = me.attributes.get(name) if name else None
    if attr is None or attr.domain != domain or attr.data_type != data_type:
        return None
    count = len(getattr(me, _DOMAIN_SIZE[domain]))
    if data_type == "FLOAT_VECTOR":
        buf = np.empty(count * 3, dtype=np.float32)
        attr.data.foreach_get("vector", buf)
        return buf.reshape(count, 3).astype(np.float64)
    if data_type == "FLOAT":
        buf = np.empty(count, dtype=np.float32)
        attr.data.foreach_get("value", buf)
        return buf.astype(np.float64)
    return np.array([d.value for d in attr.data], dtype=np.float64)


def named_attribute(obj, name: str, what: str, domain: str, data_types: tuple[str, ...], unset: str = ""):
    """The attribute `name` of obj's mesh, checked: NFieldError naming the problem if no name is given
    (`unset`: the message), it does not exist, or it has another domain or data type. `what` names its role
    ("alignment attribute", "cut attribute" ...)."""
    me = obj.data
    if not name:
        raise NFieldError(unset or f"no {what} name is set")
    attr = me.attributes.get(name)
    if attr is None:
        raise NFieldError(f"{what} '{name}' does not exist on mesh '{me.name}'")
    if attr.domain != domain or attr.data_type not in data_types:
        kinds = data_types[0] if len(data_types) == 1 else f"{', '.join(data_types[:-1])} or {data_types[-1]}"
        raise NFieldError(f"{what} '{name}' must be a{'n' if domain[0] in 'AEIOU' else ''} {domain}-domain {kinds} "
                          f"attribute (it is {attr.domain} {attr.data_type})")
    return attr


def read_face_vectors(obj, name: str, num_faces: int) -> np.ndarray:
    """A face-domain FLOAT_VECTOR attribute as (num_faces, 3) float64 (the alignment field). NFieldError
    naming the problem if it is missing or of another domain or type."""
    named_attribute(obj, name, "alignment attribute", "FACE", ("FLOAT_VECTOR",),
                    unset="alignment is 'Face Attribute' but no attribute name is set")
    values = attribute_values(obj, name, "FACE", "FLOAT_VECTOR")
    if values.shape[0] != num_faces:
        raise NFieldError(f"alignment attribute '{name}' has {values.shape[0]} values for {num_faces} faces")
    return values


def vertex_group_weights(obj, name: str) -> np.ndarray | None:
    """Weight of every vertex in the vertex group `name` (0 outside it), None if there is no such group."""
    vg = obj.vertex_groups.get(name)
    if vg is None:
        return None
    me = obj.data
    out = np.zeros(len(me.vertices), dtype=np.float64)
    gi = vg.index
    for v in me.vertices:
        for g in v.groups:
            if g.group == gi:
                out[v.index] = g.weight
                break
    return out


def polygon_vertices(arrays: MeshArrays, face: int) -> np.ndarray:
    """The vertices of polygon `face`, in corner order."""
    start = int(arrays.loop_start[face])
    later = arrays.loop_start[arrays.loop_start > start]
    end = int(later.min()) if later.size else arrays.corner_vert.shape[0]
    return arrays.corner_vert[start:end]


def selected_polygons(obj) -> list[int]:
    """Indices of the selected polygons (an edit-mode selection is read through update_from_editmode)."""
    if obj.mode == "EDIT":
        obj.update_from_editmode()
    me = obj.data
    sel = np.zeros(len(me.polygons), dtype=bool)
    me.polygons.foreach_get("select", sel)
    return np.flatnonzero(sel).tolist()


# ------------------------------------------------------------------------------------------ picking
def bvh(obj, arrays: MeshArrays | None = None) -> tuple[BVHTree, np.ndarray]:
    """(BVH of the base mesh's triangles in object space, polygon of every triangle), rebuilt when the
    signature changed. A ray cast's index is a triangle: ``triangle_polygon[index]`` is the polygon."""
    arrays = mesh_arrays(obj) if arrays is None else arrays
    hit = _bvh_cache.get(obj.name)
    if hit is not None and hit[0] == arrays.signature:
        return hit[1], arrays.triangle_polygon
    tree = BVHTree.FromPolygons(arrays.vertices.tolist(), arrays.triangles.tolist(), all_triangles=True)
    _bvh_cache[obj.name] = (arrays.signature, tree)
    return tree, arrays.triangle_polygon


# ------------------------------------------------------------------------------------------ overlay
def overlay_geometry(obj, arrays: MeshArrays | None = None) -> OverlayGeometry:
    """Centroids, normals, areas and mean edge lengths of the polygons, vertex positions and normals: read
    once per mesh signature. `arrays`: a read the caller made for this operation (reused if the mesh still
    has its counts; else the mesh is read again)."""
    me = obj.data
    if arrays is None or arrays.vertices.shape[0] != len(me.vertices) or arrays.num_polygons != len(me.polygons):
        arrays = mesh_arrays(obj)
    g = _overlay_cache.get(obj.name)
    if g is not None and g.signature == arrays.signature:
        return g
    verts, corner_vert, loop_start = arrays.vertices, arrays.corner_vert, arrays.loop_start
    np_ = arrays.num_polygons
    edge_len = np.zeros(np_)
    if np_:
        order, starts, _, sizes_sorted, nxt = _polygon_order(corner_vert, loop_start)
        corner_edge = np.linalg.norm(verts[corner_vert[nxt]] - verts[corner_vert], axis=1)
        edge_len[order] = np.add.reduceat(corner_edge, starts) / np.maximum(sizes_sorted, 1)
    g = OverlayGeometry(arrays.signature, arrays.polygon_centers, arrays.polygon_normals, arrays.polygon_areas,
                        edge_len, verts, _vertex_normals(obj.data, verts.shape[0]))
    _overlay_cache[obj.name] = g
    return g


def _vertex_normals(mesh, nv: int) -> np.ndarray:
    vn = np.empty(nv * 3, dtype=np.float32)
    try:  # Blender 3.5+: mesh.vertex_normals; 3.4: MeshVertex.normal
        mesh.vertex_normals.foreach_get("vector", vn)
    except AttributeError:
        mesh.vertices.foreach_get("normal", vn)
    return vn.reshape(nv, 3)
