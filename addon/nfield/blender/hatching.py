"""Hatching strokes along the designed field, written as a curves object (paper section 10, "hatching").

:func:`build` (``nfield.blender.build_hatching``) traces evenly spaced streamlines of the field with
``nfield.core.trace_streamlines`` (native tracer: n-symmetry-aware, stops at boundaries, near singularities
and near other strokes) and writes them as a curves object parented to the mesh:

* where ``bpy.types.Curves`` can be filled from Python (``Curves.add_curves``: Blender 4.x, 5.0): a *Curves*
  object (the new curves/hair type) with a point FLOAT ``radius`` attribute and a curve INT
  ``nfield_family`` attribute (0, or 1 for the cross-hatching family); Cycles renders it directly;
* otherwise (Blender 3.4 has the Curves type but no ``add_curves``), or with ``legacy=True``: a legacy
  poly-spline Curve object (bevel depth = radius), which Cycles renders as tubes and Blender converts to
  Grease Pencil (Object > Convert).

Points are in the mesh's object space (the curves object is parented with an identity parent inverse and an
identity local transform, so the strokes follow the mesh's transform) and lifted by ``lift`` x radius along
the surface normal so the strokes sit on the surface instead of half inside it.

Stroke density can be modulated by a scalar on the mesh vertices: a vertex group name, a point FLOAT
attribute name, or an array of one value per vertex (higher = denser strokes), passed to the tracer's
``density`` argument.

:func:`strokes_to_object` does the conversion alone (it is what the tests drive with synthetic strokes).
"""
from __future__ import annotations

from typing import Sequence

import bpy
import numpy as np
from bpy.props import BoolProperty, FloatProperty, IntProperty, StringProperty

from ..core import trace_streamlines
from . import api, mesh_read
from .errors import NFieldError
from .material import ensure_nodes
from .operator_base import NFieldObjectOperator

__all__ = ["build", "strokes_to_object", "density_values", "NFIELD_OT_hatching", "register", "unregister"]

HATCH_FLAG = "nfield_hatching"  # custom property on the curves object: name of the mesh object it belongs to


def has_curves_type() -> bool:
    """True where the new Curves data type can be filled from Python (Blender 4.0+: Curves.add_curves)."""
    curves = getattr(bpy.types, "Curves", None)
    return (hasattr(bpy.data, "hair_curves") and curves is not None
            and "add_curves" in curves.bl_rna.functions.keys())


# ------------------------------------------------------------------------------------------ density
def density_values(obj, density) -> np.ndarray | None:
    """One float per mesh vertex from a vertex group name, a point FLOAT attribute name, or an array;
    None / "" -> None (uniform density)."""
    if density is None or (isinstance(density, str) and not density):
        return None
    me = obj.data
    nv = len(me.vertices)
    if isinstance(density, str):
        weights = mesh_read.vertex_group_weights(obj, density)
        if weights is not None:
            return weights
        attr = me.attributes.get(density)
        if attr is not None:
            if attr.domain != "POINT" or attr.data_type not in ("FLOAT", "INT", "BOOLEAN"):
                raise NFieldError(f"density attribute '{density}' must be a point FLOAT attribute "
                                  f"(it is {attr.domain.lower()} {attr.data_type})")
            return mesh_read.attribute_values(obj, density, "POINT", attr.data_type)
        groups = [g.name for g in obj.vertex_groups]
        attrs = [a.name for a in me.attributes if a.domain == "POINT" and a.data_type == "FLOAT"
                 and not a.name.startswith(".")]
        raise NFieldError(f"density {density!r} is neither a vertex group (have: {groups or 'none'}) nor a point "
                          f"FLOAT attribute (have: {attrs or 'none'}) of '{obj.name}'")
    arr = np.asarray(density, dtype=np.float64).ravel()
    if arr.shape[0] != nv:
        raise NFieldError(f"density has {arr.shape[0]} values; mesh '{me.name}' has {nv} vertices")
    if not np.all(np.isfinite(arr)):
        raise NFieldError("density values must be finite")
    return arr


# ------------------------------------------------------------------------------------------ conversion
def _stroke_arrays(points: Sequence, faces, normals: np.ndarray | None, radius: float, lift: float):
    pts = []
    keep = []
    for i, p in enumerate(points):
        p = np.asarray(p, dtype=np.float64).reshape(-1, 3)
        if p.shape[0] < 2 or not np.all(np.isfinite(p)):
            continue
        if normals is not None and faces is not None and lift:
            f = np.asarray(faces[i], dtype=np.int64).ravel()
            if f.shape[0] == p.shape[0] and f.size and f.min() >= 0 and f.max() < normals.shape[0]:
                p = p + normals[f] * (lift * radius)
        pts.append(p)
        keep.append(i)
    return pts, keep


