"""The guide part of the scripting API (re-exported by `api` and by the package): feature alignment, guide
attributes, curve guides, mirror symmetry, cuts and the comb.

Guides are stored settings (obj.nfield_guides, guide_properties) read again at every solve
(session_cache -> guide_session). Each function writes them, then checks them against the mesh at once (the
session is configured, not solved): on a problem the previous settings come back and NFieldError names it.
"""
from __future__ import annotations

import math
from typing import Iterable

import numpy as np

from ..core import DirectionConstraint, SingularityConstraint, VectorConstraint
from . import design, guides, session_cache
from .errors import NFieldError
from .mesh_read import check_mesh_object
from .object_session import ensure_idle, open_session

_GUIDE_MODES = ("soft", "hard")


def _guide_settings(obj):
    check_mesh_object(obj)
    g = getattr(obj, "nfield_guides", None)
    if g is None:
        raise NFieldError("the guide settings are not registered (enable the nfield add-on)")
    return g


def _guide_snapshot(g) -> dict:
    keep = {p.identifier: getattr(g, p.identifier) for p in g.bl_rna.properties
            if p.identifier not in ("rna_type", "curves") and not p.is_readonly}
    keep["curves"] = [{p.identifier: getattr(c, p.identifier) for p in c.bl_rna.properties
                       if p.identifier != "rna_type" and not p.is_readonly} for c in g.curves]
    return keep


def _guide_restore(g, saved: dict) -> None:
    for key, value in saved.items():
        if key != "curves" and getattr(g, key) != value:
            setattr(g, key, value)
    g.curves.clear()
    for values in saved["curves"]:
        item = g.curves.add()
        for key, value in values.items():
            setattr(item, key, value)


def _edit_guides(obj, edit) -> None:
    """Apply edit(guide settings) without re-solving per property, then check the guides against the mesh by
    configuring the session; restore the previous settings on a problem."""
    g = _guide_settings(obj)
    ensure_idle(obj)
    saved = _guide_snapshot(g)
    try:
        with design.suspended_updates():
            edit(g)
        open_session(obj)
    except (ValueError, RuntimeError) as exc:
        with design.suspended_updates():
            _guide_restore(g, saved)
        if isinstance(exc, NFieldError):
            raise
        raise NFieldError(str(exc)) from None


def _guide_mode(mode: str, what: str) -> str:
    m = str(mode).lower()
    if m not in _GUIDE_MODES:
        raise NFieldError(f"{what} mode must be 'soft' or 'hard' (got {mode!r})")
    return m.upper()


def set_feature_alignment(obj, enabled: bool = True, *, boundary: bool | None = None, dihedral: bool | None = None,
                          angle: float | None = None, marked: Iterable[str] | None = None, mode: str | None = None,
                          weight: float | None = None, width: int | None = None, every: int | None = None) -> None:
    """Align the field with feature edges (None keeps a setting). Features: boundary edges, edges bending by
    more than `angle` degrees (dihedral=True), and `marked` edges: any of "sharp", "seam", "face_sets",
    "materials" (edges marked sharp / seam, face-set and material-slot borders). mode "soft": alignment on
    `width` edge rings with `weight` (relative to the base guide); "hard": direction constraints on the faces
    next to every `every`-th feature edge, contradictions at corners dropped and reported (guide_report)."""
    sources = None
    if marked is not None:
        sources = {str(m).upper() for m in ([marked] if isinstance(marked, str) else marked)}
        unknown = sources - set(guides.MARKED_SOURCES)
        if unknown:
            raise NFieldError(f"unknown marked edge source(s) {sorted(unknown)} (expected sharp, seam, face_sets, "
                              f"materials)")
    m = None if mode is None else _guide_mode(mode, "feature")

    def edit(g):
        g.use_features = bool(enabled)
        if boundary is not None:
            g.feature_boundary = bool(boundary)
        if dihedral is not None:
            g.feature_use_angle = bool(dihedral)
        if angle is not None:
            g.feature_angle = _number(angle, "feature angle (degrees)", 0.0, 179.0)
        if sources is not None:
            g.feature_sharp, g.feature_seam = "SHARP" in sources, "SEAM" in sources
            g.feature_face_sets, g.feature_materials = "FACE_SETS" in sources, "MATERIALS" in sources
        if m is not None:
            g.feature_mode = m
        if weight is not None:
            g.feature_weight = _number(weight, "feature weight", 0.0, None)
        if width is not None:
            g.feature_width = _whole(width, "feature width (edge rings)")
        if every is not None:
            g.feature_every = _whole(every, "feature 'every'")

    _edit_guides(obj, edit)


def _number(value, what: str, lo: float | None, hi: float | None) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if isinstance(value, bool) or not math.isfinite(x) or (lo is not None and x < lo) or (hi is not None and x > hi):
        rng = " and ".join(t for t in ((f">= {lo:g}" if lo is not None else ""), (f"<= {hi:g}" if hi is not None
                                                                                    else "")) if t)
        raise NFieldError(f"{what} must be a finite number {rng} (got {value!r})")
    return x


