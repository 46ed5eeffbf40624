"""nfield.core: the pure-Python API over the compiled module (no bpy).

    from nfield.core import Mesh, DirectionConstraint, solve
    mesh = Mesh.from_file("rocker-arm.obj")
    result = solve(mesh, n=4, order=2, constraints=[DirectionConstraint(17, (1.0, 0.0, 0.0))])
    result.directions      # (F, 3) first unit direction per face

The compiled module ``nfield._native`` is imported on first use (see :func:`native`).

Parameter rules every front end shares (the command line and the Blender layer import them from here):
``MIN_STRENGTH`` / ``MAX_STRENGTH`` (admissible alignment strengths), ``TANGENT_TOLERANCE`` (a direction whose
tangent part is shorter than this fraction of its length counts as normal to the face) and
``INDEX_TOLERANCE`` (how far index x n may be from an integer).
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
from .session import DesignSession, Layer
from .spectral import DEFAULT_K, BasisInfo, default_cache_dir, load_or_compute_basis, low_pass
from .solve import (
    ALIGN_CHOICES,
    INDEX_TOLERANCE,
    MAX_STRENGTH,
    MIN_STRENGTH,
    TANGENT_TOLERANCE,
    WEIGHT_CHOICES,
    FieldResult,
    eigenvalues,
    smoothest_field,
    solve,
)
from .streamlines import Strokes, trace_streamlines
from .remesh import QuadMesh, field_directions, field_singularities, quad_mesh_stats, quad_remesh, write_polygon_obj


def __getattr__(name):
    # The native exception class, without importing the compiled module before it is needed.
    if name == "Cancelled":
        return native().Cancelled
    raise AttributeError(f"module 'nfield.core' has no attribute {name!r}")

__all__ = [
    "Mesh",
    "SUPPORTED_EXTENSIONS",
    "DirectionConstraint",
    "VectorConstraint",
    "SingularityConstraint",
    "load_constraints",
    "constraint_from_dict",
    "solve",
    "DesignSession",
    "Layer",
    "DEFAULT_K",
    "BasisInfo",
    "default_cache_dir",
    "load_or_compute_basis",
    "low_pass",
    "FieldResult",
    "eigenvalues",
    "smoothest_field",
    "ALIGN_CHOICES",
    "WEIGHT_CHOICES",
    "MIN_STRENGTH",
    "MAX_STRENGTH",
    "TANGENT_TOLERANCE",
    "INDEX_TOLERANCE",
    "native",
    "NativeModuleError",
    "Strokes",
    "trace_streamlines",
    "QuadMesh",
    "quad_remesh",
    "quad_mesh_stats",
    "field_directions",
    "field_singularities",
    "write_polygon_obj",
]
