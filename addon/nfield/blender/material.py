"""Anisotropic shading that follows the designed field (paper section 10, "anisotropic shading").

:func:`build` (``nfield.blender.build_anisotropic_material``) creates or updates a material whose anisotropic
reflection follows the field of an object::

    Attribute (nfield_direction, face; or nfield_direction_smooth, point)
      -> Vector Transform (vector, object -> world) -> Vector Math Normalize
      [-> Vector Math Cross (Geometry Normal x tangent) -> Normalize]      (direction = "perpendicular")
      -> Tangent of every Principled / Glossy / Metallic / Anisotropic BSDF of the material

with the anisotropy amount set on those BSDFs. Sockets are looked up by identifier (Principled "Anisotropic",
Glossy/Metallic/Anisotropic "Anisotropy", all "Tangent"; checked in Blender 3.4 and 5.0) and a missing one
raises NFieldError naming the node, the Blender version and the sockets the node has. Blender 3.x's Glossy
BSDF is isotropic (no Tangent): it is skipped; its Anisotropic BSDF and the Principled BSDF are driven.

Which attribute: the face attribute (default) is one of the n directions per polygon and is constant over a
polygon; the tangent's sign does not matter to anisotropic reflection, so for n = 2 it is exact, but where the
field turns quickly from face to face the reflection shows the facets. The point attribute (smoothed)
interpolates across triangles, so the reflection is smooth; its directions are combed (each vertex reports the
one of its n directions that agrees with its neighbours), and where neighbours still disagree -- along a few
paths from singularities of fractional index -- the interpolated tangent turns through zero: a thin seam. For n = 4 (and 3, 6) each polygon reports *one* of its n directions without a global choice, so the
highlight follows the field direction on some polygons and its perpendicular on others: use n = 2 for shading.

Only Cycles renders anisotropy; EEVEE ignores the Tangent/anisotropy inputs (the panel says so).
The nodes this module adds are named ``nfield ...`` so that updating a material re-uses them.
"""
from __future__ import annotations

import warnings

import bpy
from bpy.props import EnumProperty, FloatProperty, FloatVectorProperty, StringProperty

from . import api
from .choices import SHADING_DIRECTION_ITEMS, SHADING_SOURCE_ITEMS
from .errors import NFieldError
from .operator_base import NFieldObjectOperator

__all__ = ["build", "find_socket", "ensure_nodes", "NFIELD_OT_material_anisotropic", "register", "unregister"]


#: BSDF nodes with a Tangent input: bl_idname -> identifiers of the anisotropy socket (first found wins)
ANISOTROPIC_BSDFS = {
    "ShaderNodeBsdfPrincipled": ("Anisotropic", "Specular Anisotropic", "Anisotropy"),
    "ShaderNodeBsdfGlossy": ("Anisotropy",),
    "ShaderNodeBsdfAnisotropic": ("Anisotropy",),   # Blender <= 3.6; the Glossy BSDF's idname in 4.x
    "ShaderNodeBsdfMetallic": ("Anisotropy",),
}
TANGENT_IDS = ("Tangent",)
#: BSDFs that are skipped (not an error) when they have no Tangent input (the Glossy BSDF of Blender 3.x)
OPTIONAL_BSDFS = ("ShaderNodeBsdfGlossy",)
DEFAULT_ANISOTROPY = 0.8
MATERIAL_FLAG = "nfield_anisotropic"  # custom property marking materials made by build()

NODE_ATTR = "nfield Direction"
NODE_XFORM = "nfield To World"
NODE_NORM = "nfield Normalize"
NODE_GEOM = "nfield Geometry"
NODE_CROSS = "nfield Perpendicular"
NODE_NORM2 = "nfield Normalize Perpendicular"


# ------------------------------------------------------------------------------------------ sockets
def _blender_version() -> str:
    return ".".join(str(x) for x in bpy.app.version)


def find_socket(sockets, identifiers, node, what: str):
    """The first socket of `sockets` whose identifier is in `identifiers` (skipping disabled duplicates);
    NFieldError naming the node, Blender version and the available identifiers otherwise."""
    for ident in identifiers:
        for s in sockets:
            if s.identifier == ident and getattr(s, "enabled", True):
                return s
    have = ", ".join(s.identifier for s in sockets)
    raise NFieldError(f"node '{node.name}' ({node.bl_idname}) has no {what} socket "
                      f"(looked for {' / '.join(identifiers)}; Blender {_blender_version()} has: {have})")


