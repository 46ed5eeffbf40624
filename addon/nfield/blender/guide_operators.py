"""Guide operators (``bpy.ops.nfield.guide_*``, ``nfield.mirror_design``): thin wrappers around the guide
functions of :mod:`nfield.blender.api`, one undo step each, re-solving when Live Update is on. The guide
settings themselves are properties (``guide_properties``): the panel edits them directly.
"""
from __future__ import annotations

import bpy
from bpy.props import BoolProperty, CollectionProperty, EnumProperty, FloatProperty, IntProperty

from . import api
from .choices import COMB_FALLOFF_ITEMS
from .guide_properties import NFieldCombSample
from .guides import CURVE_TYPES
from .operator_base import NFieldObjectOperator


class GuideOperator(NFieldObjectOperator):
    """Mixin: the operator's edit(obj) -> message or None runs with the design kept on failure, then a
    re-solve (Live Update)."""

    keeps_design_on_failure = True

    def execute(self, context):
        return self.run(context, self.edit, solve_after=True)


class NFIELD_OT_guide_curve_add(GuideOperator, bpy.types.Operator):
    """Guide the field of the active mesh with the selected curve objects (their tangents, projected onto
    the surface; editing a curve re-solves)"""

    bl_idname = "nfield.guide_curve_add"
    bl_label = "Add Curve Guide"

    def execute(self, context):
        self._curves = [o for o in context.selected_objects if o.type in CURVE_TYPES]
        if not self._curves:
            self.report({"ERROR"}, "select one or more curve, curves or grease pencil objects together with the "
                                   "mesh (the mesh active)")
            return {"CANCELLED"}
        return super().execute(context)

    def edit(self, obj):
        for c in self._curves:
            api.add_curve_guide(obj, c)
        return f"nfield: {len(self._curves)} curve guide(s): {', '.join(c.name for c in self._curves)}"


class NFIELD_OT_guide_curve_remove(GuideOperator, bpy.types.Operator):
    """Remove a curve guide (default: the active one in the list)"""

    bl_idname = "nfield.guide_curve_remove"
    bl_label = "Remove Curve Guide"

    index: IntProperty(name="Index", default=-1, description="Curve guide to remove (-1: the active one)")

    def edit(self, obj):
        g = obj.nfield_guides
        if not len(g.curves):
            raise api.NFieldError("the object has no curve guides")
        api.remove_curve_guide(obj, self.index if self.index >= 0 else min(g.active_curve_index, len(g.curves) - 1))


class NFIELD_OT_mirror_design(GuideOperator, bpy.types.Operator):
    """Add the mirror image of every constraint and singularity that has none yet (mirror symmetry on)"""

    bl_idname = "nfield.mirror_design"
    bl_label = "Mirror Design"

    def edit(self, obj):
        return f"nfield: {api.mirror_design(obj)} mirrored item(s) added"


class NFIELD_OT_comb_stroke(GuideOperator, bpy.types.Operator):
    """Comb the field: paint guide directions along a stroke (samples of surface points and drag directions,
    object space); one undo step per stroke"""

    bl_idname = "nfield.comb_stroke"
    bl_label = "Comb Stroke"

    samples: CollectionProperty(type=NFieldCombSample, name="Samples")
    radius: FloatProperty(name="Radius", default=0.03, min=1e-6, max=1.0,
                          description="Brush radius, fraction of the bounding-box diagonal")
    falloff: EnumProperty(name="Falloff", default="smooth", items=COMB_FALLOFF_ITEMS)
    strength: FloatProperty(name="Strength", default=1.0, min=1e-6, max=1.0, subtype="FACTOR")
    mirror: BoolProperty(name="Mirror", default=False,
                         description="With mirror symmetry on, also paint the mirror images of the samples")

    def edit(self, obj):
        changed = api.comb(obj, [tuple(s.location) for s in self.samples], [tuple(s.direction) for s in self.samples],
                           radius=self.radius, falloff=self.falloff, strength=self.strength, mirror=self.mirror)
        return f"nfield: comb stroke changed {changed} faces"


class NFIELD_OT_comb_clear(GuideOperator, bpy.types.Operator):
    """Remove the comb field (the strokes stored in the comb face attributes)"""

    bl_idname = "nfield.comb_clear"
    bl_label = "Clear Comb"

    def edit(self, obj):
        return None if api.clear_comb(obj) else "nfield: there was no comb field"


classes = (NFIELD_OT_guide_curve_add, NFIELD_OT_guide_curve_remove, NFIELD_OT_mirror_design, NFIELD_OT_comb_stroke,
           NFIELD_OT_comb_clear)
register, unregister = bpy.utils.register_classes_factory(classes)
