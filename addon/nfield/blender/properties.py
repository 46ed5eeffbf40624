"""nfield's Blender data: per-object settings and the user's design, stored in the .blend.

Everything lives on the **object** (``obj.nfield``, a :class:`NFieldSettings`), not on the mesh datablock:
settings are per object, and two objects sharing one mesh can carry different designs.
All vectors are in **object space** (the base mesh, before modifiers), so a design follows the object's
transform. Face indices are polygon indices of ``obj.data.polygons``; vertex indices are ``obj.data.vertices``.

The user's design is stored as CollectionProperty items so that it survives save/reload and undo/redo:

* ``constraints`` (:class:`NFieldConstraint`): face + direction + kind + ``stale`` flag (+ the face centroid
  at placement time, used to remap the constraint when the topology changes),
* ``singularities`` (:class:`NFieldSingularity`): vertex + index (numerator / denominator: the
  index is kept when n changes; an index that is no multiple of 1/n is ignored and reported),
* ``region_faces`` + ``region_active``: the faces of the region being edited (section 9 of the paper),
* ``layers`` (:class:`NFieldLayer`): committed regions = face list + the frozen field values.

The computed field itself is not stored here (it is rebuilt on demand from the design by
``nfield.blender.session_cache``, and written to mesh attributes by ``nfield.blender.attributes``).

Names in this module are a stable interface (the overlay and the interactive tools read them). The enum items
and numeric limits come from ``choices``; the field settings' update callback is ``handlers.on_setting_changed``
(a changed setting re-solves when Live Update is on). Only ``design`` writes the design collections.
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
from .choices import (
    ALIGNMENT_CORE,
    ALIGNMENT_ITEMS,
    CONSTRAINT_KIND_ITEMS,
    ENERGY_ITEMS,
    ENERGY_ORDER,
    MAX_STRENGTH,
    MIN_STRENGTH,
    SOLVER_MODE_ITEMS,
    SYMMETRY_ITEMS,
)

# ---------------------------------------------------------------------------------------------- items
class NFieldConstraint(PropertyGroup):
    """A hard constraint on one face (object space)."""

    face: IntProperty(name="Face", description="Polygon index of the constrained face", min=0)
    direction: FloatVectorProperty(
        name="Direction", size=3, subtype="XYZ",
        description="Constraint direction in object space (projected onto the face's tangent plane)")
    kind: EnumProperty(name="Kind", items=CONSTRAINT_KIND_ITEMS, default="DIRECTION")
    stale: BoolProperty(
        name="Stale", default=False,
        description="The face this constraint was placed on no longer exists; the constraint is kept but "
                    "ignored by the solver until it is re-placed or removed")
    centroid: FloatVectorProperty(
        name="Face Centroid", size=3, subtype="XYZ",
        description="Object-space centroid of the face when the constraint was placed (used to remap it "
                    "after topology changes)")


class NFieldSingularity(PropertyGroup):
    """A prescribed singularity at a vertex: index = numerator / denominator (the n it was placed at); valid
    for a symmetry n when index x n is an integer (design.singularity_numerator)."""

    vertex: IntProperty(name="Vertex", min=0)
    numerator: IntProperty(name="Index Numerator",
                           description="Singularity index times the n it was placed at (index = numerator / denominator)")
    denominator: IntProperty(
        name="Index Denominator", default=0, min=0,
        description="The symmetry n the index was placed at (0: the object's current n, files from before). "
                    "The index, not the numerator, is kept when n changes")
    stale: BoolProperty(name="Stale", default=False,
                        description="The vertex no longer exists; kept but ignored until fixed or removed")
    position: FloatVectorProperty(name="Position", size=3, subtype="XYZ",
                                  description="Object-space vertex position when placed (for remapping)")


class NFieldFaceItem(PropertyGroup):
    """One face of a region or layer (with the frozen field value for layers)."""

    face: IntProperty(name="Face", min=0)
    value: FloatVectorProperty(
        name="Value", size=3, subtype="XYZ",
        description="Frozen field value: first direction in object space, length = |representation|")


class NFieldLayer(PropertyGroup):
    """A committed region: its faces keep their frozen field values in later global solves."""

    name: StringProperty(name="Name", default="Layer")
    faces: CollectionProperty(type=NFieldFaceItem)
    stale: BoolProperty(name="Stale", default=False,
                        description="Some faces of the layer no longer exist (topology changed)")


# ---------------------------------------------------------------------------------------------- settings
_update_setting = handlers.on_setting_changed


def _update_display(self, context):
    """Display option changed: only redraw the viewport."""
    screen = getattr(context, "screen", None)
    if screen is not None:
        for area in screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


class NFieldSettings(PropertyGroup):
    """Per-object nfield settings and design (``bpy.types.Object.nfield``)."""

    # --- field settings
    symmetry: EnumProperty(name="Symmetry", items=SYMMETRY_ITEMS, default="4",
                           description="Symmetry n of the field", update=_update_setting)
    energy: EnumProperty(name="Energy", items=ENERGY_ITEMS, default="BIHARMONIC", update=_update_setting)
    alignment: EnumProperty(name="Alignment", items=ALIGNMENT_ITEMS, default="NONE", update=_update_setting)
    alignment_attribute: StringProperty(
        name="Alignment Attribute", default="",
        description="Face-domain FLOAT_VECTOR attribute to align to (Alignment = Face Attribute)",
        update=_update_setting)
    strength: FloatProperty(name="Strength", default=1.0, min=MIN_STRENGTH, max=MAX_STRENGTH, soft_min=1e-4,
                            soft_max=100.0,
                            description="Alignment strength (weight of the alignment term; used when Alignment is not None)", update=_update_setting)
    solver_mode: EnumProperty(name="Solver", items=SOLVER_MODE_ITEMS, default="EXACT", update=_update_setting)
    spectral_k: IntProperty(name="Eigenfields", default=500, min=2, soft_max=2000,
                            description="Number k of eigenfields of the spectral basis", update=_update_setting)
    live_update: BoolProperty(name="Live Update", default=True,
                              description="Re-solve after every edit of constraints or settings")

    # --- display (read by the overlay)
    show_field: BoolProperty(name="Show Field", default=True, update=_update_display)
    glyph_density: FloatProperty(name="Glyph Density", default=0.5, min=0.01, max=1.0, subtype="FACTOR",
                                 description="Glyphs per screen area, spread evenly on screen (1: about 12 pixels apart; "
                                             "zooming in shows more of them on the surface)",
                                 update=_update_display)
    glyph_scale: FloatProperty(name="Glyph Scale", default=1.0, min=0.05, soft_max=4.0, update=_update_display)
    show_constraints: BoolProperty(name="Show Constraints", default=True, update=_update_display)
    show_singularities: BoolProperty(name="Show Singularities", default=True, update=_update_display)
    # kept so that files which set it still load unchanged; the overlay draws no streamlines and the panel
    # does not show it (hatching strokes are built as curves instead: nfield.hatching)
    show_streamlines: BoolProperty(name="Show Streamlines", default=False, update=_update_display)

    # --- output attributes
    write_attributes: BoolProperty(name="Write Attributes", default=True,
                                   description="Write the output attributes after every solve")
    direction_attribute: StringProperty(name="Direction", default="nfield_direction",
                                        description="Face FLOAT_VECTOR attribute: first unit direction")
    smooth_attribute: StringProperty(name="Smooth Direction", default="nfield_direction_smooth",
                                     description="Point FLOAT_VECTOR attribute: n-symmetry-aware averaged direction")
    singularity_attribute: StringProperty(name="Singularity Index", default="nfield_singularity",
                                          description="Point FLOAT attribute: singularity index per vertex")

    # --- the design
    constraints: CollectionProperty(type=NFieldConstraint)
    active_constraint_index: IntProperty(name="Active Constraint", default=0, min=0)
    singularities: CollectionProperty(type=NFieldSingularity)
    active_singularity_index: IntProperty(name="Active Singularity", default=0, min=0)
    region_active: BoolProperty(name="Region Editing", default=False,
                                description="A region edit is in progress (edits change only region_faces)")
    region_faces: CollectionProperty(type=NFieldFaceItem)
    layers: CollectionProperty(type=NFieldLayer)
    active_layer_index: IntProperty(name="Active Layer", default=0, min=0)

    # --- bookkeeping (written by the add-on, shown in the panel)
    mesh_signature: StringProperty(
        name="Mesh Signature", default="",
        description="Signature of the mesh the design was last mapped to (detects topology changes)")
    last_solve_seconds: FloatProperty(name="Last Solve (s)", default=0.0)
    last_energy: FloatProperty(name="Energy", default=0.0)
    last_message: StringProperty(name="Message", default="")
    spectral_ready: BoolProperty(name="Spectral Basis Ready", default=False)
    last_solver_state: StringProperty(name="Solver State", default="",
                                      description="How the last field was solved (exact / spectral, basis source)")

    # --- convenience (no math)
    @property
    def n(self) -> int:
        return int(self.symmetry)

    @property
    def order(self) -> int:
        return ENERGY_ORDER[self.energy]

    @property
    def align(self) -> str:
        return ALIGNMENT_CORE[self.alignment]

    @property
    def num_stale(self) -> int:
        return (sum(1 for c in self.constraints if c.stale) + sum(1 for s in self.singularities if s.stale)
                + sum(1 for l in self.layers if l.stale))


classes = (
    NFieldConstraint,
    NFieldSingularity,
    NFieldFaceItem,
    NFieldLayer,
    NFieldSettings,
)


def object_settings_registration(attribute: str, group, group_classes):
    """(register, unregister) of property classes whose `group` becomes ``bpy.types.Object.<attribute>``."""
    register_classes, unregister_classes = bpy.utils.register_classes_factory(group_classes)

    def register_settings():
        register_classes()
        setattr(bpy.types.Object, attribute, PointerProperty(type=group))

    def unregister_settings():
        if hasattr(bpy.types.Object, attribute):
            delattr(bpy.types.Object, attribute)
        unregister_classes()

    return register_settings, unregister_settings


register, unregister = object_settings_registration("nfield", NFieldSettings, classes)
