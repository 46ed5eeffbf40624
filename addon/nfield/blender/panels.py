"""nfield's UI: the 3D viewport sidebar tab "nfield" (object and edit mode). Drawing only, no logic."""
from __future__ import annotations

import bpy

from . import state


def _mesh_object(context):
    obj = context.active_object
    return obj if obj is not None and obj.type == "MESH" else None


def _list_with_remove(layout, list_id: str, st, items: str, active: str, rows: int, remove_op: str):
    """A UIList of st.<items> with a side column starting with the remove button; returns that column."""
    row = layout.row()
    row.template_list(list_id, "", st, items, st, active, rows=rows)
    col = row.column(align=True)
    col.operator(remove_op, icon="REMOVE", text="")
    return col


def _wrapped_labels(layout, text: str, width: int = 48) -> None:
    """`text` as labels of at most `width` characters (the sidebar does not wrap)."""
    for line in _wrap(text, width):
        layout.label(text=line)


class NFIELD_UL_constraints(bpy.types.UIList):
    bl_idname = "NFIELD_UL_constraints"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.alert = item.stale
        row.label(text=f"Face {item.face}", icon="ERROR" if item.stale else "EMPTY_SINGLE_ARROW")
        row.label(text="stale" if item.stale else item.kind.title())
        d = item.direction
        row.label(text=f"({d[0]:.2f}, {d[1]:.2f}, {d[2]:.2f})")


class NFIELD_UL_singularities(bpy.types.UIList):
    bl_idname = "NFIELD_UL_singularities"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        n = data.n
        row = layout.row(align=True)
        row.alert = item.stale
        row.label(text=f"Vertex {item.vertex}", icon="ERROR" if item.stale else "DOT")
        row.label(text="stale" if item.stale else f"index {item.numerator:+d}/{n}")


class NFIELD_UL_layers(bpy.types.UIList):
    bl_idname = "NFIELD_UL_layers"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.alert = item.stale
        row.prop(item, "name", text="", emboss=False, icon="ERROR" if item.stale else "RENDERLAYERS")
        row.label(text=f"{len(item.faces)} faces")


class _NFieldPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "nfield"

    @classmethod
    def poll(cls, context):
        return _mesh_object(context) is not None


class NFIELD_PT_main(_NFieldPanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_main"
    bl_label = "nfield"

    @classmethod
    def poll(cls, context):
        return True

    def draw(self, context):
        layout = self.layout
        if state.native_problem:
            box = layout.box()
            box.alert = True
            box.label(text="The compiled solver cannot be loaded:", icon="ERROR")
            _wrapped_labels(box.column(align=True), state.native_problem)
            return
        obj = _mesh_object(context)
        if obj is None:
            layout.label(text="Select a mesh object", icon="INFO")
            return
        st = obj.nfield
        col = layout.column()
        col.prop(st, "symmetry")
        col.prop(st, "energy")
        col.prop(st, "alignment")
        if st.alignment == "ATTRIBUTE":
            col.prop_search(st, "alignment_attribute", obj.data, "attributes", text="Attribute")
        if st.alignment != "NONE":
            col.prop(st, "strength")
        row = col.row(align=True)
        row.prop(st, "solver_mode", expand=True)
        if st.solver_mode == "SPECTRAL":
            row = col.row(align=True)
            row.prop(st, "spectral_k")
            row.operator("nfield.precompute_spectral", text="Precompute", icon="FILE_REFRESH")
        col.prop(st, "live_update")
        layout.operator("nfield.solve", icon="PLAY")
        if st.last_message:
            box = layout.box()
            box.alert = st.last_message.startswith("Solve failed") or st.num_stale > 0
            _wrapped_labels(box, st.last_message)
        if st.num_stale:
            row = layout.row()
            row.alert = True
            row.label(text=f"{st.num_stale} stale item(s): the mesh changed", icon="ERROR")


class NFIELD_PT_constraints(_NFieldPanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_constraints"
    bl_label = "Constraints"
    bl_parent_id = "NFIELD_PT_main"

    def draw(self, context):
        st = _mesh_object(context).nfield
        layout = self.layout
        col = _list_with_remove(layout, "NFIELD_UL_constraints", st, "constraints", "active_constraint_index", 3,
                                "nfield.constraint_remove")
        col.operator("nfield.constraint_clear", icon="X", text="")
        if any(c.stale for c in st.constraints):
            layout.operator("nfield.constraint_clear", text="Remove Stale").stale_only = True
        layout.label(text="Singularities")
        _list_with_remove(layout, "NFIELD_UL_singularities", st, "singularities", "active_singularity_index", 2,
                          "nfield.singularity_remove")


class NFIELD_PT_region(_NFieldPanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_region"
    bl_label = "Region Editing"
    bl_parent_id = "NFIELD_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        obj = _mesh_object(context)
        st = obj.nfield
        layout = self.layout
        if st.region_active:
            layout.label(text=f"Editing a region of {len(st.region_faces)} faces", icon="EDITMODE_HLT")
            row = layout.row(align=True)
            row.operator("nfield.region_commit", icon="CHECKMARK")
            row.operator("nfield.region_cancel", icon="CANCEL")
        else:
            if obj.mode != "EDIT":
                layout.label(text="Select faces in edit mode", icon="INFO")
            layout.operator("nfield.region_begin", text="Begin Region from Selection")
        if st.layers:
            _list_with_remove(layout, "NFIELD_UL_layers", st, "layers", "active_layer_index", 2,
                              "nfield.layer_release")


class NFIELD_PT_display(_NFieldPanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_display"
    bl_label = "Display"
    bl_parent_id = "NFIELD_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        st = _mesh_object(context).nfield
        col = self.layout.column()
        col.prop(st, "show_field")
        sub = col.column()
        sub.active = st.show_field
        sub.prop(st, "glyph_density")
        sub.prop(st, "glyph_scale")
        col.prop(st, "show_constraints")
        col.prop(st, "show_singularities")


class NFIELD_PT_output(_NFieldPanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_output"
    bl_label = "Output Attributes"
    bl_parent_id = "NFIELD_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        st = _mesh_object(context).nfield
        col = self.layout.column()
        col.prop(st, "write_attributes", text="Write After Solve")
        col.prop(st, "direction_attribute")
        col.prop(st, "smooth_attribute")
        col.prop(st, "singularity_attribute")
        col.operator("nfield.write_attributes", icon="FILE_TICK")


class NFIELD_PT_applications(_NFieldPanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_applications"
    bl_label = "Shading & Hatching"
    bl_parent_id = "NFIELD_PT_main"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        col = self.layout.column()
        col.operator("nfield.material_anisotropic", icon="MATERIAL")
        box = col.box()
        box.label(text="Anisotropy renders in Cycles;", icon="INFO")
        box.label(text="EEVEE ignores it.")
        col.operator("nfield.hatching", icon="STROKE")
        col.label(text="Options: the operator's redo panel")


def _wrap(text: str, width: int) -> list[str]:
    words, lines, cur = text.split(), [], ""
    for w in words:
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = w
        else:
            cur = f"{cur} {w}" if cur else w
    if cur:
        lines.append(cur)
    return lines


classes = (
    NFIELD_UL_constraints,
    NFIELD_UL_singularities,
    NFIELD_UL_layers,
    NFIELD_PT_main,
    NFIELD_PT_constraints,
    NFIELD_PT_region,
    NFIELD_PT_display,
    NFIELD_PT_output,
    NFIELD_PT_applications,
)

register, unregister = bpy.utils.register_classes_factory(classes)
