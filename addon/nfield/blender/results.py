"""Recording a new field: the one place a solve's result is stored.

:func:`store_result` is called after every successful solve, wherever it ran (``api.solve``, a region edit,
the background operators, the modal tools' live solves): it keeps the result in the object's session cache
entry (bumping the version the overlay watches), writes the solve bookkeeping shown in the panel
(``last_solve_seconds``, ``last_energy``, ``last_message``, ``spectral_ready``) and refreshes the overlay.
Writing the output attributes is separate (``attributes.write``), because some callers must not.
"""
from __future__ import annotations

from . import design, overlay


def store_result(obj, entry, result) -> None:
    """`result` (a FieldResult) is the object's current field; `entry` its session_cache.CacheEntry."""
    st = obj.nfield
    entry.result = result
    entry.version += 1
    st.last_solve_seconds = float(result.seconds)
    st.last_energy = float(result.energy)
    stale = design.stale_items(obj)
    st.last_message = (f"Solved: {len(result.singularities)} singularities"
                       + (f"; {len(stale)} stale item(s) ignored" if stale else ""))
    st.spectral_ready = bool(entry.session is not None and entry.session.has_basis)
    notify_overlay(obj, result, entry.arrays)


def notify_overlay(obj, result=None, arrays=None) -> None:
    """Tell the viewport overlay that the field (`result`, if given) or the design of `obj` changed.
    `arrays`: the mesh read `result` was solved on (saves the overlay a read of its own)."""
    try:
        overlay.refresh(obj, result, arrays)
    except Exception as exc:  # noqa: BLE001 - drawing problems must not break solving
        print(f"nfield: overlay refresh failed: {exc}")
