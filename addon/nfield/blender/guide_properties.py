"""The stored guides of an object (``obj.nfield_guides``, a :class:`NFieldGuides`), saved in the .blend and
restored by undo like the rest of the design.

Guides are *settings* of the design, read again at every solve (``guide_session``), so that editing a
marked edge, a painted attribute or a curve object re-solves with the new guide:

* feature alignment: which edges are features (boundary, bend angle, sharp / seam marks, face-set and
  material borders), soft or hard, with weight, width in edge rings and every k-th edge (hard);
* per-face guide weight and rotation: names of face FLOAT attributes (weight >= 0; rotation in radians);
* curve guides: curve objects (:class:`NFieldGuideCurve`), soft or hard, weight, width, tolerance;
* mirror symmetry about the X, Y or Z plane of the object, refused or partial when faces have no partner;
* cuts: seams or a named edge attribute.

Every setting's update callback is ``handlers.on_setting_changed`` (re-solve when Live Update is on).
The scripting API (``api.set_feature_alignment`` ...) writes these properties.
"""
from __future__ import annotations

import bpy
from bpy.props import (
    BoolProperty,
    CollectionProperty,
    EnumProperty,
    FloatProperty,
    FloatVectorProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)
from bpy.types import PropertyGroup

from . import handlers
from .guides import CURVE_TYPES
from .properties import object_settings_registration

_update = handlers.on_setting_changed

GUIDE_MODE_ITEMS = [
    ("SOFT", "Soft", "Weighted alignment on the faces near the guide (a pull, the field stays smooth)"),
    ("HARD", "Hard", "Direction constraints on the faces along the guide (the field follows it exactly)"),
]
MIRROR_ITEMS = [
    ("NONE", "None", "No mirror symmetry"),
    ("X", "X", "Symmetric about the object's YZ plane (x = offset)"),
    ("Y", "Y", "Symmetric about the object's XZ plane (y = offset)"),
    ("Z", "Z", "Symmetric about the object's XY plane (z = offset)"),
]
CUT_ITEMS = [
    ("NONE", "None", "No cuts"),
    ("SEAMS", "Seams", "Edges marked as seams are cuts: the field may jump across them"),
    ("ATTRIBUTE", "Edge Attribute", "Edges where a named EDGE attribute is set are cuts"),
]


def _is_curve(_self, obj) -> bool:
    return obj.type in CURVE_TYPES


class NFieldGuideCurve(PropertyGroup):
    """A curve object whose tangents guide the field (projected onto the surface)."""

    curve: PointerProperty(name="Curve", type=bpy.types.Object, poll=_is_curve, update=_update,
                           description="Curve or Curves object (editing it re-solves when Live Update is on)")
    mode: EnumProperty(name="Mode", items=GUIDE_MODE_ITEMS, default="SOFT", update=_update)
    weight: FloatProperty(name="Weight", default=1.0, min=0.0, soft_max=10.0, update=_update,
                          description="Soft mode: pull of the curve, relative to a typical face of the base guide")
    width: FloatProperty(name="Width", default=0.02, min=0.0, max=1.0, subtype="FACTOR", update=_update,
                         description="Soft mode: falloff width, fraction of the bounding-box diagonal")
    tolerance: FloatProperty(name="Tolerance", default=0.01, min=0.0, max=1.0, subtype="FACTOR", update=_update,
                             description="Curve parts farther than this from the surface (fraction of the "
                                         "diagonal) are ignored and reported")
    every: IntProperty(name="Every", default=1, min=1, update=_update,
                       description="Hard mode: constrain every k-th face the curve crosses")


class NFieldCombSample(PropertyGroup):
    """One sample of a comb stroke (operator argument of nfield.comb_stroke): a point on the surface and the
    drag direction there (object space)."""

    location: FloatVectorProperty(name="Location", size=3, subtype="XYZ")
    direction: FloatVectorProperty(name="Direction", size=3, subtype="XYZ")


class NFieldGuides(PropertyGroup):
    """Per-object guide settings (``bpy.types.Object.nfield_guides``)."""

    # --- feature alignment
    use_features: BoolProperty(name="Feature Alignment", default=False, update=_update,
                               description="Align the field with feature edges")
    feature_boundary: BoolProperty(name="Boundary", default=True, update=_update,
                                   description="Boundary edges are features")
    feature_use_angle: BoolProperty(name="Dihedral Angle", default=True, update=_update,
                                    description="Edges whose faces bend by more than the angle are features")
    feature_angle: FloatProperty(name="Angle", default=30.0, min=0.0, max=179.0, update=_update,
                                 description="Bend angle (degrees) above which an edge is a feature")
    feature_sharp: BoolProperty(name="Marked Sharp", default=False, update=_update,
                                description="Edges marked sharp are features")
    feature_seam: BoolProperty(name="Seams", default=False, update=_update, description="Seams are features")
    feature_face_sets: BoolProperty(name="Face Set Borders", default=False, update=_update,
                                    description="Borders between face sets are features")
    feature_materials: BoolProperty(name="Material Borders", default=False, update=_update,
                                    description="Borders between material slots are features")
    feature_mode: EnumProperty(name="Mode", items=GUIDE_MODE_ITEMS, default="SOFT", update=_update)
    feature_weight: FloatProperty(name="Weight", default=1.0, min=0.0, soft_max=10.0, update=_update,
                                  description="Soft mode: pull of the features, relative to a typical face of the "
                                              "base guide")
    feature_width: IntProperty(name="Width", default=2, min=1, soft_max=10, update=_update,
                               description="Soft mode: edge rings around the features that are pulled")
    feature_every: IntProperty(name="Every", default=1, min=1, soft_max=20, update=_update,
                               description="Hard mode: constrain the faces next to every k-th feature edge")

    # --- per-face weight and rotation of the base alignment
    weight_attribute: StringProperty(name="Weight Attribute", default="", update=_update,
                                     description="Face FLOAT attribute: alignment weight per face (>= 0; empty: 1)")
    rotation_attribute: StringProperty(name="Rotation Attribute", default="", update=_update,
                                       description="Face FLOAT attribute: turns the alignment per face "
                                                   "(radians; empty: no rotation)")

    # --- curve guides
    curves: CollectionProperty(type=NFieldGuideCurve)
    active_curve_index: IntProperty(name="Active Curve Guide", default=0, min=0)

    # --- mirror symmetry
    mirror_axis: EnumProperty(name="Mirror", items=MIRROR_ITEMS, default="NONE", update=_update)
    mirror_offset: FloatProperty(name="Offset", default=0.0, update=_update,
                                 description="Position of the mirror plane along the axis (object space)")
    mirror_tolerance: FloatProperty(name="Tolerance", default=1e-5, min=0.0, max=0.1, precision=6, update=_update,
                                    description="Distance (fraction of the diagonal) within which a mirrored vertex "
                                                "must meet a vertex")
    mirror_partial: BoolProperty(name="Matched Part Only", default=False, update=_update,
                                 description="Faces without a mirror partner: apply the symmetry to the matched "
                                             "faces (on) or refuse with their list (off)")

    # --- cuts
    cut_source: EnumProperty(name="Cuts", items=CUT_ITEMS, default="NONE", update=_update)
    cut_attribute: StringProperty(name="Cut Attribute", default="", update=_update,
                                  description="EDGE attribute (boolean) marking the cut edges")


classes = (NFieldGuideCurve, NFieldCombSample, NFieldGuides)
register, unregister = object_settings_registration("nfield_guides", NFieldGuides, classes)