def strokes_to_object(obj, points: Sequence, *, faces=None, family=None, radius: float = 0.001,
                      lift: float = 1.0, name: str | None = None, material=None, legacy: bool | None = None):
    """Write strokes (list of (k, 3) point arrays in the object space of mesh `obj`; faces: optional
    per-point polygon indices used to lift points off the surface along the polygon normals; family:
    optional per-stroke int) as a curves object parented to mesh
    object `obj`. Re-uses (replaces the data of) the object named `name` (default "<obj> Hatching").
    legacy: force the legacy Curve type (None: the new Curves type where available). Returns the object."""
    if radius <= 0 or not np.isfinite(radius):
        raise NFieldError(f"stroke radius must be > 0 (got {radius!r})")
    normals = mesh_read.mesh_arrays(obj).polygon_normals if faces is not None and lift else None
    pts, keep = _stroke_arrays(points, faces, normals, float(radius), float(lift))
    fam = np.zeros(len(pts), dtype=np.int32)
    if family is not None:
        fam_all = np.asarray(family, dtype=np.int32).ravel()
        if fam_all.shape[0] == len(points):
            fam = fam_all[keep] if keep else fam
    name = name or f"{obj.name} Hatching"
    use_new = has_curves_type() if legacy is None else not legacy
    if use_new and not has_curves_type():
        raise NFieldError(f"Blender {bpy.app.version_string} cannot fill the new Curves type from Python")

    sizes = [p.shape[0] for p in pts]
    allp = np.concatenate(pts) if pts else np.zeros((0, 3))
    if use_new:
        data = bpy.data.hair_curves.new(name)
        if sizes:
            data.add_curves(sizes)
            data.position_data.foreach_set("vector", allp.astype(np.float32).ravel())
            rad = data.attributes.get("radius") or data.attributes.new("radius", "FLOAT", "POINT")
            rad.data.foreach_set("value", np.full(allp.shape[0], radius, dtype=np.float32))
            fa = data.attributes.new("nfield_family", "INT", "CURVE")
            fa.data.foreach_set("value", fam)
    else:
        data = bpy.data.curves.new(name, "CURVE")
        data.dimensions = "3D"
        data.bevel_depth = float(radius)
        data.bevel_resolution = 1
        data.use_fill_caps = False
        for p in pts:
            sp = data.splines.new("POLY")
            sp.points.add(p.shape[0] - 1)
            co = np.concatenate([p, np.ones((p.shape[0], 1))], axis=1).astype(np.float32)
            sp.points.foreach_set("co", co.ravel())
            sp.points.foreach_set("radius", np.ones(p.shape[0], dtype=np.float32))
    if material is not None:
        data.materials.append(material)

    cobj = bpy.data.objects.get(name)
    if cobj is not None and cobj.type in ("CURVES", "CURVE") and cobj.get(HATCH_FLAG) is not None \
            and cobj.data.bl_rna.identifier == data.bl_rna.identifier:
        old = cobj.data
        if material is None:  # keep the user's stroke material
            for m in old.materials:
                data.materials.append(m)
        cobj.data = data
        if old.users == 0:
            (bpy.data.hair_curves if use_new else bpy.data.curves).remove(old)
    else:
        if cobj is not None:  # same name, but not ours or another type: don't touch it
            name = f"{name}.nfield"
        cobj = bpy.data.objects.new(name, data)
        colls = list(obj.users_collection) or [bpy.context.scene.collection]
        for c in colls:
            c.objects.link(cobj)
    cobj.parent = obj
    cobj.matrix_parent_inverse.identity()
    cobj.matrix_basis.identity()
    cobj.matrix_world = obj.matrix_world.copy()  # up to date now (scripts read it before a depsgraph update)
    cobj[HATCH_FLAG] = obj.name
    cobj["nfield_strokes"] = len(pts)
    cobj["nfield_points"] = int(allp.shape[0])
    cobj["nfield_radius"] = float(radius)
    return cobj