def _whole(value, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or int(value) < 1:
        raise NFieldError(f"{what} must be an integer >= 1 (got {value!r})")
    return int(value)


def set_guide_attributes(obj, *, weight: str | None = None, rotation: str | None = None) -> None:
    """Per-face guide weight and rotation from face FLOAT attributes (e.g. painted with Blender's attribute
    painting): `weight` (>= 0) scales the base alignment per face, 0 removes it there; `rotation` (radians)
    turns it. "" switches one off, None keeps it."""
    def edit(g):
        if weight is not None:
            g.weight_attribute = str(weight)
        if rotation is not None:
            g.rotation_attribute = str(rotation)

    _edit_guides(obj, edit)


def add_curve_guide(obj, curve, *, mode: str = "soft", weight: float = 1.0, width: float = 0.02,
                    tolerance: float = 0.01, every: int = 1):
    """Guide the field with the tangents of curve object `curve` (a curve or curves object), projected onto
    the surface; re-adding a curve changes its options. width and tolerance are fractions of the mesh's
    bounding-box diagonal; parts farther than `tolerance` from the surface are ignored and reported. The
    guide keeps a reference to the curve: editing the curve re-solves (Live Update). Returns the item."""
    if getattr(curve, "type", None) not in guides.CURVE_TYPES:
        raise NFieldError(f"{getattr(curve, 'name', curve)!r} is not a curve or curves object")
    m = _guide_mode(mode, "curve")
    values = dict(mode=m, weight=_number(weight, "curve weight", 0.0, None),
                  width=_number(width, "curve width", 0.0, 1.0),
                  tolerance=_number(tolerance, "curve tolerance", 0.0, 1.0), every=_whole(every, "curve 'every'"))

    def edit(g):
        item = next((c for c in g.curves if c.curve == curve), None)
        if item is None:
            item = g.curves.add()
            item.curve = curve
            g.active_curve_index = len(g.curves) - 1
        for key, value in values.items():
            setattr(item, key, value)

    _edit_guides(obj, edit)
    return next(c for c in _guide_settings(obj).curves if c.curve == curve)


def remove_curve_guide(obj, curve) -> None:
    """Stop guiding with `curve` (the curve object, or the index of the curve guide)."""
    g = _guide_settings(obj)
    if isinstance(curve, (int, np.integer)) and not isinstance(curve, bool):
        index = int(curve)
        if not 0 <= index < len(g.curves):
            raise NFieldError(f"curve guide {index} does not exist (the object has {len(g.curves)})")
    else:
        index = next((i for i, c in enumerate(g.curves) if c.curve == curve), None)
        if index is None:
            raise NFieldError(f"{getattr(curve, 'name', curve)!r} is not a curve guide of '{obj.name}'")

    def edit(g):
        g.curves.remove(index)
        g.active_curve_index = max(0, min(g.active_curve_index, len(g.curves) - 1))

    _edit_guides(obj, edit)


def set_mirror_symmetry(obj, axis: str | None, *, offset: float = 0.0, tolerance: float = 1e-5,
                        partial: bool = False) -> dict | None:
    """Make the field mirror-symmetric about the plane {axis = offset} of the object ("x", "y", "z"; None:
    off): the solve holds u(mirror f) = reflect(u(f)) exactly. Faces without a partner within `tolerance`
    (fraction of the diagonal) refuse with their list, or with partial=True the symmetry holds on the
    matched faces. Returns the matching summary (matched, unmatched faces, largest mismatch)."""
    a = "NONE" if axis is None else str(axis).upper()
    if a not in ("NONE", "X", "Y", "Z"):
        raise NFieldError(f"mirror axis must be 'x', 'y', 'z' or None (got {axis!r})")
    off = _number(offset, "mirror offset", None, None)
    tol = _number(tolerance, "mirror tolerance (fraction of the diagonal)", 0.0, 0.1)

    def edit(g):
        g.mirror_axis, g.mirror_offset, g.mirror_tolerance, g.mirror_partial = a, off, tol, bool(partial)

    _edit_guides(obj, edit)
    if a == "NONE":
        return None
    return open_session(obj)[2].symmetry_info


def set_cuts(obj, source: str | None, attribute: str = "") -> None:
    """Cut the connection along marked edges: source "seams" (edges marked as seams), "attribute" (the edges
    where the EDGE attribute `attribute` is set) or None (no cuts). The field may jump across a cut."""
    s = "NONE" if source is None else str(source).upper()
    if s not in ("NONE", "SEAMS", "ATTRIBUTE"):
        raise NFieldError(f"cut source must be 'seams', 'attribute' or None (got {source!r})")

    def edit(g):
        g.cut_source = s
        if s == "ATTRIBUTE":
            g.cut_attribute = str(attribute)

    _edit_guides(obj, edit)


def guide_report(obj) -> dict | None:
    """What the guides did in the last solve of `obj` (nfield.core GuideReport.to_dict(): feature edges and
    chains, corners, hard constraints and the dropped ones with reasons, curves that miss the surface, cuts,
    symmetry), or None when it was not solved since the mesh last changed."""
    entry = session_cache.get_entry_cached(obj)
    report = None if entry is None or entry.session is None else entry.session.guide_report
    return None if report is None else report.to_dict()


def comb(obj, points, directions, *, radius: float = 0.03, falloff: str = "smooth", strength: float = 1.0,
         mirror: bool = False) -> int:
    """One comb stroke: samples (points on the surface and drag directions, object space) paint guide
    directions within `radius` (fraction of the bounding-box diagonal) with a falloff ("smooth", "linear",
    "constant") and a strength in (0, 1]. Strokes accumulate into the comb field, stored in the face attributes
    guides.COMB_DIRECTION / COMB_WEIGHT (saved, undoable); the comb field guides the next solve. With `mirror`
    and mirror symmetry on, the stroke also paints the mirror images of its samples (what the comb tool does).
    Returns the number of faces the stroke changed."""
    ensure_idle(obj)
    _arrays, _entry, session = open_session(obj)
    try:
        if mirror:
            points, directions, _note = comb_samples(session, points, directions)
        changed = session.comb(points, directions, radius, falloff, strength)
    except ValueError as exc:
        raise NFieldError(str(exc)) from None
    store_comb(obj, session)
    return int(len(changed))


def clear_comb(obj) -> bool:
    """Remove the comb field (its attributes). Returns True if there was one."""
    check_mesh_object(obj)
    found = guides.remove_comb_field(obj)
    open_session(obj)
    return found


def guide_summary(obj) -> list[str]:
    """guide_report as readable lines (the panel shows them); [] when there is nothing to say."""
    entry = session_cache.get_entry_cached(obj)
    report = None if entry is None or entry.session is None else entry.session.guide_report
    return [] if report is None else report.summary()


def mirror_placements(session, item) -> tuple[list, str]:
    """[item] and, with mirror symmetry on, its mirror image (an nfield.core DirectionConstraint,
    VectorConstraint or SingularityConstraint at the partner face / vertex): what the design tools place in
    one step. The note says when the item has no mirror partner (partial symmetry; empty otherwise). An item
    on the mirror plane is its own image."""
    if session.symmetry is None:
        return [item], ""
    image = session.mirrored(item)
    where = f"vertex {item.vertex}" if isinstance(item, SingularityConstraint) else f"face {item.face}"
    if image is None:
        return [item], f"{where} has no mirror partner: placed on this side only"
    same = image.vertex == item.vertex if isinstance(item, SingularityConstraint) else image.face == item.face
    return ([item] if same else [item, image]), ""


def comb_samples(session, points, directions) -> tuple[np.ndarray, np.ndarray, str]:
    """The samples of a comb stroke (object space) and, with mirror symmetry on, their mirror images (one
    stroke paints both sides), with a note on samples whose face has no mirror partner (empty otherwise)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if session.symmetry is None or not len(p):
        return p, d, ""
    mp, md, unmatched = session.mirrored_samples(p, d)
    note = (f"{len(unmatched)} of {len(p)} comb samples lie on faces without a mirror partner: not mirrored"
            if unmatched else "")
    return np.concatenate([p, mp]), np.concatenate([d, md]), note


def store_comb(obj, session) -> None:
    """Write the session's comb field into the comb face attributes (saved, undoable) and make the session
    hold exactly what the file holds (float32 attributes)."""
    guides.write_comb_field(obj, *session.comb_field)
    session.set_comb(*guides.comb_field(obj))


def mirror_design(obj) -> int:
    """Add the mirror image of every constraint and singularity of the design that has none yet (mirror
    symmetry must be on). Returns how many items were added."""
    arrays, entry, session = open_session(obj)
    if session.symmetry is None:
        raise NFieldError("mirror symmetry is off: set a mirror axis first")
    st = obj.nfield
    dirs, sings = design.desired_design(obj)
    added = 0
    for face, (kind, d) in sorted(dirs.items()):
        c = (VectorConstraint if kind == "VECTOR" else DirectionConstraint)(face, d)
        m = session.mirrored(c)
        if m is None or m.face in dirs:
            continue
        design.set_constraint(obj, m.face, m.vector if kind == "VECTOR" else m.direction, kind,
                              arrays.polygon_centers[m.face])
        added += 1
    for vertex, index in sorted(sings.items()):
        m = session.mirrored(SingularityConstraint(vertex, index))
        if m is None or m.vertex in sings:
            continue
        design.set_singularity(obj, m.vertex, int(round(index * st.n)), arrays.vertices[m.vertex])
        added += 1
    return added
