"""Recording a new field: the one place a solve's result is stored.

:func:`store_result` is called after every successful solve, wherever it ran (``api.solve``, a region edit,
the background operators, the modal tools' live solves): it keeps the result in the object's session cache
entry (bumping the version the overlay watches), writes the solve bookkeeping shown in the panel
(``last_solve_seconds``, ``last_energy``, ``last_message``, ``last_solver_state``, ``spectral_ready``) and
refreshes the overlay. Writing the output attributes is separate (``attributes.write``), because some callers
must not.

Each stored result is also remembered under the key of what it was solved from (:func:`design_key`: mesh
signature, settings, design), a few per object, so that undo/redo can put back the field of a restored state
without solving (``handlers.on_undo_redo``).
"""
from __future__ import annotations

from . import design, overlay
from .guides import COMB_WEIGHT

#: results remembered per object for undo/redo: the last few states, and no more than HISTORY_BYTES of
#: arrays (a result holds a few arrays per face: about 0.2 KB per face, so 8 results of a 1M-face mesh would
#: take 1.6 GB; the byte bound keeps the newest that fit)
HISTORY_SIZE = 8
HISTORY_BYTES = 256 * 2**20


class Unkeyable(Exception):
    """The field depends on data the key cannot see cheaply (guides read from edges, attributes, curves)."""


def design_key(obj, entry) -> tuple:
    """What a field depends on, as a hashable value: the mesh signature, the settings, the design, the guide
    settings. Unkeyable when guides read data outside the settings (marked edges, face attributes, curve
    objects, a comb field): undo then always re-solves (in the background)."""
    st = obj.nfield
    dirs, sings = design.desired_design(obj)
    settings = tuple(getattr(st, k) for k in design.SETTING_KEYS if k != "live_update")
    return (entry.signature, settings, tuple(sorted(dirs.items())), tuple(sorted(sings.items())),
            design.design_state(obj), tuple(tuple(it.face for it in st.region_faces)) if st.region_active else (),
            _guide_key(obj))


def _guide_key(obj) -> tuple:
    g = getattr(obj, "nfield_guides", None)
    if g is None:
        return ()
    if (getattr(g, "use_features", False) or len(getattr(g, "curves", ())) or getattr(g, "weight_attribute", "")
            or getattr(g, "rotation_attribute", "") or getattr(g, "cut_source", "NONE") != "NONE"
            or obj.data.attributes.get(COMB_WEIGHT) is not None):
        raise Unkeyable(obj.name)
    return tuple((p.identifier, getattr(g, p.identifier)) for p in g.bl_rna.properties
                 if p.type in {"BOOLEAN", "INT", "FLOAT", "STRING", "ENUM"} and not getattr(p, "is_array", False)
                 and p.identifier != "rna_type")


def remembered_result(obj, entry):
    """The field solved earlier for exactly the object's current settings and design, or None."""
    try:
        key = design_key(obj, entry)
    except Exception:  # noqa: BLE001 - a design that cannot be read has no remembered field
        return None
    for k, result in entry.extra.get("history", ()):
        if k == key:
            return result
    return None


def solver_state_text(entry, result) -> str:
    """'exact' or 'spectral, 30 eigenfields, basis from cache' (the panel's solver line)."""
    if getattr(result, "mode", "exact") != "spectral":
        return "exact"
    info = getattr(entry.session, "basis_info", None) if entry.session is not None else None
    src = f", basis {info.source}" if info is not None else ""
    return f"spectral, {result.basis_size} eigenfields{src}"


def store_result(obj, entry, result) -> None:
    """`result` (a FieldResult) is the object's current field; `entry` its session_cache.CacheEntry."""
    st = obj.nfield
    entry.result = result
    entry.version += 1
    entry.extra.pop("stale_reason", None)
    st.last_solve_seconds = float(result.seconds)
    st.last_energy = float(result.energy)
    stale = st.num_stale  # items whose face / vertex the mesh lost
    invalid = design.invalid_for_n(obj)
    found = ("Solved live (the global solve follows)" if result.singularities is None  # solve(details=False)
             else f"Solved: {len(result.singularities)} singularities")
    st.last_message = (found
                       + (f"; {stale} stale item(s) ignored" if stale else "")
                       + ("".join(f"; {m}" for m in invalid)))
    st.last_solver_state = solver_state_text(entry, result)
    st.spectral_ready = bool(entry.session is not None and entry.session.has_basis)
    entry.extra["good_settings"] = tuple(getattr(st, k) for k in design.SETTING_KEYS)
    _remember(obj, entry, result)
    notify_overlay(obj, result, entry.arrays)


def _remember(obj, entry, result) -> None:
    if entry.session is not None and entry.session.comb_stroke_active:
        return  # a brush stroke in progress: the session holds a comb field the file does not have yet
    try:
        key = design_key(obj, entry)
    except Exception:  # noqa: BLE001
        return
    history = [(k, r) for k, r in entry.extra.get("history", ()) if k != key]
    history.append((key, result))
    history = history[-HISTORY_SIZE:]
    total = 0
    for i in range(len(history) - 1, -1, -1):  # newest first: keep what fits
        total += _result_bytes(history[i][1])
        if total > HISTORY_BYTES and i < len(history) - 1:
            history = history[i + 1:]
            break
    entry.extra["history"] = history


def _result_bytes(result) -> int:
    """Memory held by a result's arrays (its numpy attributes)."""
    return sum(v.nbytes for v in vars(result).values() if hasattr(v, "nbytes"))


def notify_overlay(obj, result=None, arrays=None) -> None:
    """Tell the viewport overlay that the field (`result`, if given) or the design of `obj` changed.
    `arrays`: the mesh read `result` was solved on (saves the overlay a read of its own)."""
    try:
        overlay.refresh(obj, result, arrays)
    except Exception as exc:  # noqa: BLE001 - drawing problems must not break solving
        print(f"nfield: overlay refresh failed: {exc}")
