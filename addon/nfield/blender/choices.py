"""The values nfield's settings can take: Blender enum items, their mapping to ``nfield.core`` arguments,
and the numeric limits (taken from ``nfield.core``, never restated here).

Plain data, no ``bpy``: the properties, the scripting API and the operators all read these tables.
"""
from __future__ import annotations

from ..core import INDEX_TOLERANCE, MAX_STRENGTH, MIN_STRENGTH, TANGENT_TOLERANCE  # noqa: F401  (re-exported)

#: the symmetry orders the add-on offers (``nfield.core`` accepts more; the panel lists these)
SYMMETRIES = (1, 2, 3, 4, 6)

SYMMETRY_ITEMS = [
    ("1", "1 (Vector)", "Vector field: one direction per face"),
    ("2", "2 (Line)", "Line field: two opposite directions per face"),
    ("3", "3", "3-direction field (120 degrees apart)"),
    ("4", "4 (Cross)", "Cross field: four directions 90 degrees apart"),
    ("6", "6", "6-direction field (60 degrees apart)"),
]
ENERGY_ITEMS = [
    ("HARMONIC", "Harmonic", "Order 1 (Dirichlet) energy: smoothest, singularities attract"),
    ("BIHARMONIC", "Biharmonic", "Order 2 energy: smooth spline-like interpolation (default)"),
    ("TRIHARMONIC", "Triharmonic", "Order 3 energy: even smoother interpolation"),
]
#: energy enum -> the order m of the m-harmonic energy
ENERGY_ORDER = {"HARMONIC": 1, "BIHARMONIC": 2, "TRIHARMONIC": 3}
ORDER_ENERGY = {v: k for k, v in ENERGY_ORDER.items()}

ALIGNMENT_ITEMS = [
    ("NONE", "None", "No alignment term"),
    ("CURVATURE_MAX", "Curvature Max", "Align to the principal direction of largest absolute curvature"),
    ("CURVATURE_MIN", "Curvature Min", "Align to the principal direction of smallest absolute curvature"),
    ("ATTRIBUTE", "Face Attribute", "Align to an existing face-domain FLOAT_VECTOR attribute"),
]
#: alignment enum -> nfield.core's ``align`` argument
ALIGNMENT_CORE = {"NONE": "none", "CURVATURE_MAX": "curvature-max", "CURVATURE_MIN": "curvature-min",
                  "ATTRIBUTE": "field"}
CORE_ALIGNMENT = {v: k for k, v in ALIGNMENT_CORE.items()}

SOLVER_MODE_ITEMS = [
    ("EXACT", "Exact", "Exact sparse solve (live editing re-uses one factorization)"),
    ("SPECTRAL", "Spectral", "Solve in the span of the k lowest eigenfields (needs a precomputed basis)"),
]
#: the anisotropic material (material.build): which attribute is the tangent, and the field or its perpendicular
SHADING_SOURCE_ITEMS = [
    ("FACE", "Face Direction", "The face attribute (one direction per polygon; exact for n = 2)"),
    ("POINT", "Smoothed Point Direction", "The smoothed point attribute (interpolated; smoother, may show seams)"),
]
SHADING_DIRECTION_ITEMS = [
    ("FIELD", "Field Direction", "Highlight stretched across the field: the tangent follows the field direction"),
    ("PERPENDICULAR", "Perpendicular", "The tangent is cross(normal, field direction) (for n = 2 and 4)"),
]
CONSTRAINT_KIND_ITEMS = [
    ("DIRECTION", "Direction", "Hard direction constraint: one of the n directions points along it"),
    ("VECTOR", "Vector", "Hard n-vector constraint: direction and magnitude"),
]
#: how a comb brush's influence falls off from its centre to its rim (nfield.core's falloff names)
COMB_FALLOFF_ITEMS = [
    ("smooth", "Smooth", "Smooth falloff to the brush rim"),
    ("linear", "Linear", "Linear falloff"),
    ("constant", "Constant", "Full strength up to the rim"),
]
