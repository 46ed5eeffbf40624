"""The stored guides (``obj.nfield_guides``) as ``nfield.core`` guide values, and applying them to a session.

:func:`desired_guides` reads the guide settings and their sources from Blender (marked edges, attributes,
curve objects, through ``guides``) into plain values: a ``FeatureGuide``, weight and rotation arrays,
``CurveGuide`` per curve spline, a ``Symmetry`` and the cut edges. :func:`apply_guides` makes a
``DesignSession`` hold exactly these, setting only what differs, so a solve whose guides did not change
redoes no feature detection, curve projection or mirror matching (and the session's own rule decides what
a change costs: weights and targets never refactor, cuts do; docs/guides.md).

Sources are read at every solve, not cached: marking an edge sharp or painting the weight attribute
changes no mesh signature, and the next solve must see it.
"""
from __future__ import annotations

import numpy as np

from ..core.guides import CurveGuide, FeatureGuide, Symmetry
from . import guides
from .errors import NFieldError

__all__ = ["desired_guides", "apply_guides", "curve_guide_names"]


def curve_guide_names(curve_name: str, count: int) -> list[str]:
    """Session names of the splines of one curve guide: "<object>" or "<object>[i]" for several splines."""
    return [curve_name] if count == 1 else [f"{curve_name}[{i}]" for i in range(count)]


def _features(obj, g) -> FeatureGuide | None:
    if not g.use_features:
        return None
    sources = [s for s, on in (("SHARP", g.feature_sharp), ("SEAM", g.feature_seam),
                               ("FACE_SETS", g.feature_face_sets), ("MATERIALS", g.feature_materials)) if on]
    edges = guides.marked_edges(obj, sources) if sources else None
    if not g.feature_boundary and not g.feature_use_angle and (edges is None or len(edges) == 0):
        what = ", ".join(s.lower().replace("_", " ") for s in sources) if sources else "no edge source"
        raise NFieldError(f"feature alignment is on but finds no feature edges ({what} selected): enable "
                          f"Boundary or Dihedral Angle, or mark edges")
    try:
        return FeatureGuide(boundary=g.feature_boundary,
                            sharp_angle=float(g.feature_angle) if g.feature_use_angle else None,
                            edges=edges, mode=g.feature_mode.lower(), weight=float(g.feature_weight),
                            width=int(g.feature_width), every=int(g.feature_every))
    except ValueError as exc:
        raise NFieldError(str(exc)) from None


def _curves(obj, g) -> dict[str, CurveGuide]:
    out: dict[str, CurveGuide] = {}
    for i, item in enumerate(g.curves):
        if item.curve is None:
            raise NFieldError(f"curve guide {i + 1} has no curve object: pick one or remove the guide")
        lines = guides.curve_polylines(item.curve, obj)
        for name, pts in zip(curve_guide_names(item.curve.name, len(lines)), lines):
            try:
                out[name] = CurveGuide(pts, mode=item.mode.lower(), weight=float(item.weight),
                                       width=float(item.width), tolerance=float(item.tolerance),
                                       every=int(item.every))
            except ValueError as exc:
                raise NFieldError(f"curve guide '{item.curve.name}': {exc}") from None
    return out


def _symmetry(g) -> Symmetry | None:
    if g.mirror_axis == "NONE":
        return None
    try:
        return Symmetry(g.mirror_axis.lower(), float(g.mirror_offset), float(g.mirror_tolerance),
                        bool(g.mirror_partial))
    except ValueError as exc:
        raise NFieldError(str(exc)) from None


def _cuts(obj, g) -> np.ndarray:
    if g.cut_source == "SEAMS":
        return guides.marked_edges(obj, ["SEAM"])
    if g.cut_source == "ATTRIBUTE":
        return guides.edge_attribute_edges(obj, g.cut_attribute)
    return np.zeros((0, 2), dtype=np.int64)


def desired_guides(obj) -> dict | None:
    """The guides `obj` asks for, as core values ({"features", "weight", "rotation", "curves", "symmetry",
    "cuts"}); None when the object has no guide settings (add-on part not registered). NFieldError naming
    the problem for a missing attribute, a curve without splines, an invalid setting."""
    g = getattr(obj, "nfield_guides", None)
    if g is None:
        return None
    weight = guides.face_values(obj, g.weight_attribute, "guide weight") if g.weight_attribute else None
    if weight is not None and (weight < 0).any():
        f = int(np.flatnonzero(weight < 0)[0])
        raise NFieldError(f"guide weight attribute '{g.weight_attribute}' is {weight[f]:g} at face {f}: weights "
                          f"must be >= 0")
    rotation = guides.face_values(obj, g.rotation_attribute, "guide rotation") if g.rotation_attribute else None
    return {"features": _features(obj, g), "weight": weight, "rotation": rotation, "curves": _curves(obj, g),
            "symmetry": _symmetry(g), "cuts": _cuts(obj, g), "comb": guides.comb_field(obj)}


def _same_array(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return a.shape == b.shape and bool(np.array_equal(a, b))


def _same_curve(a: CurveGuide, b: CurveGuide) -> bool:
    return _same_array(a.points, b.points) and (a.mode, a.every, a.weight, a.width, a.tolerance) == (
        b.mode, b.every, b.weight, b.width, b.tolerance)


def apply_guides(session, wanted: dict | None) -> bool:
    """Make `session` hold the guides `wanted` (desired_guides), setting only what differs. Returns True if
    anything changed. NFieldError with the core's message if the session refuses a guide (e.g. a mesh that
    is not mirror-symmetric)."""
    if wanted is None:
        return False
    changed = False
    try:
        if session.features != wanted["features"]:
            session.set_features(wanted["features"])
            changed = True
        if not _same_array(session.alignment_weight, wanted["weight"]):
            session.set_alignment_weight(wanted["weight"])
            changed = True
        if not _same_array(session.alignment_rotation, wanted["rotation"]):
            session.set_alignment_rotation(wanted["rotation"])
            changed = True
        have = session.curves
        for name in set(have) - set(wanted["curves"]):
            session.remove_curve(name)
            changed = True
        for name, curve in wanted["curves"].items():
            if name not in have or not _same_curve(have[name], curve):
                session.set_curve(name, curve)
                changed = True
        if session.symmetry != wanted["symmetry"]:
            session.set_symmetry(wanted["symmetry"])
            changed = True
        comb = wanted.get("comb")
        have_dirs, have_weights = session.comb_field
        if session.comb_stroke_active:
            pass  # a brush stroke in progress owns the comb field; the tool stores it at release
        elif comb is None:
            if have_weights.any():
                session.clear_comb()
                changed = True
        elif not (np.array_equal(have_weights, comb[1]) and np.array_equal(have_dirs, comb[0])):
            session.set_comb(comb[0], comb[1])
            changed = True
        cuts = wanted["cuts"]
        have_cuts = session.cuts
        if not (have_cuts.shape == cuts.shape and np.array_equal(have_cuts, cuts)):
            session.set_cuts(cuts if len(cuts) else None)
            changed = True
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    return changed
