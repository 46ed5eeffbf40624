"""nfield.core: the pure-Python API over the compiled module (no bpy).

    from nfield.core import Mesh, DirectionConstraint, solve
    mesh = Mesh.from_file("rocker-arm.obj")
    result = solve(mesh, n=4, order=2, constraints=[DirectionConstraint(17, (1.0, 0.0, 0.0))])
    result.directions      # (F, 3) first unit direction per face

The compiled module ``nfield._native`` is imported on first use (see :func:`native`).
"""
from ._loader import NativeModuleError, native
from .constraints import (
    DirectionConstraint,
    SingularityConstraint,
    VectorConstraint,
    constraint_from_dict,
    load_constraints,
)
from .mesh import SUPPORTED_EXTENSIONS, Mesh
from .solve import ALIGN_CHOICES, WEIGHT_CHOICES, FieldResult, eigenvalues, smoothest_field, solve

__all__ = [
    "Mesh",
    "SUPPORTED_EXTENSIONS",
    "DirectionConstraint",
    "VectorConstraint",
    "SingularityConstraint",
    "load_constraints",
    "constraint_from_dict",
    "solve",
    "FieldResult",
    "eigenvalues",
    "smoothest_field",
    "ALIGN_CHOICES",
    "WEIGHT_CHOICES",
    "native",
    "NativeModuleError",
]
