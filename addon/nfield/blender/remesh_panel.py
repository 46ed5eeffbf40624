"""The N-panel subpanel "Quad Remesh" of the sidebar tab "nfield": the object's remesh settings
(``obj.nfield_remesh``), the "Quad Remesh from Field" button and, on a remesh result, its quality figures.
Drawing only. Registered after ``panels`` (its parent panel is ``NFIELD_PT_main``)."""
from __future__ import annotations

import bpy

from .panels import NFieldMeshSubpanel
from .remesh_object import INFO_PROPERTY
from .remesh_properties import OPTION_NAMES


class NFIELD_PT_remesh(NFieldMeshSubpanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_remesh"
    bl_label = "Quad Remesh"

    def draw(self, context):
        obj = context.active_object
        layout = self.layout
        info = obj.get(INFO_PROPERTY)
        if info is not None:
            box = layout.box()
            box.label(text=f"Remeshed from '{info.get('source', '?')}'", icon="MESH_GRID")
            box.label(text=f"{info.get('num_faces', 0)} faces, {100 * info.get('quad_fraction', 0):.1f}% quads")
            if "irregular_vertices" in info:
                box.label(text=f"irregular vertices: {info['irregular_vertices']} "
                               f"(field singularities: {info.get('field_singularities', '?')})")
            if "alignment_mean_deg" in info:
                box.label(text=f"alignment: {info['alignment_mean_deg']:.1f} deg mean, "
                               f"{info['alignment_p95_deg']:.1f} deg p95")
            if "hausdorff_relative" in info:
                box.label(text=f"Hausdorff: {100 * info['hausdorff_relative']:.2f}% of the diagonal")
        st = obj.nfield_remesh
        col = layout.column()
        row = col.row(align=True)
        row.prop(st, "use_edge_length", text="", icon="DRIVER_DISTANCE")
        row.prop(st, "edge_length" if st.use_edge_length else "target_faces")
        col.prop(st, "pure_quads")
        col.prop(st, "keep_boundary")
        row = col.row(align=True)
        row.prop(st, "keep_sharp", text="")
        sub = row.row(align=True)
        sub.active = st.keep_sharp
        sub.prop(st, "sharp_angle")
        col.prop(st, "pair_row_ends")
        col.prop(st, "solve_first")
        col.prop(st, "seed")
        op = layout.operator("nfield.quad_remesh", icon="MOD_REMESH")
        for name in OPTION_NAMES:
            setattr(op, name, getattr(st, name))


classes = (NFIELD_PT_remesh,)
register, unregister = bpy.utils.register_classes_factory(classes)
