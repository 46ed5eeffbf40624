"""Guide operators (``bpy.ops.nfield.guide_*``, ``nfield.mirror_design``): thin wrappers around the guide
functions of :mod:`nfield.blender.api`, one undo step each, re-solving when Live Update is on. The guide
settings themselves are properties (``guide_properties``): the panel edits them directly.
"""
from __future__ import annotations

import bpy
from bpy.props import CollectionProperty, EnumProperty, FloatProperty, IntProperty

from . import api
from .choices import COMB_FALLOFF_ITEMS
from .guide_properties import NFieldCombSample
from .guides import CURVE_TYPES
from .operator_base import NFieldObjectOperator


class NFIELD_OT_guide_curve_add(NFieldObjectOperator, bpy.types.Operator):
    """Guide the field of the active mesh with the selected curve objects (their tangents, projected onto
    the surface; editing a curve re-solves)"""

    bl_idname = "nfield.guide_curve_add"
    bl_label = "Add Curve Guide"
    keeps_design_on_failure = True

    def execute(self, context):
        curves = [o for o in context.selected_objects if o.type in CURVE_TYPES]
        if not curves:
            self.report({"ERROR"}, "select one or more curve objects together with the mesh (the mesh active)")
            return {"CANCELLED"}

        def fn(obj):
            for c in curves:
                api.add_curve_guide(obj, c)
            return f"nfield: {len(curves)} curve guide(s): {', '.join(c.name for c in curves)}"

        return self.run(context, fn, solve_after=True)


class NFIELD_OT_guide_curve_remove(NFieldObjectOperator, bpy.types.Operator):
    """Remove a curve guide (default: the active one in the list)"""

    bl_idname = "nfield.guide_curve_remove"
    bl_label = "Remove Curve Guide"
    keeps_design_on_failure = True

    index: IntProperty(name="Index", default=-1, description="Curve guide to remove (-1: the active one)")

    def execute(self, context):
        def fn(obj):
            g = obj.nfield_guides
            if not len(g.curves):
                raise api.NFieldError("the object has no curve guides")
            index = self.index if self.index >= 0 else min(g.active_curve_index, len(g.curves) - 1)
            api.remove_curve_guide(obj, index)
            return None

        return self.run(context, fn, solve_after=True)


class NFIELD_OT_mirror_design(NFieldObjectOperator, bpy.types.Operator):
    """Add the mirror image of every constraint and singularity that has none yet (mirror symmetry on)"""

    bl_idname = "nfield.mirror_design"
    bl_label = "Mirror Design"
    keeps_design_on_failure = True

    def execute(self, context):
        return self.run(context, lambda obj: f"nfield: {api.mirror_design(obj)} mirrored item(s) added",
                        solve_after=True)


class NFIELD_OT_comb_stroke(NFieldObjectOperator, bpy.types.Operator):
    """Comb the field: paint guide directions along a stroke (samples of surface points and drag directions,
    object space); one undo step per stroke"""

    bl_idname = "nfield.comb_stroke"
    bl_label = "Comb Stroke"
    keeps_design_on_failure = True

    samples: CollectionProperty(type=NFieldCombSample, name="Samples")
    radius: FloatProperty(name="Radius", default=0.03, min=1e-6, max=1.0,
                          description="Brush radius, fraction of the bounding-box diagonal")
    falloff: EnumProperty(name="Falloff", default="smooth", items=COMB_FALLOFF_ITEMS)
    strength: FloatProperty(name="Strength", default=1.0, min=1e-6, max=1.0, subtype="FACTOR")

    def execute(self, context):
        points = [tuple(s.location) for s in self.samples]
        dirs = [tuple(s.direction) for s in self.samples]

        def fn(obj):
            changed = api.comb(obj, points, dirs, radius=self.radius, falloff=self.falloff, strength=self.strength)
            return f"nfield: comb stroke changed {changed} faces"

        return self.run(context, fn, solve_after=True)


class NFIELD_OT_comb_clear(NFieldObjectOperator, bpy.types.Operator):
    """Remove the comb field (the strokes stored in the comb face attributes)"""

    bl_idname = "nfield.comb_clear"
    bl_label = "Clear Comb"
    keeps_design_on_failure = True

    def execute(self, context):
        return self.run(context, lambda obj: None if api.clear_comb(obj) else "nfield: there was no comb field",
                        solve_after=True)


classes = (NFIELD_OT_guide_curve_add, NFIELD_OT_guide_curve_remove, NFIELD_OT_mirror_design, NFIELD_OT_comb_stroke,
           NFIELD_OT_comb_clear)
register, unregister = bpy.utils.register_classes_factory(classes)
