"""nfield's UI: the 3D viewport sidebar tab "nfield" (object and edit mode). Drawing only, no logic.

The main panel holds the tools' buttons, the field settings in Blender's split layout (labels on the left,
values on the right, ``use_property_split``) and the status (last solve, solver state, messages wrapped over
several lines). Everything else is a subpanel of it: :data:`SUBPANELS` lists them in drawing order; a new
feature adds its ``bpy.types.Panel`` subclass there (``bl_parent_id = "NFIELD_PT_main"``, deriving from
:class:`NFieldSubpanel`).
"""
from __future__ import annotations

import bpy

from . import design, session_cache, state

#: the viewport tools the main panel offers buttons for: (tool id, button text, icon)
TOOL_BUTTONS = (("nfield.tool_constraint", "Constraint Tool", "EMPTY_SINGLE_ARROW"),
                ("nfield.tool_singularity", "Singularity Tool", "DOT"),
                ("nfield.tool_comb", "Comb Tool", "BRUSH_DATA"))
#: width of one character of the UI font, in pixels at UI scale 1 (wrapping estimate; the sidebar does not
#: wrap labels itself). Blender's default UI font averages ~6.5 px per character at 11 pt; 7 errs on the
#: side of shorter lines.
CHAR_PX = 7.0
#: what a label line inside a box loses to the region's tab strip, the panel and box margins and an icon
#: (pixels at UI scale 1; measured on Blender 3.4's screenshot at the default sidebar width)
LABEL_MARGIN_PX = 80.0


def _mesh_object(context):
    obj = context.active_object
    return obj if obj is not None and obj.type == "MESH" else None


def _split(layout):
    """A column in Blender's property-split layout (label column left, value column right)."""
    col = layout.column()
    col.use_property_split = True
    col.use_property_decorate = False
    return col


def wrap_width(context, margin_px: float = LABEL_MARGIN_PX) -> int:
    """How many characters fit on one label line of the sidebar as it is now."""
    region = getattr(context, "region", None)
    width = getattr(region, "width", 0) or 300
    scale = context.preferences.system.ui_scale if context.preferences else 1.0
    return max(16, int((width - margin_px * scale) / (CHAR_PX * scale)))


def wrapped_labels(layout, text: str, width: int, icon: str = "NONE") -> None:
    """`text` as labels of at most `width` characters; the first carries `icon`."""
    col = layout.column(align=True)
    for i, line in enumerate(wrap(text, width)):
        col.label(text=line, icon=icon if i == 0 else "BLANK1" if icon != "NONE" else "NONE")


def wrap(text: str, width: int) -> list[str]:
    """Greedy word wrap; a word longer than `width` is cut."""
    words, lines, cur = text.split(), [], ""
    for w in words:
        while len(w) > width:
            if cur:
                lines.append(cur)
                cur = ""
            lines.append(w[:width])
            w = w[width:]
        if cur and len(cur) + 1 + len(w) > width:
            lines.append(cur)
            cur = w
        else:
            cur = f"{cur} {w}" if cur else w
    if cur:
        lines.append(cur)
    return lines


# ------------------------------------------------------------------------------------------------ lists
def constraint_row_text(item) -> str:
    """'Face 25118 → direction' (what the list row says)."""
    return f"Face {item.face} → {'stale' if item.stale else item.kind.lower()}"


def singularity_row_text(item, n: int) -> str:
    """'Vertex 7032 +1/2'; an index that n does not allow says so."""
    den = item.denominator or n
    text = f"Vertex {item.vertex} {design.index_text(item.numerator, den)}"
    if item.stale:
        return text + " stale"
    if design.singularity_numerator(item, n) is None:
        return text + f" (not at n = {n})"
    return text


class NFIELD_UL_constraints(bpy.types.UIList):
    bl_idname = "NFIELD_UL_constraints"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.alert = item.stale
        # no icon on live rows: at the default sidebar width the text needs the room
        row.label(text=constraint_row_text(item), icon="ERROR" if item.stale else "NONE")


class NFIELD_UL_singularities(bpy.types.UIList):
    bl_idname = "NFIELD_UL_singularities"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        n = data.n
        bad = item.stale or design.singularity_numerator(item, n) is None
        row = layout.row(align=True)
        row.alert = bad
        row.label(text=singularity_row_text(item, n), icon="ERROR" if bad else "NONE")


class NFIELD_UL_layers(bpy.types.UIList):
    bl_idname = "NFIELD_UL_layers"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.alert = item.stale
        row.prop(item, "name", text="", emboss=False, icon="ERROR" if item.stale else "RENDERLAYERS")
        row.label(text=f"{len(item.faces)} faces")


