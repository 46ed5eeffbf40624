"""The Guides sub-panel of the nfield N-panel (drawing only): feature alignment, per-face weight and rotation
attributes, curve guides, mirror symmetry, cuts, and what the guides did in the last solve."""
from __future__ import annotations

import bpy

from . import api
from .guides import COMB_WEIGHT
from .panels import NFieldMeshSubpanel


class NFIELD_UL_guide_curves(bpy.types.UIList):
    bl_idname = "NFIELD_UL_guide_curves"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.prop(item, "curve", text="", icon="CURVE_DATA")
        row.prop(item, "mode", text="")


class NFIELD_PT_guides(NFieldMeshSubpanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_guides"
    bl_label = "Guides"

    def draw(self, context):
        obj = context.active_object
        g = obj.nfield_guides
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False

        box = layout.box()
        box.prop(g, "use_features")
        col = box.column()
        col.active = g.use_features
        col.prop(g, "feature_boundary")
        row = col.row(heading="Dihedral Angle")
        row.prop(g, "feature_use_angle", text="")
        sub = row.row()
        sub.active = g.feature_use_angle
        sub.prop(g, "feature_angle", text="")
        col.prop(g, "feature_sharp")
        col.prop(g, "feature_seam")
        col.prop(g, "feature_face_sets")
        col.prop(g, "feature_materials")
        col.row().prop(g, "feature_mode", expand=True)
        if g.feature_mode == "SOFT":
            col.prop(g, "feature_weight")
            col.prop(g, "feature_width")
        else:
            col.prop(g, "feature_every")

        box = layout.box()
        box.label(text="Per-Face Alignment")
        box.prop_search(g, "weight_attribute", obj.data, "attributes", text="Weight")
        box.prop_search(g, "rotation_attribute", obj.data, "attributes", text="Rotation")

        box = layout.box()
        box.label(text="Curve Guides")
        row = box.row()
        row.template_list("NFIELD_UL_guide_curves", "", g, "curves", g, "active_curve_index", rows=2)
        ops = row.column(align=True)
        ops.operator("nfield.guide_curve_add", text="", icon="ADD")
        ops.operator("nfield.guide_curve_remove", text="", icon="REMOVE")
        if len(g.curves):
            item = g.curves[min(g.active_curve_index, len(g.curves) - 1)]
            col = box.column()
            if item.mode == "SOFT":
                col.prop(item, "weight")
                col.prop(item, "width")
            else:
                col.prop(item, "every")
            col.prop(item, "tolerance")

        box = layout.box()
        box.row().prop(g, "mirror_axis", expand=True)
        if g.mirror_axis != "NONE":
            col = box.column()
            col.prop(g, "mirror_offset")
            col.prop(g, "mirror_tolerance")
            col.prop(g, "mirror_partial")
            col.operator("nfield.mirror_design", icon="MOD_MIRROR")

        if obj.data.attributes.get(COMB_WEIGHT) is not None:
            row = layout.row()
            row.label(text="Comb field stored", icon="BRUSH_DATA")
            row.operator("nfield.comb_clear", text="Clear")

        box = layout.box()
        box.prop(g, "cut_source")
        if g.cut_source == "ATTRIBUTE":
            box.prop_search(g, "cut_attribute", obj.data, "attributes", text="Attribute")

        lines = api.guide_summary(obj)
        if lines:
            col = layout.box().column(align=True)
            for line in lines:
                col.label(text=line)


classes = (NFIELD_UL_guide_curves, NFIELD_PT_guides)
register, unregister = bpy.utils.register_classes_factory(classes)
