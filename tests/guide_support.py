"""Helpers of the headless Blender guide tests (test_blender_guides.py, test_blender_guide_tools.py): mesh
objects with Live Update off, poly curves, and the angle between the field and a line. Imports bpy (through
blender_support), so only Blender-suite files import it."""
from __future__ import annotations

import importlib
import math

import numpy as np
from blender_support import blender_module, bpy, object_from_arrays

import meshgen


def guide_core(nf):
    return importlib.import_module(nf.__name__ + ".core")


def guide_api(nf):
    return blender_module(nf, "api")


def still_object(name, V, F):
    """A mesh object from arrays with Live Update off (the test solves when it wants)."""
    obj = object_from_arrays(name, V, F)
    obj.nfield.live_update = False
    return obj


def ellipsoid_object(name="ellipsoid"):
    """(object, V, F): an icosphere scaled to an ellipsoid (symmetric about every coordinate plane, with
    varying curvature), Live Update off."""
    V, F = meshgen.icosphere(3)
    V = V * [1.0, 0.8, 0.6]
    return still_object(name, V, F), V, F


def poly_curve(name, points):
    cd = bpy.data.curves.new(name, "CURVE")
    cd.dimensions = "3D"
    sp = cd.splines.new("POLY")
    sp.points.add(len(points) - 1)
    for p, xyz in zip(sp.points, points):
        p.co = (*xyz, 1.0)
    ob = bpy.data.objects.new(name, cd)
    bpy.context.collection.objects.link(ob)
    return ob


def move_curve(curve, points):
    """New points for the first spline of a poly curve object, and the depsgraph update that follows an edit."""
    for p, xyz in zip(curve.data.splines[0].points, points):
        p.co = (*xyz, 1.0)
    curve.data.update_tag()
    bpy.context.view_layer.update()


def line_deviation(result, faces, direction):
    """Per face: degrees between the line of `direction` and the nearest of the field's directions."""
    u = np.asarray(direction, dtype=np.float64) / np.linalg.norm(direction)
    alld = np.asarray(result.all_directions())
    return [math.degrees(math.acos(min(1.0, float(np.abs(alld[f] @ u).max())))) for f in faces]


def faces_along(V, F, start, direction, tol):
    """Faces whose centroid lies within `tol` of the line start + t direction. With `tol` below the inradius
    (grid triangles: right isosceles with legs h, inradius (2 - sqrt 2) h / 2 = 0.29 h) the line crosses them."""
    c = V[F].mean(axis=1) - start
    d = np.asarray(direction) / np.linalg.norm(direction)
    dist = np.linalg.norm(c - np.outer(c @ d, d), axis=1)
    return np.flatnonzero(dist < tol)