def _list_with_side(layout, list_id: str, st, items: str, active: str, rows: int, remove: str):
    """A UIList of st.<items> with a side column (returned) for its buttons, the first of them the operator
    `remove` (removes the active item)."""
    row = layout.row()
    row.template_list(list_id, "", st, items, st, active, rows=rows)
    side = row.column(align=True)
    side.operator(remove, icon="REMOVE", text="")
    return side


# ------------------------------------------------------------------------------------------------ panels
class _NFieldPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "nfield"

    @classmethod
    def poll(cls, context):
        return _mesh_object(context) is not None and not state.native_problem


class NFieldSubpanel(_NFieldPanel):
    """Base of the subpanels of the nfield tab (list them in SUBPANELS)."""

    bl_parent_id = "NFIELD_PT_main"


class NFieldClosedSubpanel(NFieldSubpanel):
    """A subpanel of the nfield tab that starts closed (what is not needed at every step)."""

    bl_options = {"DEFAULT_CLOSED"}


class NFieldMeshSubpanel(NFieldClosedSubpanel):
    """Base of the subpanels that register themselves (guides, quad remesh): closed at first, shown for any
    active mesh object (they draw their own message when the compiled solver cannot be loaded)."""

    @classmethod
    def poll(cls, context):
        return _mesh_object(context) is not None


def solver_state_text(obj) -> str:
    """The status line of the solver: the mode and, in spectral mode, whether the basis is ready."""
    st = obj.nfield
    if st.solver_mode == "SPECTRAL":
        basis = "basis ready" if st.spectral_ready else "basis not computed"
        return f"Spectral (k = {st.spectral_k}): {basis}"
    return "Exact"


def field_stale_text(obj) -> str:
    """Why the field drawn is not the one of the current design ('' if it is)."""
    entry = session_cache.get_entry_cached(obj)
    if entry is not None and entry.extra.get("stale_reason") == "undo":
        return "Field out of date after undo" + (": solving in the background" if obj.nfield.live_update
                                                 else ": press Solve")
    return ""


