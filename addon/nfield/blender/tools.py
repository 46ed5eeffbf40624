"""Interactive viewport tools: the toolbar entries of the 3D view (object mode) and their registration.

* *Field Constraint*: ``nfield.constraint_tool`` (LMB drag), ``nfield.constraint_delete`` (X, Del); module
  ``tool_constraint``;
* *Field Singularity*: ``nfield.singularity_tool`` (LMB), ``nfield.singularity_delete`` (X, Del); module
  ``tool_singularity``;
* *Comb*: ``nfield.comb_tool`` (LMB drag), its brush settings in the tool header, the brush circle as its
  cursor; module ``tool_comb``.

What the tools share (picking on the mesh, the header text, the live session, the press / drag / release
handling) is in ``tool_common``.
In background Blender (no window) only the operators are registered: there is no toolbar.
"""
from __future__ import annotations

import bpy
from bpy.types import WorkSpaceTool

from . import tool_comb, tool_constraint, tool_singularity

CONSTRAINT_HINT = ("Field Constraint: drag on a face to aim | drag from an arrow to re-aim | "
                   "X/Del: delete constraint under cursor | Esc/RMB during drag: cancel")
COMB_HINT = ("Comb: drag over the surface to paint guide directions (radius, strength and falloff in the tool "
             "header) | Esc/RMB during a stroke: cancel it")
SINGULARITY_HINT = ("Field Singularity: click near a vertex, then Wheel / +- / 1-9 to pick the index, "
                    "Minus flips sign, LMB/Enter to confirm, Esc/RMB to cancel | X/Del: remove pinned singularity")


def _keymap(press_operator: str, delete_operator: str) -> tuple:
    """LMB press starts the tool's modal operator; X and Del delete the item under the cursor."""
    return ((press_operator, {"type": "LEFTMOUSE", "value": "PRESS"}, None),
            (delete_operator, {"type": "X", "value": "PRESS"}, None),
            (delete_operator, {"type": "DEL", "value": "PRESS"}, None))


class _NFieldTool(WorkSpaceTool):
    """What both toolbar entries share: the 3D view in object mode, no gizmo."""

    bl_space_type = "VIEW_3D"
    bl_context_mode = "OBJECT"
    bl_widget = None


class NFIELD_TL_constraint(_NFieldTool):
    bl_idname = "nfield.tool_constraint"
    bl_label = "Field Constraint"
    bl_description = CONSTRAINT_HINT
    bl_icon = "ops.gpencil.primitive_line"
    bl_keymap = _keymap("nfield.constraint_tool", "nfield.constraint_delete")


class NFIELD_TL_singularity(_NFieldTool):
    bl_idname = "nfield.tool_singularity"
    bl_label = "Field Singularity"
    bl_description = SINGULARITY_HINT
    bl_icon = "ops.transform.tosphere"
    bl_keymap = _keymap("nfield.singularity_tool", "nfield.singularity_delete")


class NFIELD_TL_comb(WorkSpaceTool):
    bl_space_type = "VIEW_3D"
    bl_context_mode = "OBJECT"
    bl_idname = "nfield.tool_comb"
    bl_label = "Comb"
    bl_description = COMB_HINT
    bl_icon = "brush.particle.comb"
    bl_widget = None
    bl_keymap = (("nfield.comb_tool", {"type": "LEFTMOUSE", "value": "PRESS"}, None),)

    @staticmethod
    def draw_settings(context, layout, tool):
        props = tool.operator_properties(tool_comb.NFIELD_OT_comb_tool.bl_idname)
        layout.prop(props, "radius")
        layout.prop(props, "strength")
        layout.prop(props, "falloff", text="")

    draw_cursor = staticmethod(tool_comb.draw_cursor)


classes = tool_constraint.classes + tool_singularity.classes + tool_comb.classes
_tools = (NFIELD_TL_constraint, NFIELD_TL_singularity, NFIELD_TL_comb)
_registered_tools: list = []


#: the block the tools go after: the transform tools (Move ... Transform) of the object-mode toolbar
AFTER_TOOL = "builtin.scale_cage"


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    if bpy.app.background:
        return  # no toolbar without a window
    # Each tool is a group of its own (a one-tool group draws as a plain button): register_tool then inserts
    # it at the top level after the group holding `after` (the Scale group) and its block, so the
    # separator lands between blocks. group=False would put the tools and a None separator *inside* the
    # Scale flyout, which breaks every toolbar query (_tool_get_group_by_id reads item.idname of the None).
    after = {AFTER_TOOL}
    for i, tool in enumerate(_tools):
        try:
            bpy.utils.register_tool(tool, after=after, separator=(i == 0), group=True)
            _registered_tools.append(tool)
        except Exception as exc:  # noqa: BLE001 - an older/newer toolbar layout must not block the add-on
            print(f"nfield: cannot add the toolbar tool {tool.bl_label!r}: {exc}")
        after = {tool.bl_idname}


def toolbar_layout(context_mode: str = "OBJECT") -> list:
    """The 3D view toolbar of `context_mode` as nested lists of tool ids (None: a separator), for checks."""
    from bl_ui.space_toolsystem_common import ToolSelectPanelHelper

    cls = ToolSelectPanelHelper._tool_class_from_space_type("VIEW_3D")
    out = []

    def name(t):
        # a ToolDef is a namedtuple: ask for its id before treating tuples as groups
        return None if t is None else getattr(t, "idname", None) or repr(t)

    for item in cls._tools[context_mode]:
        if item is None or hasattr(item, "idname") or not isinstance(item, tuple):
            out.append(name(item))
        else:
            out.append([name(t) for t in item])
    return out


def unregister():
    for tool in reversed(_registered_tools):
        try:
            bpy.utils.unregister_tool(tool)
        except Exception:  # noqa: BLE001
            pass
    _registered_tools.clear()
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