def ink_material(name: str = "nfield Ink", color=(0.02, 0.02, 0.025, 1.0)):
    """A rough, almost non-specular material of `color` (default: dark ink for strokes); created once, then
    re-used by name."""
    mat = bpy.data.materials.get(name)
    if mat is not None:
        return mat
    mat = bpy.data.materials.new(name)
    mat.diffuse_color = color
    ensure_nodes(mat)
    bsdf = next((n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"), None)
    if bsdf is not None:
        for sock in bsdf.inputs:
            if sock.identifier == "Base Color":
                sock.default_value = color
            elif sock.identifier == "Roughness":
                sock.default_value = 0.9
            elif sock.identifier in ("Specular IOR Level", "Specular"):
                sock.default_value = 0.1
    return mat


# ------------------------------------------------------------------------------------------ tracing
def build(obj, *, spacing: float = 0.01, family: int = 0, cross_hatch: bool = False, seed: int = 0,
          max_length: float | None = None, min_length: float | None = None, radius: float | None = None,
          density=None, lift: float = 1.0, name: str | None = None, material=None, legacy: bool | None = None):
    """Trace strokes on mesh object `obj` (solving first if needed) and write them as a curves object.

    spacing: stroke separation as a fraction of the mesh's bounding-box diagonal; family: which of the
    field's n directions strokes start along (0 .. n-1); cross_hatch: also the family rotated by 90 degrees
    (n = 1, 2, 4); seed: deterministic seeding; max_length / min_length: stroke length limits (fractions of
    the diagonal; None: unlimited / 2 x spacing); radius: stroke radius in object units (default 0.1 x
    spacing x diagonal); density: vertex group / point attribute name / per-vertex array, clipped to [0, 1]
    (the local separation is spacing / max(density, 0.1): 1 = full density, lower = sparser); material:
    bpy Material for the strokes (default: a dark "nfield Ink" material for a new object). Returns the
    curves object (custom properties nfield_strokes, nfield_points).
    """
    api.check_mesh_object(obj)
    sp = float(spacing)
    if not np.isfinite(sp) or sp <= 0:
        raise NFieldError(f"spacing must be > 0 (a fraction of the bounding-box diagonal; got {spacing!r})")
    arrays, entry = api.synced_entry(obj)
    result = entry.result if entry.result is not None else api.solve(obj)
    dens = density_values(obj, density)
    if dens is not None:
        dens = np.clip(dens, 0.0, 1.0)  # the tracer takes [0, 1]: d_sep / max(density, 0.1)
    kwargs = dict(spacing=sp, family=int(family), cross_hatch=bool(cross_hatch), max_length=max_length,
                  min_length=min_length, seed=int(seed))
    if dens is not None:
        kwargs["density"] = dens
    try:
        strokes = trace_streamlines(entry.mesh, result, **kwargs)
    except (ValueError, RuntimeError) as exc:
        raise NFieldError(f"tracing strokes failed: {exc}") from None
    diag = float(np.linalg.norm(arrays.vertices.max(0) - arrays.vertices.min(0)))
    r = float(radius) if radius else 0.1 * sp * diag
    tri_poly = np.asarray(entry.mesh.triangle_face, dtype=np.int64)  # per-point triangles -> polygons
    faces = [tri_poly[np.asarray(f, dtype=np.int64)] for f in strokes.faces]
    if material is None and bpy.data.objects.get(name or f"{obj.name} Hatching") is None:
        material = ink_material()
    return strokes_to_object(obj, strokes.points, faces=faces, family=strokes.families, radius=r, lift=lift,
                             name=name, material=material, legacy=legacy)


# ------------------------------------------------------------------------------------------ operator
class NFIELD_OT_hatching(NFieldObjectOperator, bpy.types.Operator):
    """Trace evenly spaced strokes along the field and write them as a curves object parented to the mesh
    (render with Cycles or convert to Grease Pencil)"""

    bl_idname = "nfield.hatching"
    bl_label = "Hatching Strokes"

    spacing: FloatProperty(name="Spacing", default=0.01, min=1e-4, soft_min=0.002, soft_max=0.1, precision=4,
                           description="Stroke separation as a fraction of the bounding-box diagonal")
    family: IntProperty(name="Family", default=0, min=0, max=5,
                        description="Which of the field's directions the strokes follow")
    cross_hatch: BoolProperty(name="Cross-Hatch", default=False,
                              description="Also trace the second family (n = 2 or 4)")
    seed: IntProperty(name="Seed", default=0, min=0, description="Seed of the stroke placement")
    max_length: FloatProperty(name="Max Length", default=0.0, min=0.0, precision=3,
                              description="Maximum stroke length (fraction of the diagonal; 0: no limit)")
    min_length: FloatProperty(name="Min Length", default=0.0, min=0.0, precision=3,
                              description="Drop strokes shorter than this (fraction of the diagonal; 0: default)")
    radius: FloatProperty(name="Radius", default=0.0, min=0.0, precision=5, subtype="DISTANCE",
                          description="Stroke radius in object units (0: a tenth of the spacing)")
    density: StringProperty(name="Density", default="",
                            description="Vertex group or point FLOAT attribute modulating stroke density "
                                        "(empty: uniform)")
    legacy: BoolProperty(name="Legacy Curve", default=False,
                         description="Write a legacy Curve object instead of the new Curves type")

    def execute(self, context):
        def fn(obj):
            cobj = build(obj, spacing=self.spacing, family=self.family, cross_hatch=self.cross_hatch,
                         seed=self.seed, max_length=self.max_length or None, min_length=self.min_length or None,
                         radius=self.radius or None, density=self.density or None,
                         legacy=True if self.legacy or not has_curves_type() else None)
            return f"nfield: {cobj['nfield_strokes']} strokes in '{cobj.name}'"

        return self.run(context, fn)


classes = (NFIELD_OT_hatching,)

register, unregister = bpy.utils.register_classes_factory(classes)