class NFIELD_PT_main(_NFieldPanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_main"
    bl_label = "nfield"

    @classmethod
    def poll(cls, context):
        return True

    def draw(self, context):
        layout = self.layout
        width = wrap_width(context)
        if state.native_problem:
            box = layout.box()
            box.alert = True
            box.label(text="The compiled solver cannot be loaded:", icon="ERROR")
            wrapped_labels(box, state.native_problem, width)
            return
        obj = _mesh_object(context)
        if obj is None:
            layout.label(text="Select a mesh object", icon="INFO")
            return
        st = obj.nfield
        self.draw_tools(context, layout)

        col = _split(layout)
        col.prop(st, "symmetry")
        col.prop(st, "energy")
        col.prop(st, "alignment")
        if st.alignment == "ATTRIBUTE":
            col.prop_search(st, "alignment_attribute", obj.data, "attributes", text="Attribute")
        if st.alignment != "NONE":
            col.prop(st, "strength")
        col.prop(st, "solver_mode", expand=True)
        if st.solver_mode == "SPECTRAL":
            col.prop(st, "spectral_k")
            # its own full-width row: beside the number field the button's text would be cut
            layout.operator("nfield.precompute_spectral", text="Precompute Basis", icon="FILE_REFRESH")
        col = _split(layout)
        col.prop(st, "live_update")
        layout.operator("nfield.solve", icon="PLAY")
        self.draw_status(context, layout, obj, width)

    @staticmethod
    def draw_tools(context, layout):
        tool = context.workspace.tools.from_space_view3d_mode(context.mode, create=False) \
            if context.workspace is not None and context.mode == "OBJECT" else None
        active = getattr(tool, "idname", "")
        col = layout.column(align=True)  # stacked: side by side their texts would be cut at the default width
        col.enabled = context.mode == "OBJECT"
        for idname, text, icon in TOOL_BUTTONS:
            col.operator("wm.tool_set_by_id", text=text, icon=icon, depress=(active == idname)).name = idname

    @staticmethod
    def draw_status(context, layout, obj, width):
        st = obj.nfield
        box = layout.box()
        col = box.column(align=True)
        if st.last_solver_state:
            wrapped_labels(col, f"Solved in {st.last_solve_seconds:.2f} s ({st.last_solver_state})", width,
                           icon="TIME")
        if st.solver_mode == "SPECTRAL" or not st.last_solver_state:  # exact: the line above says it
            wrapped_labels(col, solver_state_text(obj), width, icon="SETTINGS")
        stale = field_stale_text(obj)
        if stale:
            sub = box.column(align=True)
            sub.alert = True
            wrapped_labels(sub, stale, width, icon="ERROR")
        if st.last_message:
            sub = box.column(align=True)
            sub.alert = st.last_message.startswith("Solve failed")
            wrapped_labels(sub, st.last_message, width, icon="INFO")
        invalid = design.invalid_for_n(obj)
        if st.num_stale or invalid:
            sub = box.column(align=True)
            sub.alert = True
            if st.num_stale:
                wrapped_labels(sub, f"{st.num_stale} stale item(s): the mesh changed", width, icon="ERROR")
            for message in invalid:
                wrapped_labels(sub, message, width, icon="ERROR")


class NFIELD_PT_constraints(NFieldSubpanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_constraints"
    bl_label = "Constraints"

    def draw(self, context):
        st = _mesh_object(context).nfield
        layout = self.layout
        side = _list_with_side(layout, "NFIELD_UL_constraints", st, "constraints", "active_constraint_index", 3,
                               "nfield.constraint_remove")
        side.separator()
        side.operator("nfield.constraint_clear", icon="X", text="").stale_only = False
        if any(c.stale for c in st.constraints):
            layout.operator("nfield.constraint_clear", text="Remove Stale").stale_only = True


class NFIELD_PT_singularities(NFieldSubpanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_singularities"
    bl_label = "Singularities"

    def draw(self, context):
        st = _mesh_object(context).nfield
        _list_with_side(self.layout, "NFIELD_UL_singularities", st, "singularities", "active_singularity_index", 2,
                        "nfield.singularity_remove")


class NFIELD_PT_region(NFieldClosedSubpanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_region"
    bl_label = "Region"

    def draw(self, context):
        obj = _mesh_object(context)
        st = obj.nfield
        layout = self.layout
        if st.region_active:
            layout.label(text=f"Editing {len(st.region_faces)} faces", icon="EDITMODE_HLT")
            row = layout.row(align=True)
            row.operator("nfield.region_commit", icon="CHECKMARK")
            row.operator("nfield.region_cancel", icon="CANCEL")
        else:
            if obj.mode != "EDIT":
                layout.label(text="Select faces in Edit Mode", icon="INFO")
            layout.operator("nfield.region_begin", text="Begin Region from Selection")
        if st.layers:
            _list_with_side(layout, "NFIELD_UL_layers", st, "layers", "active_layer_index", 2, "nfield.layer_release")


class NFIELD_PT_display(NFieldClosedSubpanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_display"
    bl_label = "Display"

    def draw(self, context):
        st = _mesh_object(context).nfield
        col = _split(self.layout)
        col.prop(st, "show_field", text="Field")
        sub = col.column()
        sub.active = st.show_field
        sub.prop(st, "glyph_density", text="Density")
        sub.prop(st, "glyph_scale", text="Scale")
        col.prop(st, "show_constraints", text="Constraints")
        col.prop(st, "show_singularities", text="Singularities")


class NFIELD_PT_output(NFieldClosedSubpanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_output"
    bl_label = "Output"

    def draw(self, context):
        st = _mesh_object(context).nfield
        col = _split(self.layout)
        col.prop(st, "write_attributes", text="Write After Solve")
        col.prop(st, "direction_attribute")
        col.prop(st, "smooth_attribute", text="Smooth")
        col.prop(st, "singularity_attribute", text="Singularity")
        self.layout.operator("nfield.write_attributes", icon="FILE_TICK")


class NFIELD_PT_shading(NFieldClosedSubpanel, bpy.types.Panel):
    bl_idname = "NFIELD_PT_shading"
    bl_label = "Shading"

    def draw(self, context):
        layout = self.layout
        layout.operator("nfield.material_anisotropic", icon="MATERIAL")
        wrapped_labels(layout, "Anisotropy renders in Cycles; EEVEE ignores it.", wrap_width(context),
                       icon="INFO")
        layout.operator("nfield.hatching", icon="STROKE")
        wrapped_labels(layout, "Hatching options: the operator's redo panel (bottom left).",
                       wrap_width(context))


#: the subpanels of the nfield tab, in drawing order (new features add theirs here)
SUBPANELS = [
    NFIELD_PT_constraints,
    NFIELD_PT_singularities,
    NFIELD_PT_region,
    NFIELD_PT_display,
    NFIELD_PT_output,
    NFIELD_PT_shading,
]

LISTS = (NFIELD_UL_constraints, NFIELD_UL_singularities, NFIELD_UL_layers)


def register():
    for cls in (*LISTS, NFIELD_PT_main, *SUBPANELS):
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed((*LISTS, NFIELD_PT_main, *SUBPANELS)):
        bpy.utils.unregister_class(cls)
