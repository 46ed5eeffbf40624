"""Settings of "Quad Remesh from Field", stored per object (``obj.nfield_remesh``, saved with the .blend).

The same option set is the operator's (``remesh_operator``): :func:`option_properties` defines both, and
:func:`api_options` turns either into the keyword arguments of ``api.quad_remesh`` / ``api.remesh_recipe``.
"""
from __future__ import annotations

import math

import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, PointerProperty
from bpy.types import PropertyGroup


def _switch(name: str, description: str, default: bool = True):
    """An on/off option."""
    return BoolProperty(name=name, default=default, description=description)


def option_properties() -> dict:
    """The remesh options as Blender property definitions (one dict per class that uses them)."""
    return {
        "target_faces": IntProperty(
            name="Target Faces", default=5000, min=10, soft_max=200000,
            description="About this many output faces (quads); ignored when Edge Length is set"),
        "use_edge_length": _switch("Use Edge Length", "Give the target edge length instead of a face count", False),
        "edge_length": FloatProperty(
            name="Edge Length", default=0.05, min=1e-6, soft_max=10.0, subtype="DISTANCE", unit="LENGTH",
            description="Target edge length of the quads, in object units"),
        "pure_quads": _switch("Pure Quads", "Only quads (the few triangles and pentagons paired by half rows of quads); off: "
                              "quad-dominant (a few triangles and pentagons where rows end)", False),
        "keep_boundary": _switch("Keep Boundary", "Output edges follow the open boundary"),
        "keep_sharp": _switch("Keep Sharp Edges", "Output edges follow edges whose dihedral angle exceeds Sharp Angle "
                              "(where the field runs along them)"),
        "sharp_angle": FloatProperty(
            name="Sharp Angle", default=math.radians(40.0), min=0.0, max=math.pi, subtype="ANGLE",
            description="Edges whose faces turn by more than this are kept as feature curves"),
        "pair_row_ends": _switch("Pair Row Ends", "Cancel the lattice's row ends with a minimum-cost flow: about 2-3 "
                                 "times fewer irregular vertices and 99% quads (off: the single pass of the position "
                                 "field)"),
        "solve_first": _switch("Solve First", "When the design changed since the last solve, solve it again before "
                               "remeshing (off: remesh the last solved field, with a warning)"),
        "seed": IntProperty(
            name="Seed", default=0, min=0,
            description="Seed of the lattice origins: the same seed gives the same mesh"),
    }


def api_options(src) -> dict:
    """Keyword arguments of api.quad_remesh from the settings or the operator `src`."""
    return {
        "target_faces": int(src.target_faces),
        "edge_length": float(src.edge_length) if src.use_edge_length else None,
        "pure_quads": bool(src.pure_quads),
        "keep_boundary": bool(src.keep_boundary),
        "sharp_angle": math.degrees(src.sharp_angle) if src.keep_sharp else None,
        "seed": int(src.seed),
        "cancel_position_singularities": bool(src.pair_row_ends),
        "solve_first": bool(src.solve_first),
    }


OPTION_NAMES = tuple(option_properties())


class NFieldRemeshSettings(PropertyGroup):
    """The object's remesh options (what the N-panel shows and the operator starts from)."""

    __annotations__ = option_properties()


def register():
    bpy.utils.register_class(NFieldRemeshSettings)
    bpy.types.Object.nfield_remesh = PointerProperty(type=NFieldRemeshSettings)


def unregister():
    del bpy.types.Object.nfield_remesh
    bpy.utils.unregister_class(NFieldRemeshSettings)