def _node(nodes, name: str, idname: str, location):
    node = nodes.get(name)
    if node is not None and node.bl_idname != idname:
        nodes.remove(node)
        node = None
    if node is None:
        node = nodes.new(idname)
        node.name = name
        node.label = name
        node.location = location
    return node


def _link(links, out_socket, in_socket) -> None:
    for lk in list(in_socket.links):
        links.remove(lk)
    links.new(out_socket, in_socket)


def anisotropic_bsdfs(material) -> list:
    """The BSDF nodes of `material` that have a Tangent input nfield drives."""
    if material.node_tree is None:
        return []
    return [n for n in material.node_tree.nodes if n.bl_idname in ANISOTROPIC_BSDFS]


def _new_material(name: str, base_color, roughness: float, metallic: float):
    mat = bpy.data.materials.new(name)
    ensure_nodes(mat)
    nt = mat.node_tree
    nodes = nt.nodes
    out = next((n for n in nodes if n.bl_idname == "ShaderNodeOutputMaterial"), None)
    if out is None:
        out = nodes.new("ShaderNodeOutputMaterial")
        out.location = (300, 0)
    bsdf = next((n for n in nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"), None)
    if bsdf is None:
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
        bsdf.location = (0, 0)
    _link(nt.links, find_socket(bsdf.outputs, ("BSDF",), bsdf, "BSDF output"),
          find_socket(out.inputs, ("Surface",), out, "Surface"))
    find_socket(bsdf.inputs, ("Base Color",), bsdf, "Base Color").default_value = tuple(base_color)
    find_socket(bsdf.inputs, ("Roughness",), bsdf, "Roughness").default_value = float(roughness)
    find_socket(bsdf.inputs, ("Metallic",), bsdf, "Metallic").default_value = float(metallic)
    mat[MATERIAL_FLAG] = True
    return mat


# ------------------------------------------------------------------------------------------ build
def build(obj, *, anisotropy: float | None = None, direction: str | None = None, source: str | None = None,
          material: str | None = None, roughness: float = 0.25, metallic: float = 1.0,
          base_color=(0.8, 0.8, 0.82, 1.0), write: bool = True):
    """Create or update the anisotropic material of mesh object `obj`; returns the bpy Material.

    anisotropy: 0..1 (0 = isotropic), set on every Principled/Glossy/Metallic/Anisotropic BSDF of the
    material; direction: "field" or "perpendicular" (cross(normal, field), n = 2 or 4); source: "face" (the
    face attribute, obj.nfield.direction_attribute) or "point" (obj.nfield.smooth_attribute). None keeps
    what an nfield-updated material has (defaults: 0.8, "field", "face").
    material: name of an existing material to update (its BSDFs get the tangent); None: the object's active
    material if nfield made it, else a new Principled material (roughness, metallic, base_color). A material
    not on the object yet replaces the active slot's material (or fills the first slot).
    write: write the attributes first if the chosen one is missing (solving if needed).
    Raises NFieldError (a ValueError) with a message naming the problem.
    """
    api.check_mesh_object(obj)
    st = obj.nfield
    # --- the material (read first: None arguments keep its settings)
    if material:
        mat = bpy.data.materials.get(material)
        if mat is None:
            raise NFieldError(f"there is no material named {material!r}")
    else:
        mat = obj.active_material
        if mat is not None and not mat.get(MATERIAL_FLAG):
            mat = None
    if source is None:
        source = mat.get("nfield_source", "FACE") if mat is not None else "FACE"
    if direction is None:
        direction = mat.get("nfield_direction", "FIELD") if mat is not None else "FIELD"
    src = str(source).upper()
    if src not in ("FACE", "POINT"):
        raise NFieldError(f"source must be 'face' or 'point' (got {source!r})")
    dir_u = str(direction).upper()
    if dir_u not in ("FIELD", "PERPENDICULAR"):
        raise NFieldError(f"direction must be 'field' or 'perpendicular' (got {direction!r})")
    if dir_u == "PERPENDICULAR" and st.n not in (2, 4):
        raise NFieldError(f"the perpendicular direction needs n = 2 or 4 (the object's field has n = {st.n})")
    a = None if anisotropy is None else float(anisotropy)
    if a is not None and not 0.0 <= a <= 1.0:
        raise NFieldError(f"anisotropy must be between 0 and 1 (got {anisotropy!r})")
    attr_name = st.direction_attribute if src == "FACE" else st.smooth_attribute
    domain = "FACE" if src == "FACE" else "POINT"
    what = "Direction" if src == "FACE" else "Smooth Direction"
    if not attr_name:
        raise NFieldError(f"the {what} output attribute name of '{obj.name}' is empty (Output Attributes panel)")
    attr = obj.data.attributes.get(attr_name)
    if attr is None or attr.domain != domain or attr.data_type != "FLOAT_VECTOR":
        if not write:
            raise NFieldError(f"mesh '{obj.data.name}' has no {domain.lower()} FLOAT_VECTOR attribute "
                              f"'{attr_name}': solve and write the attributes first")
        api.write_attributes(obj)

    if mat is None:
        mat = _new_material(f"nfield Anisotropic {obj.name}", base_color, roughness, metallic)
    ensure_nodes(mat)
    bsdfs = anisotropic_bsdfs(mat)
    if not bsdfs:
        raise NFieldError(f"material '{mat.name}' has no Principled, Glossy, Metallic or Anisotropic BSDF node "
                          f"to drive (a Tangent input is needed)")
    # check every socket before changing anything; a Glossy BSDF without a Tangent (Blender 3.x: isotropic
    # only) is left alone, any other BSDF of the list must have both sockets
    plan, skipped = [], []
    for b in bsdfs:
        if b.bl_idname in OPTIONAL_BSDFS and not any(s.identifier in TANGENT_IDS for s in b.inputs):
            skipped.append(b.name)
            continue
        plan.append((b, find_socket(b.inputs, TANGENT_IDS, b, "Tangent"),
                     find_socket(b.inputs, ANISOTROPIC_BSDFS[b.bl_idname], b, "anisotropy")))
    if not plan:
        raise NFieldError(f"material '{mat.name}' has no BSDF node with a Tangent input (Blender "
                          f"{_blender_version()}: {', '.join(skipped)} cannot be anisotropic; add a Principled BSDF)")

    nt = mat.node_tree
    nodes, links = nt.nodes, nt.links
    x0 = min(b.location.x for b in bsdfs) - 900
    y0 = max(b.location.y for b in bsdfs) - 350
    n_attr = _node(nodes, NODE_ATTR, "ShaderNodeAttribute", (x0, y0))
    n_attr.attribute_type = "GEOMETRY"
    n_attr.attribute_name = attr_name
    n_xf = _node(nodes, NODE_XFORM, "ShaderNodeVectorTransform", (x0 + 200, y0))
    n_xf.vector_type = "VECTOR"
    n_xf.convert_from = "OBJECT"
    n_xf.convert_to = "WORLD"
    n_norm = _node(nodes, NODE_NORM, "ShaderNodeVectorMath", (x0 + 400, y0))
    n_norm.operation = "NORMALIZE"
    _link(links, find_socket(n_attr.outputs, ("Vector",), n_attr, "Vector"),
          find_socket(n_xf.inputs, ("Vector",), n_xf, "Vector"))
    _link(links, find_socket(n_xf.outputs, ("Vector",), n_xf, "Vector"),
          find_socket(n_norm.inputs, ("Vector",), n_norm, "Vector"))
    tangent_out = find_socket(n_norm.outputs, ("Vector",), n_norm, "Vector")
    if dir_u == "PERPENDICULAR":
        n_geo = _node(nodes, NODE_GEOM, "ShaderNodeNewGeometry", (x0 + 400, y0 - 200))
        n_cross = _node(nodes, NODE_CROSS, "ShaderNodeVectorMath", (x0 + 600, y0 - 100))
        n_cross.operation = "CROSS_PRODUCT"
        n_norm2 = _node(nodes, NODE_NORM2, "ShaderNodeVectorMath", (x0 + 800, y0 - 100))
        n_norm2.operation = "NORMALIZE"
        _link(links, find_socket(n_geo.outputs, ("Normal",), n_geo, "Normal"),
              find_socket(n_cross.inputs, ("Vector",), n_cross, "Vector A"))
        _link(links, tangent_out, find_socket(n_cross.inputs, ("Vector_001",), n_cross, "Vector B"))
        _link(links, find_socket(n_cross.outputs, ("Vector",), n_cross, "Vector"),
              find_socket(n_norm2.inputs, ("Vector",), n_norm2, "Vector"))
        tangent_out = find_socket(n_norm2.outputs, ("Vector",), n_norm2, "Vector")
    else:
        for name in (NODE_GEOM, NODE_CROSS, NODE_NORM2):
            node = nodes.get(name)
            if node is not None:
                nodes.remove(node)
    if a is None:
        a = float(mat.get("nfield_anisotropy", DEFAULT_ANISOTROPY))
    for bsdf, tangent_in, aniso_in in plan:
        _link(links, tangent_out, tangent_in)
        aniso_in.default_value = a
    mat["nfield_anisotropy"] = a
    mat["nfield_object"] = obj.name
    mat["nfield_direction"] = dir_u
    mat["nfield_source"] = src

    if not any(m == mat for m in obj.data.materials):
        if len(obj.material_slots) == 0:
            obj.data.materials.append(mat)
        else:  # the object's active slot shows the field (its polygons keep their slot indices)
            obj.active_material = mat
    return mat


def ensure_nodes(mat) -> None:
    """Give `mat` a node tree (Blender < 5: use_nodes = True; 5.0 materials always have one)."""
    with warnings.catch_warnings():  # Material.use_nodes is deprecated in Blender 5.0 (always on there)
        warnings.simplefilter("ignore", DeprecationWarning)
        if mat.node_tree is None or not getattr(mat, "use_nodes", True):
            mat.use_nodes = True


# ------------------------------------------------------------------------------------------ operator
class NFIELD_OT_material_anisotropic(NFieldObjectOperator, bpy.types.Operator):
    """Create or update a material whose anisotropic reflection follows the field (rendered by Cycles;
    EEVEE ignores anisotropy)"""

    bl_idname = "nfield.material_anisotropic"
    bl_label = "Anisotropic Material"

    anisotropy: FloatProperty(name="Anisotropy", default=0.8, min=0.0, max=1.0, subtype="FACTOR",
                              description="Amount of anisotropy (0 = isotropic); Cycles only")
    direction: EnumProperty(name="Direction", items=SHADING_DIRECTION_ITEMS, default="FIELD")
    source: EnumProperty(name="Attribute", items=SHADING_SOURCE_ITEMS, default="FACE")
    material: StringProperty(name="Material", default="",
                             description="Existing material to update (empty: the object's nfield material, "
                                         "created if needed)")
    roughness: FloatProperty(name="Roughness", default=0.25, min=0.0, max=1.0, subtype="FACTOR",
                             description="Roughness of a newly created material")
    metallic: FloatProperty(name="Metallic", default=1.0, min=0.0, max=1.0, subtype="FACTOR",
                            description="Metallic of a newly created material")
    base_color: FloatVectorProperty(name="Base Color", size=4, subtype="COLOR", min=0.0, max=1.0,
                                    default=(0.8, 0.8, 0.82, 1.0))

    def execute(self, context):
        def fn(obj):
            mat = build(obj, anisotropy=self.anisotropy, direction=self.direction, source=self.source,
                        material=self.material or None, roughness=self.roughness, metallic=self.metallic,
                        base_color=self.base_color)
            note = "" if context.scene.render.engine == "CYCLES" else " (anisotropy shows in Cycles; EEVEE ignores it)"
            message = f"nfield: material '{mat.name}' follows the field{note}"
            n = obj.nfield.n
            if n > 2:  # a warning, not the INFO report of run(): the highlight mixes directions
                self.report({"WARNING"}, f"{message}; with n = {n} each face reports one of its {n} directions, "
                            f"so the highlight mixes them face by face: use n = 2 for shading")
                return None
            return message

        return self.run(context, fn)


classes = (NFIELD_OT_material_anisotropic,)

register, unregister = bpy.utils.register_classes_factory(classes)
